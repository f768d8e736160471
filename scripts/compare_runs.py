#!/usr/bin/env python3
"""Runs side by side as one setting varies: ``ird_core.experiments.compare_runs`` (``--help``)."""

import sys

from ird_core.experiments.compare_runs import main

if __name__ == "__main__":
    sys.exit(main())
