"""Brute-force references: enumerate every trajectory of a (tiny) grid MDP.

These are the ground truth the dynamic programs are tested against. The number of
trajectories grows like ``5 ** T``, so keep grids tiny (e.g. 3x3, T <= 6).
"""

from __future__ import annotations

import numpy as np
from scipy.special import logsumexp

from ird_core.mdp.grid import GridMDP, successor_table

__all__ = ["all_trajectories", "trajectory_features", "brute_log_partition",
           "brute_feature_expectations", "brute_visitation"]

_MAX_TRAJECTORIES = 5_000_000


def all_trajectories(mdp: GridMDP) -> np.ndarray:
    """Every trajectory from the start as state indices.

    Returns:
        ``(N, T + 1)`` int64, each distinct move sequence exactly once.
    """
    table = successor_table(mdp.height, mdp.width)
    trajectories = np.array([[mdp.start_state]], dtype=np.int64)
    for _ in range(mdp.horizon):
        nxt = table[trajectories[:, -1]]  # (N, 5)
        parent, move = np.nonzero(nxt >= 0)
        trajectories = np.concatenate([trajectories[parent], nxt[parent, move][:, None]], axis=1)
        if len(trajectories) > _MAX_TRAJECTORIES:
            raise ValueError(f"horizon: {mdp.horizon} gives too many trajectories to enumerate")
    return trajectories


def trajectory_features(mdp: GridMDP, trajectories: np.ndarray) -> np.ndarray:
    """``phi(xi)`` for each trajectory; ``(N, T + 1)`` states -> ``(N, d)``."""
    flat = mdp.features.reshape(mdp.num_states, mdp.num_features)
    return flat[trajectories].sum(axis=1)


def brute_log_partition(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """``log Z`` by enumeration; ``(K, d)`` -> ``(K,)``."""
    phi = trajectory_features(mdp, all_trajectories(mdp))
    return logsumexp(np.asarray(weights) @ phi.T, axis=1)


def _trajectory_probabilities(mdp: GridMDP, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    trajectories = all_trajectories(mdp)
    scores = np.asarray(weights) @ trajectory_features(mdp, trajectories).T  # (K, N)
    probs = np.exp(scores - logsumexp(scores, axis=1, keepdims=True))
    return trajectories, probs


def brute_feature_expectations(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """``E[phi(xi) | w]`` by enumeration; ``(K, d)`` -> ``(K, d)``."""
    trajectories, probs = _trajectory_probabilities(mdp, weights)
    return probs @ trajectory_features(mdp, trajectories)


def brute_visitation(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """Expected visit counts by enumeration; ``(K, d)`` -> ``(K, H, W)``."""
    trajectories, probs = _trajectory_probabilities(mdp, weights)
    counts = np.zeros((len(trajectories), mdp.num_states))
    np.add.at(counts, (np.repeat(np.arange(len(trajectories)), mdp.horizon + 1), trajectories.ravel()), 1.0)
    return (probs @ counts).reshape(-1, mdp.height, mdp.width)
