"""Optimal (hard-max) paths of a batch of rewards and their feature counts (docs/spec.md section 3).

The paper's Sample-Z approximation writes its normaliser with "the vector of feature counts
realized optimizing" each reward: the counts of an optimal path, not MaxEnt expectations. This
module computes those paths for ``K`` rewards at once.

Invariants:

- For every batch element ``k`` the path equals ``passes.optimal_path(mdp, rewards[k])`` cell
  for cell: the same backward recursion ``V[t] = r + max_succ V[t + 1]`` (a max is exact, so
  the values are bit-identical), and the same tie-breaking, the first move in ``MOVES`` order (stay
  first) among those of largest ``V[t + 1]``. So the counts are a deterministic, piecewise
  constant function of the weights, and scale-free: ``counts(c * w) == counts(w)`` for ``c > 0``
  up to ties created by rounding.
- ``w . counts(w) = max_xi w . phi(xi)`` (the optimal return), a convex piecewise-linear
  function of ``w`` whose gradient is ``counts(w)`` wherever the optimum is unique (envelope
  theorem): the Sample-Z own term needs no ray derivative in this reading.

With numba installed (``ird_core.mdp.linear_kernels.engine``) one compiled kernel runs the same
recursion (a max is exact, an add is the same add), so both engines give the same paths.

Cost ``O(T * K * H * W * 5)`` for the values plus ``O(T * K * 5)`` for the paths, vectorised over
the batch and the cells; Python loops run over time steps and memory chunks only.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Callable

import numpy as np

from ird_core.mdp.grid import GridMDP, cell_rewards, successor_table
from ird_core.mdp.linear_kernels import engine

__all__ = ["OPTIMAL_BATCH", "optimal_paths", "optimal_feature_counts", "optimal_returns"]

#: Weights per chunk: bounds the working set to ``(T + 1, batch, H, W)`` floats.
OPTIMAL_BATCH: int = 256


def _successors(mdp: GridMDP) -> np.ndarray:
    """``(S, 5)`` successor states in ``MOVES`` order, ``S`` (a padding column of ``-inf``
    values) where a move leaves the grid."""
    table = successor_table(mdp.height, mdp.width)
    return np.where(table < 0, mdp.num_states, table)


def _paths_kernel(rewards: np.ndarray, succ: np.ndarray, start: int, horizon: int,
                  values: np.ndarray, states: np.ndarray) -> None:  # pragma: no cover - numba source
    """numba source of :func:`_paths_of_chunk` (same recursion and tie-breaking): fills
    ``values`` ``(T + 1, K, S + 1)`` (column ``S`` preset to ``-inf``) and ``states``."""
    k, s = rewards.shape
    for j in range(k):
        for c in range(s):
            values[horizon, j, c] = rewards[j, c]
    for t in range(horizon - 1, -1, -1):
        for j in range(k):
            for c in range(s):
                best = values[t + 1, j, succ[c, 0]]
                for m in range(1, 5):
                    v = values[t + 1, j, succ[c, m]]
                    if v > best:
                        best = v
                values[t, j, c] = rewards[j, c] + best
    for j in range(k):
        state = start
        states[j, 0] = state
        for t in range(1, horizon + 1):
            choice = succ[state, 0]
            best = values[t, j, choice]
            for m in range(1, 5):
                nxt = succ[state, m]
                if values[t, j, nxt] > best:
                    best = values[t, j, nxt]
                    choice = nxt
            state = choice
            states[j, t] = state


@lru_cache(maxsize=1)
def _compiled_kernel() -> Callable[..., None]:
    import numba  # noqa: PLC0415 - lazy, as ird_core.mdp.linear_kernels

    return numba.njit(cache=True, nogil=True, error_model="numpy")(_paths_kernel)


def _paths_of_chunk(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """``(K, T + 1)`` optimal state sequences of ``(K, S)`` finite rewards (first best move in
    ``MOVES`` order). ``values[t][:, :S]`` is ``V[t] = r + max_succ V[t + 1]``; column ``S``
    holds ``-inf`` so that moves off the grid never win."""
    k, s = rewards.shape
    succ = _successors(mdp)
    values = np.full((mdp.horizon + 1, k, s + 1), -np.inf)
    if engine() == "numba":
        states = np.empty((k, mdp.horizon + 1), dtype=np.int64)
        _compiled_kernel()(np.ascontiguousarray(rewards), succ, mdp.start_state, mdp.horizon, values, states)
        return states
    values[-1, :, :s] = rewards
    for t in range(mdp.horizon - 1, -1, -1):
        values[t, :, :s] = rewards + values[t + 1][:, succ].max(axis=2)
    states = np.empty((k, mdp.horizon + 1), dtype=np.int64)
    states[:, 0] = mdp.start_state
    batch = np.arange(k)[:, None]
    for t in range(1, mdp.horizon + 1):
        options = succ[states[:, t - 1]]  # (K, 5)
        choice = values[t][batch, options].argmax(axis=1)  # the first maximum: MOVES order breaks ties
        states[:, t] = options[batch[:, 0], choice]
    return states


def optimal_paths(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """Optimal paths of ``T + 1`` cells from the start for a batch of per-cell rewards.

    Args:
        mdp: the grid MDP (its start and horizon).
        rewards: ``(K, H, W)`` finite per-cell rewards.
    Returns:
        ``(K, T + 1, 2)`` int64 ``(row, col)`` cells; element ``k`` equals
        ``optimal_path(mdp, rewards[k])``'s cells.
    Raises:
        ValueError: naming ``rewards`` when its shape is wrong or a value is not finite.
    """
    r = np.asarray(rewards, dtype=np.float64)
    if r.ndim != 3 or r.shape[1:] != (mdp.height, mdp.width) or len(r) == 0:
        raise ValueError(f"rewards: expected shape (K, {mdp.height}, {mdp.width}) with K >= 1, got {r.shape}")
    if not np.all(np.isfinite(r)):
        raise ValueError("rewards: contains NaN or infinite values")
    flat = r.reshape(len(r), -1)
    states = np.concatenate([_paths_of_chunk(mdp, flat[lo: lo + OPTIMAL_BATCH])
                             for lo in range(0, len(r), OPTIMAL_BATCH)])
    return np.stack(np.divmod(states, mdp.width), axis=2)


def optimal_feature_counts(mdp: GridMDP, weights: np.ndarray,
                           count_features: "np.ndarray | None" = None) -> np.ndarray:
    """Feature counts ``phi(xi*_w)`` of each weight's optimal path (docs/spec.md section 3).

    Args:
        mdp: the MDP the rewards ``w . mdp.features`` are planned on, ``(H, W, p)``.
        weights: ``(K, p)``.
        count_features: ``(H, W, d)`` features to count along the paths (the hypothesis space
            of a proxy planned on other features); ``None`` = ``mdp.features``.
    Returns:
        ``(K, d)``: the sum of ``count_features`` over the path's ``T + 1`` cells.
    """
    rewards = cell_rewards(mdp, weights)
    features = mdp.features if count_features is None else np.asarray(count_features, dtype=np.float64)
    flat = features.reshape(mdp.num_states, -1)
    states = np.concatenate([_paths_of_chunk(mdp, rewards[lo: lo + OPTIMAL_BATCH].reshape(-1, mdp.num_states))
                             for lo in range(0, len(rewards), OPTIMAL_BATCH)])
    visits = np.zeros((len(states), mdp.num_states))
    np.add.at(visits, (np.repeat(np.arange(len(states)), states.shape[1]), states.ravel()), 1.0)
    return visits @ flat


def optimal_returns(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """``max_xi w . phi(xi)`` for each weight, ``(K, p) -> (K,)`` (``w . optimal_feature_counts``)."""
    w = np.atleast_2d(np.asarray(weights, dtype=np.float64))
    return np.sum(w * optimal_feature_counts(mdp, w), axis=1)
