"""A novelty-avoiding control planner (docs/spec.md section 4): the literal proxy, kept off cells
unlike any training cell. It separates "avoid what the designer never saw" (plain caution about
novelty) from IRD's posterior uncertainty about what the proxy meant.

A test cell is novel when its hypothesis features are farther (Euclidean) from every training
cell's than the training cells are from each other: the threshold is the largest
nearest-neighbour distance among the training cells (each cell against the others), so no
training cell would count as novel if it appeared on the test map. Novel cells cost
``penalty`` more than the proxy's reward, with ``penalty`` larger than any path's proxy return
span, so a path avoids every novel cell it can (an unavoidable one is entered as rarely as
possible). Everything is vectorised over cells; distances are computed in chunks.
"""

from __future__ import annotations

import numpy as np

from ird_core.mdp import GridMDP, optimal_path

__all__ = ["novel_cells", "novelty_avoiding_path"]

_CHUNK = 4096


def _nearest_distance(points: np.ndarray, reference: np.ndarray, exclude_self: bool) -> np.ndarray:
    """``(n,)`` distance from each point to its nearest reference point (itself excluded)."""
    ref_sq = np.sum(reference**2, axis=1)
    out = np.empty(len(points))
    for lo in range(0, len(points), _CHUNK):
        block = points[lo: lo + _CHUNK]
        sq = np.sum(block**2, axis=1)[:, None] + ref_sq[None] - 2.0 * block @ reference.T
        if exclude_self:
            sq[np.arange(len(block)), lo + np.arange(len(block))] = np.inf
        out[lo: lo + len(block)] = np.sqrt(np.maximum(sq.min(axis=1), 0.0))
    return out


def novel_cells(train_features: "np.ndarray | list[np.ndarray]", test_features: np.ndarray) -> np.ndarray:
    """``(H, W)`` bool: test cells unlike any training cell (module docstring).

    Args:
        train_features: ``(H', W', d)`` training map features, or a list of them (every
            training world).
        test_features: ``(H, W, d)``.
    """
    worlds = train_features if isinstance(train_features, list) else [train_features]
    train = np.concatenate([np.asarray(f, dtype=np.float64).reshape(-1, f.shape[-1]) for f in worlds])
    test = np.asarray(test_features, dtype=np.float64)
    if len(train) < 2:
        raise ValueError("train_features: at least two training cells are needed to judge novelty")
    threshold = _nearest_distance(train, train, exclude_self=True).max()
    distance = _nearest_distance(test.reshape(-1, test.shape[-1]), train, exclude_self=False)
    return (distance > threshold).reshape(test.shape[:2])


def novelty_avoiding_path(proxy_mdp: GridMDP, proxy_weights: np.ndarray, novel: np.ndarray
                          ) -> list[tuple[int, int]]:
    """The proxy's optimal path with novel cells penalised (module docstring).

    Args:
        proxy_mdp: the test MDP on the proxy's features.
        proxy_weights: ``(p,)``.
        novel: ``(H, W)`` bool from :func:`novel_cells`.
    """
    reward = proxy_mdp.features @ np.asarray(proxy_weights, dtype=np.float64)
    span = float(reward.max() - reward.min())
    penalty = (proxy_mdp.horizon + 1) * span + 1.0
    cells, _ = optimal_path(proxy_mdp, reward - penalty * novel)
    return cells
