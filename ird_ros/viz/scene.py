"""What the live view shows, as plain data: grids, plan lines, Rob's trail, posterior and query JSON.

ROS-free and Foxglove-free (numpy and the project's own ROS-free modules only): the viz node
(:mod:`ird_ros.nodes.viz`) decodes messages with ``ird_ros.conversions`` and hands arrays to the
functions here; :mod:`ird_ros.viz.foxglove_view` turns the results into Foxglove messages.

Invariants:

- Grids follow the stack's grid convention (docs/spec.md section 6): ``data`` is row-major with
  row 0 (the bottom row, at ``origin``) first, one cell per map cell, so a Foxglove Grid posed at
  ``origin`` with cell size ``resolution`` covers exactly the map. Every grid carries ``red``,
  ``green``, ``blue``, ``alpha`` (uint8) fields for the Grid panel's "RGBA fields" colour mode, plus
  its value field (``class`` uint8 index into the class names, or ``risk`` float32, NaN unknown).
- Every colour is :mod:`ird_core.style`'s, the one set of every picture: terrains by name (a class
  name the style does not know and an unknown cell are its grey ``UNKNOWN_COLOR``), plans as in
  the demo's pictures (literal magenta, IRD blue), Rob's trail, and the risk colour map
  (:func:`ird_core.style.risk_rgb`: pale yellow at 0 to dark red at 100).
- Lines are in frame ``map`` at height :data:`LINE_Z`, one point per pose (a plan of T+1 cells
  is a line of T+1 points).
- JSON dicts hold only JSON types (no NaN: a missing number is ``None``).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ird_core import style
from ird_core.vocabulary import PlanMode, QueryEvent
from ird_ros.bags.rounds import QueryRecordData, open_queries, record_dict

__all__ = [
    "RGBA",
    "GridLayer",
    "Line",
    "RobTrail",
    "LINE_Z",
    "LITERAL_COLOR",
    "IRD_COLOR",
    "ROB_COLOR",
    "UNKNOWN_COLOR",
    "hex_rgba",
    "terrain_layer",
    "risk_layer",
    "plan_kind",
    "plan_line",
    "posterior_by_terrain",
    "no_posterior",
    "query_state",
    "no_query",
    "rob_status_state",
]

#: A colour as (r, g, b, a) floats in [0, 1].
RGBA = tuple[float, float, float, float]

LINE_Z = 0.05
"""Height of lines above the grid (metres), so they are drawn over it."""
LITERAL_COLOR = style.LITERAL_COLOR
IRD_COLOR = style.IRD_COLOR
ROB_COLOR = style.ROB_COLOR
UNKNOWN_COLOR = style.UNKNOWN_COLOR


def hex_rgba(color: str, alpha: float = 1.0) -> RGBA:
    """``"#rrggbb"`` -> (r, g, b, alpha) in [0, 1]."""
    text = color.lstrip("#")
    if len(text) != 6:
        raise ValueError(f"colour: expected #rrggbb, got {color!r}")
    r, g, b = (int(text[i:i + 2], 16) / 255.0 for i in (0, 2, 4))
    return (r, g, b, float(alpha))


@dataclass(frozen=True)
class GridLayer:
    """A map-sized grid of packed cells (a Foxglove Grid without Foxglove).

    Attributes:
        frame_id: frame of the grid (``map``).
        width, height: W columns, H rows (one grid cell per map cell).
        resolution: metres per cell.
        origin: (x, y) of the corner of cell (0, 0).
        fields: ``(name, numpy dtype name)`` of each packed field, in order; offsets follow.
        data: H*W cells of ``cell_stride`` bytes, row-major, row 0 first.
        stamp_ns: stamp of the message it was made from.
        labels: what the values mean (e.g. class names), for the legend.
    """

    frame_id: str
    width: int
    height: int
    resolution: float
    origin: tuple[float, float]
    fields: tuple[tuple[str, str], ...]
    data: bytes
    stamp_ns: int
    labels: tuple[str, ...] = ()

    @property
    def cell_stride(self) -> int:
        return sum(np.dtype(t).itemsize for _, t in self.fields)

    @property
    def row_stride(self) -> int:
        return self.cell_stride * self.width

    def offsets(self) -> tuple[int, ...]:
        """Byte offset of each field in a cell."""
        out, at = [], 0
        for _, t in self.fields:
            out.append(at)
            at += np.dtype(t).itemsize
        return tuple(out)

    def field_array(self, name: str) -> np.ndarray:
        """The (H, W) values of one field (the inverse of the packing; tests and pictures)."""
        dtype = np.dtype([(n, t) for n, t in self.fields])
        return np.frombuffer(self.data, dtype=dtype).reshape(self.height, self.width)[name].copy()


def _pack(fields: Sequence[tuple[str, str]], arrays: dict[str, np.ndarray]) -> bytes:
    dtype = np.dtype(list(fields))  # packed: numpy adds no padding to a list of (name, type)
    shape = next(iter(arrays.values())).shape
    cells = np.zeros(shape, dtype=dtype)
    for name, _ in fields:
        cells[name] = arrays[name]
    return cells.tobytes(order="C")


_RGBA_FIELDS: tuple[tuple[str, str], ...] = (("red", "uint8"), ("green", "uint8"), ("blue", "uint8"),
                                             ("alpha", "uint8"))


def _class_palette(class_names: Sequence[str]) -> np.ndarray:
    """(C + 1, 4) uint8 colours: one per class name, the last for unknown cells."""
    colors = [style.terrain_color(n) for n in class_names]
    return np.array([[round(v * 255) for v in hex_rgba(c)] for c in [*colors, UNKNOWN_COLOR]], dtype=np.uint8)


def terrain_layer(classes: np.ndarray, class_names: Sequence[str], *, resolution: float,
                  origin: Sequence[float], stamp_ns: int, frame_id: str = "map") -> GridLayer:
    """A terrain map (``/world/terrain`` or ``/terrain/classes``) as a grid.

    Args:
        classes: (H, W) class indices into ``class_names``; an index out of range (255) is unknown.
    Returns:
        fields ``class`` (uint8, as given) and RGBA (the terrain's colour; unknown grey).
    """
    classes = np.asarray(classes)
    if classes.ndim != 2:
        raise ValueError(f"classes: expected an (H, W) array, got shape {classes.shape}")
    palette = _class_palette(class_names)
    index = np.where((classes >= 0) & (classes < len(class_names)), classes, len(class_names)).astype(np.intp)
    rgba = palette[index]
    fields = (("class", "uint8"), *_RGBA_FIELDS)
    arrays = {"class": classes.astype(np.uint8), "red": rgba[..., 0], "green": rgba[..., 1], "blue": rgba[..., 2],
              "alpha": rgba[..., 3]}
    h, w = classes.shape
    return GridLayer(frame_id, w, h, float(resolution), (float(origin[0]), float(origin[1])), fields,
                     _pack(fields, arrays), int(stamp_ns), tuple(class_names))


def risk_layer(costs: np.ndarray, *, resolution: float, origin: Sequence[float], stamp_ns: int,
               frame_id: str = "map") -> GridLayer:
    """The planner's risk map (OccupancyGrid values 0..100, -1 unknown) as a grid.

    Returns:
        field ``risk`` (float32 0..100, NaN unknown) and RGBA: the style's risk colours
        (:func:`ird_core.style.risk_rgb` of risk / 100), opacity growing with the risk (0.3 to 0.9),
        unknown cells transparent.
    """
    costs = np.asarray(costs)
    if costs.ndim != 2:
        raise ValueError(f"costs: expected an (H, W) array, got shape {costs.shape}")
    known = costs >= 0
    frac = np.where(known, np.clip(costs, 0, 100), 0).astype(np.float64) / 100.0
    rgb = style.risk_rgb(frac)
    fields = (("risk", "float32"), *_RGBA_FIELDS)
    arrays = {"risk": np.where(known, costs, np.nan).astype(np.float32), "red": rgb[..., 0],
              "green": rgb[..., 1], "blue": rgb[..., 2],
              "alpha": np.where(known, np.round(255 * (0.3 + 0.6 * frac)), 0).astype(np.uint8)}
    h, w = costs.shape
    return GridLayer(frame_id, w, h, float(resolution), (float(origin[0]), float(origin[1])), fields,
                     _pack(fields, arrays), int(stamp_ns))


@dataclass(frozen=True)
class Line:
    """A polyline entity in frame ``map``.

    Attributes:
        id: entity id (unique per channel; a new line with the same id replaces the old one).
        points: (N, 3) float64 points.
        color: RGBA.
        thickness: metres.
        label: what it is (shown as the entity's metadata).
        stamp_ns: stamp of the message it was made from.
    """

    id: str
    points: np.ndarray
    color: RGBA
    thickness: float
    label: str
    stamp_ns: int


def plan_kind(label: str, mode: str) -> str:
    """``"literal"`` for the literal planner's plan (by mode, or a label starting with it), else ``"ird"``."""
    literal = PlanMode.LITERAL.value
    return literal if mode == literal or label.startswith(literal) else "ird"


def plan_line(label: str, mode: str, xy: np.ndarray, *, resolution: float, stamp_ns: int) -> Line:
    """One plan (the poses of its ``/plan`` path, labelled by ``/ird/plan_info``) as a line.

    The entity id is ``plan/<label>`` (so the literal and IRD plans are two entities); the colour
    is the kind's (:func:`plan_kind`); one point per pose.
    """
    xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
    kind = plan_kind(label, mode)
    points = np.column_stack([xy, np.full(len(xy), LINE_Z)])
    return Line(f"plan/{label or kind}", points, hex_rgba(LITERAL_COLOR if kind == "literal" else IRD_COLOR),
                0.12 * float(resolution), f"{kind} plan" + (f" '{label}'" if label != kind else "")
                + (f" ({mode})" if mode != kind else ""), int(stamp_ns))


class RobTrail:
    """Rob's last ``length`` poses from ``/odom`` (x, y, yaw), oldest first; the last is Rob's pose.

    Invariants: at most ``length`` poses; consecutive duplicates are kept (Rob may stay put); a
    pose farther than ``max_step`` from the previous one starts a new trail (Rob moves one cell per
    tick, so a jump means he started a new plan at its first cell).
    """

    def __init__(self, length: int) -> None:
        if length < 1:
            raise ValueError(f"trail_length: expected >= 1, got {length}")
        self.length = int(length)
        self._poses: deque[tuple[float, float, float]] = deque(maxlen=self.length)
        self.stamp_ns = 0

    def add(self, x: float, y: float, qz: float, qw: float, stamp_ns: int, *, max_step: float = math.inf) -> None:
        """Append a pose (planar orientation from the quaternion's z and w); a jump of more than
        ``max_step`` from the last pose clears the trail first."""
        if self._poses and math.hypot(x - self._poses[-1][0], y - self._poses[-1][1]) > max_step:
            self._poses.clear()
        self._poses.append((float(x), float(y), 2.0 * math.atan2(float(qz), float(qw))))
        self.stamp_ns = int(stamp_ns)

    def poses(self) -> list[tuple[float, float, float]]:
        return list(self._poses)

    def line(self, resolution: float) -> Line:
        """The trail as a line (points at :data:`LINE_Z`)."""
        pts = np.array([[x, y, LINE_Z] for x, y, _ in self._poses], dtype=np.float64).reshape(-1, 3)
        return Line("rob/trail", pts, hex_rgba(ROB_COLOR, 0.8), 0.06 * float(resolution), "Rob's trail",
                    self.stamp_ns)


def _number(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def posterior_by_terrain(samples: np.ndarray, feature_names: Sequence[str], *, classes: np.ndarray | None,
                         class_names: Sequence[str], features: np.ndarray | None, source: str | None,
                         stamp_ns: int, method: str = "", converged: bool = False) -> dict[str, Any]:
    """Mean and sd over the posterior samples of the reward per terrain, and per feature.

    Reward of terrain t for sample ``w``: ``w . mu_t``, with ``mu_t`` the mean feature vector of
    the map's cells of terrain t (``classes`` == t) in ``features`` (the map whose layers are the
    posterior's features). Indicator features give ``mu_t`` = that terrain's indicator, so the
    reward is the weight of its indicator; raw observations give ``w . (mean observation)`` (as
    ``ird_core.experiments.posterior_terrain``). Terrains absent from the map are left out.

    Args:
        samples: (K, d) posterior samples; ``feature_names`` their d names.
        classes: (H, W) ground-truth class indices, or None when not known yet.
        features: (H, W, d) map with the posterior's features, or None (then only per feature).
        source: the topic ``features`` came from (reported).
    Returns:
        ``{"stamp", "method", "converged", "num_samples", "feature_source", "terrains": {name:
        {"mean", "sd", "cells"}}, "features": {name: {"mean", "sd"}}}``.
    """
    samples = np.asarray(samples, dtype=np.float64)
    if samples.ndim != 2 or samples.shape[1] != len(feature_names):
        raise ValueError(f"samples: expected (K, {len(feature_names)}), got shape {samples.shape}")
    out: dict[str, Any] = {
        "stamp": stamp_ns / 1e9, "method": str(method), "converged": bool(converged),
        "num_samples": int(samples.shape[0]), "feature_source": source, "terrains": {},
        "features": {n: {"mean": _number(samples[:, k].mean()), "sd": _number(samples[:, k].std())}
                     for k, n in enumerate(feature_names)},
    }
    if classes is None or features is None or samples.shape[0] == 0:
        return out
    features = np.asarray(features, dtype=np.float64)
    if features.shape[:2] != np.shape(classes) or features.shape[2] != samples.shape[1]:
        raise ValueError(f"features: shape {features.shape} does not match classes {np.shape(classes)} "
                         f"and {samples.shape[1]} features")
    for t, name in enumerate(class_names):
        mask = np.asarray(classes) == t
        if not mask.any():
            continue
        rewards = samples @ features[mask].mean(axis=0)
        out["terrains"][name] = {"mean": _number(rewards.mean()), "sd": _number(rewards.std()),
                                 "cells": int(mask.sum())}
    return out


def query_state(events: Sequence[QueryRecordData]) -> dict[str, Any] | None:
    """The designer's open question: the newest proposal still unanswered, else the last event.

    Returns:
        ``ird_ros.bags.rounds.record_dict`` of that event (query id, event, options as cell lists,
        ...) plus ``"open"`` (True while the question waits for an answer), ``"open_ids"`` (every
        open query id) and ``"events"`` (events seen); None before the first event.
    """
    if not events:
        return None
    waiting = open_queries(events)
    shown = waiting[-1] if waiting else events[-1]
    out = record_dict(shown)
    out["open"] = bool(waiting) and shown.event is QueryEvent.PROPOSED
    out["open_ids"] = [ev.query_id for ev in waiting]
    out["events"] = len(events)
    return out


def no_posterior(stamp_ns: int) -> dict[str, Any]:
    """The posterior channel's state for a new world that has no posterior yet (the keys of
    :func:`posterior_by_terrain`, empty): the previous world's posterior is not this world's."""
    return {"stamp": stamp_ns / 1e9, "method": "", "converged": False, "num_samples": 0, "feature_source": None,
            "terrains": {}, "features": {}, "note": "new world: no posterior yet"}


def no_query(stamp_ns: int) -> dict[str, Any]:
    """The query channel's state for a new world with no question yet."""
    return {"stamp": stamp_ns / 1e9, "query_id": None, "event": None, "open": False, "open_ids": [], "events": 0,
            "note": "new world: no question yet"}


def rob_status_state(*, stamp_ns: int, plan_label: str, row: int, col: int, terrain: str, step: int, horizon: int,
                     done: bool, stopped: bool, touched_lava: bool, reached_target: bool, true_return: float,
                     moved: bool) -> dict[str, Any]:
    """Rob's ``/rob/status`` as JSON, with ``state`` saying how the drive stands: ``driving``,
    ``done`` or ``stopped`` (cancelled before the plan's end), and ``outcome``: ``touched lava``,
    ``reached the target``, ``stayed put`` (no move yet, or none in the whole drive) or
    ``moved`` (``moved``: whether any status of this drive had Rob off his first cell)."""
    state = "stopped" if stopped else "done" if done else "driving"
    outcome = ("touched lava" if touched_lava else "reached the target" if reached_target
               else "moved" if moved else "stayed put")
    return {"stamp": stamp_ns / 1e9, "plan_label": str(plan_label), "cell": [int(row), int(col)],
            "terrain": str(terrain), "step": int(step), "horizon": int(horizon), "state": state,
            "outcome": outcome, "touched_lava": bool(touched_lava), "reached_target": bool(reached_target),
            "true_return": _number(float(true_return))}
