"""Convergence diagnostics of multi-chain MCMC draws, numpy/scipy only.

Split R-hat (Gelman et al., BDA3, 11.4), its rank-normalised and folded variant (Vehtari et al.
2021) and the multi-chain effective sample size with Geyer's initial monotone sequence estimator
(as in Stan), plus the bulk ESS of rank-normalised split chains. Draws are ``(C, N, d)`` arrays:
``C`` chains, ``N`` draws each, ``d`` coordinates, every coordinate handled at once.

``tests/core/test_diagnostics.py`` checks these against ArviZ (``rhat(method="rank")``,
``ess(method="bulk")``); ArviZ is a test-time reference only, so the core needs neither pandas
nor xarray at run time. arviz-stats (numpy/scipy only) gives the same R-hat and the same
run-until decisions but loops over coordinates in Python: 2.5-45x slower per check on windows
of up to 256 draws (``scripts/bench_diagnostics.py``, docs/dependencies.md); in d = 50 a check
would cost more than the 16 sampler iterations between checks, so these stay.
"""

from __future__ import annotations

import numpy as np
from scipy.special import ndtri

__all__ = [
    "split_chains",
    "rank_normalize",
    "split_r_hat",
    "rank_normalized_r_hat",
    "effective_sample_size",
    "bulk_effective_sample_size",
]


def _check_draws(draws: np.ndarray, min_draws: int) -> np.ndarray:
    x = np.asarray(draws, dtype=np.float64)
    if x.ndim == 2:
        x = x[:, :, None]
    if x.ndim != 3 or x.shape[0] < 1 or x.shape[1] < min_draws:
        raise ValueError(f"draws: expected shape (C, N >= {min_draws}, d), got {np.shape(draws)}")
    if not np.all(np.isfinite(x)):
        raise ValueError("draws: contains NaN or infinite values")
    return x


def split_chains(draws: np.ndarray) -> np.ndarray:
    """Split each chain into halves (the middle draw of an odd chain is dropped).

    Args:
        draws: ``(C, N, d)``, ``N >= 2``.
    Returns:
        ``(2C, N // 2, d)``.
    """
    x = _check_draws(draws, 2)
    half = x.shape[1] // 2
    return np.concatenate([x[:, :half], x[:, x.shape[1] - half:]], axis=0)


def rank_normalize(draws: np.ndarray) -> np.ndarray:
    """Normal scores of the pooled ranks (Vehtari et al. 2021): ``Phi^-1((r - 3/8) / (S + 1/4))``.

    Args:
        draws: ``(C, N, d)``.
    Returns:
        ``(C, N, d)``; ties get their average rank.
    """
    from scipy.stats import rankdata  # noqa: PLC0415 - scipy.stats costs every node process 0.3 s at start

    x = _check_draws(draws, 1)
    c, n, d = x.shape
    ranks = rankdata(x.reshape(c * n, d), axis=0)
    return ndtri((ranks - 0.375) / (c * n + 0.25)).reshape(c, n, d)


def _r_hat(chains: np.ndarray) -> np.ndarray:
    """Potential scale reduction over the given chains ``(M, n, d) -> (d,)`` (no splitting)."""
    m, n, _ = chains.shape
    within = chains.var(axis=1, ddof=1).mean(axis=0)
    between = n * chains.mean(axis=1).var(axis=0, ddof=1)
    var_plus = (n - 1) / n * within + between / n
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.sqrt(var_plus / within)
    # Every draw of a coordinate equal: no evidence of non-convergence.
    return np.where((within == 0) & (between == 0), 1.0, r)


def split_r_hat(draws: np.ndarray) -> np.ndarray:
    """Split R-hat (Gelman et al., BDA3, section 11.4) of each coordinate.

    Chains are split in halves, then ``sqrt(var_plus / W)`` with ``W`` the mean within-chain
    variance, ``B`` the between-chain variance of the means (times ``n``) and
    ``var_plus = (n - 1)/n W + B/n``.

    Args:
        draws: ``(C, N, d)`` (or ``(C, N)`` for one coordinate), ``N >= 4``.
    Returns:
        ``(d,)``; ``1`` for a constant coordinate, ``inf`` if chains are constant but differ.
    """
    return _r_hat(split_chains(_check_draws(draws, 4)))


def rank_normalized_r_hat(draws: np.ndarray) -> np.ndarray:
    """Rank-normalised split R-hat (Vehtari et al. 2021): max of the bulk and folded (tail) values.

    Robust to heavy tails and sensitive to chains that differ in scale but not location.

    Args:
        draws: ``(C, N, d)``, ``N >= 4``.
    Returns:
        ``(d,)``.
    """
    x = _check_draws(draws, 4)
    bulk = split_r_hat(rank_normalize(x))
    folded = np.abs(x - np.median(x.reshape(-1, x.shape[2]), axis=0))
    return np.maximum(bulk, split_r_hat(rank_normalize(folded)))


def _autocovariance(x: np.ndarray) -> np.ndarray:
    """Biased autocovariance of each chain and coordinate by FFT; ``(M, n, d) -> (M, n, d)``."""
    n = x.shape[1]
    centred = x - x.mean(axis=1, keepdims=True)
    size = 1 << int(np.ceil(np.log2(2 * n)))
    spectrum = np.fft.rfft(centred, n=size, axis=1)
    return np.fft.irfft(spectrum * np.conj(spectrum), n=size, axis=1)[:, :n] / n


def effective_sample_size(draws: np.ndarray) -> np.ndarray:
    """Multi-chain effective sample size of each coordinate (BDA3 11.5 / Stan), chains as given.

    ``rho_t = 1 - (W - mean_m acov_m(t)) / var_plus``; Geyer's initial positive sequence of pair
    sums ``P_k = rho_2k + rho_2k+1`` truncated at the first negative pair and made monotone
    non-increasing; ``tau = -1 + 2 sum_k P_k``; ``ESS = C N / tau``, capped at
    ``C N log10(C N)`` as in Stan.

    Args:
        draws: ``(C, N, d)`` (or ``(C, N)``), ``N >= 4``.
    Returns:
        ``(d,)``; NaN for a constant coordinate.
    """
    x = _check_draws(draws, 4)
    m, n, d = x.shape
    acov = _autocovariance(x)  # (M, n, d)
    within = acov[:, 0].mean(axis=0) * n / (n - 1)  # mean within-chain variance (ddof=1)
    var_plus = within * (n - 1) / n
    if m > 1:
        var_plus = var_plus + x.mean(axis=1).var(axis=0, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = 1.0 - (within - acov.mean(axis=0)) / var_plus  # (n, d)
    rho[0] = 1.0
    pairs = n // 2
    sums = rho[0 : 2 * pairs : 2] + rho[1 : 2 * pairs : 2]  # (pairs, d)
    positive = np.cumprod(sums > 0, axis=0).astype(bool)  # initial positive sequence
    monotone = np.minimum.accumulate(np.where(positive, sums, np.inf), axis=0)
    tau = -1.0 + 2.0 * np.sum(np.where(positive, monotone, 0.0), axis=0)
    total = m * n
    tau = np.maximum(tau, 1.0 / np.log10(total)) if total > 1 else tau
    with np.errstate(divide="ignore", invalid="ignore"):
        ess = total / tau
    return np.where(var_plus > 0, ess, np.nan)


def bulk_effective_sample_size(draws: np.ndarray) -> np.ndarray:
    """Bulk ESS (Vehtari et al. 2021): ``effective_sample_size`` of rank-normalised split chains.

    Args:
        draws: ``(C, N, d)``, ``N >= 8``.
    Returns:
        ``(d,)``.
    """
    x = _check_draws(draws, 8)
    return effective_sample_size(rank_normalize(split_chains(x)))
