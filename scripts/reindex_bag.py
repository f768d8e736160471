#!/usr/bin/env python3
"""Rebuild a bag whose recorder was killed, no ROS: ``ird-reindex-bag``.

The program is ``ird_ros.apps.reindex_bag.main``; ``--help`` lists the flags.
"""

import sys

from ird_ros.apps.reindex_bag import main

if __name__ == "__main__":
    sys.exit(main())
