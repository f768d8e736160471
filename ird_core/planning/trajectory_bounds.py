"""Exact dynamic programs over the time-expanded grid graph, for the trajectory solver.

Every bound :mod:`ird_core.planning.trajectory_solver` prunes with is one of these tables: best reward
still to collect (:func:`to_go`), best reward collected so far (:func:`come_from`), and each
reward row's own optimum (:func:`best_returns`). Hard max DPs, vectorised over reward rows and
states; Python loops run over time steps only. States are flat indices ``s = row * W + col``.
"""

from __future__ import annotations

import numpy as np

from ird_core.mdp import GridMDP, optimal_path, successor_table, validate_path

__all__ = ["best_returns", "come_from", "path_states", "start_distance", "states_to_cells", "successors", "to_go",
           "trajectory_value"]


def start_distance(mdp: GridMDP) -> np.ndarray:
    """``(S,)`` Manhattan distance of every state from the start: state ``s`` can be occupied at
    time ``t`` iff ``dist[s] <= t`` (a "stay" move is always available)."""
    rows, cols = np.divmod(np.arange(mdp.num_states), mdp.width)
    return np.abs(rows - mdp.start[0]) + np.abs(cols - mdp.start[1])


def successors(mdp: GridMDP) -> np.ndarray:
    """``(S, 5)`` successor states, off-grid moves pointing at the sentinel index ``S``."""
    table = successor_table(mdp.height, mdp.width)
    return np.where(table < 0, mdp.num_states, table)


def to_go(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """Best reward still to collect, ``V[t, j, s] = max sum_{u = t+1..T} rewards[j, s_u]`` over
    walks with ``s_t = s``; ``V[T] = 0``. Hard DP vectorised over reward rows and states.

    Args:
        rewards: ``(m, S)``.
    Returns:
        ``(T + 1, m, S)``.
    """
    succ = successors(mdp)
    values = np.zeros((mdp.horizon + 1,) + rewards.shape)
    sentinel = np.full((len(rewards), 1), -np.inf)
    for t in range(mdp.horizon - 1, -1, -1):
        values[t] = np.concatenate([rewards + values[t + 1], sentinel], axis=1)[:, succ].max(axis=2)
    return values


def best_returns(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """Each row's own optimum ``max_xi sum_t rewards[j, s_t]``; ``(m, S)`` -> ``(m,)``.
    The same recursion as :func:`to_go`, keeping one time step in memory."""
    succ = successors(mdp)
    values = np.zeros_like(rewards)
    sentinel = np.full((len(rewards), 1), -np.inf)
    for _ in range(mdp.horizon):
        values = np.concatenate([rewards + values, sentinel], axis=1)[:, succ].max(axis=2)
    return values[:, mdp.start_state] + rewards[:, mdp.start_state]


def come_from(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """Best collected reward ``A[t, j, s] = max sum_{u = 0..t} rewards[j, s_u]`` over walks from
    the start with ``s_t = s`` (``-inf`` where unreachable). Predecessors equal successors.

    Args:
        rewards: ``(m, S)``.
    Returns:
        ``(T + 1, m, S)``.
    """
    succ = successors(mdp)
    values = np.full((mdp.horizon + 1,) + rewards.shape, -np.inf)
    values[0][:, mdp.start_state] = rewards[:, mdp.start_state]
    sentinel = np.full((len(rewards), 1), -np.inf)
    for t in range(1, mdp.horizon + 1):
        values[t] = rewards + np.concatenate([values[t - 1], sentinel], axis=1)[:, succ].max(axis=2)
    return values


def path_states(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """``optimal_path`` for an ``(S,)`` reward, as ``(T + 1,)`` state indices."""
    cells = validate_path(mdp, optimal_path(mdp, rewards.reshape(mdp.height, mdp.width))[0])
    return cells[:, 0] * mdp.width + cells[:, 1]


def trajectory_value(q: np.ndarray, states: np.ndarray) -> float:
    """``min_i sum_t q_i(s_t)`` for ``q`` ``(K, S)`` and a path of state indices."""
    return float(q[:, states].sum(axis=1).min())


def states_to_cells(mdp: GridMDP, states: np.ndarray) -> np.ndarray:
    """``(T + 1,)`` state indices -> checked ``(T + 1, 2)`` cells."""
    return validate_path(mdp, np.stack(np.divmod(np.asarray(states), mdp.width), axis=1))
