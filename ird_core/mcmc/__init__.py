"""MCMC (the posterior's sampler engine, docs/spec.md section 3): kernels as blackjax-style
init/step pairs, one per module (``rwm``, ``mala``, ``hmc``, ``elliptical_slice``,
``independence``; by name in ``kernels``), their shared types (``base``), warm-up adaptation
(``adaptation``), batched chains (``chains``) and convergence diagnostics (``diagnostics``)."""

from __future__ import annotations

from ird_core.mcmc.adaptation import (
    DualAveraging,
    WarmupState,
    WarmupStep,
    estimate_preconditioner,
    find_initial_step,
    warmup_schedule,
    warmup_update,
    warmup_windows,
)
from ird_core.mcmc.base import (
    DIVERGENCE_THRESHOLD,
    PRECONDITIONERS,
    ChainState,
    Kernel,
    KernelParams,
    LogDensityFn,
    Preconditioner,
    StepInfo,
    gradient_init,
    metropolis_accept,
    rwm_init,
)
from ird_core.mcmc.chains import (
    ChainContinuation,
    MCMCResult,
    ProgressFn,
    continue_chains,
    sample_chains,
)
from ird_core.mcmc.diagnostics import (
    bulk_effective_sample_size,
    effective_sample_size,
    rank_normalize,
    rank_normalized_r_hat,
    split_chains,
    split_r_hat,
)
from ird_core.mcmc.elliptical_slice import (
    ELLIPTICAL_MAX_SHRINKS,
    ELLIPTICAL_WIDTH,
    elliptical_residual,
    elliptical_step,
)
from ird_core.mcmc.hmc import hmc_step, leapfrog
from ird_core.mcmc.independence import (
    INDEPENDENCE_DOF,
    INDEPENDENCE_WIDTH,
    independence_elliptical_step,
    independence_log_proposal,
    independence_step,
)
from ird_core.mcmc.kernels import (
    KERNEL_TABLE,
    KERNELS,
    TARGET_ACCEPT,
    get_kernel,
    num_leapfrog_steps,
    step_sizes,
)
from ird_core.mcmc.mala import mala_log_proposal, mala_mean, mala_step
from ird_core.mcmc.rwm import rwm_proposal, rwm_step

__all__ = [
    "KERNELS",
    "KERNEL_TABLE",
    "PRECONDITIONERS",
    "TARGET_ACCEPT",
    "DIVERGENCE_THRESHOLD",
    "ELLIPTICAL_MAX_SHRINKS",
    "ELLIPTICAL_WIDTH",
    "LogDensityFn",
    "Preconditioner",
    "ChainState",
    "StepInfo",
    "KernelParams",
    "Kernel",
    "rwm_proposal",
    "mala_mean",
    "mala_log_proposal",
    "leapfrog",
    "metropolis_accept",
    "rwm_init",
    "gradient_init",
    "rwm_step",
    "mala_step",
    "hmc_step",
    "elliptical_residual",
    "elliptical_step",
    "INDEPENDENCE_DOF",
    "INDEPENDENCE_WIDTH",
    "independence_log_proposal",
    "independence_step",
    "independence_elliptical_step",
    "get_kernel",
    "num_leapfrog_steps",
    "step_sizes",
    "split_chains",
    "rank_normalize",
    "split_r_hat",
    "rank_normalized_r_hat",
    "effective_sample_size",
    "bulk_effective_sample_size",
    "ProgressFn",
    "DualAveraging",
    "WarmupStep",
    "WarmupState",
    "MCMCResult",
    "ChainContinuation",
    "estimate_preconditioner",
    "find_initial_step",
    "warmup_windows",
    "warmup_schedule",
    "warmup_update",
    "sample_chains",
    "continue_chains",
]
