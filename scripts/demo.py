#!/usr/bin/env python3
"""The demo mission (``ird_ros.apps.demo``; also the ``ird-demo`` command): run it with
``bash scripts/demo.sh [options]``, which sets up the venv and a private ROS domain first."""

import sys

from ird_ros.apps.demo import main

if __name__ == "__main__":
    sys.exit(main())
