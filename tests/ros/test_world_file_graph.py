"""The whole graph launched with a shipped world file (worlds/figure1.yaml), over real DDS.

The world node publishes the file's maps (not a generated Lavaland); the /ird/infer request
the world poses (/world/infer_request) gives the joint posterior over its training worlds; the
IRD per_step plan equals ird_core's plan_path on the published test map; Rob drives it, and
the executed path never touches the file's lava (the shortcut the designer never saw).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

from ird_core import planning, posterior
from ird_core.mdp import GridMDP
from ird_core.worlds import evaluation, lavaland, world_file
from ird_core.worlds.terrain import Terrain

REPO = Path(__file__).resolve().parents[2]
WORLD = REPO / "worlds" / "figure1.yaml"


@pytest.fixture(scope="module")
def mission(tmp_path_factory: pytest.TempPathFactory) -> dict:
    from _mission import drive_ird_plan

    from ird_ros.client import IrdClient
    from ird_ros.graph import NODES, names
    from ird_ros.launch import GraphLauncher
    from ird_ros.nodes.world import with_world_file

    tmp = tmp_path_factory.mktemp("world_file")
    params = yaml.safe_load((REPO / "msgs_config/params/graph.yaml").read_text())
    params["rob"]["ros__parameters"]["rate_hz"] = 50.0
    params_file = tmp / "graph.yaml"
    params_file.write_text(yaml.safe_dump(params))
    out: dict = {"wf": world_file.load_world_file(WORLD)}
    specs = with_world_file(NODES, WORLD)
    with GraphLauncher(specs=specs, params=params_file, private_domain=True, output="quiet",
                       log_dir=tmp / "logs") as graph:
        graph.wait_ready(timeout=120)
        with IrdClient(graph.domain_id, node_name="world_file_client") as ird:
            ird.watch_rob(timeout=60)
            proxy = ird.proxy(timeout=60)
            out["proxy"] = proxy
            for key, topic in (("train", names.TOPIC_TRAIN_FEATURES), ("test", names.TOPIC_TEST_FEATURES),
                               ("terrain", names.TOPIC_TERRAIN), ("classes", names.TOPIC_TERRAIN_CLASSES)):
                out[key] = ird.latest(topic, timeout=60)
            req = ird.world_infer_request(timeout=60)
            out["request"] = req
            req.beta, req.method, req.num_samples, req.seed = 5.0, "maxent_z", 40, 11
            # The unit-temperature designer with a unit prior: with the calibrated default
            # (temperature 0.2, sigma 5) this world's IRD plan crosses one lava cell to reach the
            # target sooner (docs/limits.md, "The calibrated designer on hand-drawn worlds").
            req.designer_temperature, req.prior_sigma = 1.0, 1.0
            result = ird.infer(req, timeout=300)
            assert result.ok, result.message
            out["posterior"] = result.unwrap()
            # The planner holds the posterior and the test map once its risk map is out.
            ird.risk_map(timeout=60)

            inst = out["wf"].instance
            reference = posterior.proxy_feature_expectations(inst, posterior.MAXENT_OBSERVATION_MODEL) / (
                inst.train_horizon + 1)
            out.update(drive_ird_plan(ird, proxy, out["posterior"].samples, reference))
            out["reference"] = reference
    return out


def test_world_publishes_the_files_maps(mission: dict) -> None:
    from ird_ros import conversions as conv

    wf = mission["wf"]
    inst = wf.instance
    proxy = mission["proxy"]
    assert proxy.condition == lavaland.FILE_CONDITION and proxy.seed == inst.seed
    for key, values in (("train", inst.train_features), ("test", inst.test_features)):
        grid = conv.feature_grid_from_msg(mission[key])
        assert grid.layers == inst.feature_names == ("dirt", "grass", "target", "lava")
        assert np.array_equal(grid.features, values.astype(np.float32)), key
        assert grid.resolution == wf.resolution and grid.origin == wf.origin[:2]
    terrain = conv.terrain_grid_from_msg(mission["terrain"])
    assert terrain.class_names == inst.terrain_names
    assert np.array_equal(terrain.classes, inst.test_labels.astype(np.uint8))
    assert np.any(inst.test_labels == Terrain.LAVA) and not np.any(inst.train_labels == Terrain.LAVA)
    assert tuple(proxy.terrain_names) == inst.terrain_names
    assert np.array_equal(np.asarray(proxy.true_terrain_rewards), inst.true_terrain_reward)
    assert np.array_equal(np.asarray(proxy.weights), inst.proxy_weights)
    assert (proxy.start_row, proxy.start_col, proxy.horizon) == (*inst.train_start, inst.train_horizon)
    assert (proxy.test_start_row, proxy.test_start_col, proxy.test_horizon) == (*inst.test_start, inst.test_horizon)
    req = mission["request"]
    assert np.array_equal(conv.feature_grid_from_msg(req.training_map).features, inst.train_features.astype(np.float32))
    assert (req.start_row, req.start_col, req.horizon) == (*inst.train_start, inst.train_horizon)
    assert len(req.training_worlds) == len(inst.extra_training_worlds) == 0
    # Perception on indicator features: the layers are the classes.
    classes = conv.terrain_grid_from_msg(mission["classes"])
    assert classes.class_names == inst.feature_names
    assert np.array_equal(classes.classes, inst.test_labels.astype(np.uint8))


def test_rob_drives_the_ird_plan_and_avoids_the_lava(mission: dict) -> None:
    inst = mission["wf"].instance
    test_mdp = GridMDP(inst.test_features.astype(np.float32).astype(np.float64), inst.test_start,
                       inst.test_horizon)
    # The planner scales the samples by their range over the published (float32) training map.
    scaled = planning.normalise_samples(mission["posterior"].samples,
                                        inst.train_features.astype(np.float32).astype(np.float64))
    expected = planning.plan_path(test_mdp, scaled, "per_step", "training_features", mission["reference"])
    assert "sample_scale=training_spread@" in mission["plan_message"], mission["plan_message"]
    cells = mission["plan_cells"]
    assert tuple(cells) == tuple(expected.cells)
    assert [(s.row, s.col) for s in mission["statuses"]] == cells
    final = mission["final"]
    assert final.step == inst.test_horizon and (final.row, final.col) == cells[-1]
    assert not evaluation.touches_lava(inst.test_labels, cells)
    assert not final.touched_lava
    assert final.true_return == pytest.approx(evaluation.true_return(inst.test_labels, cells, inst.true_terrain_reward))


@pytest.mark.parametrize("condition", ["latent_classifier", "latent_raw"])
def test_perception_classifies_a_gaussian_file_world(condition: str, tmp_path: Path) -> None:
    """A Gaussian file world (an exported latent instance): perception, given the same
    world_file, uses the file's classifier (latent_classifier: /terrain/features = the proxy's
    features) or one fitted on the file's observation model (seed instance.seed)."""
    from ird_core.worlds.observations import fit_classifier
    from ird_ros import conversions as conv
    from ird_ros.client import IrdClient
    from ird_ros.graph import names
    from ird_ros.graph.domains import lease_domain
    from ird_ros.testing import running_nodes

    generated = lavaland.make_instance(condition, 5, size=(6, 7), horizon=8, obs_dim=8)
    path = world_file.export_instance(generated, tmp_path, "gauss", obs_dim=8)
    inst = world_file.load_world(path)
    params = str(REPO / "msgs_config" / "params" / "graph.yaml")
    args = ["--ros-args", "--params-file", params, "-p", f"world_file:={path}"]
    with lease_domain() as lease, \
            running_nodes(lease, ("world", ["-m", "ird_ros.nodes.world", *args]),
                          ("perception", ["-m", "ird_ros.nodes.perception", *args])) as procs, \
            IrdClient(lease.domain_id, node_name="gauss_probe", processes=procs) as ird:
        topics = {"proxy": names.TOPIC_PROXY, "classes": names.TOPIC_TERRAIN_CLASSES,
                  "features": names.TOPIC_TERRAIN_FEATURES}
        ird.subscribe(*topics.values())
        got = {key: ird.received(topic) for key, topic in topics.items()}
        ird.spin_until(lambda: all(got.values()), timeout=60.0, what="perception of the file world")
    assert got["proxy"][-1].condition == lavaland.FILE_CONDITION
    obs = inst.test_features.astype(np.float32).astype(np.float64)
    clf = inst.classifier or fit_classifier(inst.observation_model, np.random.default_rng(inst.seed))
    classes = conv.terrain_grid_from_msg(got["classes"][-1])
    assert classes.class_names == ("dirt", "grass", "target")
    assert np.array_equal(classes.classes, clf.predict(obs).astype(np.uint8))
    assert np.allclose(classes.probabilities, clf.predict_proba(obs), atol=1e-6)
    features = conv.feature_grid_from_msg(got["features"][-1])
    assert features.layers == inst.proxy_feature_names
    assert np.allclose(features.features, inst.proxy_test_features, atol=1e-5)


def test_launch_graph_refuses_a_bad_world_file_before_any_node_starts(tmp_path: Path) -> None:
    import subprocess
    import sys

    doc = yaml.safe_load(WORLD.read_text())
    doc["training_worlds"][0]["start"] = [40, 1]  # off the 7x12 map
    for image in ("figure1_train.png", "figure1_test.png"):
        (tmp_path / image).write_bytes((WORLD.parent / image).read_bytes())
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump(doc))
    run = subprocess.run([sys.executable, str(REPO / "scripts" / "launch_graph.py"), "--world", str(bad),
                          "--private-domain"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 2, run.stderr
    assert f"{bad}: training_worlds[0].start:" in run.stderr
    assert "started" not in run.stdout
