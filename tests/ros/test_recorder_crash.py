"""A SIGKILLed ird_ros.nodes.recorder loses at most what it received in the documented bound.

The recorder (its own process, default ``flush_period``) records a PointStamped stream that
this test publishes at a known rate, each message numbered in ``point.x``. Once the recorder
has reported (``/recorder/status``) a couple of seconds of messages and the bag file has grown,
it gets SIGKILL. Then: the bag as left behind opens with rosbags (unless the kill landed in a
write), ``scripts/reindex_bag.py`` rebuilds it, and rosbags and the mcap library both read the
same messages: exactly the first k published, and k is at least every count the recorder had
reported in a status this test received ``loss_bound(flush_period)`` s or more before the kill
(the recorder's promise: what it received earlier than that is on disk; what DDS had not yet
delivered to it is not its to bound, so the loss since publication is printed, not asserted).
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from ird_ros.bags.repair import MAGIC
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.nodes.recorder import PARAMETERS, STATUS_TOPIC, loss_bound
from ird_ros.testing import spawn_node_process
from ird_ros.waits import spin_until, wait_for_subscribers

ROOT = Path(__file__).resolve().parents[2]
TOPIC = "/crash_test/points"
RATE_HZ = 50.0
BOUND_NS = int(loss_bound(float(PARAMETERS["flush_period"].default)) * 1e9)  # the default flush_period
TS = get_typestore(Stores.ROS2_JAZZY)


def _indices(messages: list[bytes]) -> list[int]:
    return [int(TS.deserialize_cdr(data, "geometry_msgs/msg/PointStamped").point.x) for data in messages]


def _rosbags_messages(bag: Path) -> list[bytes]:
    with Reader(bag) as reader:
        assert [c.topic for c in reader.connections] == [TOPIC]
        assert reader.connections[0].msgtype == "geometry_msgs/msg/PointStamped"
        got = [bytes(data) for _c, _t, data in reader.messages()]
        assert reader.message_count == len(got)
        return got


def test_sigkill_loses_only_what_arrived_within_the_bound(ros_node: Any, ros_domain: DomainLease, tmp_path: Path) -> None:
    from geometry_msgs.msg import PointStamped
    from std_msgs.msg import String

    out = tmp_path / "bag"
    proc = spawn_node_process(
        ["-m", "ird_ros.nodes.recorder", "--ros-args", "-p", f"output_dir:={out}", "-p", f"topics:=[{TOPIC}]"],
        domain=ros_domain, name="recorder-crash", ready_text="recording")
    try:
        mcap_path = out / "bag.mcap"
        assert (out / "metadata.yaml").is_file()  # written when the bag is opened
        empty_size = mcap_path.stat().st_size

        received = [0]
        statuses: list[tuple[int, int]] = []  # (wall-clock time this test got it, messages counted)

        def on_status(msg: Any) -> None:
            received[0] = json.loads(msg.data)["counts"].get(TOPIC, 0)
            statuses.append((time.time_ns(), received[0]))

        status_qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                                durability=DurabilityPolicy.TRANSIENT_LOCAL)
        ros_node.create_subscription(String, STATUS_TOPIC, on_status, status_qos)
        pub = ros_node.create_publisher(PointStamped, TOPIC, names.stream_qos(depth=100))
        wait_for_subscribers(ros_node, pub, processes=[proc], timeout=30.0)

        sent_at: list[int] = []  # wall-clock publish time of message i

        def publish() -> None:
            msg = PointStamped()
            msg.header.stamp = ros_node.get_clock().now().to_msg()
            msg.header.frame_id = "map"
            msg.point.x = float(len(sent_at))
            pub.publish(msg)
            sent_at.append(time.time_ns())

        timer = ros_node.create_timer(1.0 / RATE_HZ, publish)
        spin_until(ros_node, lambda: received[0] >= 2 * RATE_HZ and mcap_path.stat().st_size > empty_size,
                   timeout=60.0, what="two seconds of messages in the recorder and a grown bag file",
                   processes=[proc])
        killed_at = time.time_ns()
        proc.proc.kill()
        proc.proc.wait(timeout=15)
        ros_node.destroy_timer(timer)
        published = len(sent_at)
    finally:
        proc.stop()

    # As left behind: unless the kill hit a write, a valid MCAP up to the last checkpoint.
    as_is: list[bytes] = []
    if mcap_path.read_bytes().endswith(MAGIC):
        as_is = _rosbags_messages(out)
        assert _indices(as_is) == list(range(len(as_is)))

    done = subprocess.run([sys.executable, str(ROOT / "scripts" / "reindex_bag.py"), str(out)],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert (out / "bag.mcap.orig").is_file()

    got = _rosbags_messages(out)
    k = len(got)
    assert _indices(got) == list(range(k))  # a prefix of what was published, nothing invented
    assert got[: len(as_is)] == as_is
    with mcap_path.open("rb") as fh:
        from_mcap = [bytes(m.data) for _s, ch, m in make_reader(fh).iter_messages() if ch.topic == TOPIC]
    assert from_mcap == got

    assert 0 < k <= published
    # Every message the recorder had counted (received and handed to the writer) by a status that
    # reached this test at least the bound before the kill is in the bag.
    covered = max((n for t, n in statuses if t <= killed_at - BOUND_NS), default=0)
    assert covered > 0, f"no status older than the bound ({BOUND_NS / 1e9:g} s): the test proves nothing"
    assert k >= covered, (f"the bag holds {k} messages, but {covered} were counted by the recorder "
                          f"{BOUND_NS / 1e9:g} s or more before the kill")
    print(f"[crash] published {published}, recovered {k} (as is {len(as_is)}), counted {covered} by the "
          f"bound; first lost published {(killed_at - sent_at[k]) / 1e9 if k < published else 0:.3f} s before the kill")
