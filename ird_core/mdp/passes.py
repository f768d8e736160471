"""Exact maximum-entropy trajectory inference on grid MDPs (docs/spec.md sections 1-2).

The grid, its moves and paths follow the conventions of :mod:`ird_core.mdp.grid`; the successor
relation is symmetric, so predecessors equal successors, which lets the forward and the backward
passes share one operator.

Maximum-entropy agent (section 2): ``P(xi | w) ∝ exp(w . phi(xi))`` over all trajectories.
Every quantity is computed exactly by dynamic programming over the grid, vectorised over a
batch of ``K`` weight vectors and over cells, never a Python loop over cells or weights. Cost
``O(T * K * H * W * 5 + K * H * W * d)``. Two implementations:

- the fast path: scaled *linear-space* passes (``exp`` once per cell, then only adds and
  multiplies) on one flat array holding the whole batch, so a step is 5-8 numpy calls on
  contiguous memory (``ird_core.mdp.linear_passes``: why it is exact and when it is not used);
- the reference: *log-space* passes (log-sum-exp over shifted grid views), exact for any
  reward magnitudes; used for the batch elements the fast path flags (reward spreads of
  hundreds of nats) and by ``soft_values``.
"""

from __future__ import annotations

import numpy as np

from ird_core.mdp.grid import MOVES, GridMDP, cell_rewards
from ird_core.mdp.linear_passes import linear_backward, linear_visitation
from ird_core.mdp.threads import map_chunks

__all__ = [
    "soft_values",
    "log_partition",
    "expected_visitation",
    "feature_expectations",
    "hard_values",
    "optimal_path",
    "warm_up",
    "log_partition_and_feature_expectations",
]

def _shifted(values: np.ndarray, fill: float) -> list[np.ndarray]:
    """The five successor views of ``values`` ``(..., H, W)``, off-grid entries set to ``fill``.

    Entry ``m`` at ``[..., r, c]`` holds ``values[..., r + dr, c + dc]`` for ``MOVES[m]``.
    """
    # np.full + one assignment: cheaper than np.pad on the small grids of the hot loops.
    padded = np.full(values.shape[:-2] + (values.shape[-2] + 2, values.shape[-1] + 2), fill)
    padded[..., 1:-1, 1:-1] = values
    views = []
    for d_row, d_col in MOVES:
        views.append(padded[..., 1 + d_row : padded.shape[-2] - 1 + d_row,
                            1 + d_col : padded.shape[-1] - 1 + d_col])
    return views


#: A neighbour sum below this (relative to the batch's largest value) may have lost terms to
#: underflow; such cells are recomputed with the per-cell maximum.
_UNDERFLOW_GUARD = 1e-250


def _neighbour_logsumexp(values: np.ndarray) -> np.ndarray:
    """``log sum_{s' in succ(s)} exp(values[s'])`` for every cell; ``(..., H, W)`` -> same.

    Fast path: one ``exp`` per cell, scaled by the largest value of each grid in the batch,
    then shifted sums. Where a sum is so small that a term may have underflowed, those cells
    are recomputed exactly with their own neighbourhood maximum, so the result is exact for
    any magnitudes and for ``-inf`` entries (unreachable cells).
    """
    peak = np.max(values, axis=(-2, -1), keepdims=True)
    peak = np.where(np.isfinite(peak), peak, 0.0)
    total = sum(_shifted(np.exp(values - peak), 0.0))
    with np.errstate(divide="ignore"):
        result = peak + np.log(total)
    suspect = total < _UNDERFLOW_GUARD
    if suspect.any():
        views = _shifted(values, -np.inf)
        local_peak = np.maximum.reduce(views)
        suspect &= np.isfinite(local_peak)  # an all -inf neighbourhood is exactly -inf
        if suspect.any():
            finite_peak = np.where(np.isfinite(local_peak), local_peak, 0.0)
            exact_total = sum(np.exp(view - finite_peak) for view in views)
            with np.errstate(divide="ignore"):
                exact = finite_peak + np.log(exact_total)
            result = np.where(suspect, exact, result)
    return result


def _soft_values_from_rewards(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """Log-space backward induction on per-cell rewards ``(K, H, W)``; ``-> (T + 1, K, H, W)``."""
    values = np.empty((mdp.horizon + 1,) + rewards.shape)
    values[-1] = rewards
    for t in range(mdp.horizon - 1, -1, -1):
        values[t] = rewards + _neighbour_logsumexp(values[t + 1])
    return values


def soft_values(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """Soft (log-sum-exp) values of the time-indexed grid, by backward induction.

    ``V[T] = r`` and ``V[t](s) = r(s) + log sum_{s' in succ(s)} exp(V[t+1](s'))``, so
    ``V[t](s)`` is the log of the summed exponentiated return of all trajectory suffixes that
    occupy ``s`` at time ``t``.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(T + 1, K, H, W)``.
    """
    return _soft_values_from_rewards(mdp, cell_rewards(mdp, weights))


def _log_visitation_exact(mdp: GridMDP, rewards: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Log occupancy ``log P(s_t = s)`` summed over time, and ``log Z``, in log space throughout.

    Uses forward messages ``alpha[t](s)`` (log summed exponentiated return of prefixes ending in
    ``s`` at ``t``) and backward soft values: ``P(s_t = s) = exp(alpha[t] + V[t] - r - log Z)``.
    Exact for any reward magnitudes; the fallback of the linear-space passes below.

    Args:
        rewards: ``(K, H, W)``.
    Returns:
        ``(K, H, W)`` log expected visit counts, and ``(K,)`` log Z.
    """
    values = _soft_values_from_rewards(mdp, rewards)
    row, col = mdp.start
    log_z = values[0][:, row, col].copy()
    alpha = np.full_like(rewards, -np.inf)
    alpha[:, row, col] = rewards[:, row, col]
    offset = (log_z[:, None, None] + rewards)  # subtracted from alpha + V at every step
    log_visits = alpha + values[0] - offset
    for t in range(1, mdp.horizon + 1):
        alpha = rewards + _neighbour_logsumexp(alpha)
        log_visits = np.logaddexp(log_visits, alpha + values[t] - offset)
    return log_visits, log_z


#: Working set of one fast-path chunk (the kept neighbour sums and values, two
#: ``(T + 1) (H + 1) (W + 1)`` float64 arrays per weight), sized to stay in cache. Larger
#: batches are split evenly.
_CHUNK_BYTES = 8_000_000

#: Working set of one exact log-space batch (its soft values, one ``(T + 1) H W`` float64 array
#: per weight, dominate). The elements the fast path flags in all its chunks are gathered and
#: recomputed in batches of this size, which bounds their memory and gives the threads
#: (``IRD_THREADS``) a few large tasks: on a 64x64 map with T = 120 a fast-path chunk holds one
#: weight, and nearly all of Sample-Z's prior-drawn proxies are flagged.
_EXACT_CHUNK_BYTES = 64_000_000


def _chunks(mdp: GridMDP, num: int, budget: int = 0, per_weight: int = 0) -> list[slice]:
    """Even slices of a batch of ``num`` weights, each within ``budget`` bytes (0: the fast
    path's ``_CHUNK_BYTES``; ``per_weight``: bytes per weight, 0 for the fast path's)."""
    budget = budget or _CHUNK_BYTES
    per_weight = per_weight or 2 * 8 * (mdp.horizon + 1) * (mdp.height + 1) * (mdp.width + 1)
    count = -(-num * per_weight // budget)
    if count <= 1:
        return [slice(0, num)] if num else []
    bounds = np.linspace(0, num, count + 1).round().astype(int)
    return [slice(int(lo), int(hi)) for lo, hi in zip(bounds[:-1], bounds[1:]) if hi > lo]


def _visitation_and_log_partition(mdp: GridMDP, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Expected visits ``(K, H, W)`` and ``log Z`` ``(K,)``: linear-space passes on cache-sized
    chunks, then the exact log-space passes for all the elements the fast path flags, in batches
    of at most ``_EXACT_CHUNK_BYTES`` (every flagged element's result is the same however the
    batch is split: the exact passes are elementwise per weight). Chunks and batches run on
    ``IRD_THREADS`` threads (``ird_core.mdp.threads``), with the same results."""
    rewards = cell_rewards(mdp, weights)
    visits = np.empty(rewards.shape)
    log_z = np.empty(len(rewards))
    redo = np.zeros(len(rewards), dtype=bool)

    def fast_path(part: slice) -> None:  # writes only its own rows: safe on threads
        back = linear_backward(mdp, rewards[part])
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            visits[part], unsure = linear_visitation(mdp, back)
        log_z[part] = back.log_z
        redo[part] = back.suspect | unsure | ~np.isfinite(back.log_z)

    map_chunks(fast_path, _chunks(mdp, len(rewards)))
    flagged = np.flatnonzero(redo)
    exact_bytes = 8 * (mdp.horizon + 1) * mdp.height * mdp.width

    def exact(part: slice) -> None:
        batch = flagged[part]
        log_visits, log_z[batch] = _log_visitation_exact(mdp, rewards[batch])
        visits[batch] = np.exp(log_visits)

    map_chunks(exact, _chunks(mdp, len(flagged), _EXACT_CHUNK_BYTES, exact_bytes))
    return visits, log_z


def log_partition(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """``log Z(w) = log sum_xi exp(w . phi(xi))`` over all trajectories from the start.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(K,)``.
    """
    rewards = cell_rewards(mdp, weights)
    log_z = np.empty(len(rewards))
    redo = np.zeros(len(rewards), dtype=bool)

    def fast_path(part: slice) -> None:
        back = linear_backward(mdp, rewards[part], keep_sums=False)
        log_z[part], redo[part] = back.log_z, back.suspect | ~np.isfinite(back.log_z)

    map_chunks(fast_path, _chunks(mdp, len(rewards)))
    if redo.any():
        row, col = mdp.start
        log_z[redo] = _soft_values_from_rewards(mdp, rewards[redo])[0][:, row, col]
    return log_z


def expected_visitation(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """Expected number of visits to each cell over ``t = 0..T`` under ``P(xi | w)``.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(K, H, W)``; each slice sums to ``T + 1``.
    """
    return _visitation_and_log_partition(mdp, weights)[0]


def feature_expectations(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """``E[phi(xi) | w]``, the gradient of ``log Z`` with respect to ``w``.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(K, d)``.
    """
    return log_partition_and_feature_expectations(mdp, weights)[1]


def log_partition_and_feature_expectations(
    mdp: GridMDP, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``log Z`` ``(K,)`` and ``E[phi]`` ``(K, d)`` from one pair of passes (for gradients)."""
    visits, log_z = _visitation_and_log_partition(mdp, weights)
    flat = mdp.features.reshape(mdp.num_states, mdp.num_features)
    return log_z, visits.reshape(len(visits), mdp.num_states) @ flat


def _check_cell_rewards(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    r = np.asarray(rewards, dtype=np.float64)
    if r.shape != (mdp.height, mdp.width):
        raise ValueError(f"cell_rewards: expected shape ({mdp.height}, {mdp.width}), got {r.shape}")
    if np.any(np.isnan(r)) or np.any(r == np.inf):
        raise ValueError("cell_rewards: contains NaN or +inf")
    return r


def hard_values(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """Optimal (hard max) values for a per-cell reward: ``V[t] = r + max_succ V[t+1]``.

    Args:
        rewards: ``(H, W)`` per-cell reward (``-inf`` marks a forbidden cell).
    Returns:
        ``(T + 1, H, W)``; ``V[0][start]`` is the best total reward of ``T + 1`` states.
    """
    r = _check_cell_rewards(mdp, rewards)
    values = np.empty((mdp.horizon + 1,) + r.shape)
    values[-1] = r
    for t in range(mdp.horizon - 1, -1, -1):
        values[t] = r + np.maximum.reduce(_shifted(values[t + 1], -np.inf))
    return values


def optimal_path(mdp: GridMDP, rewards: np.ndarray) -> tuple[list[tuple[int, int]], float]:
    """A path maximising ``sum_t rewards[s_t]`` and its value.

    Ties are broken in ``MOVES`` order (stay first), so the result is deterministic.

    Args:
        rewards: ``(H, W)`` per-cell reward.
    Returns:
        ``T + 1`` cells ``(row, col)`` starting at the start, and the optimal value.
    """
    values = hard_values(mdp, rewards)
    row, col = mdp.start
    cells = [(row, col)]
    for t in range(1, mdp.horizon + 1):
        best_move, best_value = None, -np.inf
        for d_row, d_col in MOVES:
            r2, c2 = row + d_row, col + d_col
            if 0 <= r2 < mdp.height and 0 <= c2 < mdp.width and values[t][r2, c2] > best_value:
                best_move, best_value = (r2, c2), values[t][r2, c2]
        if best_move is None:  # every successor forbidden: stay (value is -inf anyway)
            best_move = (row, col)
        row, col = best_move
        cells.append((row, col))
    return cells, float(values[0][mdp.start])


def warm_up() -> None:
    """Run one tiny pass of each kind, so that the compiled engine of the passes
    (``ird_core.mdp.linear_kernels``: numba's import, and its kernels loaded from the cache or
    compiled) is paid now, by a worker starting up, not by its first request. Without numba (or
    with ``IRD_ENGINE=numpy``) it is a tiny pass."""
    grid = GridMDP(np.zeros((2, 2, 1)), (0, 0), 2)
    weights = np.zeros((1, 1))
    log_partition(grid, weights)
    log_partition_and_feature_expectations(grid, weights)
