"""The graph's nodes, one module each, run as ``python -m ird_ros.nodes.<name>``: managed (lifecycle)
rclpy shells (``ird_ros.runtime.lifecycle.ManagedNode``) that validate input, call ``ird_core``
(through ``ird_ros.jobs``) and publish while active. On their own they configure and activate
themselves (``autostart``); the launcher starts them with ``autostart:=false`` and drives them."""
