"""Metropolis-adjusted Langevin: ``x' = x + h^2/2 M g(x) + h L z`` (optimal-scaling target
acceptance 0.574, Roberts & Rosenthal 1998)."""

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
    gradient_init,
    gradient_of,
    metropolis_step,
)

__all__ = ["mala_mean", "mala_log_proposal", "mala_step", "MALA"]


def mala_mean(x: np.ndarray, grad: np.ndarray, step: np.ndarray, precond: Preconditioner) -> np.ndarray:
    """Langevin proposal mean ``x + h^2 / 2 M g(x)``; ``(C, d)`` -> ``(C, d)``."""
    h = np.reshape(step, (-1, 1))
    return x + 0.5 * h**2 * precond.times_cov(grad)


def mala_log_proposal(x_to: np.ndarray, mean_from: np.ndarray, step: np.ndarray,
                      precond: Preconditioner) -> np.ndarray:
    """``log q(x_to | x_from)`` up to a constant shared by both directions; ``(C,)``.

    ``q = N(mean_from, h^2 M)``, so this is ``-|L^{-1}(x_to - mean_from)|^2 / (2 h^2)``.
    """
    u = precond.whiten(x_to - mean_from)
    return -0.5 * np.sum(u**2, axis=1) / np.reshape(step, (-1,)) ** 2


def mala_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn, params: KernelParams
              ) -> tuple[ChainState, StepInfo]:
    """One Metropolis-adjusted Langevin transition of every chain (one batched call)."""
    h, precond = params.step_size, params.preconditioner
    z = rng.standard_normal(state.position.shape)
    proposal = mala_mean(state.position, gradient_of(state, "mala"), h, precond) + np.reshape(h, (-1, 1)) * precond.scale(z)
    log_p, grad = evaluate(log_density, proposal, need_grad=True)
    forward = -0.5 * np.sum(z**2, axis=1)
    backward = mala_log_proposal(state.position, mala_mean(proposal, grad, h, precond), h, precond)
    return metropolis_step(rng, state, proposal, log_p, grad, log_p - state.log_density + backward - forward, 1)


#: The MALA kernel, with the ``1.65 d^(-1/3)`` optimal-scaling step.
MALA = Kernel(gradient_init, mala_step, 0.574, lambda dim: 1.65 * dim ** (-1.0 / 3.0))
