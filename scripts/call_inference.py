#!/usr/bin/env python3
"""A minimal client of /ird/infer (``ird_ros.apps.call_inference``; also the ``ird-infer`` command).

    .venv/bin/python scripts/call_inference.py [--from-world] [--method ...] [--timeout 120]

It searches the graph in ROS_DOMAIN_ID (printed first); attach to a graph's domain with
``export ROS_DOMAIN_ID=N; source scripts/lib/ros_env.sh && ird_ros_env``.
"""

import sys

from ird_ros.apps.call_inference import main

if __name__ == "__main__":
    sys.exit(main())
