"""The one evaluation of a path on a terrain map (docs/spec.md section 5): its true return and
whether it touches lava, reaches a target, reaches gold.

A path is a sequence of ``(row, col)`` cells, the start included; every visited cell counts,
revisits too, so a plan of ``T`` moves has ``T + 1`` cells. The true return is the sum of the
per-label true reward (default :data:`ird_core.worlds.lavaland.TRUE_TERRAIN_REWARD`; a file
world's ``instance.true_terrain_reward``) over those cells.

Unknown terrain: a cell whose label has no entry in the reward table (``label < 0`` or ``label >=
len(terrain_reward)``) adds nothing to :attr:`PathOutcome.true_return` and is counted in
:attr:`PathOutcome.unknown_cells`, so every caller chooses its own policy (a robot on an
unmapped cell scores 0; :func:`true_return` refuses such a path).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ird_core.worlds.lavaland import TRUE_TERRAIN_REWARD
from ird_core.worlds.terrain import Terrain

__all__ = ["PathOutcome", "evaluate_path", "true_return", "touches_lava", "reaches_target", "reaches_gold"]

Cells = "list[tuple[int, int]] | np.ndarray"


@dataclass(frozen=True)
class PathOutcome:
    """What a path achieved on a map.

    Attributes:
        true_return: sum of the true reward over the cells with a known label.
        touched_lava, reached_target, reached_gold: whether any cell is lava, a target, gold.
        unknown_cells: number of visited cells (revisits counted) whose label has no reward.
    """

    true_return: float
    touched_lava: bool
    reached_target: bool
    reached_gold: bool
    unknown_cells: int


def path_labels(labels: np.ndarray, cells: Cells) -> np.ndarray:
    """Terrain labels along a path of (row, col) cells; (n, 2) -> (n,).

    Raises:
        ValueError: ``labels`` not (H, W), ``cells`` not a non-empty (n, 2), or a cell off the map.
    """
    labels = np.asarray(labels)
    if labels.ndim != 2:
        raise ValueError(f"labels must be an (H, W) array, got shape {labels.shape}")
    path = np.asarray(cells, dtype=np.int64)
    if path.ndim != 2 or path.shape[1] != 2 or path.shape[0] < 1:
        raise ValueError(f"cells must be a non-empty list of (row, col), got shape {path.shape}")
    inside = (
        (path[:, 0] >= 0) & (path[:, 0] < labels.shape[0])
        & (path[:, 1] >= 0) & (path[:, 1] < labels.shape[1])
    )
    if not inside.all():
        raise ValueError(f"cells: cell {tuple(path[np.argmin(inside)])} is off the map")
    return labels[path[:, 0], path[:, 1]]


def evaluate_path(labels: np.ndarray, cells: Cells, terrain_reward: np.ndarray = TRUE_TERRAIN_REWARD) -> PathOutcome:
    """The :class:`PathOutcome` of ``cells`` on the (H, W) ``labels`` under ``terrain_reward`` (per label)."""
    along = path_labels(labels, cells)
    reward = np.asarray(terrain_reward)
    known = (along >= 0) & (along < len(reward))
    return PathOutcome(
        true_return=float(reward[along[known]].sum()),
        touched_lava=bool(np.any(along == Terrain.LAVA)),
        reached_target=bool(np.any(along == Terrain.TARGET)),
        reached_gold=bool(np.any(along == Terrain.GOLD)),
        unknown_cells=int(np.count_nonzero(~known)),
    )


def true_return(labels: np.ndarray, cells: Cells, terrain_reward: np.ndarray = TRUE_TERRAIN_REWARD) -> float:
    """Sum of the true reward per label over the path's cells (T + 1 cells, start included).

    Raises:
        ValueError: a cell's label has no entry in ``terrain_reward``.
    """
    outcome = evaluate_path(labels, cells, terrain_reward)
    if outcome.unknown_cells:
        raise ValueError(f"cells: {outcome.unknown_cells} cell(s) have a label with no entry in terrain_reward")
    return outcome.true_return


def touches_lava(labels: np.ndarray, cells: Cells) -> bool:
    """Whether any cell of the path is lava."""
    return evaluate_path(labels, cells).touched_lava


def reaches_target(labels: np.ndarray, cells: Cells) -> bool:
    """Whether any cell of the path is a target."""
    return evaluate_path(labels, cells).reached_target


def reaches_gold(labels: np.ndarray, cells: Cells) -> bool:
    """Whether any cell of the path is gold."""
    return evaluate_path(labels, cells).reached_gold
