"""Generalised elliptical slice sampling (Murray, Adams & MacKay 2010; Nishihara, Murray & Adams
2014).

The target is written ``N(x; m, M) * exp(r(x))`` with the preconditioner's Gaussian ``N(m, M)``
(its ``mean`` and covariance) and the residual ``r = log p - log N(m, M)``, and a slice move on
the ellipse through ``x`` and a draw of ``N(m, M)`` leaves the target invariant. No gradient and
no step size; it is never rejected, and it shrinks its angle bracket until the residual clears
the slice, one batched call per shrink, so it stays valid and keeps moving on targets whose log
density has creases (the Sample-Z likelihood at large beta) where gradient kernels need tiny
steps.
"""

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
    rwm_init,
)

__all__ = ["ELLIPTICAL_MAX_SHRINKS", "ELLIPTICAL_WIDTH", "elliptical_residual", "elliptical_step", "ELLIPTICAL"]

#: Shrinks of the elliptical bracket before a chain gives up and stays put (the bracket is then
#: ``2 pi / 2^50`` wide; never reached on a continuous target, whose slice contains a
#: neighbourhood of the current point).
ELLIPTICAL_MAX_SHRINKS = 50


#: The elliptical kernel slices around ``N(m, w^2 M)``, ``w`` this factor: wider than the
#: covariance estimate so that chains can spread out when the estimate is too narrow (an
#: ellipse never leaves the span of ``x - m`` and the reference draw), at the price of a few
#: more shrinks when it is right.
ELLIPTICAL_WIDTH: float = 1.5


def elliptical_residual(log_p: np.ndarray, x: np.ndarray, precond: Preconditioner) -> np.ndarray:
    """``r(x) = log p(x) - log N(x; m, w^2 M)`` up to a constant (``w = ELLIPTICAL_WIDTH``):
    ``log p + |L^-1 (x - m)|^2 / (2 w^2)``; ``(C,), (C, d) -> (C,)``."""
    u = precond.whiten(x - precond.centre)
    return log_p + 0.5 * np.sum(u**2, axis=1) / ELLIPTICAL_WIDTH**2


def elliptical_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn,
                    params: KernelParams) -> tuple[ChainState, StepInfo]:
    """One generalised elliptical slice move of every chain (Murray et al. 2010, Figure 2).

    With ``m``, ``L`` from ``params.preconditioner``, draws ``nu = L z`` and a slice level
    ``y = r(x) + log U``, then proposes ``m + (x - m) cos t + nu sin t`` for ``t`` uniform on a
    bracket ``[t - 2 pi, t]`` that shrinks towards 0 after each rejected angle, until
    ``r > y``. Every shrink is one batched call on the chains still searching. The step size
    and leapfrog count are ignored. Random numbers in a fixed order: ``z``, the uniforms of the
    level, the first angles, then one uniform per searching chain per shrink.
    """
    x, precond = state.position, params.preconditioner
    num_chains = x.shape[0]
    centre = precond.centre
    nu = ELLIPTICAL_WIDTH * precond.scale(rng.standard_normal(x.shape))
    level = elliptical_residual(state.log_density, x, precond) + np.log(rng.random(num_chains))
    angle = rng.uniform(0.0, 2.0 * np.pi, num_chains)
    low, high = angle - 2.0 * np.pi, angle.copy()
    position, log_p = x.copy(), state.log_density.copy()
    searching = np.arange(num_chains)
    evaluations = 0
    for _ in range(ELLIPTICAL_MAX_SHRINKS):
        t = angle[searching][:, None]
        proposal = centre + (x[searching] - centre) * np.cos(t) + nu[searching] * np.sin(t)
        value, _ = evaluate(log_density, proposal, need_grad=False)
        evaluations += 1
        accept = elliptical_residual(value, proposal, precond) > level[searching]  # NaN: shrink
        done = searching[accept]
        position[done], log_p[done] = proposal[accept], value[accept]
        searching = searching[~accept]
        if len(searching) == 0:
            break
        below = angle[searching] < 0.0
        low[searching] = np.where(below, angle[searching], low[searching])
        high[searching] = np.where(below, high[searching], angle[searching])
        angle[searching] = rng.uniform(low[searching], high[searching])
    moved = np.ones(num_chains, dtype=bool)
    moved[searching] = False  # out of shrinks: stay (valid: the current point is on its slice)
    return (ChainState(position, log_p, None),
            StepInfo(np.ones(num_chains), moved, np.zeros(num_chains, dtype=bool), evaluations))


#: The elliptical slice kernel: no step size (the slice shrinks its own bracket); only the
#: Gaussian (mean, metric) adapts.
ELLIPTICAL = Kernel(rwm_init, elliptical_step, 1.0, lambda dim: 1.0, needs_gradient=False, tunes_step=False)
