"""The perception node over real DDS, fed by a real world node, for every condition."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest

from ird_core.worlds import lavaland
from ird_core.worlds.terrain import Terrain
from ird_msgs.msg import FeatureGrid, ProxyReward, TerrainGrid
from ird_ros import conversions as conv
from ird_ros.client import IrdClient
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess
from ird_ros.testing import running_nodes as running
from ird_ros.waits import spin_until

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
H, W, T, OBS = 8, 9, 10, 10
SEED = 21


@pytest.fixture(scope="module")
def graph(ros_domain: DomainLease) -> Iterator[list[NodeProcess]]:
    world_args = ["-m", "ird_ros.nodes.world", "--ros-args", "--params-file", PARAMS, "-p", "condition:=side_effects",
                  "-p", f"seed:={SEED}", "-p", f"height:={H}", "-p", f"width:={W}", "-p", f"horizon:={T}",
                  "-p", f"obs_dim:={OBS}"]
    perception_args = ["-m", "ird_ros.nodes.perception", "--ros-args", "--params-file", PARAMS]
    with running(ros_domain, ("world", world_args), ("perception", perception_args)) as procs:
        yield procs


class Probe:
    """A module-wide IrdClient with latched subscriptions to the proxy and perception's outputs
    (created once: DDS discovery is paid once)."""

    def __init__(self, ird: IrdClient, graph: list[NodeProcess]) -> None:
        self.ird, self.node, self.graph = ird, ird.node, graph
        ird.subscribe(names.TOPIC_PROXY, names.TOPIC_TERRAIN_CLASSES, names.TOPIC_TERRAIN_FEATURES)
        self.proxies: list[ProxyReward] = ird.received(names.TOPIC_PROXY)
        self.classes: list[TerrainGrid] = ird.received(names.TOPIC_TERRAIN_CLASSES)
        self.features: list[FeatureGrid] = ird.received(names.TOPIC_TERRAIN_FEATURES)
        ird.wait_ready(20.0, services=(names.SRV_GENERATE,))

    def perceive(self, condition: str, seed: int) -> tuple[TerrainGrid, FeatureGrid]:
        """Generate a world; return perception's (/terrain/classes, /terrain/features) of it."""
        response = self.ird.generate_world(condition, seed, timeout=30.0)
        assert response.ok, response.message
        found: list[Any] = []

        def arrived() -> bool:
            matching = [p for p in self.proxies if (p.condition, p.seed) == (condition, seed)]
            if not matching:
                return False
            stamp = matching[-1].header.stamp
            classes = [m for m in self.classes if m.header.stamp == stamp]
            features = [m for m in self.features if m.header.stamp == stamp]
            found[:] = [classes[-1], features[-1]] if classes and features else []
            return bool(found)

        spin_until(self.node, arrived, timeout=30.0, what=f"perception of {condition}", processes=self.graph)
        return found[0], found[1]


@pytest.fixture(scope="module")
def probe(ros_ctx: Any, graph: list[NodeProcess]) -> Iterator[Probe]:
    with IrdClient(context=ros_ctx, node_name="perception_probe", processes=graph) as ird:
        yield Probe(ird, graph)


@pytest.mark.parametrize("condition", lavaland.CONDITIONS)
def test_perception(condition: str, probe: Probe) -> None:
    classes_msg, features_msg = probe.perceive(condition, SEED)
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
