"""The grid MDP and its basics (docs/spec.md section 1): the ``GridMDP`` record, the moves,
per-cell rewards, successor tables and the features and returns of a path.

Conventions:

- A map is a feature array ``F`` of shape ``(H, W, d)``; cell ``(row, col)`` has state index
  ``s = row * W + col``; row 0 is the bottom row.
- The successors of a cell are the cell itself ("stay") and its in-grid 4-neighbours, each once
  (:data:`MOVES`). The relation is symmetric, so predecessors equal successors.
- A trajectory ``xi = (s_0, ..., s_T)`` has ``T = horizon`` moves and ``T + 1`` states, start
  included; ``phi(xi) = sum_t F[s_t]`` and ``r(xi; w) = w . phi(xi)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "MOVES",
    "GridMDP",
    "cell_rewards",
    "successor_table",
    "validate_path",
    "path_features",
    "path_return",
]

#: The actions as (d_row, d_col), in tie-breaking order: "stay" first, so an indifferent agent
#: stays put, then up (row + 1), down, right (col + 1), left.
MOVES: tuple[tuple[int, int], ...] = ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1))


@dataclass(frozen=True, eq=False)
class GridMDP:
    """A deterministic grid MDP with a finite horizon.

    Attributes:
        features: ``(H, W, d)`` float64 feature array, finite.
        start: ``(row, col)`` start cell, on the map.
        horizon: ``T >= 1`` moves; trajectories visit ``T + 1`` states.
    """

    features: np.ndarray
    start: tuple[int, int]
    horizon: int

    def __post_init__(self) -> None:
        features = np.asarray(self.features, dtype=np.float64)
        if features.ndim != 3:
            raise ValueError(f"features: expected shape (H, W, d), got {features.shape}")
        if min(features.shape) < 1:
            raise ValueError(f"features: every dimension must be >= 1, got {features.shape}")
        if not np.all(np.isfinite(features)):
            raise ValueError("features: contains NaN or infinite values")
        try:
            row, col = (int(v) for v in self.start)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"start: expected (row, col), got {self.start!r}") from exc
        height, width = features.shape[:2]
        if not (0 <= row < height and 0 <= col < width):
            raise ValueError(f"start: ({row}, {col}) is off the {height}x{width} map")
        if isinstance(self.horizon, bool) or int(self.horizon) != self.horizon or self.horizon < 1:
            raise ValueError(f"horizon: expected an integer >= 1, got {self.horizon!r}")
        features.setflags(write=False)
        object.__setattr__(self, "features", features)
        object.__setattr__(self, "start", (row, col))
        object.__setattr__(self, "horizon", int(self.horizon))

    @property
    def height(self) -> int:
        return int(self.features.shape[0])

    @property
    def width(self) -> int:
        return int(self.features.shape[1])

    @property
    def num_features(self) -> int:
        return int(self.features.shape[2])

    @property
    def num_states(self) -> int:
        return self.height * self.width

    @property
    def start_state(self) -> int:
        return self.start[0] * self.width + self.start[1]

    def with_features(self, features: np.ndarray) -> "GridMDP":
        """The same grid, start and horizon with another ``(H, W, d')`` feature array."""
        return GridMDP(features, self.start, self.horizon)


def _as_weights(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """Validate a ``(K, d)`` batch of weight vectors (a single ``(d,)`` vector is rejected)."""
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 2 or w.shape[1] != mdp.num_features:
        raise ValueError(f"weights: expected shape (K, {mdp.num_features}), got {w.shape}")
    if not np.all(np.isfinite(w)):
        raise ValueError("weights: contains NaN or infinite values")
    return w


def cell_rewards(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """Per-cell rewards ``w_k . F[row, col]``.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(K, H, W)``.
    """
    w = _as_weights(mdp, weights)
    # A plain gemm: einsum's per-call path search is a visible share of an MCMC step.
    flat = mdp.features.reshape(-1, mdp.num_features)
    return (w @ flat.T).reshape(len(w), mdp.height, mdp.width)


def successor_table(height: int, width: int) -> np.ndarray:
    """Successor state indices of every cell, ``-1`` where a move leaves the grid.

    Returns:
        ``(H * W, 5)`` int64, columns in ``MOVES`` order (column 0 is the cell itself).
    """
    rows, cols = np.divmod(np.arange(height * width), width)
    table = np.full((height * width, len(MOVES)), -1, dtype=np.int64)
    for m, (d_row, d_col) in enumerate(MOVES):
        r2, c2 = rows + d_row, cols + d_col
        inside = (r2 >= 0) & (r2 < height) & (c2 >= 0) & (c2 < width)
        table[inside, m] = r2[inside] * width + c2[inside]
    return table


def validate_path(mdp: GridMDP, cells: "list[tuple[int, int]] | np.ndarray") -> np.ndarray:
    """Check that ``cells`` is a legal trajectory of ``mdp``; return it as ``(T + 1, 2)`` ints."""
    path = np.asarray(cells, dtype=np.int64)
    if path.shape != (mdp.horizon + 1, 2):
        raise ValueError(f"cells: expected {mdp.horizon + 1} (row, col) pairs, got shape {path.shape}")
    if tuple(path[0]) != mdp.start:
        raise ValueError(f"cells: path starts at {tuple(path[0])}, not at the start {mdp.start}")
    inside = (path[:, 0] >= 0) & (path[:, 0] < mdp.height) & (path[:, 1] >= 0) & (path[:, 1] < mdp.width)
    if not inside.all():
        raise ValueError(f"cells: step {int(np.argmin(inside))} is off the map")
    steps = np.abs(np.diff(path, axis=0)).sum(axis=1)
    if np.any(steps > 1):
        raise ValueError(f"cells: move {int(np.argmax(steps > 1))} is not a stay or a 4-neighbour step")
    return path


def path_features(mdp: GridMDP, cells: "list[tuple[int, int]] | np.ndarray") -> np.ndarray:
    """``phi(xi) = sum_t F[s_t]`` for a legal path; ``(d,)``."""
    path = validate_path(mdp, cells)
    return mdp.features[path[:, 0], path[:, 1]].sum(axis=0)


def path_return(mdp: GridMDP, cells: "list[tuple[int, int]] | np.ndarray", weights: np.ndarray) -> np.ndarray:
    """``w_k . phi(xi)`` for a batch ``(K, d)`` of weights; ``(K,)``."""
    return _as_weights(mdp, weights) @ path_features(mdp, cells)
