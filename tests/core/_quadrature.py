"""Moments of a 2-d density by quadrature on a dense grid: the reference the samplers' tests
compare their draws with (shared by test_inference.py and test_evidence.py)."""

from __future__ import annotations

from typing import Callable

import numpy as np


def quadrature_moments(log_density: Callable[[np.ndarray], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Mean (2,) and covariance (2, 2) of ``exp(log_density)``, a density on R^2.

    A coarse grid on [-7, 7]^2 finds the bulk; a fine 241 x 241 grid over +-8 sd of it gives
    the moments. ``log_density`` maps (n, 2) points to (n,) unnormalised log densities.
    """
    def moments(lo: np.ndarray, hi: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
        axes = [np.linspace(lo[i], hi[i], n) for i in range(2)]
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 2)
        logp = np.concatenate([log_density(chunk) for chunk in np.array_split(grid, 16)])
        p = np.exp(logp - logp.max())
        p /= p.sum()
        mean = p @ grid
        centred = grid - mean
        return mean, (centred * p[:, None]).T @ centred

    mean, cov = moments(np.full(2, -7.0), np.full(2, 7.0), 141)
    sd = np.sqrt(np.diag(cov))
    return moments(mean - 8 * sd, mean + 8 * sd, 241)
