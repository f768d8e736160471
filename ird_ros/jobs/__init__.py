"""The ROS-free work behind the nodes: typed, validated jobs that run in worker processes and
the logic the rclpy shells in ``ird_ros.nodes`` call."""
