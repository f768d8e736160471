"""The Laplace start of the IRD posterior sampler: the mode and a covariance there (docs/spec.md section 3).

``laplace_approximation`` gives ``ird_core.posterior.sampler`` its chains' starting points
(``mode + 2 L z``) and its initial HMC metric. Damped Newton finds the mode of a smooth posterior
(MaxEnt-Z); when it stalls on a creased one (Sample-Z at large beta) L-BFGS takes over and the
covariance's axes are narrowed to the density's measured extent (``_profile_widths``).
"""

from __future__ import annotations

import numpy as np

from ird_core.posterior.evidence import PosteriorModel

__all__ = ["laplace_approximation"]

#: Absolute coordinate step of the forward-difference Hessian.
_HESSIAN_STEP: float = 1e-4


def _gradient_and_hessian(model: PosteriorModel, w: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Value, gradient ``(d,)`` and symmetrised forward-difference Hessian ``(d, d)`` at ``w``,
    from one batched call on ``d + 1`` weights."""
    dim = len(w)
    points = w[None, :] + np.concatenate([np.zeros((1, dim)), _HESSIAN_STEP * np.eye(dim)])
    values, grads = model.log_density_and_grad(points)
    hessian = (grads[1:] - grads[0]) / _HESSIAN_STEP
    return float(values[0]), grads[0], 0.5 * (hessian + hessian.T)


def laplace_approximation(model: PosteriorModel, max_iterations: int = 30
                          ) -> tuple[np.ndarray, np.ndarray]:
    """MAP by damped Newton from ``w = 0`` and the covariance ``(-Hessian)^{-1}`` there.

    The negative Hessian's eigenvalues are floored at ``0.5 / sigma^2`` (for MaxEnt-Z they are at
    least ``1 / sigma^2`` anyway: ``log Z`` is convex), so the Newton direction is an ascent
    direction and the covariance is positive definite. Each iteration is two batched calls: the
    Hessian (``d + 1`` weights) and a line search over 8 step lengths at once.

    When Newton stalls far from a stationary point (its line search finds no ascent while the
    Newton decrement is above ``_NEWTON_STALL``) the log density is not smooth at the scale of
    its steps: the Sample-Z likelihood at large beta is a soft maximum over the proxies' feature
    counts, with creases ~1/beta wide, and Newton can stop far below the mode (chains started
    there spend their whole run walking out). Then the mode is found by L-BFGS (scipy, exact
    gradients, batched one-weight calls) and the covariance
    is rescaled by ``_profile_widths``, since a Hessian at a crease says nothing about how far the
    density extends.

    Returns:
        The mode ``(d,)`` and the covariance ``(d, d)``.
    """
    dim = model.dim
    w = np.zeros(dim)
    floor = 0.5 / model.prior_sigma**2
    steps = 0.5 ** np.arange(8)
    stalled = False
    for _ in range(max_iterations):
        value, grad, hessian = _gradient_and_hessian(model, w)
        eigval, eigvec = np.linalg.eigh(-hessian)
        eigval = np.maximum(eigval, floor)
        direction = eigvec @ ((eigvec.T @ grad) / eigval)
        decrement = float(grad @ direction)
        if decrement < 1e-8:
            break
        candidates = w[None, :] + steps[:, None] * direction[None, :]
        values = model.log_density(candidates)
        best = int(np.argmax(values))
        if values[best] <= value:
            stalled = decrement > _NEWTON_STALL
            break
        w = candidates[best]
    else:  # out of iterations after a step: the last Hessian is not at w (after a break it is)
        _, _, hessian = _gradient_and_hessian(model, w)
    if stalled:
        w, hessian = _quasi_newton_mode(model, w)
    eigval, eigvec = np.linalg.eigh(-hessian)
    cov = (eigvec / np.maximum(eigval, floor)) @ eigvec.T
    cov = 0.5 * (cov + cov.T)
    if stalled:
        cov = _profile_widths(model, w, cov)
    return w, cov


#: A Newton decrement above this when the line search fails means Newton stalled (see
#: ``laplace_approximation``); below it, the mode is as good as the smooth case's.
_NEWTON_STALL: float = 1e-3
#: ``_profile_widths`` reads each axis at the largest tried point within this many nats of the
#: mode (3: not ``0.5 * 4^k``, so a Gaussian axis off by a power of 2 is never read at a tie).
_PROFILE_DROP: float = 3.0
#: Halvings of each axis tried by ``_profile_widths`` (down to 2^-23 of the Laplace axis).
_PROFILE_LEVELS: int = 24


def _quasi_newton_mode(model: PosteriorModel, start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mode by L-BFGS from ``start`` and the forward-difference Hessian there."""
    from scipy.optimize import minimize

    def negative(w: np.ndarray) -> tuple[float, np.ndarray]:
        value, grad = model.log_density_and_grad(w[None, :])
        return -float(value[0]), -grad[0]

    result = minimize(negative, start, jac=True, method="L-BFGS-B", options={"maxiter": 1000})
    w = result.x if -result.fun >= float(model.log_density(start[None, :])[0]) else start
    return w, _gradient_and_hessian(model, w)[2]


def _profile_widths(model: PosteriorModel, mode: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """``cov`` with each eigen-axis narrowed to the log density's measured extent along it.

    Along each axis ``+-sqrt(lambda_i) e_i`` the points at fractions ``2^-k`` (``k < 24``) are
    evaluated for both signs in ONE batched call (``2 * 24 * d`` weights); at the largest
    fraction ``f`` whose drop ``D`` from the mode is at most ``_PROFILE_DROP`` nats the axis is
    read as a Gaussian's, half-width ``f sqrt(0.5 / D)`` (exact for a Gaussian; ``~1/s`` for a
    crease of slope ``s``), and ``lambda_i`` is multiplied by the square of the mean over both
    signs, capped at 1 (never widened: a flat profile says nothing about the extent). At a
    crease the Hessian overstates the extent by orders of magnitude (1000x on the latent_raw
    case above), which forces a gradient sampler's step down to ~1e-3 of the typical scale.
    ``(d,), (d, d) -> (d, d)``.
    """
    dim = len(mode)
    eigval, eigvec = np.linalg.eigh(cov)
    axes = (eigvec * np.sqrt(eigval)).T  # (d, d): row i is the axis i
    fractions = 0.5 ** np.arange(_PROFILE_LEVELS)
    offsets = np.array([1.0, -1.0])[:, None, None, None] * fractions[None, :, None, None] * axes[None, None]
    values = model.log_density(mode[None, :] + offsets.reshape(-1, dim)).reshape(2, _PROFILE_LEVELS, dim)
    drop = float(model.log_density(mode[None, :])[0]) - values
    within = drop <= _PROFILE_DROP  # NaN: outside
    first = np.where(within.any(axis=1), within.argmax(axis=1), _PROFILE_LEVELS - 1)  # (2, d)
    at = np.take_along_axis(drop, first[:, None, :], axis=1)[:, 0]  # (2, d)
    with np.errstate(divide="ignore"):
        half = fractions[first] * np.sqrt(0.5 / np.maximum(at, 0.0))
    width = np.minimum(half, 1.0).mean(axis=0)
    out = (eigvec * (eigval * width**2)) @ eigvec.T
    return 0.5 * (out + out.T)
