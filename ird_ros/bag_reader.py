"""Read the stack's rosbag2 (MCAP) bags without ROS: rosbags only, no rclpy.

Bags written by ``ird_ros.recorder`` (or by ``ros2 bag record`` on a full ROS install) are
read here with the ``rosbags`` library. The ``ird_msgs`` types are registered in a
``rosbags`` typestore from the ``.msg`` files shipped in the repository
(``msgs_config/ird_msgs/msg``), so this works on a machine without the venv's ``ird_msgs``;
standard types come from ``Stores.ROS2_JAZZY``. A type neither knows (a topic of another
package) is registered from the definition stored in the bag itself.

Main entry points:

- ``make_typestore()``: the typestore (Jazzy + ird_msgs).
- ``iter_messages(bag)`` / ``read_messages(bag)``: decoded messages with their log time.
- ``summarize(bag)``: per topic type, count, first/last time and rate.
- ``extract_missions(bag)``: per executed plan (mission) its label, plan, Rob's executed
  trajectory and final status (touched lava, reached target, true return).
- ``terrain_from_msg``, ``path_xy``, ``odom_xy``: small decoders used by the plots.

Mission segmentation: a mission is a maximal run of consecutive ``/rob/status`` messages
with the same ``plan_label`` whose ``step`` never decreases; a new mission starts when the
label changes, the step goes back, or a status follows a ``done`` one with step 0. Each
mission is matched with the latest ``/plan`` logged at or before its first status that no
earlier mission took, and that plan with its ``/ird/plan_info`` (same header stamp; else the
latest one logged before the plan), which gives the mode, baseline, objective, the plan's
cells, and the label when the status has none. A mission's window (for ``/odom``) runs from
its plan (or first status) to the next mission's start. A bag without ``/rob/status`` has
one mission per ``/plan`` (plans only, no outcome).
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

__all__ = [
    "REPO_MSG_ROOT",
    "BagMessage",
    "TopicSummary",
    "Mission",
    "Terrain",
    "find_msg_files",
    "msg_types_from_files",
    "make_typestore",
    "register_type",
    "referenced_types",
    "iter_messages",
    "read_messages",
    "summarize",
    "extract_missions",
    "terrain_from_msg",
    "path_xy",
    "path_cells",
    "odom_xy",
    "stamp_ns",
]

REPO_MSG_ROOT = Path(__file__).resolve().parents[1] / "msgs_config"
"""Folder holding the repository's interface packages (``<pkg>/msg/*.msg``)."""

PLAN_TOPIC = "/plan"
PLAN_INFO_TOPIC = "/ird/plan_info"
STATUS_TOPIC = "/rob/status"
ODOM_TOPIC = "/odom"
TERRAIN_TOPIC = "/world/terrain"


# --------------------------------------------------------------------------- types


def find_msg_files(roots: Iterable[str | Path]) -> dict[str, Path]:
    """``{"pkg/msg/Name": path}`` for every ``<root>/**/<pkg>/msg/<Name>.msg`` under ``roots``.

    A root may also be a package folder (``.../ird_msgs``) or its ``msg`` folder.
    """
    found: dict[str, Path] = {}
    for root in roots:
        root = Path(root)
        if not root.is_dir():
            continue
        for path in sorted(root.rglob("*.msg")):
            if path.parent.name != "msg":
                continue
            pkg = path.parent.parent.name
            found.setdefault(f"{pkg}/msg/{path.stem}", path)
    return found


def msg_types_from_files(files: dict[str, Path]) -> dict[str, Any]:
    """Parse ``.msg`` files (``{"pkg/msg/Name": path}``) into a rosbags types dict."""
    types: dict[str, Any] = {}
    for name, path in files.items():
        types.update(get_types_from_msg(Path(path).read_text(encoding="utf-8"), name))
    return types


def make_typestore(msg_roots: Sequence[str | Path] | None = None) -> Typestore:
    """A ``Stores.ROS2_JAZZY`` typestore plus every ``.msg`` type found under ``msg_roots``.

    ``msg_roots`` defaults to the repository's ``msgs_config`` (the ird_msgs sources).
    """
    store = get_typestore(Stores.ROS2_JAZZY)
    roots = [REPO_MSG_ROOT] if msg_roots is None else list(msg_roots)
    types = msg_types_from_files(find_msg_files(roots))
    if types:
        store.register(types)
    return store


def referenced_types(fields: Any) -> set[str]:
    """Type names (``pkg/msg/Name``) referenced by a rosbags field list, at any nesting."""
    from rosbags.typesys.base import Nodetype

    found: set[str] = set()

    def walk(desc: Any) -> None:
        kind, rest = desc
        if kind == Nodetype.NAME:
            found.add(rest)
        elif kind in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            walk(rest[0])

    for _name, desc in fields:
        walk(desc)
    return found


def register_type(store: Typestore, typename: str, find_msg_text: Any) -> None:
    """Register ``typename`` and, first, every type it references that ``store`` lacks.

    ``find_msg_text(typename) -> str | None`` returns a ``.msg`` file's text (or None if
    unknown, which raises ``KeyError`` naming the type).
    """
    if typename in store.fielddefs:
        return
    text = find_msg_text(typename)
    if text is None:
        raise KeyError(f"no .msg definition found for {typename}")
    types = get_types_from_msg(text, typename)
    for dep in referenced_types(types[typename][1]):
        if dep != typename:
            register_type(store, dep, find_msg_text)
    store.register(types)


def _ensure_connection_type(store: Typestore, connection: Any) -> None:
    """Register a connection's type from the bag's stored definition if the store lacks it."""
    if connection.msgtype in store.fielddefs:
        return
    data = connection.msgdef.data if connection.msgdef is not None else ""
    if not data:
        raise KeyError(f"{connection.topic}: type {connection.msgtype} is unknown and the bag stores no definition")
    if data.startswith("=" * 80 + "\nIDL: "):
        from rosbags.typesys import get_types_from_idl

        types: dict[str, Any] = {}
        for part in data.split("=" * 80 + "\nIDL: ")[1:]:
            types.update(get_types_from_idl(part.split("\n", 1)[1]))
    else:
        types = get_types_from_msg(data, connection.msgtype)
    store.register({k: v for k, v in types.items() if k not in store.fielddefs})


# --------------------------------------------------------------------------- messages


@dataclass(frozen=True)
class BagMessage:
    """One decoded message: ``timestamp`` is the bag's log (receive) time in ns."""

    topic: str
    msgtype: str
    timestamp: int
    msg: Any


def iter_messages(
    bag: str | Path,
    topics: Iterable[str] | None = None,
    typestore: Typestore | None = None,
) -> Iterator[BagMessage]:
    """Decoded messages of ``bag`` (optionally only ``topics``) in log-time order."""
    store = typestore or make_typestore()
    wanted = None if topics is None else set(topics)
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if wanted is None or c.topic in wanted]
        for conn in conns:
            _ensure_connection_type(store, conn)
        if not conns:
            return
        for conn, timestamp, raw in reader.messages(connections=conns):
            yield BagMessage(conn.topic, conn.msgtype, int(timestamp), store.deserialize_cdr(raw, conn.msgtype))


def read_messages(
    bag: str | Path,
    topics: Iterable[str] | None = None,
    typestore: Typestore | None = None,
) -> dict[str, list[BagMessage]]:
    """``{topic: [BagMessage, ...]}`` in log-time order."""
    out: dict[str, list[BagMessage]] = defaultdict(list)
    for item in iter_messages(bag, topics, typestore):
        out[item.topic].append(item)
    return dict(out)


@dataclass(frozen=True)
class TopicSummary:
    """Per-topic statistics of a bag (times in ns, rate in Hz; NaN rate for < 2 messages)."""

    topic: str
    msgtype: str
    count: int
    first_ns: int | None
    last_ns: int | None
    durability: str

    @property
    def duration_s(self) -> float:
        if self.first_ns is None or self.last_ns is None:
            return 0.0
        return (self.last_ns - self.first_ns) / 1e9

    @property
    def rate_hz(self) -> float:
        if self.count < 2 or self.duration_s <= 0:
            return math.nan
        return (self.count - 1) / self.duration_s


def summarize(bag: str | Path) -> list[TopicSummary]:
    """Per topic (sorted by name): type, message count, first/last log time, QoS durability.

    Counts and times come from the message index, so no message is decoded.
    """
    stats: dict[str, list[Any]] = {}
    with Reader(bag) as reader:
        for conn in reader.connections:
            qos = getattr(conn.ext, "offered_qos_profiles", None) or []
            dur = qos[0].durability.name.lower() if qos else "unknown"
            stats.setdefault(conn.topic, [conn.msgtype, 0, None, None, dur])
        for conn, timestamp, _raw in reader.messages():
            entry = stats[conn.topic]
            entry[1] += 1
            entry[2] = timestamp if entry[2] is None else min(entry[2], timestamp)
            entry[3] = timestamp if entry[3] is None else max(entry[3], timestamp)
    return [TopicSummary(topic, *stats[topic]) for topic in sorted(stats)]


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
        return (
            int(math.floor((y - self.origin[1]) / self.resolution)),
            int(math.floor((x - self.origin[0]) / self.resolution)),
        )


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


def stamp_ns(stamp: Any) -> int:
    """A ``builtin_interfaces/Time`` in ns."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def path_xy(msg: Any) -> np.ndarray:
    """(N, 2) x, y of a ``nav_msgs/Path``'s poses."""
    return np.array([[p.pose.position.x, p.pose.position.y] for p in msg.poses], dtype=float).reshape(-1, 2)


def path_cells(xy: np.ndarray, resolution: float = 1.0, origin: tuple[float, float] = (0.0, 0.0)) -> list[tuple[int, int]]:
    """Cells (row, col) of map points (cell centres or anywhere inside the cell)."""
    return [
        (int(math.floor((y - origin[1]) / resolution)), int(math.floor((x - origin[0]) / resolution)))
        for x, y in np.asarray(xy, dtype=float).reshape(-1, 2)
    ]


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


def _segment_statuses(statuses: list[BagMessage]) -> list[list[BagMessage]]:
    groups: list[list[BagMessage]] = []
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


def extract_missions(bag: str | Path, messages: dict[str, list[BagMessage]] | None = None) -> list[Mission]:
    """The missions of a bag (see the module docstring for how they are segmented)."""
    if messages is None:
        messages = read_messages(bag, [PLAN_TOPIC, PLAN_INFO_TOPIC, STATUS_TOPIC, ODOM_TOPIC])
    plans = messages.get(PLAN_TOPIC, [])
    infos = messages.get(PLAN_INFO_TOPIC, [])
    statuses = messages.get(STATUS_TOPIC, [])
    odoms = messages.get(ODOM_TOPIC, [])

    missions: list[Mission] = []
    if statuses:
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
    else:
        for p in plans:
            missions.append(
                Mission(index=len(missions), label="", start_ns=p.timestamp, end_ns=p.timestamp,
                        plan_ns=p.timestamp, plan_xy=path_xy(p.msg))
            )

    # the plan's /ird/plan_info: same header stamp as the /plan message, else the latest
    # one logged at or before the plan (or the mission start)
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

    # odometry windows: [start, next mission's start)
    if odoms:
        odom_arr = np.array([[o.timestamp, *odom_xy(o.msg)] for o in odoms], dtype=float)
        for i, mission in enumerate(missions):
            stop = missions[i + 1].start_ns if i + 1 < len(missions) else math.inf
            sel = (odom_arr[:, 0] >= mission.start_ns) & (odom_arr[:, 0] < stop)
            mission.odom = odom_arr[sel]
    return missions


def latest_before(items: list[BagMessage], t_ns: int) -> int | None:
    """Index of the last item with ``timestamp <= t_ns`` (else 0 if any item, else None)."""
    best = None
    for i, item in enumerate(items):
        if item.timestamp <= t_ns:
            best = i
    if best is None and items:
        best = 0
    return best


# --------------------------------------------------------------------------- analysis and plots

TERRAIN_COLORS = {
    "dirt": "#b08850",
    "grass": "#5fa84a",
    "target": "#f2d13a",
    "lava": "#e0401f",
}
UNKNOWN_COLOR = "#9a9a9a"


def _terrain_image(terrain: Terrain) -> tuple[np.ndarray, list[tuple[str, str]]]:
    """RGB image (H, W, 3) of a terrain and its legend entries (name, colour)."""
    from matplotlib import colors as mcolors
    from matplotlib import colormaps

    palette = colormaps["tab10"]
    cols = []
    for i, name in enumerate(terrain.class_names):
        cols.append(TERRAIN_COLORS.get(name, mcolors.to_hex(palette(i % 10))))
    rgb = np.array([mcolors.to_rgb(c) for c in cols] + [mcolors.to_rgb(UNKNOWN_COLOR)])
    idx = terrain.classes.astype(int)
    idx = np.where(idx < len(cols), idx, len(cols))
    legend = list(zip(terrain.class_names, cols))
    if (idx == len(cols)).any():
        legend.append(("unknown", UNKNOWN_COLOR))
    return rgb[idx], legend


def plot_trajectories(missions: list[Mission], terrain: Terrain | None, path: str | Path, title: str = "") -> Path:
    """Rob's executed trajectories (odometry, solid) and plans (dashed) over the terrain."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Patch

    fig, ax = plt.subplots(figsize=(7, 6.5))
    handles = []
    if terrain is not None:
        img, legend = _terrain_image(terrain)
        ax.imshow(img, origin="lower", extent=terrain.extent, interpolation="nearest")
        handles += [Patch(facecolor=c, edgecolor="k", label=n) for n, c in legend]
    palette = plt.get_cmap("tab10")
    for k, m in enumerate(missions):
        color = palette(k % 10)
        if len(m.plan_xy):
            ax.plot(m.plan_xy[:, 0], m.plan_xy[:, 1], "--", color=color, lw=1.2, alpha=0.8)
        xy = m.odom[:, 1:] if len(m.odom) else m.plan_xy
        if len(xy):
            outcome = "LAVA" if m.touched_lava else ("target" if m.reached_target else "no target")
            (line,) = ax.plot(xy[:, 0], xy[:, 1], "-", color=color, lw=2.2,
                              label=f"#{m.index} {m.label}: {outcome}, return {m.true_return:.2f}")
            ax.plot(xy[0, 0], xy[0, 1], "o", color=color, ms=8, mec="k")
            ax.plot(xy[-1, 0], xy[-1, 1], "X", color=color, ms=9, mec="k")
            handles.append(line)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.set_title(title or "Rob's trajectories (solid: odometry, dashed: plan)")
    if handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def plot_returns(missions: list[Mission], start_ns: int, path: str | Path) -> Path:
    """True return over time (from /rob/status), one line per mission."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(8, 4.5))
    palette = plt.get_cmap("tab10")
    for k, m in enumerate(missions):
        if len(m.status_returns):
            t = (m.status_returns[:, 0] - start_ns) / 1e9
            ax.step(t, m.status_returns[:, 1], where="post", color=palette(k % 10), lw=1.8,
                    marker=".", label=f"#{m.index} {m.label}")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("time since start of bag [s]")
    ax.set_ylabel("true return")
    ax.set_title("True return of Rob's executed plans")
    if missions:
        ax.legend(fontsize=8, loc="best")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def plot_posterior(msg: Any, path: str | Path) -> Path:
    """Posterior samples per feature (box plots) with the proxy weights (red dots)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(msg.feature_names)
    d = len(names)
    samples = np.asarray(msg.samples, dtype=float).reshape(-1, d) if d else np.zeros((0, 0))
    fig, ax = plt.subplots(figsize=(max(6.0, 0.5 * d + 2), 4.5))
    if samples.size:
        ax.boxplot(samples, showfliers=False)
        ax.set_xticks(range(1, d + 1), names, rotation=60 if d > 8 else 0, fontsize=8)
    proxy = np.asarray(msg.proxy_weights, dtype=float)
    if proxy.size == d and d:
        ax.plot(range(1, d + 1), proxy, "o", color="red", label="proxy weights")
        ax.legend(fontsize=8)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_ylabel("weight")
    ax.set_title(f"IRD posterior ({msg.method}, beta={msg.beta:g}, K={int(msg.num_samples)}, "
                 f"R-hat max={msg.r_hat_max:.3f})")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


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


def analyze(bag: str | Path, out_dir: str | Path | None = None, typestore: Typestore | None = None) -> dict[str, Any]:
    """Summary, missions and (with ``out_dir``) PNG plots of a bag, as a JSON-able dict.

    Plots: ``trajectories_<i>.png`` (one per distinct terrain the missions ran on; without
    any /world/terrain just the paths), ``true_return.png`` and ``posterior.png`` (latest
    /ird/posterior), each only when the bag holds what it needs.
    """
    bag = Path(bag)
    store = typestore or make_typestore()
    topics = summarize(bag)
    wanted = [PLAN_TOPIC, PLAN_INFO_TOPIC, STATUS_TOPIC, ODOM_TOPIC, TERRAIN_TOPIC, "/ird/posterior"]
    messages = read_messages(bag, wanted, store)
    missions = extract_missions(bag, messages)
    firsts = [t.first_ns for t in topics if t.first_ns is not None]
    lasts = [t.last_ns for t in topics if t.last_ns is not None]
    start_ns = min(firsts) if firsts else 0
    end_ns = max(lasts) if lasts else 0

    plots: list[str] = []
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        terrains = messages.get(TERRAIN_TOPIC, [])
        groups: dict[int, list[Mission]] = defaultdict(list)
        for m in missions:
            tidx = latest_before(terrains, m.start_ns)
            groups[-1 if tidx is None else tidx].append(m)
        if not missions and terrains:
            groups[len(terrains) - 1] = []
        for n, (tidx, ms) in enumerate(sorted(groups.items())):
            terrain = terrain_from_msg(terrains[tidx].msg) if tidx >= 0 else None
            title = f"Rob's trajectories on terrain #{tidx}" if tidx >= 0 else "Rob's trajectories"
            plots.append(str(plot_trajectories(ms, terrain, out / f"trajectories_{n}.png", title)))
        if any(len(m.status_returns) for m in missions):
            plots.append(str(plot_returns(missions, start_ns, out / "true_return.png")))
        if messages.get("/ird/posterior"):
            plots.append(str(plot_posterior(messages["/ird/posterior"][-1].msg, out / "posterior.png")))

    return {
        "bag": str(bag),
        "start_ns": start_ns,
        "end_ns": end_ns,
        "duration_s": (end_ns - start_ns) / 1e9,
        "topics": [
            {
                "topic": t.topic,
                "type": t.msgtype,
                "count": t.count,
                "first_s": None if t.first_ns is None else (t.first_ns - start_ns) / 1e9,
                "last_s": None if t.last_ns is None else (t.last_ns - start_ns) / 1e9,
                "rate_hz": t.rate_hz,
                "durability": t.durability,
            }
            for t in topics
        ],
        "missions": [
            {
                "index": m.index,
                "label": m.label,
                "mode": m.mode,
                "baseline": m.baseline,
                "objective": m.objective,
                "start_s": (m.start_ns - start_ns) / 1e9,
                "plan_moves": m.plan_moves,
                "plan_length_m": m.plan_length_m,
                "executed_length_m": m.executed_length_m,
                "executed_moves": m.executed_moves,
                "steps": m.steps,
                "horizon": m.horizon,
                "done": m.done,
                "touched_lava": m.touched_lava,
                "reached_target": m.reached_target,
                "true_return": m.true_return,
            }
            for m in missions
        ],
        "labels": label_statistics(missions),
        "plots": plots,
    }
