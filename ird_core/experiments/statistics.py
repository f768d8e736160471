"""The statistics of both experiments (Figure 4 and its factorial, docs/spec.md section 5; the
designer in the loop, docs/spec.md section 7): grouping of trial rows, 95% intervals, paired
comparisons over seeds and the share of the literal-to-oracle return gap a planner closes.

Invariants:

- a proportion comes with its Wilson score interval (:func:`wilson_interval`), clipped to
  ``[0, 1]`` and exactly ``0`` / ``1`` at ``0`` / ``n`` successes;
- a mean comes with its Student-t interval (:func:`t_interval`); one value is its own interval;
- paired statistics use only the seeds every compared planner has (:func:`paired_by_seed`), so
  trials are compared with the trials of the same instance;
- :func:`gap_closed`'s bootstrap is seeded: the same inputs and seed give the same interval.
"""

from __future__ import annotations

import math
from typing import Callable, Hashable, Iterable, Mapping, Sequence, TypeVar

import numpy as np
from scipy import stats

from ird_core import posterior

__all__ = [
    "group_by",
    "wilson_interval",
    "proportion",
    "t_interval",
    "convergence",
    "paired_by_seed",
    "paired_difference",
    "gap_share",
    "gap_closed",
    "paired_gap_closed",
]

T = TypeVar("T")
K = TypeVar("K", bound=Hashable)

#: ``(estimate, low, high)`` of a 95% interval.
Interval = tuple[float, float, float]


def group_by(items: Iterable[T], key: Callable[[T], K]) -> dict[K, list[T]]:
    """The items by ``key``, groups in first-seen order, items in input order."""
    groups: dict[K, list[T]] = {}
    for item in items:
        groups.setdefault(key(item), []).append(item)
    return groups


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion; ``(nan, nan)`` for ``n = 0``."""
    if n <= 0:
        return math.nan, math.nan
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be in 0..{n}, got {successes}")
    z = float(stats.norm.ppf(0.5 + confidence / 2))
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def proportion(flags: Sequence[bool]) -> Interval:
    """``(fraction, low, high)``: the fraction of true flags and its 95% Wilson interval."""
    n = len(flags)
    successes = sum(bool(f) for f in flags)
    return (successes / n if n else math.nan), *wilson_interval(successes, n)


def t_interval(values: Sequence[float], confidence: float = 0.95) -> Interval:
    """``(mean, low, high)``: Student-t interval of the mean (``low = high = mean`` if n = 1)."""
    x = np.asarray(values, dtype=np.float64)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    if x.size == 1:
        return mean, mean, mean
    half = float(stats.t.ppf(0.5 + confidence / 2, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return mean, mean - half, mean + half


def convergence(r_hats: Iterable[float]) -> tuple[float, int]:
    """``(max_r_hat, nonconverged)`` of posteriors' split R-hats, NaNs (no posterior) ignored:
    the largest (NaN if none) and how many exceed ``posterior.R_HAT_CONVERGED``."""
    finite = [r for r in r_hats if not math.isnan(r)]
    return (max(finite) if finite else math.nan), sum(r > posterior.R_HAT_CONVERGED for r in finite)


def paired_by_seed(*by_seed: Mapping[int, float]) -> list[list[float]]:
    """The values of each ``{seed: value}`` on the seeds all of them have, in seed order."""
    seeds = sorted(set.intersection(*(set(b) for b in by_seed))) if by_seed else []
    return [[b[s] for s in seeds] for b in by_seed]


def paired_difference(a: Mapping[int, float], b: Mapping[int, float]) -> tuple[float, float, float, int]:
    """Mean per-seed difference ``a - b`` on the seeds both have: ``(mean, low, high, n)`` with a
    95% Student-t interval."""
    va, vb = paired_by_seed(a, b)
    return (*t_interval([x - y for x, y in zip(va, vb)]), len(va))


def gap_share(literal: float | np.ndarray, oracle: float | np.ndarray, planner: float | np.ndarray
              ) -> float | np.ndarray:
    """Share of the literal-to-oracle gap a planner closes, ``(planner - literal) / (oracle -
    literal)`` (1 = oracle, 0 = literal, negative = below literal); NaN where ``oracle <= literal``
    (no gap to close). Elementwise on broadcastable arrays of mean returns."""
    literal, oracle, planner = (np.asarray(v, dtype=np.float64) for v in (literal, oracle, planner))
    gap = oracle - literal
    with np.errstate(divide="ignore", invalid="ignore"):
        share = np.where(gap > 0, (planner - literal) / np.where(gap > 0, gap, 1.0), np.nan)
    return float(share) if share.ndim == 0 else share


def gap_closed(literal: Sequence[float], oracle: Sequence[float], planner: Sequence[float], seed: int = 0,
               resamples: int = 2000, confidence: float = 0.95) -> Interval:
    """``(share, low, high)``: :func:`gap_share` of the mean true returns of paired trials and its
    percentile bootstrap interval.

    Args:
        literal, oracle, planner: ``(n,)`` true returns, entry ``i`` of each from the same trial.
        seed: seeds the bootstrap (same inputs and seed, same interval).
        resamples: bootstrap resamples ``B``; each draws ``n`` trial indices with replacement and
            keeps the three planners' returns of a trial together (paired).
    Returns:
        the share and the ``confidence`` percentile interval of the resampled shares (resamples
        without a gap are dropped); all NaN when ``n = 0`` or the mean gap is ``<= 0``.
    """
    arrays = [np.asarray(v, dtype=np.float64).reshape(-1) for v in (literal, oracle, planner)]
    if len({a.size for a in arrays}) != 1:
        raise ValueError("literal, oracle, planner: must have the same length (paired trials), got "
                         f"{[a.size for a in arrays]}")
    x = np.stack(arrays)  # (3, n)
    if resamples < 1:
        raise ValueError(f"resamples must be >= 1, got {resamples!r}")
    n = x.shape[1]
    share = gap_share(*x.mean(axis=1)) if n else math.nan
    if math.isnan(share):
        return math.nan, math.nan, math.nan
    index = np.random.default_rng(seed).integers(0, n, size=(resamples, n))  # (B, n)
    boot = gap_share(*x[:, index].mean(axis=2))  # (B,)
    boot = boot[~np.isnan(boot)]
    if boot.size == 0:
        return share, math.nan, math.nan
    alpha = 100 * (1 - confidence) / 2
    low, high = np.percentile(boot, [alpha, 100 - alpha])
    return share, float(low), float(high)


def paired_gap_closed(literal: Mapping[int, float], oracle: Mapping[int, float],
                      planner: Mapping[int, float]) -> Interval:
    """:func:`gap_closed` of ``{seed: true return}`` maps, on the seeds all three have."""
    return gap_closed(*paired_by_seed(literal, oracle, planner))
