"""ird_ros: the ROS 2 Jazzy side of the Inverse Reward Design stack.

Nodes (world, perception, inference, planner, rob, recorder) wrap the pure-numpy
``ird_core`` library; ``ird_ros.conversions`` is the single place where numpy arrays
become ``ird_msgs`` / ``nav_msgs`` messages and back, and ``ird_ros.testing`` holds the
helpers tests use to run nodes in private ROS domains.
"""
