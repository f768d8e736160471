"""nav_msgs/Path <-> (row, col) cells: a path's poses lie at cell centres (docs/spec.md section 6).

The geometry is :mod:`ird_ros.geometry`; both functions validate their input and raise
``ValueError`` naming the field (``Path.poses: ...``, ``<field>.poses[i]: ...``).
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path

from ird_ros.conversions.grids import MAP_FRAME, _check_geometry, _f, make_header
from ird_ros.geometry import cell_center, grid_coordinates

__all__ = ["cells_to_path", "path_to_cells"]


def _check_cells(field: str, cells: Any, height: int | None, width: int | None) -> np.ndarray:
    arr = np.asarray(cells)
    if arr.size == 0:
        raise _f(field, "must contain at least one cell")
    if arr.ndim != 2 or arr.shape[1] != 2:
        raise _f(field, f"expected (row, col) pairs, shape (N, 2), got shape {arr.shape}")
    if arr.dtype.kind not in "iu":
        if arr.dtype.kind != "f" or not np.all(np.isfinite(arr)) or not np.all(arr == np.round(arr)):
            raise _f(field, f"cells must be integer (row, col) pairs, got dtype {arr.dtype}")
    arr = arr.astype(np.int64)
    if np.any(arr < 0):
        raise _f(field, f"negative cell index at position {int(np.flatnonzero((arr < 0).any(axis=1))[0])}")
    if height is not None and np.any(arr[:, 0] >= height):
        raise _f(field, f"row off the map (height {height}) at position {int(np.flatnonzero(arr[:, 0] >= height)[0])}")
    if width is not None and np.any(arr[:, 1] >= width):
        raise _f(field, f"col off the map (width {width}) at position {int(np.flatnonzero(arr[:, 1] >= width)[0])}")
    return arr


def cells_to_path(
    cells: Sequence[tuple[int, int]] | np.ndarray,
    *,
    resolution: float = 1.0,
    origin: Sequence[float] = (0.0, 0.0),
    height: int | None = None,
    width: int | None = None,
    stamp: Time | None = None,
    frame_id: str = MAP_FRAME,
) -> Path:
    """A nav_msgs/Path through the centres of ``cells`` ((row, col) pairs, shape (N, 2)).

    Poses carry the identity orientation. With ``height``/``width`` given, every cell must
    lie on the map.
    """
    field = "Path.poses"
    ox, oy = _check_geometry("Path", resolution, origin)
    arr = _check_cells(field, cells, height, width)
    path = Path()
    path.header = make_header(stamp, frame_id)
    poses = []
    for row, col in arr.tolist():
        pose = PoseStamped()
        pose.header = make_header(stamp, frame_id)
        pose.pose.position.x, pose.pose.position.y = cell_center(row, col, resolution, (ox, oy))
        pose.pose.orientation.w = 1.0
        poses.append(pose)
    path.poses = poses
    return path


def path_to_cells(
    path: Path,
    *,
    resolution: float = 1.0,
    origin: Sequence[float] = (0.0, 0.0),
    height: int | None = None,
    width: int | None = None,
    field: str = "Path",
    tolerance: float = 1e-6,
) -> list[tuple[int, int]]:
    """The (row, col) cells of a nav_msgs/Path whose poses lie at cell centres.

    Raises ``ValueError`` if a pose is not within ``tolerance * resolution`` of a cell
    centre, or (with ``height``/``width``) off the map.
    """
    ox, oy = _check_geometry(field, resolution, origin)
    if not path.poses:
        raise _f(f"{field}.poses", "must contain at least one pose")
    xy = np.array([(p.pose.position.x, p.pose.position.y) for p in path.poses], dtype=np.float64)
    finite = np.isfinite(xy).all(axis=1)
    offset = np.zeros_like(xy)  # (N, 2) (row, col) distance from the nearest cell centre
    offset[finite] = grid_coordinates(xy[finite], resolution, (ox, oy)) - 0.5
    cells = np.round(offset)  # half-to-even, like round()
    off_centre = (np.abs(offset - cells) > tolerance).any(axis=1)
    rows, cols = cells[:, 0], cells[:, 1]
    off_map = (rows < 0) | (cols < 0)
    if height is not None:
        off_map |= rows >= height
    if width is not None:
        off_map |= cols >= width
    bad = ~finite | off_centre | off_map
    if bad.any():  # report the first bad pose, its first problem in the order checked
        i = int(np.argmax(bad))
        x, y = path.poses[i].pose.position.x, path.poses[i].pose.position.y
        if not finite[i]:
            raise _f(f"{field}.poses[{i}]", f"non-finite position ({x}, {y})")
        if off_centre[i]:
            raise _f(f"{field}.poses[{i}]", f"position ({x}, {y}) is not at a cell centre")
        raise _f(f"{field}.poses[{i}]", f"cell (row={int(rows[i])}, col={int(cols[i])}) is off the map")
    return [(int(r), int(c)) for r, c in cells.astype(np.int64)]
