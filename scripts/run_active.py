#!/usr/bin/env python3
"""Run the designer-in-the-loop experiment (docs/spec.md section 7): ``ird-active``.

The program is ``ird_core.experiments.active_cli.main``; ``--help`` lists the flags and outputs.
BLAS is pinned to one thread per process before numpy loads (the process pool uses every core).
"""

import os
import sys

for variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(variable, "1")

from ird_core.experiments.active_cli import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
