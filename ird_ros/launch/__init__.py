"""Starting the graph: process events, the ROS-free supervisor, the readiness probe and the
launcher."""
