#!/usr/bin/env python3
"""Start the IRD ROS graph and supervise it (``ird_ros.apps.launch_graph``; also the ``ird-launch`` command).

    .venv/bin/python scripts/launch_graph.py [--nodes world,perception,...] [--private-domain] [--record DIR] ...
    .venv/bin/python scripts/launch_graph.py --private-domain --record DIR --mission 3 --mission-then-exit

It prints its ROS_DOMAIN_ID and the line a second shell runs to attach to the graph.

Every option is described by ``--help``.
"""

import sys

from ird_ros.apps.launch_graph import main

if __name__ == "__main__":
    sys.exit(main())
