"""Recorded bags, without ROS: rosbags typestore and reading (``storage``), crash-safe writing and
repair (``repair``, on the tolerant MCAP reader ``mcap_scan``), missions and question rounds from
recorded messages (``missions``, ``rounds``), plots (``plots``) and the analysis behind
``scripts/analyze_bag.py`` (``analysis``). Import from the modules; this package imports none."""
