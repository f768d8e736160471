"""numpy <-> ROS message conversions: the only place where arrays become messages.

Import this module (``from ird_ros import conversions as conv``): it holds the posterior,
weights and Path conversions and re-exports the grid ones (:mod:`ird_ros.conversions.grids`)
and the cell geometry (:mod:`ird_ros.conversions.geometry`), so ``conv.X`` is the one name of each.

Grid convention (docs/spec.md section 6): a map of H rows and W columns is a numpy array
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
from typing import Any, Sequence

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path

from ird_msgs.msg import RewardPosterior
from ird_ros.conversions.geometry import cell_center, grid_coordinates
from ird_ros.conversions.grids import (
    MAP_FRAME,
    UNKNOWN_CLASS,
    FeatureGridData,
    TerrainGridData,
    _as_float_array,
    _check_finite,
    _check_geometry,
    _check_names,
    _f,
    _read,
    feature_grid_from_msg,
    feature_grid_to_msg,
    make_header,
    make_map_info,
    occupancy_grid_from_msg,
    occupancy_grid_to_msg,
    terrain_grid_from_msg,
    terrain_grid_to_msg,
)
from ird_ros.conversions.queries import options_to_paths, query_record_from_msg, query_record_to_msg

__all__ = [
    "MAP_FRAME",
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
    "options_to_paths",
    "query_record_to_msg",
    "query_record_from_msg",
]

R_HAT_CONVERGED = 1.1
"""A posterior is ``converged`` when its largest split R-hat is at most this."""


# --------------------------------------------------------------------------- data classes


@dataclass(frozen=True)
class PosteriorData:
    """A RewardPosterior as numpy: ``samples`` (K, d) float64, ``proxy_weights`` (p,), where
    p = d unless the proxy lives on its own proxy map (latent_classifier).

    Has the attributes of ``ird_core.posterior.Posterior`` (samples, method, beta,
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


def _check_uint32(field: str, value: Any) -> int:
    v = int(value)
    if v < 0 or v > 0xFFFFFFFF:
        raise _f(field, f"must fit in uint32, got {value}")
    return v


def _check_method(field: str, method: str) -> None:
    """``method`` must be one of ``ird_core.posterior.METHODS`` (the one list of them)."""
    # Imported here: ird_core.posterior loads scipy, which nodes that never handle a posterior
    # (rob, the recorder) should not pay for at start-up.
    from ird_core.posterior import METHODS

    if method not in METHODS:
        raise _f(field, f"must be one of {list(METHODS)}, got {method!r}")


def posterior_to_msg(
    posterior: Any,
    *,
    feature_names: Sequence[str],
    proxy_weights: np.ndarray,
    stamp: Time | None = None,
    frame_id: str = MAP_FRAME,
) -> RewardPosterior:
    """Build an ``ird_msgs/RewardPosterior`` from any object with the attributes of
    ``ird_core.posterior.Posterior``: ``samples`` (K, d), ``method``, ``beta``,
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
    _check_method(f"{field}.method", method)
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
    _check_method(f"{field}.method", msg.method)
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
