#!/usr/bin/env python3
"""Where IRD goes wrong on robot-sized maps: ``ird_core.experiments.scale_cli`` (``--help``)."""

import sys

from ird_core.experiments.scale_cli import main

if __name__ == "__main__":
    sys.exit(main())
