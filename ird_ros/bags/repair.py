"""Crash-safe rosbag2/MCAP bags: checkpoints while recording, a rebuild after a crash.

rosbags' MCAP writer keeps the open chunk in memory and writes the index, the summary, the
footer and ``metadata.yaml`` only in ``close()``: a SIGKILLed recorder leaves a file that
neither ``rosbags`` nor the ``mcap`` library opens. Two remedies, no ROS imports here (the
tolerant reading of a damaged file is :mod:`ird_ros.bags.mcap_scan`):

- ``checkpoint(writer)`` (called by ``ird_ros.nodes.recorder`` every ``flush_period``): writes
  the pending chunk out, atomically replaces ``metadata.yaml`` with the counts of what is
  now on disk, writes a placeholder end (DataEnd + a Footer without summary + magic) after
  the chunk *without moving the write position* (the next chunk overwrites it) and fsyncs.
  Until the next write the file is a valid MCAP without summary section (both readers scan
  it), so a bag killed anywhere but inside a write opens as it is, missing only the
  messages that arrived after the last checkpoint.
- ``reindex(bag)`` (``scripts/reindex_bag.py``): reads every complete record of a truncated
  or unindexed MCAP (a streaming scan that stops at the first incomplete or inconsistent
  record, so the result is always a prefix of the recorded messages; complete message
  records inside a cut-off uncompressed chunk count too) and rewrites the bag with rosbags'
  writer: chunk indexes, summary, footer, and a ``metadata.yaml`` with exact counts, time
  span, types, type hashes and offered QoS. In place: the original file is kept, hard
  linked, as ``<name>.mcap.orig``; the rebuilt file replaces ``<name>.mcap`` by an atomic
  rename, then ``metadata.yaml`` is replaced likewise.
"""

from __future__ import annotations

import contextlib
import fcntl
import mmap
import os
import shutil
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.rosbag2.metadata import dump_qos_v8, dump_qos_v9, parse_qos
from rosbags.typesys import Stores, get_types_from_idl, get_types_from_msg, get_typestore
import yaml

from ird_ros.bags.mcap_scan import (
    FOOTER_LEN,
    MAGIC,
    OP_DATA_END,
    OP_FOOTER,
    McapChannel,
    McapMessage,
    McapScan,
    McapSchema,
    summary_message_count,
)

__all__ = ["ReindexResult", "bag_state", "checkpoint", "close_writer", "reindex", "rosbag2_metadata",
           "write_metadata"]

# DataEnd (crc 0 = not computed) + Footer (no summary section) + magic: 50 bytes
PLACEHOLDER_END = (
    bytes([OP_DATA_END]) + struct.pack("<QI", 4, 0)
    + bytes([OP_FOOTER]) + struct.pack("<QQQI", FOOTER_LEN, 0, 0, 0) + MAGIC
)
METADATA = "metadata.yaml"
RECORDING = "is being recorded (a running recorder holds its lock)"
# libyaml when present: a checkpoint must not wait for a pure-Python YAML dump
_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


# ----------------------------------------------------------------------- checkpoints


def _mcap_storage(writer: Writer) -> Any:
    """rosbags' McapWriter behind ``writer``; TypeError if its internals are not the known ones."""
    storage = writer.storage
    chunk = getattr(storage, "chunk", None)
    if not (hasattr(storage, "close_chunk") and hasattr(storage, "bio") and hasattr(chunk, "msgs")):
        raise TypeError("checkpoint needs an open rosbags MCAP Writer (rosbags 0.11 McapWriter internals)")
    return storage


def rosbag2_metadata(writer: Writer) -> dict[str, Any]:
    """The ``metadata.yaml`` content rosbags' ``Writer.close()`` would write for what
    ``writer`` has written so far (same keys, uncompressed storage)."""
    dump_qos = dump_qos_v9 if writer.version >= 9 else dump_qos_v8
    count = sum(writer.counts.values())
    start = writer.min_timestamp if count else 0
    duration = max(0, writer.max_timestamp - writer.min_timestamp) if count else 0
    name = _mcap_storage(writer).path.name
    return {"rosbag2_bagfile_information": {
        "version": writer.version,
        "storage_identifier": writer.storage_plugin.name.lower(),
        "relative_file_paths": [name],
        "duration": {"nanoseconds": duration},
        "starting_time": {"nanoseconds_since_epoch": start},
        "message_count": count,
        "topics_with_message_count": [
            {"topic_metadata": {
                "name": c.topic, "type": c.msgtype,
                "serialization_format": c.ext.serialization_format,  # type: ignore[union-attr]
                "offered_qos_profiles": dump_qos(list(c.ext.offered_qos_profiles)),  # type: ignore[union-attr]
                "type_description_hash": c.digest,
            }, "message_count": writer.counts[c.id]}
            for c in writer.connections
        ],
        "compression_format": "",
        "compression_mode": "",
        "files": [{"path": name, "starting_time": {"nanoseconds_since_epoch": start},
                   "duration": {"nanoseconds": duration}, "message_count": count}],
        "custom_data": writer.custom_data or None,
        "ros_distro": "rosbags",
    }}


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_metadata(bag: Path, metadata: dict[str, Any], *, durable: bool = True) -> None:
    """Replace ``bag/metadata.yaml`` atomically (tmp file, rename); ``durable`` adds the
    fsyncs that make it survive a power loss too."""
    tmp = bag / (METADATA + ".tmp")
    with tmp.open("w", encoding="utf8") as out:
        yaml.dump(metadata, out, Dumper=_DUMPER, default_flow_style=False, sort_keys=False)
        if durable:
            out.flush()
            os.fsync(out.fileno())
    tmp.replace(bag / METADATA)
    if durable:
        _fsync_dir(bag)


def checkpoint(writer: Writer) -> None:
    """Make everything ``writer`` got so far durable and readable without ``close()``.

    Closes the pending chunk (if it holds messages) and writes it out, rewrites
    ``metadata.yaml`` (atomically; not fsynced: after a power loss ``reindex`` rebuilds it
    from the fsynced data), then writes ``PLACEHOLDER_END`` at the end of the file with
    ``pwrite`` (the buffered write position stays before it, so the next chunk or
    ``close()`` overwrites it) and fsyncs. In that order a file that ends with the MCAP magic
    always has a ``metadata.yaml`` that matches it, whenever the process was killed. Schema
    and channel records of topics without messages yet stay in the pending chunk: such
    topics are listed in ``metadata.yaml`` with 0 messages.

    Also takes an exclusive ``flock`` on the file (the kernel drops it when the process
    dies), by which ``reindex`` refuses a bag that is still being recorded.
    """
    storage = _mcap_storage(writer)
    with contextlib.suppress(OSError):  # a filesystem without locks: recording matters more
        fcntl.flock(storage.bio.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
    if storage.chunk.msgs:
        storage.close_chunk()
    bio = storage.bio
    bio.flush()
    write_metadata(Path(writer.path), rosbag2_metadata(writer), durable=False)
    os.pwrite(bio.fileno(), PLACEHOLDER_END, bio.tell())
    os.fsync(bio.fileno())


def close_writer(writer: Writer) -> None:
    """``writer.close()`` after cutting off a checkpoint's placeholder end, so no stale bytes
    can follow the real footer."""
    storage = _mcap_storage(writer)
    storage.bio.flush()
    storage.bio.truncate(storage.bio.tell())
    writer.close()


# ----------------------------------------------------------------------- reindex


def _read_yaml(path: Path) -> dict[str, Any] | None:
    try:
        data = yaml.load(path.read_text(encoding="utf8"), Loader=_LOADER)
        return data["rosbag2_bagfile_information"]
    except Exception:  # noqa: BLE001 - missing, half-written or foreign: treated as absent
        return None


def _bag_dir(path: Path | str) -> Path:
    """The bag folder of ``path`` (the folder itself or the .mcap file in it)."""
    path = Path(path)
    return path.parent if path.is_file() and path.suffix == ".mcap" else path


def _bag_file(bag: Path) -> Path:
    """The bag's single MCAP file (named in metadata.yaml if readable, else found)."""
    if not bag.is_dir():
        raise ValueError(f"bag: {bag} {'is not a directory' if bag.exists() else 'does not exist'}")
    meta = _read_yaml(bag / METADATA)
    names = [Path(p).name for p in (meta or {}).get("relative_file_paths") or []]
    if not names:
        names = sorted(p.name for p in bag.glob("*.mcap"))
    if len(names) != 1 or not names[0].endswith(".mcap"):
        raise ValueError(f"bag: {bag} must hold exactly one .mcap file (found {names or 'none'})")
    path = bag / names[0]
    if not path.is_file():
        raise ValueError(f"bag: {path} does not exist")
    return path


def _map(path: Path) -> Any:
    with path.open("rb") as fh:
        if os.fstat(fh.fileno()).st_size == 0:
            return b""
        return mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)


def _unmap(data: Any) -> None:
    if isinstance(data, mmap.mmap):
        with contextlib.suppress(BufferError):  # a scan cut short by an error still holds a view
            data.close()


def _being_recorded(path: Path) -> bool:
    """True while a writer holds ``checkpoint``'s lock on ``path``."""
    with path.open("rb") as fh:
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_SH | fcntl.LOCK_NB)
        except BlockingIOError:
            return True
    return False


def bag_state(bag: Path | str) -> str:
    """``"complete"`` when the MCAP has its summary and metadata.yaml agrees with it, else a
    sentence saying why the bag needs ``reindex``. ``bag``: the folder or its .mcap file."""
    bag = _bag_dir(bag)
    mcap_path = _bag_file(bag)
    if _being_recorded(mcap_path):
        return RECORDING
    data = _map(mcap_path)
    try:
        count = summary_message_count(data)
    finally:
        _unmap(data)
    if count is None:
        return f"{mcap_path.name} has no summary/footer (the recorder did not close it)"
    meta = _read_yaml(bag / METADATA)
    if meta is None:
        return f"{METADATA} is missing or unreadable"
    if meta.get("message_count") != count:
        return f"{METADATA} counts {meta.get('message_count')} messages, the MCAP {count}"
    return "complete"


@dataclass(frozen=True)
class ReindexResult:
    bag: Path
    rebuilt: bool
    state: str  # bag_state before the rebuild
    counts: dict[str, int]
    stop_reason: str
    dropped_bytes: int
    original: Path | None


def _type_hash(schema: McapSchema | None, msgtype: str, known: dict[str, str]) -> tuple[str, str]:
    """(message definition, RIHS01 hash): the hash from the old metadata.yaml, else computed."""
    msgdef = schema.data.decode() if schema else ""
    if digest := known.get(msgtype):
        return msgdef, digest
    try:
        store = get_typestore(Stores.EMPTY)
        idl = schema is not None and schema.encoding == "ros2idl"
        store.register(get_types_from_idl(msgdef) if idl else get_types_from_msg(msgdef, msgtype))
        return msgdef, store.hash_rihs01(msgtype)
    except Exception as exc:  # noqa: BLE001
        raise ValueError(f"schema {msgtype!r}: cannot compute its type hash ({exc})") from exc


def _rebuild(src: Path, out: Path, old_meta: dict[str, Any] | None) -> tuple[McapScan, dict[str, int]]:
    known = {t["topic_metadata"]["type"]: t["topic_metadata"].get("type_description_hash", "")
             for t in (old_meta or {}).get("topics_with_message_count") or []}
    data = _map(src)
    try:
        scan = McapScan(data)
        writer = Writer(out, version=9, storage_plugin=StoragePlugin.MCAP)
        for key, value in ((old_meta or {}).get("custom_data") or {}).items():
            writer.set_custom_data(str(key), str(value))
        writer.open()
        conns: dict[int, Any] = {}
        counts: dict[str, int] = {}
        for item in scan:
            if isinstance(item, McapChannel):
                schema = scan.schemas.get(item.schema_id)
                msgtype = schema.name if schema else ""
                msgdef, digest = _type_hash(schema, msgtype, known)
                qos = parse_qos(item.metadata.get("offered_qos_profiles", ""))
                same = [c for c in writer.connections if (c.topic, c.msgtype) == (item.topic, msgtype)]
                conns[item.id] = same[0] if same else writer.add_connection(
                    item.topic, msgtype, msgdef=msgdef, rihs01=digest,
                    serialization_format=item.message_encoding, offered_qos_profiles=qos)
                counts.setdefault(item.topic, 0)
            elif isinstance(item, McapMessage):
                conn = conns[item.channel_id]
                writer.write(conn, item.log_time, item.data)
                counts[conn.topic] += 1
        writer.close()
    finally:
        _unmap(data)
    return scan, counts


def reindex(bag: Path | str, *, force: bool = False, keep_original: bool = True) -> ReindexResult:
    """Rebuild a bag whose recorder died (see the module docstring); a complete bag is left
    alone unless ``force``. ``keep_original``: keep the old file as ``<name>.mcap.orig``
    (an existing ``.orig``, the older original, is kept as it is)."""
    bag = _bag_dir(bag)
    src = _bag_file(bag)
    state = bag_state(bag)
    if state == RECORDING:
        raise ValueError(f"bag: {bag} {RECORDING}: stop the recorder first")
    with src.open("rb") as fh:
        head = fh.read(len(MAGIC))
    if not MAGIC.startswith(head):
        raise ValueError(f"bag: {src} is not an MCAP file (no MCAP magic)")
    if state == "complete" and not force:
        meta = _read_yaml(bag / METADATA) or {}
        counts = {t["topic_metadata"]["name"]: int(t["message_count"]) for t in meta.get("topics_with_message_count") or []}
        return ReindexResult(bag, False, state, counts, "", 0, None)
    work = bag / ".reindex.tmp"
    if work.exists():
        shutil.rmtree(work)  # left by an interrupted reindex
    work.mkdir()
    # The Writer names its file after its folder: build in work/<stem> to get the same name.
    out = work / src.name[: -len(".mcap")]
    scan, counts = _rebuild(src, out, _read_yaml(bag / METADATA))
    rebuilt = out / src.name
    with rebuilt.open("rb+") as fh:
        os.fsync(fh.fileno())
    original = src.with_name(src.name + ".orig")
    if not keep_original:
        original = None
    elif not original.exists():
        try:
            os.link(src, original)
        except OSError:  # no hard links here: copy
            shutil.copy2(src, original)
    dropped = 0 if scan.complete else src.stat().st_size - scan.valid_bytes
    rebuilt.replace(src)
    write_metadata(bag, yaml.load((out / METADATA).read_text(encoding="utf8"), Loader=_LOADER))
    shutil.rmtree(work)
    return ReindexResult(bag, True, state, counts, scan.stop_reason, dropped, original)
