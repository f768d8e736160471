#!/usr/bin/env python3
"""A minimal client of /ird/infer (``ird_ros.apps.call_inference``; also the ``ird-infer`` command).

    .venv/bin/python scripts/call_inference.py [--from-world] [--method ...] [--timeout 120]
"""

import sys

from ird_ros.apps.call_inference import main

if __name__ == "__main__":
    sys.exit(main())
