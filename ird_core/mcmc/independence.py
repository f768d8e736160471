"""Independence Metropolis-Hastings with a multivariate Student-t proposal ``t_nu(m, w^2 M)``
around the preconditioner's Gaussian (``nu = INDEPENDENCE_DOF``, ``w = INDEPENDENCE_WIDTH``).

One batched call per step, no gradient, no step size, and a proposal that does not depend on the
current point, so creases cost nothing. Efficient only while the t covers the target well, which
in practice means a few dimensions.

``independence_elliptical``: an ``independence`` step, then an elliptical slice step around the
same ``(m, M)`` (a composition of two invariant kernels is invariant). The independence move
jumps across the target; the slice move keeps a chain moving where the t proposal is too thin
(without it a chain that reaches such a region can sit there for hundreds of steps).
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
    metropolis_step,
    rwm_init,
)
from ird_core.mcmc.elliptical_slice import elliptical_step

__all__ = ["INDEPENDENCE_DOF", "INDEPENDENCE_WIDTH", "independence_log_proposal", "independence_step",
           "independence_elliptical_step", "INDEPENDENCE", "INDEPENDENCE_ELLIPTICAL"]

#: Degrees of freedom of the independence kernel's Student-t: heavy tails, so that a target wider
#: than the fitted Gaussian in some direction is still proposed there (a proposal lighter-tailed
#: than the target makes the tails sticky).
INDEPENDENCE_DOF: float = 5.0
#: The independence kernel proposes from ``t_nu(m, w^2 M)``, ``w`` this factor (wider than the
#: covariance estimate, for the same reason as ``ELLIPTICAL_WIDTH``).
INDEPENDENCE_WIDTH: float = 1.2


def independence_log_proposal(x: np.ndarray, precond: Preconditioner) -> np.ndarray:
    """``log t_nu(x; m, w^2 M)`` up to a constant: ``-(nu + d)/2 log(1 + |L^-1 (x - m)|^2 / (w^2 nu))``;
    ``(C, d) -> (C,)``."""
    u = precond.whiten(x - precond.centre) / INDEPENDENCE_WIDTH
    return -0.5 * (INDEPENDENCE_DOF + x.shape[1]) * np.log1p(np.sum(u**2, axis=1) / INDEPENDENCE_DOF)


def independence_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn,
                      params: KernelParams) -> tuple[ChainState, StepInfo]:
    """One independence Metropolis-Hastings transition of every chain (one batched call).

    Proposes ``y = m + w L z / sqrt(g / nu)`` (``z ~ N(0, I)``, ``g ~ chi^2_nu``) and accepts with
    ``p(y) q(x) / (p(x) q(y))``. ``q`` is evaluated at the current point under the CURRENT
    preconditioner, so the warm-up may change ``(m, M)`` between steps. Random numbers in a fixed
    order: ``z``, ``g``, then the acceptance uniforms.
    """
    x, precond = state.position, params.preconditioner
    z = rng.standard_normal(x.shape)
    g = rng.chisquare(INDEPENDENCE_DOF, size=(x.shape[0], 1))
    proposal = precond.centre + INDEPENDENCE_WIDTH * precond.scale(z / np.sqrt(g / INDEPENDENCE_DOF))
    log_p, _ = evaluate(log_density, proposal, need_grad=False)
    log_ratio = (log_p - independence_log_proposal(proposal, precond)) - \
        (state.log_density - independence_log_proposal(x, precond))
    return metropolis_step(rng, state, proposal, log_p, None, log_ratio, 1)


def independence_elliptical_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn,
                                 params: KernelParams) -> tuple[ChainState, StepInfo]:
    """``independence_step`` then ``elliptical_step`` (one call, then one per shrink). The
    reported acceptance is the independence step's (the slice step always moves)."""
    jumped, jump = independence_step(rng, state, log_density, params)
    moved, slide = elliptical_step(rng, jumped, log_density, params)
    return moved, jump._replace(num_evaluations=jump.num_evaluations + slide.num_evaluations)


#: No step size either: the proposal is the fitted (m, M) itself.
INDEPENDENCE = Kernel(rwm_init, independence_step, 1.0, lambda dim: 1.0, needs_gradient=False, tunes_step=False)
INDEPENDENCE_ELLIPTICAL = Kernel(rwm_init, independence_elliptical_step, 1.0, lambda dim: 1.0,
                                 needs_gradient=False, tunes_step=False)
