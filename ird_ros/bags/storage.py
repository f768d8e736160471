"""rosbag2 (MCAP) I/O without ROS: the ``rosbags`` typestore, decoded messages, per-topic summary.

Bags written by ``ird_ros.nodes.recorder`` (or by ``ros2 bag record`` on a full ROS install) are
read here with the ``rosbags`` library. The ``ird_msgs`` types are registered in a
``rosbags`` typestore from the ``.msg`` files shipped in the repository
(``msgs_config/ird_msgs/msg``), so this works on a machine without the venv's ``ird_msgs``;
standard types come from ``Stores.ROS2_JAZZY``. A type neither knows (a topic of another
package) is registered from the definition stored in the bag itself.

Main entry points:

- ``make_typestore()``: the typestore (Jazzy + ird_msgs).
- ``iter_messages(bag)`` / ``read_messages(bag)``: decoded messages with their log time.
- ``summarize(bag)``: per topic type, count, first/last time and rate.
"""

from __future__ import annotations

import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Iterator, Sequence

from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore

from ird_ros.resources import msg_root

__all__ = [
    "REPO_MSG_ROOT",
    "BagMessage",
    "TopicSummary",
    "find_msg_files",
    "msg_types_from_files",
    "make_typestore",
    "register_type",
    "referenced_types",
    "iter_messages",
    "read_messages",
    "summarize",
]

REPO_MSG_ROOT = msg_root()
"""Folder holding the repository's interface packages (``<pkg>/msg/*.msg``): ``msgs_config``, as
package data of ``ird_ros`` (``ird_ros.resources``)."""


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
