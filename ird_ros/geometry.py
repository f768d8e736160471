"""Map frame <-> grid cell geometry, free of ROS (docs/spec.md section 6).

A grid of H rows and W columns lies in frame ``map`` with the corner of cell ``(0, 0)`` at
``origin`` and square cells of side ``resolution``; row 0 is the bottom row, x grows with the
column and y with the row. Cell ``(row, col)`` covers
``[origin_x + col * res, origin_x + (col + 1) * res) x [origin_y + row * res, origin_y + (row + 1) * res)``
and its centre is at ``(origin_x + (col + 0.5) * res, origin_y + (row + 0.5) * res)``.

:func:`grid_coordinates` is the one map point -> cell transform of the stack: the message
conversions (which snap poses to cell centres) and the bag analysis (which locates odometry
and plan poses in cells) both build on it. Only numpy is imported, and it lives outside
``ird_ros.conversions`` (whose package imports the message types), so the bag tools can use it
on a machine without ROS; ``ird_ros.conversions`` exports it with the conversions.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = ["cell_center", "grid_coordinates", "point_cells"]


def cell_center(row: int, col: int, resolution: float = 1.0, origin: Sequence[float] = (0.0, 0.0)) -> tuple[float, float]:
    """(x, y) of the centre of cell (row, col)."""
    return (
        float(origin[0]) + (col + 0.5) * float(resolution),
        float(origin[1]) + (row + 0.5) * float(resolution),
    )


def grid_coordinates(xy: np.ndarray, resolution: float = 1.0, origin: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
    """Continuous grid coordinates of map points: cell ``(r, c)`` spans ``[r, r + 1) x [c, c + 1)``.

    Args:
        xy: ``(N, 2)`` map points ``(x, y)`` (anything reshapeable to it).
        resolution: metres per cell, > 0.
        origin: ``(x, y)`` of the corner of cell ``(0, 0)``.
    Returns:
        ``(N, 2)`` float64 ``(row, col)``; a cell centre maps to ``(r + 0.5, c + 0.5)``.
    """
    pts = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    return np.stack([(pts[:, 1] - float(origin[1])) / float(resolution),
                     (pts[:, 0] - float(origin[0])) / float(resolution)], axis=1)


def point_cells(xy: np.ndarray, resolution: float = 1.0, origin: Sequence[float] = (0.0, 0.0)) -> np.ndarray:
    """``(N, 2)`` int64 ``(row, col)`` of the cells containing map points ``xy`` ``(N, 2)``.

    Cells may lie off any particular map (negative or too large): the caller checks bounds.
    """
    return np.floor(grid_coordinates(xy, resolution, origin)).astype(np.int64)
