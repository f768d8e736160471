#!/usr/bin/env python3
"""Posterior reward per terrain for the latent_raw condition: IRD is uncertain about lava.

The program is ``ird_core.experiments.posterior_terrain.main``; ``--help`` lists the flags.
The MCMC hot path is single-threaded numpy, so BLAS is pinned to one thread before numpy loads
(multithreaded BLAS only oversubscribes small machines); set OPENBLAS_NUM_THREADS to override.
"""

import os
import sys

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from ird_core.experiments.posterior_terrain import main  # noqa: E402

if __name__ == "__main__":
    sys.exit(main())
