"""The graph's nodes, one module each, run as ``python -m ird_ros.nodes.<name>``: rclpy shells that
validate input, call ``ird_core`` (through ``ird_ros.jobs``) and publish."""
