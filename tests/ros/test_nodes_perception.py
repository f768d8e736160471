"""The perception node over real DDS, fed by a real world node, for every condition."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest

from ird_core import lavaland
from ird_core.terrain import Terrain
from ird_msgs.msg import FeatureGrid, ProxyReward, TerrainGrid
from ird_msgs.srv import GenerateWorld
from ird_ros import conversions as conv
from ird_ros import names
from ird_ros.testing import DomainLease, NodeProcess, call_service, spawn_node_process, spin_until, wait_for_service

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
H, W, T, OBS = 8, 9, 10, 10
SEED = 21


@pytest.fixture(scope="module")
def graph(ros_domain: DomainLease) -> Iterator[list[NodeProcess]]:
    world_args = ["-m", "ird_ros.world", "--ros-args", "--params-file", PARAMS, "-p", "condition:=side_effects",
                  "-p", f"seed:={SEED}", "-p", f"height:={H}", "-p", f"width:={W}", "-p", f"horizon:={T}",
                  "-p", f"obs_dim:={OBS}"]
    perception_args = ["-m", "ird_ros.perception", "--ros-args", "--params-file", PARAMS]
    with spawn_node_process(world_args, domain=ros_domain, name="world", ready_text="world ready") as world, \
            spawn_node_process(perception_args, domain=ros_domain, name="perception",
                               ready_text="perception ready") as perception:
        yield [world, perception]
    assert world.returncode == 0, world.describe()
    assert perception.returncode == 0, perception.describe()


def perceive(node: Any, graph: list[NodeProcess], condition: str, seed: int) -> tuple[Any, Any]:
    """Generate a world and return perception's (/terrain/classes, /terrain/features) for it."""
    client = node.create_client(GenerateWorld, names.SRV_GENERATE)
    wait_for_service(node, client, processes=graph)
    response = call_service(node, client, GenerateWorld.Request(condition=condition, seed=seed), processes=graph)
    node.destroy_client(client)
    assert response.success, response.message
    proxies: list[ProxyReward] = []
    classes: list[TerrainGrid] = []
    features: list[FeatureGrid] = []
    qos = names.latched_qos()
    subs = [node.create_subscription(ProxyReward, names.TOPIC_PROXY, proxies.append, qos),
            node.create_subscription(TerrainGrid, names.TOPIC_TERRAIN_CLASSES, classes.append, qos),
            node.create_subscription(FeatureGrid, names.TOPIC_TERRAIN_FEATURES, features.append, qos)]

    def arrived() -> bool:
        if not proxies or (proxies[-1].condition, proxies[-1].seed) != (condition, seed):
            return False
        stamp = proxies[-1].header.stamp
        return (any(m.header.stamp == stamp for m in classes) and any(m.header.stamp == stamp for m in features))

    try:
        spin_until(node, arrived, timeout=30.0, what=f"perception of {condition}", processes=graph)
    finally:
        for sub in subs:
            node.destroy_subscription(sub)
    stamp = proxies[-1].header.stamp
    return (next(m for m in reversed(classes) if m.header.stamp == stamp),
            next(m for m in reversed(features) if m.header.stamp == stamp))


@pytest.mark.parametrize("condition", lavaland.CONDITIONS)
def test_perception(condition: str, ros_node: Any, graph: list[NodeProcess]) -> None:
    classes_msg, features_msg = perceive(ros_node, graph, condition, SEED)
    inst = lavaland.make_instance(condition, SEED, size=(H, W), horizon=T, obs_dim=OBS)
    grid = conv.terrain_grid_from_msg(classes_msg)
    features = conv.feature_grid_from_msg(features_msg)
    lava = inst.test_labels == Terrain.LAVA
    assert lava.any(), "the test map should contain lava for this test to mean something"
    assert grid.classes.shape == (H, W) and grid.novelty.shape == (H, W)
    assert grid.probabilities.shape == (H, W, len(grid.class_names))

    if condition == "side_effects":
        assert grid.class_names == ("dirt", "grass", "target", "lava")
        assert np.array_equal(grid.classes, inst.test_labels.astype(np.uint8))
        assert np.all(grid.novelty == 0)
    elif condition == "reward_hacking":
        # Lava is unknown to the sensors: they disagree (grass vs target), so the class is unknown.
        assert grid.class_names == ("dirt", "grass", "target")
        assert np.array_equal(grid.classes[~lava], inst.test_labels[~lava].astype(np.uint8))
        assert np.all(grid.classes[lava] == conv.UNKNOWN_CLASS)
        assert np.array_equal(grid.novelty, lava.astype(np.float32))
        assert np.allclose(grid.probabilities[lava], [0.0, 0.5, 0.5])
    else:
        clf = lavaland.make_instance("latent_classifier", SEED, size=(H, W), horizon=T, obs_dim=OBS).classifier
        obs = inst.test_features.astype(np.float32).astype(np.float64)
        assert grid.class_names == ("dirt", "grass", "target")
        assert np.array_equal(grid.classes, clf.predict(obs).astype(np.uint8))
        assert np.allclose(grid.probabilities, clf.predict_proba(obs), atol=1e-6)
        assert np.allclose(grid.novelty, clf.novelty(obs), rtol=1e-5, atol=1e-4)
        # The classifier knows nothing of lava, but lava is far more novel than any safe cell.
        assert grid.novelty[lava].min() > grid.novelty[~lava].max()
        safe_accuracy = np.mean(grid.classes[~lava] == inst.test_labels[~lava])
        assert safe_accuracy > 0.9

    if condition == "latent_classifier":
        assert features.layers == inst.proxy_feature_names
        assert np.allclose(features.features, inst.proxy_test_features, atol=1e-5)
    else:
        assert features.layers == inst.feature_names
        assert np.array_equal(features.features, inst.test_features.astype(np.float32))
    assert features.shape[:2] == (H, W) and grid.frame_id == "map"
