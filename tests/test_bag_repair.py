"""ird_ros.bags.repair without ROS: checkpointed bags open before close(); reindex turns any
prefix of an MCAP file (a killed recorder's, or a cut-off copy of a finished bag) into a bag
that rosbags and the mcap library read, holding exactly the messages whose records are
complete in that prefix."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import Reader, StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from ird_ros.bags import repair as bag_repair
from ird_ros.bags.repair import MAGIC, bag_state, checkpoint, close_writer, reindex

ROOT = Path(__file__).resolve().parents[1]
TS = get_typestore(Stores.ROS2_JAZZY)
ZERO = QosTime(0, 0)
QOS = [Qos(QosHistory.KEEP_LAST, 10, QosReliability.RELIABLE, QosDurability.TRANSIENT_LOCAL, ZERO, ZERO,
           QosLiveliness.AUTOMATIC, ZERO, False)]
Sent = tuple[str, int, bytes]


def _message(i: int) -> tuple[str, str, bytes]:
    """(topic, type, CDR bytes) of the i-th test message; its bytes occur once in a bag."""
    if i % 3:
        msg = TS.types["std_msgs/msg/String"](data=f"message {i:05d}")
        return "/chatter", "std_msgs/msg/String", bytes(TS.serialize_cdr(msg, "std_msgs/msg/String"))
    header = TS.types["std_msgs/msg/Header"](stamp=TS.types["builtin_interfaces/msg/Time"](sec=i, nanosec=7),
                                            frame_id=f"frame{i:05d}")
    point = TS.types["geometry_msgs/msg/Point"](x=float(i), y=-1.5 * i, z=0.25)
    msg = TS.types["geometry_msgs/msg/PointStamped"](header=header, point=point)
    return "/point", "geometry_msgs/msg/PointStamped", bytes(TS.serialize_cdr(msg, "geometry_msgs/msg/PointStamped"))


def _record(bag: Path, n: int, checkpoint_every: int, close: bool) -> tuple[list[Sent], int]:
    """Write n messages, checkpointing every ``checkpoint_every``; returns (sent, checkpointed)."""
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    checkpoint(writer)
    conns = {
        "/chatter": writer.add_connection("/chatter", "std_msgs/msg/String", typestore=TS, offered_qos_profiles=QOS),
        "/point": writer.add_connection("/point", "geometry_msgs/msg/PointStamped", typestore=TS),
    }
    sent: list[Sent] = []
    checkpointed = 0
    for i in range(n):
        topic, _type, data = _message(i)
        stamp = 1_700_000_000_000_000_000 + i * 10_000_000
        writer.write(conns[topic], stamp, data)
        sent.append((topic, stamp, data))
        if (i + 1) % checkpoint_every == 0:
            checkpoint(writer)
            checkpointed = i + 1
    if close:
        close_writer(writer)
    else:
        writer.abort()  # closes the file without writing: what a SIGKILL leaves behind
    return sent, checkpointed


def _read_rosbags(bag: Path) -> tuple[list[Sent], dict[str, int], Reader]:
    with Reader(bag) as reader:
        got = [(c.topic, t, bytes(d)) for c, t, d in reader.messages()]
        counts = {c.topic: c.msgcount for c in reader.connections}
        assert reader.message_count == len(got)
        return got, counts, reader


def _read_mcap(path: Path) -> list[Sent]:
    with path.open("rb") as fh:
        return [(ch.topic, m.log_time, bytes(m.data)) for _s, ch, m in make_reader(fh).iter_messages(log_time_order=False)]


def _complete_before(blob: bytes, sent: list[Sent], cut: int) -> int:
    """How many messages have their whole record in blob[:cut] (a message record ends with
    its data; uncompressed chunks keep the data as it is)."""
    ends = []
    for _t, _s, data in sent:
        pos = blob.find(data)
        assert pos > 0 and blob.find(data, pos + 1) == -1
        ends.append(pos + len(data))
    assert ends == sorted(ends)
    return sum(end <= cut for end in ends)


def _check_rebuilt(bag: Path, sent: list[Sent], k: int) -> None:
    got, counts, _ = _read_rosbags(bag)
    assert got == sent[:k]
    assert _read_mcap(bag / f"{bag.name}.mcap") == sent[:k]
    expected_counts = {t: sum(1 for s in sent[:k] if s[0] == t) for t in ("/chatter", "/point")}
    assert {t: c for t, c in counts.items() if c} == {t: c for t, c in expected_counts.items() if c}
    with Reader(bag) as reader:
        for conn in reader.connections:
            assert conn.digest == TS.hash_rihs01(conn.msgtype)
            if conn.topic == "/chatter":
                assert conn.ext.offered_qos_profiles == QOS
        if k:
            assert reader.start_time == sent[0][1] and reader.end_time == sent[k - 1][1] + 1
    assert bag_state(bag) == "complete"


def test_checkpointed_bag_opens_before_close(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    sent, checkpointed = _record(bag, 47, checkpoint_every=10, close=False)
    assert checkpointed == 40
    got, counts, _reader = _read_rosbags(bag)
    assert got == sent[:40]  # the last 7 were still in memory
    assert _read_mcap(bag / "bag.mcap") == sent[:40]
    assert counts == {"/chatter": 26, "/point": 14}
    assert bag_state(bag) != "complete"  # readable, but without index and summary


def test_a_bag_still_being_recorded_is_refused(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
    writer.open()
    checkpoint(writer)
    assert bag_state(bag) == bag_repair.RECORDING
    with pytest.raises(ValueError, match="stop the recorder first"):
        reindex(bag)
    writer.abort()  # the lock goes with the file, as when the recorder is killed
    assert reindex(bag).rebuilt
    _check_rebuilt(bag, [], 0)


def test_checkpoint_then_close_is_a_normal_bag(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    sent, _ = _record(bag, 47, checkpoint_every=10, close=True)
    assert bag_state(bag) == "complete"
    with (bag / "bag.mcap").open("rb") as fh:
        reader = make_reader(fh, validate_crcs=True)
        assert reader.get_summary().statistics.message_count == 47
    _check_rebuilt(bag, sent, 47)
    before = (bag / "bag.mcap").read_bytes()
    result = reindex(bag)
    assert not result.rebuilt and result.counts == {"/chatter": 31, "/point": 16}
    assert (bag / "bag.mcap").read_bytes() == before and not (bag / "bag.mcap.orig").exists()


@pytest.mark.parametrize("kind", ["killed", "closed"])
def test_any_prefix_reindexes_to_the_complete_messages(kind: str, tmp_path: Path) -> None:
    """Cut the file at record boundaries, next to them and at a stride: reindex always yields a
    bag both libraries read, with exactly the messages whose records are complete."""
    source = tmp_path / "source"
    sent, checkpointed = _record(source, 24, checkpoint_every=5, close=kind == "closed")
    blob = (source / "source.mcap").read_bytes()
    if kind == "killed":
        sent = sent[:checkpointed]
        assert blob.endswith(MAGIC)
    ends = [blob.find(d) + len(d) for _t, _s, d in sent]
    cuts = sorted({0, 5, 8, 9, 20, len(blob)} | set(range(0, len(blob), 89)) | {e + d for e in ends for d in (-1, 0)})
    previous = -1
    for cut in cuts:
        bag = tmp_path / f"cut{cut}"
        bag.mkdir()
        (bag / f"{bag.name}.mcap").write_bytes(blob[:cut])
        if kind == "killed":  # what the last checkpoint left (hashes from it); closed: none at all
            shutil.copy(source / "metadata.yaml", bag / "metadata.yaml")
            text = (bag / "metadata.yaml").read_text().replace("source.mcap", f"{bag.name}.mcap")
            (bag / "metadata.yaml").write_text(text)
        result = reindex(bag)
        k = _complete_before(blob, sent, cut)
        assert result.rebuilt or cut == len(blob) and kind == "closed"
        _check_rebuilt(bag, sent, k)
        assert sum(result.counts.values()) == k
        assert k >= previous
        previous = k
        if result.rebuilt:
            assert (bag / f"{bag.name}.mcap.orig").read_bytes() == blob[:cut]
        shutil.rmtree(bag)
    assert previous == len(sent)


def test_zeros_after_the_data_stop_the_scan(tmp_path: Path) -> None:
    """After a power loss a file can end in zeros (size updated, data blocks not written)."""
    source = tmp_path / "source"
    sent, _ = _record(source, 30, checkpoint_every=30, close=True)
    blob = (source / "source.mcap").read_bytes()
    cut = blob.find(sent[20][2]) + len(sent[20][2])
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag.mcap").write_bytes(blob[:cut] + bytes(4096))
    result = reindex(bag)
    assert "corrupt" in result.stop_reason and result.dropped_bytes >= 4096
    _check_rebuilt(bag, sent, 21)


def test_force_rebuild_of_a_complete_bag_keeps_everything(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    sent, _ = _record(bag, 25, checkpoint_every=100, close=True)
    result = reindex(bag, force=True, keep_original=False)
    assert result.rebuilt and result.stop_reason == "" and result.dropped_bytes == 0
    assert not (bag / "bag.mcap.orig").exists() and not (bag / ".reindex.tmp").exists()
    _check_rebuilt(bag, sent, 25)


def test_not_a_bag_is_a_value_error(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=f"^bag: {tmp_path / 'missing'} does not exist$"):
        reindex(tmp_path / "missing")
    (tmp_path / "a_file").write_text("not a bag")
    with pytest.raises(ValueError, match=f"^bag: {tmp_path / 'a_file'} is not a directory$"):
        reindex(tmp_path / "a_file")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="exactly one .mcap"):
        reindex(tmp_path / "empty")
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "other.mcap").write_bytes(b"SQLite format 3\x00" + bytes(100))
    with pytest.raises(ValueError, match="not an MCAP file"):
        reindex(tmp_path / "other", keep_original=False)
    assert (tmp_path / "other" / "other.mcap").read_bytes().startswith(b"SQLite")


def test_cli_checks_and_rebuilds(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    sent, checkpointed = _record(bag, 20, checkpoint_every=6, close=False)
    script = [sys.executable, str(ROOT / "scripts" / "reindex_bag.py")]
    assert subprocess.run([*script, "--check", str(bag)], capture_output=True).returncode == 1
    done = subprocess.run([*script, str(bag / "bag.mcap")], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert f"{checkpointed} messages on 2 topics" in done.stdout
    _check_rebuilt(bag, sent, checkpointed)
    again = subprocess.run([*script, "--check", str(bag)], capture_output=True, text=True)
    assert again.returncode == 0 and "complete" in again.stdout
    assert subprocess.run([*script, str(tmp_path / "nope")], capture_output=True).returncode == 2


def test_repair_module_does_not_import_rclpy() -> None:
    code = f"import sys; sys.path.insert(0, {str(ROOT)!r}); import ird_ros.bags.repair; print('rclpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", bag_repair.__name__
