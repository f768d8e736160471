"""Rob's missions from decoded bag messages: pure segmentation and statistics, no ROS, no rosbags.

The input is what ``ird_ros.bags.storage.read_messages`` returns, ``{topic: [logged, ...]}`` in
log-time order, where each ``logged`` has a ``timestamp`` (log time, ns) and a decoded ``msg``;
messages are read by attribute only (``msg.plan_label``, ``msg.header.stamp.sec``, ...), so
plain objects with those fields work as well (the unit tests build them by hand). Topic names
come from :mod:`ird_ros.graph.names`.

Mission segmentation: a mission is a maximal run of consecutive ``/rob/status`` messages
with the same ``plan_label`` whose ``step`` never decreases; a new mission starts when the
label changes, the step goes back, or a status follows a ``done`` one with step 0. Each
mission is matched with the latest ``/plan`` logged at or before its first status that no
earlier mission took, and that plan with its ``/ird/plan_info`` (same header stamp; else the
latest one logged before the plan), which gives the mode, baseline, objective, the plan's
cells, and the label when the status has none. A mission's window (for ``/odom``) runs from
its plan (or first status) to the next mission's start. A bag without ``/rob/status`` has
one mission per ``/plan`` (plans only, no outcome).

Also here: the small decoders the analysis needs (``terrain_from_msg``, ``path_xy``,
``odom_xy``), ``label_statistics`` (per plan label: runs, lava and target
fractions, mean true return) and ``drive_outcome`` (what one drive did, in words: a goal that
"succeeded" may have left Rob where he started). A mission whose final status says ``stopped``
(``/rob/stop``: the navigator's cancel) is ``cancelled``, not ``done``.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any, Mapping, Protocol, Sequence

import numpy as np

from ird_ros.graph import names
from ird_ros.geometry import point_cells
from ird_ros.stamps import stamp_ns

__all__ = [
    "MISSION_TOPICS",
    "Logged",
    "Mission",
    "Terrain",
    "missions_from_messages",
    "drive_outcome",
    "label_statistics",
    "latest_before",
    "terrain_from_msg",
    "path_xy",
    "path_cells",
    "odom_xy",
    "polyline_length",
]

MISSION_TOPICS: tuple[str, ...] = (names.TOPIC_PLAN, names.TOPIC_PLAN_INFO, names.TOPIC_ROB_STATUS, names.TOPIC_ODOM)
"""Topics :func:`missions_from_messages` reads."""


class Logged(Protocol):
    """A decoded message with its log time (``ird_ros.bags.storage.BagMessage`` is one)."""

    @property
    def timestamp(self) -> int: ...

    @property
    def msg(self) -> Any: ...


# --------------------------------------------------------------------------- decoders


@dataclass(frozen=True)
class Terrain:
    """A TerrainGrid as numpy: ``classes`` (H, W) uint8 (255 = unknown)."""

    classes: np.ndarray
    class_names: tuple[str, ...]
    resolution: float
    origin: tuple[float, float]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(x0, x1, y0, y1) of the grid in the map frame (for matplotlib's ``imshow``)."""
        h, w = self.classes.shape
        x0, y0 = self.origin
        return (x0, x0 + w * self.resolution, y0, y0 + h * self.resolution)

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(row, col) of the cell containing map point (x, y)."""
        row, col = point_cells([(x, y)], self.resolution, self.origin)[0]
        return int(row), int(col)


def terrain_from_msg(msg: Any) -> Terrain:
    """Decode an ``ird_msgs/TerrainGrid`` read from a bag."""
    h, w = int(msg.info.height), int(msg.info.width)
    classes = np.asarray(msg.classes, dtype=np.uint8)
    if classes.size != h * w:
        raise ValueError(f"TerrainGrid.classes: expected {h * w} values (H={h} x W={w}), got {classes.size}")
    return Terrain(
        classes=classes.reshape(h, w),
        class_names=tuple(msg.class_names),
        resolution=float(msg.info.resolution),
        origin=(float(msg.info.origin.position.x), float(msg.info.origin.position.y)),
    )


def path_xy(msg: Any) -> np.ndarray:
    """(N, 2) x, y of a ``nav_msgs/Path``'s poses."""
    return np.array([[p.pose.position.x, p.pose.position.y] for p in msg.poses], dtype=float).reshape(-1, 2)


def path_cells(xy: np.ndarray, resolution: float = 1.0, origin: tuple[float, float] = (0.0, 0.0)) -> list[tuple[int, int]]:
    """Cells (row, col) of map points (cell centres or anywhere inside the cell)."""
    return [(int(r), int(c)) for r, c in point_cells(xy, resolution, origin)]


def odom_xy(msg: Any) -> tuple[float, float]:
    """x, y of a ``nav_msgs/Odometry``."""
    p = msg.pose.pose.position
    return float(p.x), float(p.y)


def polyline_length(xy: np.ndarray) -> float:
    """Euclidean length of a polyline (N, 2)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if len(xy) < 2:
        return 0.0
    return float(np.linalg.norm(np.diff(xy, axis=0), axis=1).sum())


def _has_stamp(msg: Any, stamp: int | None) -> bool:
    header = getattr(msg, "header", None)
    return stamp is not None and header is not None and stamp_ns(header.stamp) == stamp


def _label_of(msg: Any) -> str:
    """Label of a plan-info message of unknown type: a ``label`` field, or JSON ``data``."""
    label = getattr(msg, "label", None)
    if isinstance(label, str):
        return label
    data = getattr(msg, "data", None)
    if isinstance(data, str):
        try:
            parsed = json.loads(data)
        except ValueError:
            return data
        if isinstance(parsed, dict) and isinstance(parsed.get("label"), str):
            return parsed["label"]
    return ""


# --------------------------------------------------------------------------- missions


# --------------------------------------------------------------------------- missions


@dataclass
class Mission:
    """One executed plan: what was planned, what Rob did, and how it ended.

    ``plan_xy`` is the planned path (from ``/plan``), ``odom`` Rob's recorded positions
    (t_ns, x, y) in the mission's window, ``status_returns`` (t_ns, true_return) per status.
    The outcome fields come from the mission's final ``/rob/status``.
    """

    index: int
    label: str
    start_ns: int
    end_ns: int
    plan_ns: int | None = None
    plan_xy: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    odom: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    status_returns: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    executed_cells: list[tuple[int, int]] = field(default_factory=list)
    steps: int = 0
    horizon: int = 0
    done: bool = False
    stopped: bool = False
    touched_lava: bool = False
    reached_target: bool = False
    true_return: float = math.nan
    final_terrain: str = ""
    mode: str = ""
    baseline: str = ""
    objective: float = math.nan
    plan_cells: list[tuple[int, int]] = field(default_factory=list)

    @property
    def plan_moves(self) -> int:
        """Moves T of the plan (its poses, else its plan-info cells, minus one); 0 without a plan."""
        return max(len(self.plan_xy) - 1, len(self.plan_cells) - 1, 0)

    @property
    def plan_length_m(self) -> float:
        """Metric length of the planned path."""
        return polyline_length(self.plan_xy)

    @property
    def executed_length_m(self) -> float:
        """Metric length of Rob's recorded odometry in the mission (NaN without odometry)."""
        if len(self.odom) == 0:
            return math.nan
        return polyline_length(self.odom[:, 1:])

    @property
    def executed_moves(self) -> int:
        """Cell changes along Rob's executed cells (stays not counted)."""
        cells = self.executed_cells
        return sum(1 for a, b in zip(cells, cells[1:]) if a != b)

    @property
    def end(self) -> str:
        """How the drive ended: ``cancelled`` (stopped before the plan's end), ``done`` or ``running``
        (no final status in the bag); ``-`` without any status."""
        if not self.executed_cells:
            return "-"
        return "cancelled" if self.stopped else "done" if self.done else "running"

    @property
    def outcome(self) -> str:
        """:func:`drive_outcome` of the mission (``-`` without any status)."""
        if not self.executed_cells:
            return "-"
        return drive_outcome(touched_lava=self.touched_lava, reached_target=self.reached_target,
                             moves=self.executed_moves)


def drive_outcome(*, touched_lava: bool | None, reached_target: bool | None, moves: int) -> str:
    """What one drive did, in words: ``touched lava`` (``touched lava, reached the target`` when
    both), ``reached the target``, ``stayed put`` (Rob never left his start cell: ``moves`` is 0),
    else ``moved N cell(s), reached no target``. ``None`` flags (not judged) count as False."""
    if touched_lava:
        return "touched lava, reached the target" if reached_target else "touched lava"
    if reached_target:
        return "reached the target"
    if moves <= 0:
        return "stayed put"
    return f"moved {moves} cell{'s' if moves != 1 else ''}, reached no target"


def _segment_statuses(statuses: Sequence[Logged]) -> list[list[Logged]]:
    """Consecutive ``/rob/status`` messages grouped into missions (see the module docstring)."""
    groups: list[list[Logged]] = []
    for item in statuses:
        m = item.msg
        if groups:
            prev = groups[-1][-1].msg
            same = (
                m.plan_label == prev.plan_label
                and int(m.step) >= int(prev.step)
                and not (prev.done and int(m.step) == 0)
            )
            if same:
                groups[-1].append(item)
                continue
        groups.append([item])
    return groups


def missions_from_messages(messages: Mapping[str, Sequence[Logged]]) -> list[Mission]:
    """The missions in ``{topic: [logged, ...]}`` (log-time order; see the module docstring).

    Reads :data:`MISSION_TOPICS`; a missing topic counts as empty.
    """
    plans = messages.get(names.TOPIC_PLAN, [])
    statuses = messages.get(names.TOPIC_ROB_STATUS, [])
    if statuses:
        missions = _status_missions(statuses, plans)
    else:
        missions = [Mission(index=i, label="", start_ns=p.timestamp, end_ns=p.timestamp, plan_ns=p.timestamp,
                            plan_xy=path_xy(p.msg)) for i, p in enumerate(plans)]
    _attach_plan_infos(missions, plans, messages.get(names.TOPIC_PLAN_INFO, []))
    _attach_odometry(missions, messages.get(names.TOPIC_ODOM, []))
    return missions


def _status_missions(statuses: Sequence[Logged], plans: Sequence[Logged]) -> list[Mission]:
    """One mission per segment of ``/rob/status``, each with the plan it executed (if logged)."""
    missions: list[Mission] = []
    used_plans: set[int] = set()
    for group in _segment_statuses(statuses):
        first_t = group[0].timestamp
        # the latest /plan at or before the first status that no earlier mission took
        plan_idx = None
        for i, p in enumerate(plans):
            if p.timestamp <= first_t and i not in used_plans:
                plan_idx = i
        if plan_idx is not None:
            used_plans.update(range(plan_idx + 1))
        last = group[-1].msg
        mission = Mission(
            index=len(missions),
            label=str(last.plan_label),
            start_ns=min(first_t, plans[plan_idx].timestamp) if plan_idx is not None else first_t,
            end_ns=group[-1].timestamp,
            steps=int(last.step),
            horizon=int(last.horizon),
            done=bool(last.done),
            stopped=bool(getattr(last, "stopped", False)),  # older bags have no `stopped`
            touched_lava=bool(last.touched_lava),
            reached_target=bool(last.reached_target),
            true_return=float(last.true_return),
            final_terrain=str(last.terrain),
            status_returns=np.array([[s.timestamp, s.msg.true_return] for s in group], dtype=float),
            executed_cells=[],
        )
        # Rob's cell per executed step (the last status of each step wins)
        steps_seen: dict[int, tuple[int, int]] = {}
        for s in group:
            steps_seen[int(s.msg.step)] = (int(s.msg.row), int(s.msg.col))
        mission.executed_cells = [steps_seen[k] for k in sorted(steps_seen)]
        if plan_idx is not None:
            mission.plan_ns = plans[plan_idx].timestamp
            mission.plan_xy = path_xy(plans[plan_idx].msg)
        missions.append(mission)
    return missions


def _attach_plan_infos(missions: list[Mission], plans: Sequence[Logged], infos: Sequence[Logged]) -> None:
    """Each mission's plan's ``/ird/plan_info``: the one with the /plan message's header stamp,
    else the latest one logged at or before the plan (or the mission start)."""
    plan_stamps = {p.timestamp: stamp_ns(p.msg.header.stamp) for p in plans}
    for mission in missions:
        info = None
        if infos:
            if mission.plan_ns is not None:
                stamp = plan_stamps.get(mission.plan_ns)
                info = next((i for i in infos if _has_stamp(i.msg, stamp)), None)
            if info is None:
                ref = mission.plan_ns if mission.plan_ns is not None else mission.start_ns
                idx = latest_before(infos, ref)
                info = infos[idx] if idx is not None else None
        if info is not None:
            m = info.msg
            if not mission.label:
                mission.label = _label_of(m)
            mission.mode = str(getattr(m, "mode", "") or "")
            mission.baseline = str(getattr(m, "baseline", "") or "")
            mission.objective = float(getattr(m, "objective", math.nan))
            rows, cols = getattr(m, "rows", None), getattr(m, "cols", None)
            if rows is not None and cols is not None:
                mission.plan_cells = [(int(r), int(c)) for r, c in zip(rows, cols)]
        if not mission.label:
            mission.label = f"mission_{mission.index}"


def _attach_odometry(missions: list[Mission], odoms: Sequence[Logged]) -> None:
    """Each mission's ``/odom`` window: [its start, the next mission's start)."""
    if not odoms:
        return
    odom_arr = np.array([[o.timestamp, *odom_xy(o.msg)] for o in odoms], dtype=float)
    for i, mission in enumerate(missions):
        stop = missions[i + 1].start_ns if i + 1 < len(missions) else math.inf
        sel = (odom_arr[:, 0] >= mission.start_ns) & (odom_arr[:, 0] < stop)
        mission.odom = odom_arr[sel]


def latest_before(items: Sequence[Logged], t_ns: int) -> int | None:
    """Index of the last item with ``timestamp <= t_ns`` (else 0 if any item, else None)."""
    best = None
    for i, item in enumerate(items):
        if item.timestamp <= t_ns:
            best = i
    if best is None and items:
        best = 0
    return best


def label_statistics(missions: list[Mission]) -> dict[str, dict[str, float]]:
    """Per label: runs, fraction touching lava, fraction reaching a target, mean true return."""
    by_label: dict[str, list[Mission]] = defaultdict(list)
    for m in missions:
        by_label[m.label].append(m)
    out = {}
    for label, ms in by_label.items():
        returns = np.array([m.true_return for m in ms], dtype=float)
        out[label] = {
            "runs": len(ms),
            "lava_fraction": float(np.mean([m.touched_lava for m in ms])),
            "target_fraction": float(np.mean([m.reached_target for m in ms])),
            "mean_true_return": float(np.nanmean(returns)) if np.isfinite(returns).any() else math.nan,
        }
    return out
