"""numpy <-> ROS grid messages: FeatureGrid, TerrainGrid, OccupancyGrid (and MapMetaData, Header).

Part of :mod:`ird_ros.conversions` (which exports every public name here; import that).
Grid convention (docs/spec.md section 6): a map of H rows and W columns is a numpy array
indexed ``[row, col, ...]`` in C order; row 0 is the bottom row, x grows with the column
and y with the row (the geometry itself is in :mod:`ird_ros.geometry`).

Also home of the validation helpers every conversion shares (``_f`` builds the
``ValueError`` naming the offending field; ``_check_*`` / ``_read`` / ``_as_float_array``).
"""

from __future__ import annotations

import array
import math
from dataclasses import dataclass
from typing import Any, Iterable, Mapping, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from nav_msgs.msg import MapMetaData, OccupancyGrid
from std_msgs.msg import Header

from ird_core.checks import check_magnitude
from ird_msgs.msg import FeatureGrid, TerrainGrid

__all__ = [
    "MAP_FRAME",
    "UNKNOWN_CLASS",
    "FeatureGridData",
    "TerrainGridData",
    "make_header",
    "make_map_info",
    "now_stamp",
    "first_with_layers",
    "feature_grid_to_msg",
    "feature_grid_from_msg",
    "terrain_grid_to_msg",
    "terrain_grid_from_msg",
    "occupancy_grid_to_msg",
    "occupancy_grid_from_msg",
]

MAP_FRAME = "map"
"""Frame of every grid, path and pose of the stack."""

UNKNOWN_CLASS = 255
"""TerrainGrid.classes value of a cell of unknown terrain."""

Origin = tuple[float, float]


# --------------------------------------------------------------------------- data classes


@dataclass(frozen=True)
class FeatureGridData:
    """A FeatureGrid as numpy: ``features`` has shape (H, W, d), dtype float32."""

    features: np.ndarray
    layers: tuple[str, ...]
    resolution: float = 1.0
    origin: Origin = (0.0, 0.0)
    frame_id: str = MAP_FRAME

    @property
    def shape(self) -> tuple[int, int, int]:
        """(H, W, d)."""
        h, w, d = self.features.shape
        return int(h), int(w), int(d)


@dataclass(frozen=True)
class TerrainGridData:
    """A TerrainGrid as numpy.

    ``classes``: (H, W) uint8, indices into ``class_names`` or ``UNKNOWN_CLASS``;
    ``probabilities``: (H, W, C) float32 or None (not estimated);
    ``novelty``: (H, W) float32 >= 0 or None (not computed).
    """

    classes: np.ndarray
    class_names: tuple[str, ...]
    probabilities: np.ndarray | None = None
    novelty: np.ndarray | None = None
    resolution: float = 1.0
    origin: Origin = (0.0, 0.0)
    frame_id: str = MAP_FRAME


# --------------------------------------------------------------------------- helpers


def _f(field: str, problem: str) -> ValueError:
    return ValueError(f"{field}: {problem}")


def make_header(stamp: Time | None = None, frame_id: str = MAP_FRAME) -> Header:
    """A std_msgs/Header with the given stamp (default: zero time) and frame."""
    header = Header(frame_id=frame_id)
    if stamp is not None:
        header.stamp = stamp
    return header


def now_stamp(node: Any) -> Time:
    """The node's clock now, as a message stamp (the stamp of everything a node publishes)."""
    return node.get_clock().now().to_msg()


def first_with_layers(maps: Mapping[str, FeatureGridData], topics: Iterable[str],
                      layers: Sequence[str]) -> tuple[str, FeatureGridData] | None:
    """The first of ``topics`` (in order) whose latest map in ``maps`` has exactly ``layers``,
    with its topic; ``None`` when none has."""
    wanted = tuple(layers)
    for topic in topics:
        grid = maps.get(topic)
        if grid is not None and grid.layers == wanted:
            return topic, grid
    return None


def _check_geometry(field: str, resolution: float, origin: Sequence[float]) -> Origin:
    res = float(resolution)
    if not math.isfinite(res) or res <= 0.0:
        raise _f(f"{field}.resolution", f"must be a finite number > 0, got {resolution!r}")
    if len(origin) != 2:
        raise _f(f"{field}.origin", f"expected (x, y), got {origin!r}")
    ox, oy = float(origin[0]), float(origin[1])
    if not (math.isfinite(ox) and math.isfinite(oy)):
        raise _f(f"{field}.origin", f"must be finite, got {origin!r}")
    return ox, oy


def make_map_info(
    height: int, width: int, resolution: float = 1.0, origin: Sequence[float] = (0.0, 0.0)
) -> MapMetaData:
    """nav_msgs/MapMetaData of an H x W grid whose cell (0, 0) corner is at ``origin``."""
    if int(height) <= 0:
        raise _f("info.height", f"must be > 0, got {height}")
    if int(width) <= 0:
        raise _f("info.width", f"must be > 0, got {width}")
    ox, oy = _check_geometry("info", resolution, origin)
    info = MapMetaData(width=int(width), height=int(height), resolution=float(resolution))
    info.origin.position.x = ox
    info.origin.position.y = oy
    info.origin.orientation.w = 1.0
    return info


def _info_shape(field: str, info: MapMetaData) -> tuple[int, int, float, Origin]:
    """(H, W, resolution, origin) of a MapMetaData, validated."""
    if info.height == 0:
        raise _f(f"{field}.info.height", "must be > 0, got 0")
    if info.width == 0:
        raise _f(f"{field}.info.width", "must be > 0, got 0")
    origin = (info.origin.position.x, info.origin.position.y)
    ox, oy = _check_geometry(f"{field}.info", info.resolution, origin)
    return int(info.height), int(info.width), float(info.resolution), (ox, oy)


def _check_names(field: str, names: Iterable[str], *, allow_empty: bool = False) -> tuple[str, ...]:
    names = tuple(names)
    if not names and not allow_empty:
        raise _f(field, "must not be empty")
    for i, name in enumerate(names):
        if not isinstance(name, str) or not name:
            raise _f(field, f"entry {i} must be a non-empty string, got {name!r}")
    seen: set[str] = set()
    dups = sorted({n for n in names if n in seen or seen.add(n)})  # linear: a request may send many names
    if dups:
        raise _f(field, f"duplicate names {dups}")
    return names


def _check_finite(field: str, values: np.ndarray) -> None:
    if values.size and not np.all(np.isfinite(values)):
        bad = np.flatnonzero(~np.isfinite(values.reshape(-1)))
        raise _f(field, f"{bad.size} non-finite value(s) (NaN or inf), first at flat index {bad[0]}")


def _as_float_array(field: str, values: Any, dtype: type) -> np.ndarray:
    try:
        arr = np.asarray(values)
    except Exception as exc:  # ragged lists and the like
        raise _f(field, f"not an array: {exc}") from None
    if arr.dtype.kind not in "fiub":
        raise _f(field, f"expected numbers, got dtype {arr.dtype}")
    with np.errstate(over="ignore"):  # values too large for float32 become inf, rejected later
        return arr.astype(dtype, copy=False)


def _read(field: str, data: Any, dtype: type) -> np.ndarray:
    """A message array field as a fresh numpy array (fast for array.array)."""
    if isinstance(data, array.array):
        return np.frombuffer(data, dtype=dtype).copy()
    return np.asarray(data, dtype=dtype).copy()


# --------------------------------------------------------------------------- FeatureGrid


def feature_grid_to_msg(
    features: np.ndarray,
    layers: Sequence[str],
    *,
    resolution: float = 1.0,
    origin: Sequence[float] = (0.0, 0.0),
    stamp: Time | None = None,
    frame_id: str = MAP_FRAME,
) -> FeatureGrid:
    """Build an ``ird_msgs/FeatureGrid`` from ``features`` of shape (H, W, d).

    ``layers`` names the d feature layers (unique, non-empty). Values are sent as float32
    (row 0 = bottom row; data index ``(row*W + col)*d + k``).
    """
    field = "FeatureGrid"
    arr = _as_float_array(f"{field}.data", features, np.float32)
    if arr.ndim != 3:
        raise _f(f"{field}.data", f"expected an (H, W, d) array, got shape {arr.shape}")
    h, w, d = arr.shape
    if h == 0:
        raise _f(f"{field}.info.height", "must be > 0, got 0")
    if w == 0:
        raise _f(f"{field}.info.width", "must be > 0, got 0")
    names = _check_names(f"{field}.layers", layers)
    if len(names) != d:
        raise _f(f"{field}.layers", f"expected d={d} names (features have shape {arr.shape}), got {len(names)}")
    _check_finite(f"{field}.data", arr)
    msg = FeatureGrid()
    msg.header = make_header(stamp, frame_id)
    msg.info = make_map_info(h, w, resolution, origin)
    msg.layers = list(names)
    msg.data = array.array("f", np.ascontiguousarray(arr).tobytes())
    return msg


def feature_grid_from_msg(msg: FeatureGrid, *, field: str = "FeatureGrid",
                          max_abs: float | None = None) -> FeatureGridData:
    """Read an ``ird_msgs/FeatureGrid`` into a ``FeatureGridData`` ((H, W, d) float32).

    ``max_abs``: refuse values of larger magnitude (the nodes pass
    ``ird_core.checks.MAX_ABS_FEATURE`` for maps in requests); ``None`` = any finite value, since a
    grid message as such may carry any float32.
    """
    h, w, res, origin = _info_shape(field, msg.info)
    names = _check_names(f"{field}.layers", msg.layers)
    d = len(names)
    data = _read(f"{field}.data", msg.data, np.float32)
    if data.size != h * w * d:
        raise _f(f"{field}.data", f"expected {h * w * d} values (H={h} x W={w} x d={d}), got {data.size}")
    _check_finite(f"{field}.data", data)
    if max_abs is not None:
        check_magnitude(f"{field}.data", data, max_abs)
    return FeatureGridData(
        features=data.reshape(h, w, d),
        layers=names,
        resolution=res,
        origin=origin,
        frame_id=msg.header.frame_id,
    )


# --------------------------------------------------------------------------- TerrainGrid


def terrain_grid_to_msg(
    classes: np.ndarray,
    class_names: Sequence[str],
    *,
    probabilities: np.ndarray | None = None,
    novelty: np.ndarray | None = None,
    resolution: float = 1.0,
    origin: Sequence[float] = (0.0, 0.0),
    stamp: Time | None = None,
    frame_id: str = MAP_FRAME,
) -> TerrainGrid:
    """Build an ``ird_msgs/TerrainGrid``.

    ``classes``: (H, W) integers in ``[0, C)`` or ``UNKNOWN_CLASS`` (255), C =
    ``len(class_names)``; ``probabilities``: optional (H, W, C), finite, in [0, 1];
    ``novelty``: optional (H, W), finite, >= 0.
    """
    field = "TerrainGrid"
    names = _check_names(f"{field}.class_names", class_names)
    n_classes = len(names)
    if n_classes >= UNKNOWN_CLASS:
        raise _f(f"{field}.class_names", f"at most {UNKNOWN_CLASS} classes, got {n_classes}")
    cls = np.asarray(classes)
    if cls.ndim != 2:
        raise _f(f"{field}.classes", f"expected an (H, W) array, got shape {cls.shape}")
    if cls.dtype.kind not in "iub":
        raise _f(f"{field}.classes", f"expected integers, got dtype {cls.dtype}")
    h, w = cls.shape
    if h == 0:
        raise _f(f"{field}.info.height", "must be > 0, got 0")
    if w == 0:
        raise _f(f"{field}.info.width", "must be > 0, got 0")
    bad = (cls != UNKNOWN_CLASS) & ((cls < 0) | (cls >= n_classes))
    if np.any(bad):
        raise _f(
            f"{field}.classes",
            f"values must be in [0, {n_classes}) or {UNKNOWN_CLASS} (unknown), "
            f"got {cls[bad].reshape(-1)[0]} at flat index {np.flatnonzero(bad)[0]}",
        )
    msg = TerrainGrid()
    msg.header = make_header(stamp, frame_id)
    msg.info = make_map_info(h, w, resolution, origin)
    msg.class_names = list(names)
    msg.classes = array.array("B", np.ascontiguousarray(cls, dtype=np.uint8).tobytes())
    if probabilities is not None:
        probs = _as_float_array(f"{field}.probabilities", probabilities, np.float32)
        if probs.shape != (h, w, n_classes):
            raise _f(f"{field}.probabilities", f"expected shape (H={h}, W={w}, C={n_classes}), got {probs.shape}")
        _check_probabilities(f"{field}.probabilities", probs)
        msg.probabilities = array.array("f", np.ascontiguousarray(probs).tobytes())
    if novelty is not None:
        nov = _as_float_array(f"{field}.novelty", novelty, np.float32)
        if nov.shape != (h, w):
            raise _f(f"{field}.novelty", f"expected shape (H={h}, W={w}), got {nov.shape}")
        _check_novelty(f"{field}.novelty", nov)
        msg.novelty = array.array("f", np.ascontiguousarray(nov).tobytes())
    return msg


def _check_probabilities(field: str, probs: np.ndarray) -> None:
    _check_finite(field, probs)
    if probs.size and (probs.min() < 0.0 or probs.max() > 1.0):
        raise _f(field, f"values must be in [0, 1], got range [{probs.min()}, {probs.max()}]")


def _check_novelty(field: str, nov: np.ndarray) -> None:
    _check_finite(field, nov)
    if nov.size and nov.min() < 0.0:
        raise _f(field, f"values must be >= 0, got {nov.min()}")


def terrain_grid_from_msg(msg: TerrainGrid, *, field: str = "TerrainGrid") -> TerrainGridData:
    """Read an ``ird_msgs/TerrainGrid`` into a ``TerrainGridData``.

    Returns classes (H, W) uint8, probabilities (H, W, C) float32 or None if the message
    has none, novelty (H, W) float32 or None.
    """
    h, w, res, origin = _info_shape(field, msg.info)
    names = _check_names(f"{field}.class_names", msg.class_names)
    n_classes = len(names)
    cls = _read(f"{field}.classes", msg.classes, np.uint8)
    if cls.size != h * w:
        raise _f(f"{field}.classes", f"expected {h * w} values (H={h} x W={w}), got {cls.size}")
    bad = (cls != UNKNOWN_CLASS) & (cls >= n_classes)
    if np.any(bad):
        raise _f(
            f"{field}.classes",
            f"values must be in [0, {n_classes}) or {UNKNOWN_CLASS} (unknown), "
            f"got {cls[bad][0]} at flat index {np.flatnonzero(bad)[0]}",
        )
    probs: np.ndarray | None = None
    if len(msg.probabilities):
        probs = _read(f"{field}.probabilities", msg.probabilities, np.float32)
        if probs.size != h * w * n_classes:
            raise _f(
                f"{field}.probabilities",
                f"expected {h * w * n_classes} values (H={h} x W={w} x C={n_classes}) or none, got {probs.size}",
            )
        _check_probabilities(f"{field}.probabilities", probs)
        probs = probs.reshape(h, w, n_classes)
    nov: np.ndarray | None = None
    if len(msg.novelty):
        nov = _read(f"{field}.novelty", msg.novelty, np.float32)
        if nov.size != h * w:
            raise _f(f"{field}.novelty", f"expected {h * w} values (H={h} x W={w}) or none, got {nov.size}")
        _check_novelty(f"{field}.novelty", nov)
        nov = nov.reshape(h, w)
    return TerrainGridData(
        classes=cls.reshape(h, w),
        class_names=names,
        probabilities=probs,
        novelty=nov,
        resolution=res,
        origin=origin,
        frame_id=msg.header.frame_id,
    )


# --------------------------------------------------------------------------- OccupancyGrid


def occupancy_grid_to_msg(
    costs: np.ndarray,
    *,
    resolution: float = 1.0,
    origin: Sequence[float] = (0.0, 0.0),
    stamp: Time | None = None,
    frame_id: str = MAP_FRAME,
) -> OccupancyGrid:
    """A nav_msgs/OccupancyGrid (e.g. /ird/risk_map) from ``costs`` of shape (H, W).

    Integer values in 0..100 or -1 (unknown), Nav2 costmap convention; data index
    ``row*W + col`` with row 0 the bottom row.
    """
    field = "OccupancyGrid"
    arr = np.asarray(costs)
    if arr.ndim != 2:
        raise _f(f"{field}.data", f"expected an (H, W) array, got shape {arr.shape}")
    if arr.dtype.kind not in "iu":
        raise _f(f"{field}.data", f"expected integers, got dtype {arr.dtype}")
    h, w = arr.shape
    if h == 0:
        raise _f(f"{field}.info.height", "must be > 0, got 0")
    if w == 0:
        raise _f(f"{field}.info.width", "must be > 0, got 0")
    bad = (arr < -1) | (arr > 100)
    if np.any(bad):
        raise _f(f"{field}.data", f"values must be in 0..100 or -1 (unknown), got {arr[bad][0]} "
                                  f"at flat index {np.flatnonzero(bad)[0]}")
    msg = OccupancyGrid()
    msg.header = make_header(stamp, frame_id)
    msg.info = make_map_info(h, w, resolution, origin)
    msg.data = array.array("b", np.ascontiguousarray(arr, dtype=np.int8).tobytes())
    return msg


def occupancy_grid_from_msg(msg: OccupancyGrid, *, field: str = "OccupancyGrid") -> np.ndarray:
    """The (H, W) int8 costs of a nav_msgs/OccupancyGrid (validated like ``occupancy_grid_to_msg``)."""
    h, w, _, _ = _info_shape(field, msg.info)
    data = _read(f"{field}.data", msg.data, np.int8)
    if data.size != h * w:
        raise _f(f"{field}.data", f"expected {h * w} values (H={h} x W={w}), got {data.size}")
    bad = (data < -1) | (data > 100)
    if np.any(bad):
        raise _f(f"{field}.data", f"values must be in 0..100 or -1 (unknown), got {data[bad][0]} "
                                  f"at flat index {np.flatnonzero(bad)[0]}")
    return data.reshape(h, w)
