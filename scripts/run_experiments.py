#!/usr/bin/env python3
"""Run the Lavaland experiments (Figure 4, the appendix factorial): ``ird-experiments``.

The program is ``ird_ros.apps.experiments.main`` (``ird_core.experiments.cli`` plus
``--via-ros``); ``--help`` lists the flags and outputs.
"""

import sys

from ird_ros.apps.experiments import main

if __name__ == "__main__":
    sys.exit(main())
