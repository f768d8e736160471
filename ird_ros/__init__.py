"""ird_ros: the ROS 2 Jazzy side of the Inverse Reward Design stack (docs/spec.md section 6).

Sub-packages, by layer:

- ``nodes``: the graph's nodes (world, perception, inference, planner, rob, navigator, designer,
  recorder), thin rclpy shells over ``jobs`` (the ROS-free worker jobs and logic they call) and ``ird_core``;
- ``conversions``: the single place where numpy arrays become ``ird_msgs`` / ``nav_msgs`` messages
  and back; ``runtime``: what every node process runs on (start-up, parameters, worker pool);
- ``graph``: topic, service and node names, node table, private ROS domains; ``launch``: starts
  the graph; ``client``: one client of the graph for scripts and tests; ``apps``: the scripts;
- ``bags`` (recorded bags) and ``web`` (the designer's page): ROS-free.

Three ROS-free modules serve every layer: ``geometry`` (map frame <-> grid cells), ``stamps``
(header stamps as keys, nanoseconds, text) and ``waits`` (waiting on the graph without sleeps,
given an rclpy node). ``testing`` adds what only tests use. This package
imports nothing, so ``import ird_ros.geometry`` works on a machine without ROS.
"""
