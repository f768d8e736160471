#!/usr/bin/env python3
"""Summarise a recorded IRD bag and plot Rob's missions, without ROS: ``ird-analyze-bag``.

The program is ``ird_ros.apps.analyze_bag.main``; ``--help`` lists the flags and outputs.
"""

import sys

from ird_ros.apps.analyze_bag import main

if __name__ == "__main__":
    sys.exit(main())
