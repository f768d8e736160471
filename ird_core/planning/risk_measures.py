"""Risk measures over posterior samples (docs/spec.md section 4).

A risk-averse plan maximises a statistic of the samples' returns ``R_k`` (per trajectory) or of
their per-cell rewards ``q_k(s)`` (per step, summed over the path). The statistics, for samples
with probabilities ``p_k`` (uniform unless a weighted posterior is given):

- ``min``: ``min_k R_k`` (the paper's appendix; samples of zero probability are ignored).
- ``cvar`` at level ``alpha`` in ``(0, 1]``: the mean of the worst ``alpha`` share of the
  probability mass, ``CVaR_alpha = (1/alpha) * sum_j min(p_(j), max(0, alpha - P_(j-1))) R_(j)``
  over the values sorted ascending (Rockafellar and Uryasev 2000). ``alpha <= min_k p_k`` gives
  the min exactly, ``alpha = 1`` the mean. Monotone in ``alpha``: larger levels are less cautious.
- ``mean_sd`` with ``lambda >= 0``: ``mean - lambda * sd`` (Markowitz), population sd.

All three are concave in the values except ``mean_sd``, are positively homogeneous and
translation-equivariant (adding ``c`` to every sample adds ``c``), so per-sample baselines keep
the meaning they have for the min. Everything is vectorised over the trailing axes.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ird_core.vocabulary import RiskMeasure, parse

__all__ = ["Risk", "MIN_RISK", "check_risk", "check_sample_weights", "risk_statistic", "weighted_cvar_batch",
           "SortedColumns", "sort_columns", "weighted_cvar_sorted"]

#: Largest ``lambda`` of ``mean_sd`` (beyond it the plan is the min's in practice).
MAX_LAMBDA: float = 100.0


class Risk(NamedTuple):
    """A risk measure and its level (``alpha`` for ``cvar``, ``lambda`` for ``mean_sd``, NaN for
    ``min``)."""

    measure: str
    level: float

    def label(self) -> str:
        """``"min"``, ``"cvar0.25"``, ``"mean_sd1"``: a short name for tables and plan labels."""
        if self.measure == RiskMeasure.MIN:
            return "min"
        return f"{self.measure}{self.level:g}"


#: The paper's worst case.
MIN_RISK = Risk(RiskMeasure.MIN.value, math.nan)


def check_risk(measure: object = "min", level: object = None) -> Risk:
    """A checked :class:`Risk`; ``ValueError`` naming ``risk`` or ``risk_level``.

    ``cvar`` needs ``level`` = alpha in ``(0, 1]``; ``mean_sd`` needs ``level`` = lambda in
    ``[0, MAX_LAMBDA]``; ``min`` takes no level (``None`` or NaN).
    """
    name = parse(RiskMeasure, measure, "risk").value
    if name == RiskMeasure.MIN:
        if level is not None and not (isinstance(level, float) and math.isnan(level)):
            raise ValueError(f"risk_level: the 'min' risk measure takes no level, got {level!r}")
        return MIN_RISK
    if isinstance(level, bool) or not isinstance(level, (int, float, np.integer, np.floating)) \
            or not math.isfinite(float(level)):
        raise ValueError(f"risk_level: {name} needs a finite number, got {level!r}")
    value = float(level)
    if name == RiskMeasure.CVAR and not 0.0 < value <= 1.0:
        raise ValueError(f"risk_level: cvar's alpha must be in (0, 1], got {value!r}")
    if name == RiskMeasure.MEAN_SD and not 0.0 <= value <= MAX_LAMBDA:
        raise ValueError(f"risk_level: mean_sd's lambda must be in [0, {MAX_LAMBDA:g}], got {value!r}")
    return Risk(name, value)


def check_sample_weights(sample_weights: object, num_samples: int) -> "np.ndarray | None":
    """``None`` (uniform) or ``(K,)`` finite non-negative probabilities summing to 1 (within
    1e-9, then renormalised); ``ValueError`` naming ``sample_weights``."""
    if sample_weights is None:
        return None
    p = np.asarray(sample_weights, dtype=np.float64)
    if p.shape != (num_samples,):
        raise ValueError(f"sample_weights: expected shape ({num_samples},), got {p.shape}")
    if not np.all(np.isfinite(p)) or np.any(p < 0):
        raise ValueError("sample_weights: expected finite values >= 0")
    total = p.sum()
    if not abs(total - 1.0) <= 1e-9:
        raise ValueError(f"sample_weights: expected a sum of 1, got {total!r}")
    return p / total


def risk_statistic(values: np.ndarray, risk: Risk, sample_weights: "np.ndarray | None" = None) -> np.ndarray:
    """The risk statistic over axis 0 of ``values``.

    Args:
        values: ``(K, ...)`` returns or per-cell rewards of ``K`` samples.
        risk: a checked :class:`Risk`.
        sample_weights: ``None`` (uniform) or checked ``(K,)`` probabilities.
    Returns:
        ``values.shape[1:]``.
    """
    v = np.asarray(values, dtype=np.float64)
    k = v.shape[0]
    if risk.measure == RiskMeasure.MIN:
        if sample_weights is None:
            return v.min(axis=0)
        alive = (sample_weights > 0).reshape((k,) + (1,) * (v.ndim - 1))
        return np.where(alive, v, np.inf).min(axis=0)
    p = np.full(k, 1.0 / k) if sample_weights is None else sample_weights
    shape = (k,) + (1,) * (v.ndim - 1)
    if risk.measure == RiskMeasure.MEAN_SD:
        mean = np.tensordot(p, v, axes=1)
        var = np.tensordot(p, (v - mean) ** 2, axes=1)
        return mean - risk.level * np.sqrt(var)
    order = np.argsort(v, axis=0, kind="stable")
    ordered = np.take_along_axis(v, order, axis=0)
    mass = np.broadcast_to(p.reshape(shape), v.shape)
    mass = np.take_along_axis(mass, order, axis=0) if sample_weights is not None else mass
    before = np.cumsum(mass, axis=0) - mass
    share = np.minimum(mass, np.maximum(0.0, risk.level - before))
    cvar = (share * ordered).sum(axis=0) / risk.level
    # The worst value alone carries the level: its exact value, not ``share * v / alpha``.
    return np.where(risk.level <= mass[0], ordered[0], cvar)


class SortedColumns(NamedTuple):
    """``values`` ``(K, S)`` sorted per column: ``order`` the sample indices, ``ordered`` the values."""

    order: np.ndarray
    ordered: np.ndarray


def sort_columns(values: np.ndarray) -> SortedColumns:
    """The per-column ascending sort of ``(K, S)`` values that :func:`weighted_cvar_sorted` takes."""
    v = np.asarray(values, dtype=np.float64)
    order = np.argsort(v, axis=0, kind="stable")
    return SortedColumns(order, np.take_along_axis(v, order, axis=0))


def weighted_cvar_batch(values: np.ndarray, sample_weights: np.ndarray, alpha: float) -> np.ndarray:
    """``risk_statistic(values, Risk("cvar", alpha), p_m)`` for every row ``p_m`` of a batch.

    Args:
        values: ``(K, S)`` per-cell rewards (or returns) of ``K`` samples.
        sample_weights: ``(M, K)`` rows of checked probabilities.
        alpha: the level, in ``(0, 1]``.
    Returns:
        ``(M, S)``.
    """
    return weighted_cvar_sorted(sort_columns(values), np.asarray(sample_weights, dtype=np.float64), alpha)


#: Sorted samples per column :func:`weighted_cvar_sorted` tries first (then 4x more, up to all).
TAIL_FIRST: int = 16
#: Float64 elements of one block's ``(rows, head, S)`` tables (32 MB).
_CVAR_ELEMENTS: int = 4_000_000


def weighted_cvar_sorted(columns: SortedColumns, sample_weights: np.ndarray, alpha: float) -> np.ndarray:
    """:func:`weighted_cvar_batch` on values sorted once (:func:`sort_columns`).

    The order of the samples per column does not depend on the weights, so each weight vector only
    accumulates its mass in that order. The tail of mass ``alpha`` usually ends within the first
    few sorted samples: the first :data:`TAIL_FIRST` are tried, and the rows whose tail runs past
    them are recomputed with 4 times as many, up to all ``K``: the same sums as a full pass, since
    the later samples' shares are 0.
    """
    order, ordered = columns
    k, cells = ordered.shape
    out = np.empty((len(sample_weights), cells))
    pending = np.arange(len(sample_weights))
    head = min(k, TAIL_FIRST)
    while len(pending):
        block = max(1, _CVAR_ELEMENTS // (head * cells))
        still = []
        for lo in range(0, len(pending), block):
            rows = pending[lo: lo + block]
            value, done = _tail_cvar(ordered[:head], sample_weights[rows][:, order[:head]], alpha)
            complete = done.all(axis=1) | (head == k)
            out[rows[complete]] = value[complete]
            still.append(rows[~complete])
        pending = np.concatenate(still)
        head = min(k, 4 * head)
    return out


def _tail_cvar(ordered: np.ndarray, mass: np.ndarray, alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """CVaR ``(M, S)`` from the first ``m`` sorted values ``(m, S)`` and their masses ``(M, m, S)``,
    and whether the tail of mass ``alpha`` ends within them ``(M, S)``."""
    before = np.cumsum(mass, axis=1) - mass
    share = np.minimum(mass, np.maximum(0.0, alpha - before))
    cvar = np.einsum("mks,ks->ms", share, ordered) / alpha
    done = before[:, -1] + mass[:, -1] >= alpha
    return np.where(alpha <= mass[:, 0], ordered[0], cvar), done | (alpha <= mass[:, 0])
