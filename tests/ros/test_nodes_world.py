"""The world node over real DDS: every latched topic for every condition, /world/generate."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest

from ird_core import lavaland
from ird_core.terrain import TERRAIN_NAMES
from ird_msgs.msg import FeatureGrid, ProxyReward, TerrainGrid
from ird_msgs.srv import GenerateWorld
from ird_ros import conversions as conv
from ird_ros import names
from ird_ros.testing import DomainLease, NodeProcess, call_service, spawn_node_process, spin_until, wait_for_service

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
H, W, T, OBS = 6, 7, 8, 12


def world_args(condition: str = "side_effects", seed: int = 3) -> list[str]:
    return ["-m", "ird_ros.world", "--ros-args", "--params-file", PARAMS,
            "-p", f"condition:={condition}", "-p", f"seed:={seed}", "-p", f"height:={H}", "-p", f"width:={W}",
            "-p", f"horizon:={T}", "-p", f"obs_dim:={OBS}", "-p", "resolution:=0.5"]


@pytest.fixture(scope="module")
def world(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    with spawn_node_process(world_args(), domain=ros_domain, name="world", ready_text="world ready") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()


def latest(node: Any, msg_type: Any, topic: str, accept: Any, processes: list, timeout: float = 20.0) -> Any:
    """Subscribe (latched QoS) and spin until a message satisfying ``accept`` arrives."""
    got: list[Any] = []
    sub = node.create_subscription(msg_type, topic, lambda m: got.append(m) if accept(m) else None,
                                   names.latched_qos())
    try:
        spin_until(node, lambda: bool(got), timeout=timeout, what=f"a matching message on {topic}",
                   processes=processes)
    finally:
        node.destroy_subscription(sub)
    return got[-1]


def generate(node: Any, world: NodeProcess, condition: str, seed: int) -> GenerateWorld.Response:
    client = node.create_client(GenerateWorld, names.SRV_GENERATE)
    try:
        wait_for_service(node, client, processes=[world])
        return call_service(node, client, GenerateWorld.Request(condition=condition, seed=seed),
                            processes=[world])
    finally:
        node.destroy_client(client)


def world_messages(node: Any, world: NodeProcess, condition: str, seed: int) -> dict[str, Any]:
    """The latched messages of the generation (condition, seed): the proxy first, then the
    maps with the proxy's stamp."""
    proxy = latest(node, ProxyReward, names.TOPIC_PROXY,
                   lambda m: m.condition == condition and m.seed == seed, [world])
    stamp = (proxy.header.stamp.sec, proxy.header.stamp.nanosec)
    same = lambda m: (m.header.stamp.sec, m.header.stamp.nanosec) == stamp  # noqa: E731
    out = {names.TOPIC_PROXY: proxy}
    for topic, msg_type in ((names.TOPIC_TRAIN_FEATURES, FeatureGrid), (names.TOPIC_TEST_FEATURES, FeatureGrid),
                            (names.TOPIC_TRAIN_PROXY_FEATURES, FeatureGrid), (names.TOPIC_TERRAIN, TerrainGrid)):
        out[topic] = latest(node, msg_type, topic, same, [world])
    return out


@pytest.mark.parametrize("condition", lavaland.CONDITIONS)
def test_every_topic_for_every_condition(condition: str, ros_node: Any, world: NodeProcess) -> None:
    seed = 11
    response = generate(ros_node, world, condition, seed)
    assert response.success, response.message
    msgs = world_messages(ros_node, world, condition, seed)
    inst = lavaland.make_instance(condition, seed, size=(H, W), horizon=T, obs_dim=OBS)

    for topic, values, layers in (
        (names.TOPIC_TRAIN_FEATURES, inst.train_features, inst.feature_names),
        (names.TOPIC_TEST_FEATURES, inst.test_features, inst.feature_names),
        (names.TOPIC_TRAIN_PROXY_FEATURES, inst.proxy_train_features, inst.proxy_feature_names),
    ):
        grid = conv.feature_grid_from_msg(msgs[topic])
        assert grid.shape == (H, W, len(layers)), topic
        assert grid.layers == layers, topic
        assert np.array_equal(grid.features, values.astype(np.float32)), topic
        assert grid.resolution == 0.5 and grid.origin == (0.0, 0.0) and grid.frame_id == "map"

    terrain = conv.terrain_grid_from_msg(msgs[names.TOPIC_TERRAIN])
    assert terrain.class_names == TERRAIN_NAMES
    assert np.array_equal(terrain.classes, inst.test_labels.astype(np.uint8))
    assert np.array_equal(terrain.probabilities.argmax(axis=-1), inst.test_labels)
    assert np.array_equal(terrain.probabilities.sum(axis=-1), np.ones((H, W), np.float32))

    proxy = msgs[names.TOPIC_PROXY]
    assert proxy.condition == condition and proxy.seed == seed
    assert tuple(proxy.feature_names) == inst.proxy_feature_names
    assert np.array_equal(np.asarray(proxy.weights), inst.proxy_weights)
    assert (proxy.start_row, proxy.start_col, proxy.horizon) == (*inst.train_start, inst.train_horizon)
    assert (proxy.test_start_row, proxy.test_start_col, proxy.test_horizon) == (*inst.test_start, inst.test_horizon)
    assert tuple(proxy.terrain_names) == TERRAIN_NAMES
    assert np.array_equal(np.asarray(proxy.true_terrain_rewards), lavaland.TRUE_TERRAIN_REWARD)
    if condition == "latent_classifier":
        assert inst.proxy_feature_names == ("clf_dirt", "clf_grass", "clf_target")
    else:
        assert inst.proxy_feature_names == inst.feature_names


def test_generate_changes_the_maps(ros_node: Any, world: NodeProcess) -> None:
    first = generate(ros_node, world, "latent_raw", 1)
    assert first.success, first.message
    a = world_messages(ros_node, world, "latent_raw", 1)
    second = generate(ros_node, world, "", 2)  # empty condition: keep latent_raw
    assert second.success, second.message
    b = world_messages(ros_node, world, "latent_raw", 2)
    for topic in (names.TOPIC_TRAIN_FEATURES, names.TOPIC_TEST_FEATURES):
        fa, fb = (conv.feature_grid_from_msg(m[topic]).features for m in (a, b))
        assert fa.shape == fb.shape and not np.array_equal(fa, fb), topic
    assert b[names.TOPIC_PROXY].header.stamp != a[names.TOPIC_PROXY].header.stamp
    # The condition / seed parameters follow the world that is published.
    from rcl_interfaces.srv import GetParameters

    client = ros_node.create_client(GetParameters, "/world/get_parameters")
    wait_for_service(ros_node, client, processes=[world])
    values = call_service(ros_node, client, GetParameters.Request(names=["condition", "seed"]),
                          processes=[world]).values
    assert (values[0].string_value, values[1].integer_value) == ("latent_raw", 2)


@pytest.mark.parametrize("bad", ["lava_land", "SIDE_EFFECTS", " side_effects", "x" * 300])
def test_bad_condition_is_rejected(bad: str, ros_node: Any, world: NodeProcess) -> None:
    ok = generate(ros_node, world, "reward_hacking", 5)
    assert ok.success, ok.message
    before = world_messages(ros_node, world, "reward_hacking", 5)
    response = generate(ros_node, world, bad, 6)
    assert not response.success
    assert response.message.startswith("condition:"), response.message
    # Nothing was republished: the latched proxy is still the previous generation.
    after = latest(ros_node, ProxyReward, names.TOPIC_PROXY, lambda m: True, [world])
    assert (after.condition, after.seed, after.header.stamp) == ("reward_hacking", 5, before[names.TOPIC_PROXY].header.stamp)
    # ... and the node keeps serving.
    assert generate(ros_node, world, "side_effects", 7).success


def test_bad_startup_parameter_exits_2(ros_domain: DomainLease) -> None:
    proc = spawn_node_process(world_args(condition="no_such_condition"), domain=ros_domain, name="bad_world")
    try:
        proc.wait_for_output("cannot start", timeout=30.0)
        assert proc.proc.wait(timeout=30.0) == 2, proc.describe()
        assert "condition" in proc.output()
    finally:
        proc.stop()
