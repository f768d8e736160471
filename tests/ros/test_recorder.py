"""ird_ros.nodes.recorder over real DDS in a private domain.

The recorder runs as its own process (``python -m ird_ros.nodes.recorder``); this test process
publishes (FeatureGrid maps big enough to span several MCAP chunks, a latched TerrainGrid
published before the recorder even started, volatile RobStatus/Odometry streams, and a topic
the recorder must ignore), waits until every reliable message was acknowledged by the
recorder's readers (``wait_for_all_acked``: the messages are in the recorder's process), then
stops it with SIGINT or SIGTERM. The bag must then hold exactly what was published, decode
to equal values, carry the publishers' QoS and the same type hashes as rclpy's.
"""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rclpy.duration import Duration

from ird_ros import conversions as conv
from ird_ros.bags import missions, storage
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import spawn_node_process
from ird_ros.waits import wait_for_subscribers

N_STATUS = 37
N_ODOM = 23
N_MAPS = 4
MAP_SHAPE = (40, 40, 50)  # 80 000 float32 = 320 kB per message: several 1 MiB chunks in all


def _recorder(domain: DomainLease, out: Path, topics: list[str] | None, name: str = "recorder") -> Any:
    args = ["-m", "ird_ros.nodes.recorder", "--ros-args", "-p", f"output_dir:={out}", "-p", "flush_period:=0.2"]
    if topics is not None:
        args += ["-p", "topics:=[" + ",".join(topics) + "]"]
    return spawn_node_process(args, domain=domain, name=name, ready_text="recording")


def _terrain() -> Any:
    classes = np.arange(12 * 9, dtype=np.uint8).reshape(12, 9) % 4
    return conv.terrain_grid_to_msg(classes, ["dirt", "grass", "target", "lava"], resolution=0.5, origin=(1.0, -2.0))


def _publish_and_record(node: Any, domain: DomainLease, tmp: Path, sig: int, topics: list[str] | None) -> tuple[Path, dict, Any]:
    from nav_msgs.msg import Odometry
    from std_msgs.msg import String

    from ird_msgs.msg import FeatureGrid, RobStatus, TerrainGrid

    out = tmp / "bag"
    # Published before the recorder exists: only transient-local durability can bring it in.
    terrain_pub = node.create_publisher(TerrainGrid, names.TOPIC_TERRAIN, names.latched_qos())
    terrain = _terrain()
    terrain_pub.publish(terrain)

    proc = _recorder(domain, out, topics)
    maps_pub = node.create_publisher(FeatureGrid, names.TOPIC_TEST_FEATURES, names.latched_qos())
    status_pub = node.create_publisher(RobStatus, names.TOPIC_ROB_STATUS, names.stream_qos(depth=100))
    odom_pub = node.create_publisher(Odometry, names.TOPIC_ODOM, names.stream_qos(depth=100))
    ignored_pub = node.create_publisher(String, "/not_recorded", names.stream_qos())
    pubs = [terrain_pub, maps_pub, status_pub, odom_pub]
    for pub in pubs:
        wait_for_subscribers(node, pub, processes=[proc], timeout=30.0)
    # with an explicit list the ignored topic gets no subscriber (checked after the run)

    rng = np.random.default_rng(7)
    maps = [rng.normal(size=MAP_SHAPE).astype(np.float32) for _ in range(N_MAPS)]
    layers = [f"f{k}" for k in range(MAP_SHAPE[2])]
    for arr in maps:
        maps_pub.publish(conv.feature_grid_to_msg(arr, layers))
        # latched = keep last 1 at the writer: a newer map may replace one not yet delivered
        assert maps_pub.wait_for_all_acked(Duration(seconds=30))
    statuses = []
    for i in range(N_STATUS):
        msg = RobStatus(row=i % 5, col=i % 7, terrain="dirt", step=i, horizon=N_STATUS - 1, done=i == N_STATUS - 1,
                        touched_lava=i > 20, reached_target=i > 30, true_return=0.1 * i - 3.0, plan_label="literal")
        statuses.append(msg)
        status_pub.publish(msg)
    for i in range(N_ODOM):
        msg = Odometry()
        msg.header.frame_id = "map"
        msg.pose.pose.position.x = 0.25 * i
        msg.pose.pose.position.y = -0.5 * i
        odom_pub.publish(msg)
        ignored_pub.publish(String(data=str(i)))
    for pub in pubs:
        assert pub.wait_for_all_acked(Duration(seconds=30)), f"{pub.topic_name}: not acknowledged"
    ignored_subscribers = ignored_pub.get_subscription_count()

    proc.proc.send_signal(sig)
    assert proc.proc.wait(timeout=15) == 0, proc.describe()
    proc.stop()
    for pub in pubs + [ignored_pub]:
        node.destroy_publisher(pub)
    expected = {"terrain": terrain, "maps": maps, "statuses": statuses, "ignored_subscribers": ignored_subscribers}
    return out, expected, proc


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_bag_holds_exactly_what_was_published(sig: int, ros_node: Any, ros_domain: DomainLease, tmp_path: Path) -> None:
    topics = [names.TOPIC_TERRAIN, names.TOPIC_TEST_FEATURES, names.TOPIC_ROB_STATUS, names.TOPIC_ODOM]
    out, exp, proc = _publish_and_record(ros_node, ros_domain, tmp_path, sig, topics)
    assert exp["ignored_subscribers"] == 0

    assert (out / "metadata.yaml").is_file()
    summary = {t.topic: t for t in storage.summarize(out)}
    assert {t: s.count for t, s in summary.items()} == {
        names.TOPIC_TERRAIN: 1, names.TOPIC_TEST_FEATURES: N_MAPS, names.TOPIC_ROB_STATUS: N_STATUS, names.TOPIC_ODOM: N_ODOM,
    }
    assert summary[names.TOPIC_TERRAIN].msgtype == "ird_msgs/msg/TerrainGrid"
    assert summary[names.TOPIC_TERRAIN].durability == "transient_local"
    assert summary[names.TOPIC_ROB_STATUS].durability == "volatile"
    # the log says how many messages each topic got
    assert f"{names.TOPIC_ROB_STATUS}" in proc.output() and str(N_STATUS) in proc.output()

    msgs = storage.read_messages(out)  # types from the repository's .msg files
    terrain = missions.terrain_from_msg(msgs[names.TOPIC_TERRAIN][0].msg)
    np.testing.assert_array_equal(terrain.classes.ravel(), np.asarray(exp["terrain"].classes))
    assert terrain.resolution == 0.5 and terrain.origin == (1.0, -2.0)
    for got, arr in zip(msgs[names.TOPIC_TEST_FEATURES], exp["maps"]):
        np.testing.assert_array_equal(np.asarray(got.msg.data, dtype=np.float32).reshape(MAP_SHAPE), arr)
    for got, sent in zip(msgs[names.TOPIC_ROB_STATUS], exp["statuses"]):
        m = got.msg
        assert (m.row, m.col, m.step, m.done, m.touched_lava, m.reached_target, m.plan_label) == (
            sent.row, sent.col, sent.step, sent.done, sent.touched_lava, sent.reached_target, sent.plan_label)
        assert m.true_return == sent.true_return
    xs = [missions.odom_xy(o.msg) for o in msgs[names.TOPIC_ODOM]]
    assert xs == [(0.25 * i, -0.5 * i) for i in range(N_ODOM)]
    times = [m.timestamp for m in msgs[names.TOPIC_ROB_STATUS]]
    assert times == sorted(times)


def test_type_hashes_match_rclpy(ros_node: Any, ros_domain: DomainLease, tmp_path: Path) -> None:
    """The bag's RIHS01 hashes equal the ones rosidl generated for the installed types."""
    from rosbags.rosbag2 import Reader

    out, _exp, _proc = _publish_and_record(ros_node, ros_domain, tmp_path, signal.SIGINT, None)  # all topics
    share = Path(sys.prefix) / "share"
    with Reader(out) as reader:
        conns = {c.topic: c for c in reader.connections}
    assert "/not_recorded" in conns  # all-topics mode records it too
    assert "/rosout" not in conns
    for topic in (names.TOPIC_TERRAIN, names.TOPIC_ROB_STATUS, names.TOPIC_TEST_FEATURES):
        pkg, _msg, name = conns[topic].msgtype.split("/")
        desc = json.loads((share / pkg / "msg" / f"{name}.json").read_text())
        assert conns[topic].digest == desc["type_hashes"][0]["hash_string"]


def test_existing_output_dir_is_refused(ros_domain: DomainLease, tmp_path: Path) -> None:
    out = tmp_path / "exists"
    out.mkdir()
    (out / "keep.txt").write_text("precious")
    proc = spawn_node_process(["-m", "ird_ros.nodes.recorder", "--ros-args", "-p", f"output_dir:={out}"],
                              domain=ros_domain, name="recorder-refuse")
    assert proc.proc.wait(timeout=30) == 2
    proc.stop()
    assert "already exists" in proc.output() and str(out) in proc.output()
    assert sorted(os.listdir(out)) == ["keep.txt"]


def test_a_failed_configure_under_a_lifecycle_manager_ends_cleanly(ros_node: Any, ros_domain: DomainLease,
                                                                    tmp_path: Path) -> None:
    """As the launcher runs it (autostart off): a configure that cannot make the bag's folder is
    refused naming output_dir, and the stop that follows ends without a traceback or a bag summary."""
    from lifecycle_msgs.msg import Transition
    from lifecycle_msgs.srv import ChangeState

    from ird_ros.waits import call_service

    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    out = blocker / "bag"
    proc = spawn_node_process(["-m", "ird_ros.nodes.recorder", "--ros-args", "-p", f"output_dir:={out}",
                               "-p", "autostart:=false"], domain=ros_domain, name="recorder-unmade")
    client = ros_node.create_client(ChangeState, "/recorder/change_state")
    try:
        configure = ChangeState.Request(transition=Transition(id=Transition.TRANSITION_CONFIGURE))
        answer = call_service(ros_node, client, configure, timeout=30.0, processes=[proc])
        assert not answer.success
    finally:
        ros_node.destroy_client(client)
        code = proc.stop()
    output = proc.output()
    assert code == 0, output
    assert f"output_dir {out}: cannot make its folder" in output, output
    assert "Traceback" not in output and "messages on" not in output, output
    assert blocker.read_text() == "kept"

def test_missing_output_dir_is_an_error(ros_domain: DomainLease) -> None:
    proc = spawn_node_process(["-m", "ird_ros.nodes.recorder"], domain=ros_domain, name="recorder-noout")
    assert proc.proc.wait(timeout=30) == 2
    proc.stop()
    assert "output_dir is required" in proc.output()


def test_stamp_placeholder_makes_a_fresh_folder(ros_node: Any, ros_domain: DomainLease, tmp_path: Path) -> None:
    proc = _recorder(ros_domain, Path(str(tmp_path / "runs" / "bag_{stamp}")), [names.TOPIC_ODOM], name="recorder-stamp")
    proc.proc.send_signal(signal.SIGINT)
    assert proc.proc.wait(timeout=15) == 0, proc.describe()
    proc.stop()
    (bag,) = (tmp_path / "runs").iterdir()
    assert bag.name.startswith("bag_2") and (bag / "metadata.yaml").is_file()
    assert storage.summarize(bag) == []
