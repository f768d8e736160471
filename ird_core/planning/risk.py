"""The posterior's reward spread per cell and its risk map, a Nav2-style cost layer
(docs/spec.md section 4): where the posterior samples disagree about a cell's reward."""

from __future__ import annotations

import numpy as np

from ird_core.planning.arguments import check_features, check_weights
from ird_core.vocabulary import RiskStatistic, parse

__all__ = ["reward_spread", "risk_map"]


def reward_spread(features: np.ndarray, weights: np.ndarray, statistic: str = "std") -> np.ndarray:
    """Per-cell spread of the posterior reward ``w_i . F[cell]`` over the samples.

    ``std`` is the population standard deviation (ddof 0), ``range`` is max - min. Rewards are
    taken relative to the first sample (``(w_i - w_0) . F``), which leaves both statistics
    unchanged and makes identical samples give exactly 0.

    Args:
        features: ``(H, W, d)``.
        weights: ``(K, d)``.
        statistic: one of :data:`STATISTICS`.
    Returns:
        ``(H, W)`` float64, >= 0.
    """
    f = check_features(features)
    w = check_weights(weights, f.shape[2])
    parse(RiskStatistic, statistic, "statistic")
    rewards = np.einsum("hwd,kd->khw", f, w - w[:1], optimize=True)
    if statistic == RiskStatistic.STD:
        return rewards.std(axis=0)
    return np.ptp(rewards, axis=0)


def risk_map(
    features: np.ndarray,
    weights: np.ndarray,
    statistic: str = "std",
    reference: float | None = None,
) -> np.ndarray:
    """The reward spread as a Nav2-style ``OccupancyGrid`` cost layer.

    ``cost = ceil(100 * spread / reference)`` clipped to ``[0, 100]``, where ``reference`` is the
    map's largest spread by default (that cell costs 100) or a fixed spread given by the caller
    (for costs comparable across maps). Any positive spread costs at least 1; a posterior whose
    samples agree everywhere costs 0 everywhere; -1 (unknown) is never produced. Monotone: more
    spread never costs less.

    Args:
        features: ``(H, W, d)``.
        weights: ``(K, d)``.
        statistic: one of :data:`STATISTICS`.
        reference: ``> 0`` fixed spread mapped to 100, or ``None``.
    Returns:
        ``(H, W)`` int8 in ``0..100``, row 0 first (the OccupancyGrid data order).
    """
    spread = reward_spread(features, weights, statistic)
    if reference is not None and not (np.isfinite(reference) and reference > 0):
        raise ValueError(f"reference: expected a finite spread > 0 or None, got {reference!r}")
    scale = float(spread.max()) if reference is None else float(reference)
    if scale <= 0.0:
        return np.zeros(spread.shape, dtype=np.int8)
    return np.clip(np.ceil(100.0 * (spread / scale)), 0, 100).astype(np.int8)
