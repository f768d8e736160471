"""Hostile requests and messages against the other nodes (world, perception, rob, navigator,
designer) running together: a bad /world/generate or NavigateIrd goal is refused naming the field,
/rob/stop always answers, and malformed messages on the topics the nodes read are logged and
dropped; every node keeps serving and exits cleanly (code 0) at the end."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Path as PathMsg
from std_srvs.srv import Trigger

from ird_msgs.msg import FeatureGrid, ProxyReward, QueryRecord
from ird_ros import conversions as conv
from ird_ros.client import CallStatus, IrdClient, NavigationGoal, NavigationStatus
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.runtime.guard import MAX_MESSAGE
from ird_ros.testing import NodeProcess, running_nodes

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
WORLD = ["-p", "condition:=side_effects", "-p", "height:=5", "-p", "width:=5", "-p", "horizon:=4"]


def _node(module: str, *extra: str) -> list[str]:
    return ["-m", f"ird_ros.nodes.{module}", "--ros-args", "--params-file", PARAMS, *extra]


@pytest.fixture(scope="module")
def procs(ros_domain: DomainLease) -> Iterator[dict[str, NodeProcess]]:
    nodes = [("world", _node("world", *WORLD)), ("perception", _node("perception")), ("rob", _node("rob")),
             ("navigator", _node("navigator", "-p", "service_timeout:=2.0")), ("designer", _node("designer"))]
    with running_nodes(ros_domain, *nodes) as started:
        yield {name: proc for (name, _), proc in zip(nodes, started)}


@pytest.fixture(scope="module")
def ird(ros_ctx: Any, procs: dict[str, NodeProcess]) -> Iterator[IrdClient]:
    with IrdClient(context=ros_ctx, node_name="battery_graph_client", processes=list(procs.values())) as client:
        client.wait_ready(30.0, services=(names.SRV_GENERATE, names.SRV_ROB_STOP))
        yield client


def _alive(procs: dict[str, NodeProcess]) -> None:
    assert all(p.alive() for p in procs.values()), [p.describe() for p in procs.values() if not p.alive()]


@pytest.mark.parametrize("condition,seed", [("c" * 100000, 1), ("file", 2), ("\u2620" * 1000, 3)])
def test_hostile_generate_is_refused(condition: str, seed: int, ird: IrdClient, procs: dict[str, NodeProcess]) -> None:
    result = ird.generate_world(condition, seed, timeout=60.0)
    assert result.status is CallStatus.REFUSED and result.field == "condition", result.message
    assert len(result.message) <= MAX_MESSAGE + 40
    assert ird.generate_world("side_effects", seed, timeout=60.0).ok
    _alive(procs)


def test_rob_stop_always_answers(ird: IrdClient, procs: dict[str, NodeProcess]) -> None:
    for _ in range(3):
        answer = ird.call(names.SRV_ROB_STOP, Trigger.Request(), timeout=30.0).response
        assert answer.success and answer.message.startswith(("idle", "stopped")), answer.message
    _alive(procs)


def _publish(ird: IrdClient, msg_type: Any, topic: str, msg: Any, qos: Any) -> None:
    publisher = ird.node.create_publisher(msg_type, topic, qos)
    ird.spin_until(lambda: publisher.get_subscription_count() > 0, timeout=30.0, what=f"subscribers of {topic}")
    publisher.publish(msg)


def test_malformed_messages_are_dropped(ird: IrdClient, procs: dict[str, NodeProcess]) -> None:
    # Rob: a plan with NaN poses and a plan far off the map.
    bad_plan = PathMsg()
    bad_plan.header = conv.make_header(conv.now_stamp(ird.node))
    for x in (math.nan, 1e300):
        pose = PoseStamped()
        pose.pose.position.x = x
        bad_plan.poses.append(pose)
    _publish(ird, PathMsg, names.TOPIC_PLAN, bad_plan, names.latched_qos())
    procs["rob"].wait_for_output("ignoring plan", timeout=30.0)
    # Perception: a test map and a proxy of one generation that perception cannot classify.
    stamp = conv.now_stamp(ird.node)
    grid = conv.feature_grid_to_msg(np.full((3, 3, 3), 7.0, dtype=np.float32), ["a", "b", "c"], stamp=stamp)
    proxy = ProxyReward(condition="latent_raw", seed=1, horizon=0, feature_names=["a"])
    proxy.header.stamp = stamp
    _publish(ird, FeatureGrid, names.TOPIC_TEST_FEATURES, grid, names.latched_qos())
    _publish(ird, ProxyReward, names.TOPIC_PROXY, proxy, names.latched_qos())
    procs["perception"].wait_for_output("cannot perceive the test map", timeout=30.0)
    # Designer: a record whose poses are not numbers and whose features do not fit.
    record = QueryRecord(query_id=1, event="proposed", strategy="info_gain", feature_names=["a"],
                         option_features=[math.inf, 1.0, 2.0])
    record.header.stamp = conv.now_stamp(ird.node)
    record.options = [bad_plan, bad_plan]
    _publish(ird, QueryRecord, names.TOPIC_QUERIES, record, names.history_qos())
    procs["designer"].wait_for_output("query record", timeout=30.0)
    # Every node still serves: a new world is generated and perceived.
    assert ird.generate_world("side_effects", 9, timeout=60.0).ok
    answer = ird.call(names.SRV_ROB_STOP, Trigger.Request(), timeout=30.0).response
    assert answer.success, answer.message
    _alive(procs)


@pytest.mark.parametrize("changes,field", [
    (dict(label="l" * 1000), "label"),
    (dict(method="m" * 100000), "method"),
    (dict(beta=math.nan), "beta"),
    (dict(num_samples=10**9), "num_samples"),
    (dict(mode="sideways"), "mode"),
    (dict(queries=-1), "queries"),
    (dict(method=""), "method"),  # the current posterior: none was published
])
def test_hostile_goals_are_rejected_naming_the_field(changes: dict[str, Any], field: str, ird: IrdClient,
                                                     procs: dict[str, NodeProcess]) -> None:
    result = ird.navigate(NavigationGoal(**changes), timeout=120.0)
    assert result.status is NavigationStatus.REJECTED and result.field == field, result
    assert len(result.message) <= MAX_MESSAGE + 40
    _alive(procs)
