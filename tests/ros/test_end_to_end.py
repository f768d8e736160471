"""The whole graph, started by the launcher, over real DDS in a private domain.

One mission as a user runs it: the seeded /ird/infer answer equals ird_core's
sample_posterior, the IRD plan equals plan_path, Rob executes it and judges it like
ird_core.worlds.lavaland, and the recorder's bag holds exactly what was published; analyze_bag.py
reads it without ROS.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from ird_core import planning, posterior
from ird_core.mdp import GridMDP
from ird_core.worlds import evaluation, lavaland
from ird_ros import conversions as conv

REPO = Path(__file__).resolve().parents[2]
SIZE, HORIZON, OBS_DIM, SEED = 6, 8, 6, 4


@pytest.fixture(scope="module")
def mission(tmp_path_factory: pytest.TempPathFactory) -> dict:
    from _mission import drive_ird_plan

    from ird_ros.client import IrdClient, infer_request
    from ird_ros.graph import names
    from ird_ros.launch import GraphLauncher

    tmp = tmp_path_factory.mktemp("e2e")
    params = yaml.safe_load((REPO / "msgs_config/params/graph.yaml").read_text())
    params["world"]["ros__parameters"].update(condition="latent_raw", seed=SEED, height=SIZE, width=SIZE,
                                              horizon=HORIZON, obs_dim=OBS_DIM)
    params["rob"]["ros__parameters"]["rate_hz"] = 50.0
    params_file = tmp / "graph.yaml"
    params_file.write_text(yaml.safe_dump(params))
    out: dict = {"bag": tmp / "bag"}
    with GraphLauncher(params=params_file, record_dir=out["bag"], private_domain=True, output="quiet",
                       log_dir=tmp / "logs") as graph:
        graph.wait_ready(timeout=120)
        with IrdClient(graph.domain_id, node_name="e2e_client") as ird:
            ird.watch_rob(timeout=60)
            proxy = ird.proxy(timeout=60)
            train = ird.latest(names.TOPIC_TRAIN_FEATURES, timeout=60)
            request = infer_request(train, (proxy.start_row, proxy.start_col), proxy.horizon, proxy.weights,
                                    beta=5.0, method="maxent_z", num_samples=40, seed=11)
            result = ird.infer(request, timeout=300)
            assert result.ok, result.message
            out["posterior"] = result.unwrap()
            out["train"] = conv.feature_grid_from_msg(train)
            out["proxy"] = proxy
            # "planner ready" does not mean the planner has matched the world, perception and
            # inference yet: under load DDS discovery between two nodes can lag seconds, and
            # the latched maps and posterior reach the planner only then. Its risk map (out
            # once it holds the posterior and a test map) is the event that says it has its
            # inputs; without this wait the plan could fail for want of a map, or the graph
            # be stopped before the risk map was published (an empty /ird/risk_map in the bag).
            ird.risk_map(timeout=60)

            inst = lavaland.make_instance("latent_raw", SEED, size=SIZE, horizon=HORIZON, obs_dim=OBS_DIM)
            reference = posterior.proxy_feature_expectations(inst) / (inst.train_horizon + 1)
            out.update(drive_ird_plan(ird, proxy, out["posterior"].samples, reference))
            out["inst"], out["reference"] = inst, reference
    return out


def test_world_matches_ird_core(mission: dict) -> None:
    inst = mission["inst"]
    assert np.array_equal(mission["train"].features, inst.train_features.astype(np.float32))
    assert np.allclose(mission["proxy"].weights, inst.proxy_weights)


def test_posterior_equals_sample_posterior(mission: dict) -> None:
    proxy, train = mission["proxy"], mission["train"]
    mdp = GridMDP(np.asarray(train.features, dtype=np.float64), (proxy.start_row, proxy.start_col), proxy.horizon)
    direct = posterior.sample_posterior(np.asarray(proxy.weights), mdp, 5.0, "maxent_z", 40, 11)
    got = mission["posterior"]
    assert np.array_equal(got.samples, direct.samples)
    assert got.r_hat_max == pytest.approx(direct.r_hat_max)


def test_rob_executes_the_plan_and_judges_it_like_ird_core(mission: dict) -> None:
    inst = mission["inst"]
    # The planner sees the test map as published: float32 features.
    test_mdp = GridMDP(inst.test_features.astype(np.float32).astype(np.float64), inst.test_start,
                       inst.test_horizon)
    # ... and scales the samples by their range over the published (float32) training map.
    scaled = planning.normalise_samples(mission["posterior"].samples,
                                        inst.train_features.astype(np.float32).astype(np.float64))
    expected = planning.plan_path(test_mdp, scaled, "per_step", "training_features", mission["reference"])
    cells = mission["plan_cells"]
    assert tuple(cells) == tuple(expected.cells)
    final = mission["final"]
    assert final.step == inst.test_horizon and (final.row, final.col) == cells[-1]
    assert final.touched_lava == evaluation.touches_lava(inst.test_labels, cells)
    assert final.reached_target == evaluation.reaches_target(inst.test_labels, cells)
    assert final.true_return == pytest.approx(evaluation.true_return(inst.test_labels, cells))
    assert [(s.row, s.col) for s in mission["statuses"]] == cells


def test_bag_holds_every_recorded_topic_and_analyze_bag_reads_it(mission: dict) -> None:
    from ird_ros.bags.storage import summarize

    counts = {t.topic: t.count for t in summarize(mission["bag"])}
    steps = HORIZON + 1
    expected = {"/world/train_features": 1, "/world/test_features": 1, "/world/terrain": 1,
                "/world/proxy": 1, "/terrain/classes": 1, "/ird/posterior": 1, "/ird/risk_map": 1,
                "/plan": 1, "/ird/plan_info": 1, "/rob/status": steps, "/odom": steps}
    for topic, count in expected.items():
        assert counts.get(topic) == count, (topic, counts)
    run = subprocess.run([sys.executable, str(REPO / "scripts/analyze_bag.py"), str(mission["bag"]),
                          "--out", str(mission["bag"].parent / "plots")],
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "ird" in run.stdout and "/rob/status" in run.stdout
    assert list((mission["bag"].parent / "plots").glob("*.png"))
