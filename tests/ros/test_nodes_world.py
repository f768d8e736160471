"""The world node over real DDS: every latched topic for every condition, /world/generate, world files."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest
import yaml

from ird_core.worlds import lavaland, world_file
from ird_core.worlds.terrain import TERRAIN_NAMES
from ird_core.worlds.training_worlds import with_training_worlds
from ird_msgs.msg import ProxyReward
from ird_ros import conversions as conv
from ird_ros.client import CallResult, CallStatus, IrdClient
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease, lease_domain
from ird_ros.testing import NodeProcess, spawn_node_process
from ird_ros.waits import call_service, spin_until, wait_for_service

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
H, W, T, OBS = 6, 7, 8, 12


def world_args(condition: str = "side_effects", seed: int = 3) -> list[str]:
    return ["-m", "ird_ros.nodes.world", "--ros-args", "--params-file", PARAMS,
            "-p", f"condition:={condition}", "-p", f"seed:={seed}", "-p", f"height:={H}", "-p", f"width:={W}",
            "-p", f"horizon:={T}", "-p", f"obs_dim:={OBS}", "-p", "resolution:=0.5"]


@pytest.fixture(scope="module")
def world(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    with spawn_node_process(world_args(), domain=ros_domain, name="world", ready_text="world ready") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()


class Probe:
    """An IrdClient with latched subscriptions to every world topic, module-wide (creating them
    per test would pay DDS discovery every time)."""

    TOPICS = (names.TOPIC_PROXY, names.TOPIC_TRAIN_FEATURES, names.TOPIC_TEST_FEATURES,
              names.TOPIC_TRAIN_PROXY_FEATURES, names.TOPIC_TERRAIN)

    def __init__(self, ird: IrdClient, world: NodeProcess) -> None:
        self.ird, self.node, self.world = ird, ird.node, world
        ird.subscribe(*self.TOPICS)
        self.received: dict[str, list[Any]] = {topic: ird.received(topic) for topic in self.TOPICS}
        ird.wait_ready(20.0, services=(names.SRV_GENERATE,))

    def generate(self, condition: str, seed: int) -> CallResult[str]:
        return self.ird.generate_world(condition, seed, timeout=30.0)

    def latest_proxy(self) -> ProxyReward:
        spin_until(self.node, lambda: bool(self.received[names.TOPIC_PROXY]), timeout=20.0, what="/world/proxy",
                   processes=[self.world])
        return self.received[names.TOPIC_PROXY][-1]

    def mark(self) -> int:
        """A point in the received proxies, for :meth:`messages` ``since``."""
        return len(self.received[names.TOPIC_PROXY])

    def messages(self, condition: str, seed: int, since: int = 0) -> dict[str, Any]:
        """The latched messages of the generation (condition, seed), all with the proxy's stamp;
        with ``since`` (a :meth:`mark`), only a generation received after that mark (the service
        answers before its publications arrive, so an earlier one would otherwise match)."""
        proxies = self.received[names.TOPIC_PROXY]
        out: dict[str, Any] = {}

        def complete() -> bool:
            matching = [p for p in proxies[since:] if (p.condition, p.seed) == (condition, seed)]
            if not matching:
                return False
            stamp = matching[-1].header.stamp
            out.clear()
            for topic, msgs in self.received.items():
                found = [m for m in msgs if m.header.stamp == stamp]
                if not found:
                    return False
                out[topic] = found[-1]
            return True

        spin_until(self.node, complete, timeout=20.0, what=f"the world {condition}/{seed}", processes=[self.world])
        return out


@pytest.fixture(scope="module")
def probe(ros_ctx: Any, world: NodeProcess) -> Iterator[Probe]:
    with IrdClient(context=ros_ctx, node_name="world_probe", processes=[world]) as ird:
        yield Probe(ird, world)


@pytest.mark.parametrize("condition", lavaland.CONDITIONS)
def test_every_topic_for_every_condition(condition: str, probe: Probe) -> None:
    seed = 11
    response = probe.generate(condition, seed)
    assert response.ok, response.message
    msgs = probe.messages(condition, seed)
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


def test_generate_changes_the_maps(probe: Probe, world: NodeProcess) -> None:
    ros_node = probe.node
    mark = probe.mark()  # since marks: another test may have published the same generation earlier
    first = probe.generate("latent_raw", 1)
    assert first.ok, first.message
    a = probe.messages("latent_raw", 1, since=mark)
    mark = probe.mark()
    second = probe.generate("", 2)  # empty condition: keep latent_raw
    assert second.ok, second.message
    b = probe.messages("latent_raw", 2, since=mark)
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


def test_generate_publishes_one_generation(probe: Probe) -> None:
    """/world/generate that changes condition and seed publishes that world once: setting the
    parameters to it afterwards must not publish the half-changed pair in between."""
    before = probe.mark()  # an earlier test published latent_raw/1 too: wait for this test's own
    assert probe.generate("latent_raw", 1).ok
    probe.messages("latent_raw", 1, since=before)
    mark = probe.mark()
    assert probe.generate("reward_hacking", 5).ok
    assert probe.generate("side_effects", 7).ok
    probe.messages("side_effects", 7, since=mark)  # one publisher, in order: everything before is in
    got = [(p.condition, p.seed) for p in probe.received[names.TOPIC_PROXY][mark:]]
    assert got == [("reward_hacking", 5), ("side_effects", 7)]


def test_bad_condition_is_rejected(probe: Probe, ros_node: Any, world: NodeProcess) -> None:
    mark = probe.mark()  # test_generate_publishes_one_generation published reward_hacking/5 too
    ok = probe.generate("reward_hacking", 5)
    assert ok.ok, ok.message
    before = probe.messages("reward_hacking", 5, since=mark)[names.TOPIC_PROXY]
    for bad in ("lava_land", "SIDE_EFFECTS", " side_effects", "x" * 300):
        response = probe.generate(bad, 6)
        assert not response.ok, bad
        assert response.status is CallStatus.REFUSED and response.field == "condition", response
        assert response.message.startswith("condition:"), response.message
    # Nothing was republished: a fresh subscriber gets the previous generation's latched proxy.
    fresh: list[ProxyReward] = []
    sub = ros_node.create_subscription(ProxyReward, names.TOPIC_PROXY, fresh.append, names.latched_qos())
    spin_until(ros_node, lambda: bool(fresh), timeout=20.0, what="/world/proxy", processes=[world])
    ros_node.destroy_subscription(sub)
    assert (fresh[-1].condition, fresh[-1].seed, fresh[-1].header.stamp) == ("reward_hacking", 5, before.header.stamp)
    # ... and the node keeps serving.
    assert probe.generate("side_effects", 7).ok


def test_bad_startup_parameter_exits_2(ros_domain: DomainLease) -> None:
    proc = spawn_node_process(world_args(condition="no_such_condition"), domain=ros_domain, name="bad_world")
    try:
        proc.wait_for_output("cannot start", timeout=30.0)
        assert proc.proc.wait(timeout=30.0) == 2, proc.describe()
        assert "condition" in proc.output()
    finally:
        proc.stop()


def test_bad_world_file_fails_at_start_naming_file_and_key(ros_domain: DomainLease, tmp_path: Path) -> None:
    good = yaml.safe_load((ROOT / "worlds" / "figure1.yaml").read_text())
    good["test_world"]["horizon"] = 0
    for image in ("figure1_train.png", "figure1_test.png"):
        (tmp_path / image).write_bytes((ROOT / "worlds" / image).read_bytes())
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(good))
    proc = spawn_node_process(world_args() + ["-p", f"world_file:={bad}"], domain=ros_domain, name="bad_file")
    try:
        proc.wait_for_output("cannot start", timeout=30.0)
        assert proc.proc.wait(timeout=30.0) == 2, proc.describe()
        assert f"{bad}: test_world.horizon:" in proc.output() and "world ready" not in proc.output()
    finally:
        proc.stop()


def test_world_file_is_published_with_every_training_world() -> None:
    """two_training_worlds.yaml: the file's maps and geometry; /world/infer_request carries the
    second training world; /world/generate replaces the file world and "file" brings it back.
    A domain of its own: the module's world node publishes the same topics."""
    wf = world_file.load_world_file(ROOT / "worlds" / "two_training_worlds.yaml")
    inst = wf.instance
    args = world_args() + ["-p", f"world_file:={wf.path}"]
    with lease_domain() as lease, \
            spawn_node_process(args, domain=lease, name="file_world", ready_text="world ready") as proc, \
            IrdClient(lease.domain_id, node_name="file_world_probe", processes=[proc]) as ird:
        probe = Probe(ird, proc)
        requests = ird.received(names.TOPIC_INFER_REQUEST)
        msgs = probe.messages(lavaland.FILE_CONDITION, inst.seed)
        ird.world_infer_request(timeout=20.0)
        train = conv.feature_grid_from_msg(msgs[names.TOPIC_TRAIN_FEATURES])
        assert np.array_equal(train.features, inst.train_features.astype(np.float32))
        assert train.resolution == wf.resolution and train.origin == wf.origin[:2]
        terrain = conv.terrain_grid_from_msg(msgs[names.TOPIC_TERRAIN])
        assert terrain.class_names == inst.terrain_names
        assert np.array_equal(terrain.classes, inst.test_labels.astype(np.uint8))
        req = requests[-1]
        assert req.training_map.header.stamp == msgs[names.TOPIC_PROXY].header.stamp
        (extra,) = inst.extra_training_worlds
        (sent,) = req.training_worlds
        assert np.array_equal(conv.feature_grid_from_msg(sent.training_map).features,
                              extra.features.astype(np.float32))
        assert (sent.start_row, sent.start_col, sent.horizon) == (*extra.start, extra.horizon)
        assert np.array_equal(np.asarray(sent.proxy_weights), extra.proxy_weights)
        assert not sent.proxy_map.layers  # the proxy is on the hypothesis features

        assert probe.generate("side_effects", 4).ok
        assert probe.messages("side_effects", 4)[names.TOPIC_TERRAIN].class_names == list(TERRAIN_NAMES)
        mark = probe.mark()
        again = probe.generate(lavaland.FILE_CONDITION, 0)
        assert again.ok, again.message
        back = probe.messages(lavaland.FILE_CONDITION, inst.seed, since=mark)
        assert back[names.TOPIC_PROXY].header.stamp != msgs[names.TOPIC_PROXY].header.stamp


def test_generated_training_worlds_travel_in_the_infer_request() -> None:
    """``training_worlds:=3``: /world/train_features is the one-world instance's first map, and
    /world/infer_request carries the two extra worlds of ``with_training_worlds`` (latent_classifier:
    each with its classifier map as the proxy map). A domain of its own, like the file test."""
    inst = with_training_worlds(lavaland.make_instance("latent_classifier", 5, size=(H, W), horizon=T, obs_dim=OBS), 3)
    args = world_args("latent_classifier", 5) + ["-p", "training_worlds:=3"]
    with lease_domain() as lease, \
            spawn_node_process(args, domain=lease, name="worlds3", ready_text="world ready") as proc, \
            IrdClient(lease.domain_id, node_name="worlds3_probe", processes=[proc]) as ird:
        probe = Probe(ird, proc)
        requests = ird.received(names.TOPIC_INFER_REQUEST)
        msgs = probe.messages("latent_classifier", 5)
        ird.world_infer_request(timeout=20.0)
        train = conv.feature_grid_from_msg(msgs[names.TOPIC_TRAIN_FEATURES])
        assert np.array_equal(train.features, inst.train_features.astype(np.float32))
        sent = requests[-1].training_worlds
        assert len(sent) == 2
        for world, extra in zip(sent, inst.extra_training_worlds):
            assert np.array_equal(conv.feature_grid_from_msg(world.training_map).features,
                                  extra.features.astype(np.float32))
            assert np.array_equal(conv.feature_grid_from_msg(world.proxy_map).features,
                                  extra.proxy_features.astype(np.float32))
            assert (world.start_row, world.start_col, world.horizon) == (*extra.start, extra.horizon)


def test_generate_file_without_a_world_file_is_rejected(probe: Probe) -> None:
    response = probe.generate(lavaland.FILE_CONDITION, 0)
    assert response.status is CallStatus.REFUSED and response.message.startswith("condition:"), response.message
