"""Hamiltonian Monte Carlo with ``L`` leapfrog steps in whitened coordinates (target acceptance
0.8, Stan's default; the step is jittered by +-10% at every iteration so that no fixed trajectory
length resonates with the target)."""

from __future__ import annotations

from functools import partial

import numpy as np

from ird_core.mcmc.base import (
    ChainState,
    Kernel,
    KernelParams,
    LogDensityFn,
    Preconditioner,
    StepInfo,
    evaluate,
    gradient_init,
    gradient_of,
    metropolis_step,
)

__all__ = ["leapfrog", "hmc_step", "HMC"]


def leapfrog(x: np.ndarray, p: np.ndarray, grad: np.ndarray, step: np.ndarray, num_steps: int,
             log_density: LogDensityFn, precond: Preconditioner
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``num_steps`` leapfrog steps of HMC with whitened momentum ``p`` (kinetic ``|p|^2 / 2``).

    In whitened coordinates ``u = L^{-1} x`` the force is ``L^T g``, so a step is
    ``p += h/2 L^T g; x += h L p; p += h/2 L^T g``. Volume preserving and reversible for any
    deterministic field ``g``.

    Args:
        x, p, grad: ``(C, d)``; step: ``(C,)``; log_density: the batched target.
    Returns:
        The end position ``(C, d)``, momentum ``(C, d)``, log density ``(C,)`` and field ``(C, d)``.
    """
    h = np.reshape(step, (-1, 1))
    log_p = None
    p = p + 0.5 * h * precond.scale_gradient(grad)
    for i in range(num_steps):
        x = x + h * precond.scale(p)
        log_p, grad = log_density(x)
        if grad is None:
            raise ValueError("log_density: hmc needs a gradient, got None")
        p = p + (0.5 if i == num_steps - 1 else 1.0) * h * precond.scale_gradient(grad)
    return x, p, log_p, grad


def hmc_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn, params: KernelParams
             ) -> tuple[ChainState, StepInfo]:
    """One HMC transition of every chain: ``params.num_leapfrog`` batched calls."""
    z = rng.standard_normal(state.position.shape)
    target = partial(evaluate, log_density, need_grad=True)
    proposal, p_end, log_p, grad = leapfrog(state.position, z, gradient_of(state, "hmc"), params.step_size,
                                            params.num_leapfrog, target, params.preconditioner)
    log_ratio = (log_p - 0.5 * np.sum(p_end**2, axis=1)) - (state.log_density - 0.5 * np.sum(z**2, axis=1))
    return metropolis_step(rng, state, proposal, log_p, grad, log_ratio, params.num_leapfrog)


#: The HMC kernel: step ``d^(-1/4)``, jittered, leapfrog count from the trajectory length.
HMC = Kernel(gradient_init, hmc_step, 0.8, lambda dim: dim ** (-0.25), step_jitter=(0.9, 1.1), uses_trajectory=True)
