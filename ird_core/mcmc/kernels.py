"""The MCMC kernels by name (the registry): each is an ``init``/``step`` pair shaped like blackjax,
one kernel per module, over the shared types of :mod:`ird_core.mcmc.base`.

- ``init(position (C, d), log_density) -> ChainState`` evaluates the target at the start;
- ``step(rng, state, log_density, params) -> (ChainState, StepInfo)`` makes one transition of
  every chain with ``KernelParams`` (per-chain step size, preconditioner, leapfrog steps) fixed by
  the caller, who owns adaptation (:mod:`ird_core.mcmc.adaptation`).

Kernels: ``rwm`` (:mod:`~ird_core.mcmc.rwm`), ``mala`` (:mod:`~ird_core.mcmc.mala`), ``hmc``
(:mod:`~ird_core.mcmc.hmc`), ``elliptical`` (:mod:`~ird_core.mcmc.elliptical_slice`),
``independence`` and ``independence_elliptical`` (:mod:`~ird_core.mcmc.independence`).
"""

from __future__ import annotations

import numpy as np

from ird_core.mcmc.base import Kernel
from ird_core.mcmc.elliptical_slice import ELLIPTICAL
from ird_core.mcmc.hmc import HMC
from ird_core.mcmc.independence import INDEPENDENCE, INDEPENDENCE_ELLIPTICAL
from ird_core.mcmc.mala import MALA
from ird_core.mcmc.rwm import RWM

__all__ = ["KERNEL_TABLE", "KERNELS", "TARGET_ACCEPT", "get_kernel", "num_leapfrog_steps", "step_sizes"]

#: The kernels by name.
KERNEL_TABLE: dict[str, Kernel] = {
    "rwm": RWM,
    "mala": MALA,
    "hmc": HMC,
    "elliptical": ELLIPTICAL,
    "independence": INDEPENDENCE,
    "independence_elliptical": INDEPENDENCE_ELLIPTICAL,
}
KERNELS: tuple[str, ...] = tuple(KERNEL_TABLE)
TARGET_ACCEPT: dict[str, float] = {name: k.target_accept for name, k in KERNEL_TABLE.items()}


def get_kernel(name: str) -> Kernel:
    """The kernel called ``name``; ValueError naming the ``kernel`` field otherwise."""
    if not isinstance(name, str) or name not in KERNEL_TABLE:
        raise ValueError(f"kernel: expected one of {KERNELS}, got {name!r}")
    return KERNEL_TABLE[name]


def num_leapfrog_steps(kernel: Kernel, step: float, trajectory_length: float, cap: int) -> int:
    """``clip(round(trajectory_length / step), 1, cap)`` for HMC, 1 for the other kernels."""
    return int(np.clip(round(trajectory_length / step), 1, cap)) if kernel.uses_trajectory else 1


def step_sizes(kernel: Kernel, step: float, num_chains: int, rng: np.random.Generator) -> np.ndarray:
    """Per-chain step sizes ``(C,)``: ``step`` times the kernel's random jitter factor, if any."""
    steps = np.full(num_chains, step)
    if kernel.step_jitter is not None:
        steps = steps * rng.uniform(*kernel.step_jitter, size=num_chains)
    return steps
