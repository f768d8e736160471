"""numpy <-> ROS message conversions: the only place where arrays become messages.

Grid convention (IRD spec, section 6): a map of H rows and W columns is a numpy array
indexed ``[row, col, ...]`` in C order; row 0 is the bottom row, x grows with the column
and y with the row, and the centre of cell ``(row, col)`` is at
``x = origin_x + (col + 0.5) * resolution``, ``y = origin_y + (row + 0.5) * resolution``
in frame ``map``.

Every ``*_from_msg`` / ``*_to_msg`` function validates its input and raises
``ValueError`` with a message that starts with the offending field, e.g.
``"FeatureGrid.data: expected 4500 values (H=15 x W=15 x d=20), got 4499"``. Functions
that read a message take ``field=`` to name it as the caller sees it (a service node
passes ``field="training_map"`` so the message says ``training_map.data: ...``).

Large arrays use the fast paths: ``array.array(typecode, arr.tobytes())`` to fill a
message field and ``np.frombuffer`` to read one (the read arrays are copies, so they
stay valid and writable after the message is gone).
"""

from __future__ import annotations

import array
import math
from dataclasses import dataclass
from typing import Any, Iterable, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import MapMetaData, OccupancyGrid, Path
from std_msgs.msg import Header

from ird_msgs.msg import FeatureGrid, RewardPosterior, TerrainGrid

__all__ = [
    "MAP_FRAME",
    "POSTERIOR_METHODS",
    "R_HAT_CONVERGED",
    "UNKNOWN_CLASS",
    "FeatureGridData",
    "TerrainGridData",
    "PosteriorData",
    "make_header",
    "make_map_info",
    "feature_grid_to_msg",
    "feature_grid_from_msg",
    "terrain_grid_to_msg",
    "terrain_grid_from_msg",
    "occupancy_grid_to_msg",
    "occupancy_grid_from_msg",
    "posterior_to_msg",
    "posterior_from_msg",
    "cells_to_path",
    "path_to_cells",
    "cell_center",
    "weights_to_flat",
    "weights_from_flat",
]

MAP_FRAME = "map"
"""Frame of every grid, path and pose of the stack."""

POSTERIOR_METHODS = ("maxent_z", "sample_z")
"""Known normaliser approximations (RewardPosterior.method, InferReward.method)."""

R_HAT_CONVERGED = 1.1
"""A posterior is ``converged`` when its largest split R-hat is at most this."""

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


@dataclass(frozen=True)
class PosteriorData:
    """A RewardPosterior as numpy: ``samples`` (K, d) float64, ``proxy_weights`` (p,), where
    p = d unless the proxy lives on its own proxy map (latent_classifier).

    Has the attributes of ``ird_core.inference.Posterior`` (samples, method, beta,
    acceptance_rate, r_hat_max, ess_min, prior_sigma, num_chains, seed), so it can be
    passed back to ``posterior_to_msg``.
    """

    samples: np.ndarray
    feature_names: tuple[str, ...]
    proxy_weights: np.ndarray
    method: str
    beta: float
    prior_sigma: float
    acceptance_rate: float
    r_hat_max: float
    ess_min: float
    num_chains: int
    seed: int
    converged: bool


# --------------------------------------------------------------------------- helpers


def _f(field: str, problem: str) -> ValueError:
    return ValueError(f"{field}: {problem}")


def make_header(stamp: Time | None = None, frame_id: str = MAP_FRAME) -> Header:
    """A std_msgs/Header with the given stamp (default: zero time) and frame."""
    header = Header(frame_id=frame_id)
    if stamp is not None:
        header.stamp = stamp
    return header


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
    dups = sorted({n for n in names if names.count(n) > 1})
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


def _check_uint32(field: str, value: Any) -> int:
    v = int(value)
    if v < 0 or v > 0xFFFFFFFF:
        raise _f(field, f"must fit in uint32, got {value}")
    return v


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


def feature_grid_from_msg(msg: FeatureGrid, *, field: str = "FeatureGrid") -> FeatureGridData:
    """Read an ``ird_msgs/FeatureGrid`` into a ``FeatureGridData`` ((H, W, d) float32)."""
    h, w, res, origin = _info_shape(field, msg.info)
    names = _check_names(f"{field}.layers", msg.layers)
    d = len(names)
    data = _read(f"{field}.data", msg.data, np.float32)
    if data.size != h * w * d:
        raise _f(f"{field}.data", f"expected {h * w * d} values (H={h} x W={w} x d={d}), got {data.size}")
    _check_finite(f"{field}.data", data)
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


# --------------------------------------------------------------------------- weights


def weights_to_flat(weights: np.ndarray, *, field: str = "weights") -> array.array:
    """Flatten (K, d) or (d,) weights row-major into a float64 array for a ``float64[]`` field."""
    arr = _as_float_array(field, weights, np.float64)
    if arr.ndim not in (1, 2):
        raise _f(field, f"expected a (K, d) or (d,) array, got shape {arr.shape}")
    if arr.size == 0:
        raise _f(field, "must not be empty")
    _check_finite(field, arr)
    return array.array("d", np.ascontiguousarray(arr).tobytes())


def weights_from_flat(flat: Any, d: int, *, field: str = "weights") -> np.ndarray:
    """Read a row-major ``float64[]`` of K*d values into a (K, d) float64 array (K >= 1)."""
    if int(d) <= 0:
        raise _f(field, f"the feature dimension d must be > 0, got {d}")
    arr = _read(field, flat, np.float64).reshape(-1)
    if arr.size == 0:
        raise _f(field, "must not be empty")
    if arr.size % d:
        raise _f(field, f"length {arr.size} is not a multiple of d={d}")
    _check_finite(field, arr)
    return arr.reshape(-1, d)


# --------------------------------------------------------------------------- RewardPosterior


def posterior_to_msg(
    posterior: Any,
    *,
    feature_names: Sequence[str],
    proxy_weights: np.ndarray,
    stamp: Time | None = None,
    frame_id: str = MAP_FRAME,
) -> RewardPosterior:
    """Build an ``ird_msgs/RewardPosterior`` from any object with the attributes of
    ``ird_core.inference.Posterior``: ``samples`` (K, d), ``method``, ``beta``,
    ``acceptance_rate``, ``r_hat_max``, ``ess_min``, ``prior_sigma``, ``num_chains``, ``seed``.

    ``feature_names`` has d entries; ``proxy_weights`` has shape (p,), p = d unless the
    proxy was defined on a proxy map with its own layers (InferReward.proxy_map). ``r_hat_max`` and
    ``ess_min`` may be NaN (not computed); ``converged`` is set to ``r_hat_max <= 1.1``.
    """
    field = "RewardPosterior"
    names = _check_names(f"{field}.feature_names", feature_names)
    d = len(names)
    samples = _as_float_array(f"{field}.samples", posterior.samples, np.float64)
    if samples.ndim != 2 or samples.shape[0] == 0 or samples.shape[1] != d:
        raise _f(f"{field}.samples", f"expected shape (K>=1, d={d}), got {samples.shape}")
    _check_finite(f"{field}.samples", samples)
    proxy = _as_float_array(f"{field}.proxy_weights", proxy_weights, np.float64).reshape(-1)
    if proxy.size == 0:
        raise _f(f"{field}.proxy_weights", "must not be empty")
    _check_finite(f"{field}.proxy_weights", proxy)
    method = str(posterior.method)
    if method not in POSTERIOR_METHODS:
        raise _f(f"{field}.method", f"must be one of {list(POSTERIOR_METHODS)}, got {method!r}")
    beta = float(posterior.beta)
    if not math.isfinite(beta) or beta < 0.0:
        raise _f(f"{field}.beta", f"must be finite and >= 0, got {posterior.beta!r}")
    sigma = float(posterior.prior_sigma)
    if not math.isfinite(sigma) or sigma <= 0.0:
        raise _f(f"{field}.prior_sigma", f"must be finite and > 0, got {posterior.prior_sigma!r}")
    acc = float(posterior.acceptance_rate)
    if not (0.0 <= acc <= 1.0):
        raise _f(f"{field}.acceptance_rate", f"must be in [0, 1], got {posterior.acceptance_rate!r}")
    r_hat = float(posterior.r_hat_max)
    if math.isinf(r_hat) or (not math.isnan(r_hat) and r_hat < 0.0):
        raise _f(f"{field}.r_hat_max", f"must be >= 0 or NaN (not computed), got {posterior.r_hat_max!r}")
    ess = float(posterior.ess_min)
    if math.isinf(ess) or (not math.isnan(ess) and ess < 0.0):
        raise _f(f"{field}.ess_min", f"must be >= 0 or NaN (not computed), got {posterior.ess_min!r}")
    num_chains = _check_uint32(f"{field}.num_chains", posterior.num_chains)
    if num_chains == 0:
        raise _f(f"{field}.num_chains", "must be > 0")
    seed = _check_uint32(f"{field}.seed", posterior.seed)

    msg = RewardPosterior()
    msg.header = make_header(stamp, frame_id)
    msg.feature_names = list(names)
    msg.method = method
    msg.beta = beta
    msg.prior_sigma = sigma
    msg.proxy_weights = array.array("d", proxy.tobytes())
    msg.samples = array.array("d", np.ascontiguousarray(samples).tobytes())
    msg.num_samples = int(samples.shape[0])
    msg.num_chains = num_chains
    msg.seed = seed
    msg.acceptance_rate = acc
    msg.r_hat_max = r_hat
    msg.ess_min = ess
    msg.converged = bool(r_hat <= R_HAT_CONVERGED)  # False for NaN
    return msg


def posterior_from_msg(msg: RewardPosterior, *, field: str = "RewardPosterior") -> PosteriorData:
    """Read an ``ird_msgs/RewardPosterior`` into a ``PosteriorData`` (samples (K, d))."""
    names = _check_names(f"{field}.feature_names", msg.feature_names)
    d = len(names)
    samples = weights_from_flat(msg.samples, d, field=f"{field}.samples")
    if samples.shape[0] != msg.num_samples:
        raise _f(f"{field}.num_samples", f"is {msg.num_samples} but samples holds {samples.shape[0]} rows of d={d}")
    proxy = _read(f"{field}.proxy_weights", msg.proxy_weights, np.float64)
    if proxy.size == 0:
        raise _f(f"{field}.proxy_weights", "must not be empty")
    _check_finite(f"{field}.proxy_weights", proxy)
    if msg.method not in POSTERIOR_METHODS:
        raise _f(f"{field}.method", f"must be one of {list(POSTERIOR_METHODS)}, got {msg.method!r}")
    if not math.isfinite(msg.beta) or msg.beta < 0.0:
        raise _f(f"{field}.beta", f"must be finite and >= 0, got {msg.beta!r}")
    return PosteriorData(
        samples=samples,
        feature_names=names,
        proxy_weights=proxy,
        method=msg.method,
        beta=float(msg.beta),
        prior_sigma=float(msg.prior_sigma),
        acceptance_rate=float(msg.acceptance_rate),
        r_hat_max=float(msg.r_hat_max),
        ess_min=float(msg.ess_min),
        num_chains=int(msg.num_chains),
        seed=int(msg.seed),
        converged=bool(msg.converged),
    )


# --------------------------------------------------------------------------- Path


def cell_center(row: int, col: int, resolution: float = 1.0, origin: Sequence[float] = (0.0, 0.0)) -> tuple[float, float]:
    """(x, y) of the centre of cell (row, col)."""
    return (
        float(origin[0]) + (col + 0.5) * float(resolution),
        float(origin[1]) + (row + 0.5) * float(resolution),
    )


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
    cells: list[tuple[int, int]] = []
    for i, pose in enumerate(path.poses):
        x, y = pose.pose.position.x, pose.pose.position.y
        if not (math.isfinite(x) and math.isfinite(y)):
            raise _f(f"{field}.poses[{i}]", f"non-finite position ({x}, {y})")
        fc = (x - ox) / resolution - 0.5
        fr = (y - oy) / resolution - 0.5
        col, row = round(fc), round(fr)
        if abs(fc - col) > tolerance or abs(fr - row) > tolerance:
            raise _f(f"{field}.poses[{i}]", f"position ({x}, {y}) is not at a cell centre")
        if row < 0 or col < 0 or (height is not None and row >= height) or (width is not None and col >= width):
            raise _f(f"{field}.poses[{i}]", f"cell (row={row}, col={col}) is off the map")
        cells.append((int(row), int(col)))
    return cells
