"""ird_ros: the ROS 2 Jazzy side of the Inverse Reward Design stack.

Nodes (world, perception, inference, planner, rob, recorder) wrap the pure-numpy
``ird_core`` library; ``ird_ros.conversions`` is the single place where numpy arrays
become ``ird_msgs`` / ``nav_msgs`` messages and back. ``ird_ros.launch.launcher`` starts the graph
(on the ROS-free ``ird_ros.launch.supervisor`` and the rclpy ``ird_ros.launch.readiness`` probe);
``ird_ros.graph.domains`` leases private ROS domains and ``ird_ros.client.waits`` waits on the graph
without sleeping, for scripts and tests alike; ``ird_ros.testing`` adds what only tests use
(helper node processes).
"""
