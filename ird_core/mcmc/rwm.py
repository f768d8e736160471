"""Random-walk Metropolis: ``x' = x + h L z`` (optimal-scaling target acceptance 0.234,
Roberts, Gelman & Gilks 1997)."""

from __future__ import annotations

import numpy as np

from ird_core.mcmc.base import (
    ChainState,
    Kernel,
    KernelParams,
    LogDensityFn,
    Preconditioner,
    StepInfo,
    evaluate,
    metropolis_step,
    rwm_init,
)

__all__ = ["rwm_proposal", "rwm_step", "RWM"]


def rwm_proposal(x: np.ndarray, z: np.ndarray, step: np.ndarray, precond: Preconditioner) -> np.ndarray:
    """Random-walk proposal ``x + h L z``.

    Args:
        x: ``(C, d)`` positions; z: ``(C, d)`` standard normals; step: ``(C,)`` or scalar ``h``.
    Returns:
        ``(C, d)``.
    """
    return x + np.reshape(step, (-1, 1)) * precond.scale(z)


def rwm_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn, params: KernelParams
             ) -> tuple[ChainState, StepInfo]:
    """One random-walk Metropolis transition of every chain (one batched call)."""
    z = rng.standard_normal(state.position.shape)
    proposal = rwm_proposal(state.position, z, params.step_size, params.preconditioner)
    log_p, _ = evaluate(log_density, proposal, need_grad=False)
    return metropolis_step(rng, state, proposal, log_p, None, log_p - state.log_density, 1)


#: The RWM kernel, with the ``2.38 / sqrt(d)`` optimal-scaling step.
RWM = Kernel(rwm_init, rwm_step, 0.234, lambda dim: 2.38 / np.sqrt(dim), needs_gradient=False)
