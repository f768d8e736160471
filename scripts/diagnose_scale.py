#!/usr/bin/env python3
"""Where IRD goes wrong on robot-sized maps: ``ird_core.experiments.scale_cli`` (``--help``).
BLAS is pinned to one thread per process before numpy loads (the process pool uses every core).
"""

import os
import sys

for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(variable, "1")

from ird_core.experiments.scale_cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
