"""The designer's web page: a ROS-free Tornado server (``server``) and its static files (``static/``)."""
