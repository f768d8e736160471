"""The planner node over real DDS: plans equal ird_core.planning.plan_path, /plan and
/ird/plan_info carry them, defaults come from the latest world/perception/posterior, the risk map
follows the posterior, replan_on_posterior plans by itself, risk measures reach the library (CVaR
at alpha 1 is the posterior mean's plan), and bad requests are named."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import pytest
from nav_msgs.msg import OccupancyGrid
from nav_msgs.msg import Path as PathMsg

from ird_core import planning, posterior
from ird_core.mdp import GridMDP
from ird_core.worlds import lavaland
from ird_core.worlds.training_worlds import with_training_worlds
from ird_msgs.msg import FeatureGrid, PlanInfo, ProxyReward, RewardPosterior
from ird_msgs.srv import PlanPath
from ird_ros import conversions as conv
from ird_ros.client import CallStatus, IrdClient
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.stamps import stamp_ns, stamp_text
from ird_ros.testing import NodeProcess, spawn_node_process
from ird_ros.testing import running_nodes as running
from ird_ros.waits import spin_until, wait_for_subscribers

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
H, W, T, OBS = 7, 8, 9, 8
SEED = 13


@pytest.fixture(scope="module")
def graph(ros_domain: DomainLease) -> Iterator[list[NodeProcess]]:
    world_args = ["-m", "ird_ros.nodes.world", "--ros-args", "--params-file", PARAMS, "-p", "condition:=side_effects",
                  "-p", f"seed:={SEED}", "-p", f"height:={H}", "-p", f"width:={W}", "-p", f"horizon:={T}",
                  "-p", f"obs_dim:={OBS}", "-p", "resolution:=0.25", "-p", "training_worlds:=2"]
    perception_args = ["-m", "ird_ros.nodes.perception", "--ros-args", "--params-file", PARAMS]
    planner_args = ["-m", "ird_ros.nodes.planner", "--ros-args", "--params-file", PARAMS,
                    "-p", "replan_on_posterior:=true", "-p", "default_mode:=per_step",
                    "-p", "default_baseline:=training_features"]
    with running(ros_domain, ("world", world_args), ("perception", perception_args),
                 ("planner", planner_args)) as procs:
        yield procs


class Probe:
    """The test's IrdClient, with latched subscriptions to the planner's outputs kept for the
    whole module and a publisher of posteriors (the planner's input)."""

    def __init__(self, ctx: Any, graph: list[NodeProcess]) -> None:
        self.ird = IrdClient(context=ctx, node_name="planner_probe", processes=graph)
        self.node = self.ird.node
        self.ird.subscribe(names.TOPIC_PLAN, names.TOPIC_PLAN_INFO, names.TOPIC_RISK_MAP, names.TOPIC_PROXY,
                           names.TOPIC_TERRAIN_FEATURES)
        self.posterior_pub = self.node.create_publisher(RewardPosterior, names.TOPIC_POSTERIOR, names.latched_qos())
        self.ird.wait_ready(20.0, services=(names.SRV_PLAN, names.SRV_GENERATE))

    @property
    def plans(self) -> list[PathMsg]:
        return self.ird.received(names.TOPIC_PLAN)

    @property
    def infos(self) -> list[PlanInfo]:
        return self.ird.received(names.TOPIC_PLAN_INFO)

    @property
    def risk(self) -> list[OccupancyGrid]:
        return self.ird.received(names.TOPIC_RISK_MAP)

    @property
    def proxies(self) -> list[ProxyReward]:
        return self.ird.received(names.TOPIC_PROXY)

    @property
    def terrain_features(self) -> list[FeatureGrid]:
        return self.ird.received(names.TOPIC_TERRAIN_FEATURES)


@pytest.fixture(scope="module")
def probe(ros_ctx: Any, graph: list[NodeProcess]) -> Iterator[Probe]:
    p = Probe(ros_ctx, graph)
    yield p
    p.ird.close()


def plan(probe: Probe, graph: list[NodeProcess], **fields: Any) -> PlanPath.Response:
    req = PlanPath.Request()
    for key, value in fields.items():
        setattr(req, key, value)
    return probe.ird.call(names.SRV_PLAN, req, timeout=60.0).response  # the raw answer: every field is checked


def plan_when(probe: Probe, graph: list[NodeProcess], ready: Callable[[str], bool], **fields: Any) -> PlanPath.Response:
    """Call /ird/plan until the response says it used the expected inputs (the planner gets
    latched topics asynchronously): no sleeping, each call is a real plan."""
    last: list[PlanPath.Response] = []

    def attempt() -> bool:
        response = plan(probe, graph, **fields)
        last.append(response)
        return response.success and ready(response.message)

    spin_until(probe.node, attempt, timeout=30.0, what="a plan on the expected inputs", processes=graph)
    return last[-1]


def generation(probe: Probe, graph: list[NodeProcess], condition: str, seed: int) -> tuple[ProxyReward, Any]:
    """Generate a world; wait for its proxy and perception's /terrain/features of it."""
    response = probe.ird.generate_world(condition, seed, timeout=30.0)
    assert response.ok, response.message

    def arrived() -> bool:
        if not probe.proxies or (probe.proxies[-1].condition, probe.proxies[-1].seed) != (condition, seed):
            return False
        return any(m.header.stamp == probe.proxies[-1].header.stamp for m in probe.terrain_features)

    spin_until(probe.node, arrived, timeout=30.0, what=f"world {condition}/{seed} perceived", processes=graph)
    return probe.proxies[-1], probe.proxies[-1].header.stamp


def f32(a: np.ndarray) -> np.ndarray:
    return np.asarray(a).astype(np.float32).astype(np.float64)


def check_published(probe: Probe, graph: list[NodeProcess], response: PlanPath.Response, label: str,
                    resolution: float, origin: tuple[float, float] = (0.0, 0.0)) -> PlanInfo:
    """/plan and /ird/plan_info of this response: same stamp, same cells, the label."""
    stamp = response.path.header.stamp
    spin_until(probe.node, lambda: any(p.header.stamp == stamp for p in probe.plans)
               and any(i.header.stamp == stamp for i in probe.infos), timeout=20.0,
               what="/plan and /ird/plan_info of the response", processes=graph)
    path = next(p for p in probe.plans if p.header.stamp == stamp)
    info = next(i for i in probe.infos if i.header.stamp == stamp)
    assert path == response.path
    cells = conv.path_to_cells(path, resolution=resolution, origin=origin)
    assert cells == list(zip(response.rows, response.cols))
    assert (info.label, list(info.rows), list(info.cols)) == (label, list(response.rows), list(response.cols))
    assert info.objective == response.objective
    assert path.header.frame_id == "map" and all(p.header.frame_id == "map" for p in path.poses)
    return info


CASES = [("literal", "none", 1), ("literal", "log_z", 1), ("per_step", "none", 6), ("per_step", "initial_state", 6),
         ("per_step", "training_features", 6), ("trajectory", "log_z", 5), ("trajectory", "none", 4)]


@pytest.mark.parametrize("mode,baseline,k", CASES)
def test_explicit_plan_equals_plan_path(mode: str, baseline: str, k: int, probe: Probe,
                                        graph: list[NodeProcess]) -> None:
    rng = np.random.default_rng(hash((mode, baseline)) % 2**32)
    features = rng.normal(size=(5, 6, 3))
    weights = rng.normal(size=(k, 3))
    reference = rng.normal(size=3)
    label = f"test_{mode}_{baseline}"
    response = plan(probe, graph, map=conv.feature_grid_to_msg(features, ["a", "b", "c"], resolution=0.5,
                                                                 origin=(1.0, -2.0)),
                    start_row=2, start_col=3, horizon=7, mode=mode, baseline=baseline,
                    weights=weights.reshape(-1).tolist(), reference_features=reference.tolist(), label=label)
    assert response.success, response.message
    expected = planning.plan_path(GridMDP(f32(features), (2, 3), 7), weights, mode, baseline, reference)
    assert list(zip(response.rows, response.cols)) == list(expected.cells)
    assert response.objective == expected.objective
    assert len(response.path.poses) == 8
    x, y = conv.cell_center(2, 3, 0.5, (1.0, -2.0))
    assert (response.path.poses[0].pose.position.x, response.path.poses[0].pose.position.y) == (x, y)
    info = check_published(probe, graph, response, label, 0.5, (1.0, -2.0))
    assert (info.mode, info.baseline) == (mode, baseline)
    assert (info.risk, info.risk_level, response.risk, response.risk_level) == ("min", 0.0, "min", 0.0)


@pytest.mark.parametrize("mode", ["per_step", "trajectory"])
def test_cvar_one_plans_the_posterior_mean(mode: str, probe: Probe, graph: list[NodeProcess]) -> None:
    """risk cvar at alpha 1 is the mean over the samples: the node's path is plan_path's with that
    risk, which is the plan of the posterior mean weights, and not the min's (so the risk reached
    the library); the response and /ird/plan_info say cvar 1."""
    rng = np.random.default_rng(3)
    features, weights = rng.normal(size=(5, 6, 3)), rng.normal(size=(5, 3))
    label = f"test_cvar_{mode}"
    response = plan(probe, graph, map=conv.feature_grid_to_msg(features, ["a", "b", "c"]), start_row=2, start_col=3,
                    horizon=7, mode=mode, baseline="none", weights=weights.reshape(-1).tolist(), label=label,
                    risk="cvar", risk_level=1.0)
    assert response.success, response.message
    mdp = GridMDP(f32(features), (2, 3), 7)
    expected = planning.plan_path(mdp, weights, mode, "none", risk="cvar", risk_level=1.0)
    mean = planning.plan_path(mdp, weights.mean(axis=0)[None], "per_step", "none")
    worst = planning.plan_path(mdp, weights, mode, "none")
    cells = list(zip(response.rows, response.cols))
    assert cells == list(expected.cells) == list(mean.cells)
    assert cells != list(worst.cells)  # the measure changed the plan: this test would see it ignored
    assert math.isclose(response.objective, mean.objective, rel_tol=1e-12)
    assert response.objective == expected.objective
    assert (response.risk, response.risk_level) == ("cvar", 1.0)
    info = check_published(probe, graph, response, label, 1.0)
    assert (info.mode, info.risk, info.risk_level) == (mode, "cvar", 1.0)
    assert "CVaR alpha=1" in response.message


BAD_RISK: list[tuple[dict[str, Any], str]] = [
    (dict(risk="worst"), "risk"),
    (dict(risk="cvar"), "risk_level"),  # alpha 0: not in (0, 1]
    (dict(risk="cvar", risk_level=1.5), "risk_level"),
    (dict(risk="cvar", risk_level=math.nan), "risk_level"),
    (dict(risk="mean_sd", risk_level=-1.0), "risk_level"),
    (dict(risk="mean_sd", risk_level=101.0), "risk_level"),
    (dict(risk="mean_sd", risk_level=1.0, mode="trajectory"), "risk"),
    (dict(risk="min", risk_level=0.5), "risk_level"),
    (dict(risk_level=0.5), "risk_level"),  # "" = the planner's min, which takes no level
]


def test_bad_risks_are_refused_naming_the_field_and_the_planner_keeps_serving(probe: Probe,
                                                                              graph: list[NodeProcess]) -> None:
    grid = conv.feature_grid_to_msg(np.zeros((5, 6, 3)), ["a", "b", "c"])
    base: dict[str, Any] = dict(map=grid, start_row=1, start_col=1, horizon=4, mode="per_step", baseline="none",
                                weights=[0.1, 0.2, 0.3] * 2)
    for change, field in BAD_RISK:
        response = plan(probe, graph, **{**base, **change})
        assert not response.success and response.message.startswith(field + ":"), (change, response.message)
        assert len(response.path.poses) == 0
    response = plan(probe, graph, **base, risk="mean_sd", risk_level=0.0)  # lambda 0: the mean
    assert response.success, response.message
    assert (response.risk, response.risk_level) == ("mean_sd", 0.0)


def test_defaults_risk_map_and_replan(probe: Probe, graph: list[NodeProcess]) -> None:
    proxy, stamp = generation(probe, graph, "side_effects", SEED + 1)
    inst = with_training_worlds(lavaland.make_instance("side_effects", SEED + 1, size=(H, W), horizon=T,
                                                       obs_dim=OBS), 2)
    gen = stamp_text(stamp)
    samples = np.random.default_rng(0).normal(size=(6, 4))
    request = dict(start_row=proxy.test_start_row, start_col=proxy.test_start_col, horizon=proxy.test_horizon,
                   mode="per_step", baseline="training_features")
    # Before the posterior: the planner holds this generation's test map, proxy and training maps
    # (explicit weights, defaulted map and reference), so the replan below plans on them.
    # map, the reference's three inputs and the training map the samples are scaled on
    # (the world has two training worlds: the second from /world/infer_request, same generation)
    scaled_on = (f"sample_scale=training_spread@{names.TOPIC_TRAIN_FEATURES}@{gen}, "
                 f"+1 training worlds@{names.TOPIC_INFER_REQUEST}@{gen}")
    plan_when(probe, graph, lambda m: m.count(gen) == 6 and f"map={names.TOPIC_TEST_FEATURES}@{gen}" in m
              and scaled_on in m,
              **request, weights=samples.reshape(-1).tolist(), label="before_the_posterior")

    # A posterior in the hypothesis space, published the way the inference node does (latched).
    post = conv.PosteriorData(samples=samples, feature_names=inst.feature_names, proxy_weights=inst.proxy_weights,
                              method="maxent_z", beta=1.0, prior_sigma=1.0, acceptance_rate=0.5, r_hat_max=1.0,
                              ess_min=10.0, num_chains=2, seed=0, converged=True)
    msg = conv.posterior_to_msg(post, feature_names=inst.feature_names, proxy_weights=inst.proxy_weights,
                                stamp=probe.node.get_clock().now().to_msg())
    posted = stamp_ns(msg.header.stamp)
    wait_for_subscribers(probe.node, probe.posterior_pub, processes=graph)
    probe.posterior_pub.publish(msg)

    # The risk map of these samples on the perceived test map.
    expected_risk = planning.risk_map(f32(inst.test_features), samples)
    spin_until(probe.node, lambda: any(np.array_equal(np.asarray(r.data, np.int8).reshape(H, W), expected_risk)
                                       for r in probe.risk), timeout=20.0, what="the risk map", processes=graph)
    risk = next(r for r in probe.risk if np.array_equal(np.asarray(r.data, np.int8).reshape(H, W), expected_risk))
    assert (risk.info.width, risk.info.height, risk.info.resolution) == (W, H, 0.25)
    assert risk.header.frame_id == "map" and expected_risk.max() == 100

    # Defaults: weights = the posterior, map = /world/test_features, f_ref from the proxy.
    rounded = lavaland.LavalandInstance(**{**{f: getattr(inst, f) for f in inst.__dataclass_fields__},
                                           "train_features": f32(inst.train_features),
                                           "proxy_train_features": f32(inst.proxy_train_features)})
    f_ref = posterior.proxy_feature_expectations(rounded) / (T + 1)
    mdp = GridMDP(f32(inst.test_features), inst.test_start, T)
    scaled = planning.normalise_samples(samples, [f32(m) for m in inst.training_maps])  # sample_scale: training_spread
    expected = planning.plan_path(mdp, scaled, "per_step", "training_features", f_ref)

    # replan_on_posterior: the planner planned on its own when the posterior arrived. Until the
    # request below, nothing else can publish a plan stamped after the posterior: the replan is
    # awaited first, because /plan keeps only the latest plan and a replan published in the same
    # instant as a response's plan may replace it before the probe takes it.
    def replans() -> list[PlanInfo]:
        return [i for i in probe.infos if stamp_ns(i.header.stamp) > posted]

    spin_until(probe.node, lambda: bool(replans()), timeout=20.0, what="the replan", processes=graph)
    replan = replans()[0]
    assert (replan.label, replan.mode, replan.baseline) == ("ird_per_step_training_features", "per_step",
                                                            "training_features")
    assert list(zip(replan.rows, replan.cols)) == list(expected.cells)
    assert math.isclose(replan.objective, expected.objective, rel_tol=1e-9, abs_tol=1e-9)
    spin_until(probe.node, lambda: any(p.header.stamp == replan.header.stamp for p in probe.plans), timeout=20.0,
               what="/plan of the replan", processes=graph)

    response = plan_when(probe, graph, lambda m: m.count(gen) == 6 and stamp_text(msg.header.stamp) in m
                         and scaled_on in m, **request)
    assert f"map={names.TOPIC_TEST_FEATURES}@{gen}" in response.message
    assert list(zip(response.rows, response.cols)) == list(expected.cells)
    assert math.isclose(response.objective, expected.objective, rel_tol=1e-9, abs_tol=1e-9)
    check_published(probe, graph, response, "ird_per_step_training_features", 0.25)

    # A map whose layers are not the posterior's is refused, naming the map's layers.
    bad = plan(probe, graph, map=conv.feature_grid_to_msg(np.zeros((5, 6, 3)), ["a", "b", "c"]), start_row=1,
               start_col=1, horizon=4, mode="per_step", baseline="none")
    assert not bad.success and bad.message.startswith("map.layers:"), bad.message


def test_literal_default_uses_the_classifier_features(probe: Probe, graph: list[NodeProcess]) -> None:
    proxy, stamp = generation(probe, graph, "latent_classifier", SEED)
    inst = lavaland.make_instance("latent_classifier", SEED, size=(H, W), horizon=T, obs_dim=OBS)
    perceived = conv.feature_grid_from_msg(next(m for m in probe.terrain_features if m.header.stamp == stamp))
    assert perceived.layers == inst.proxy_feature_names
    gen = stamp_text(stamp)
    response = plan_when(probe, graph, lambda m: m.count(gen) == 2,
                         start_row=proxy.test_start_row, start_col=proxy.test_start_col, horizon=proxy.test_horizon,
                         mode="literal", baseline="none")
    assert f"map={names.TOPIC_TERRAIN_FEATURES}@{gen}" in response.message
    assert f"weights={names.TOPIC_PROXY}@{gen}" in response.message
    expected = planning.plan_path(GridMDP(perceived.features.astype(np.float64), inst.test_start, T),
                                  inst.proxy_weights[None], "literal", "none")
    assert list(zip(response.rows, response.cols)) == list(expected.cells)
    assert response.objective == expected.objective
    check_published(probe, graph, response, "literal", 0.25)


BAD: list[tuple[str, dict[str, Any], str]] = [
    ("mode unknown", dict(mode="cautious"), "mode"),
    ("baseline unknown", dict(baseline="mean"), "baseline"),
    ("horizon 0", dict(horizon=0), "horizon"),
    ("horizon huge", dict(horizon=2**32 - 1), "horizon"),
    ("start_row off", dict(start_row=5), "start_row"),
    ("start_col off", dict(start_col=6), "start_col"),
    ("weights NaN", dict(weights=[0.1, math.nan, 0.2]), "weights"),
    ("weights not a multiple of d", dict(weights=[0.1, 0.2, 0.3, 0.4]), "weights"),
    ("literal with two vectors", dict(mode="literal", weights=[0.1] * 6), "weights"),
    ("reference wrong length", dict(baseline="training_features", reference_features=[1.0, 2.0]), "reference_features"),
    ("reference NaN", dict(baseline="training_features", reference_features=[1.0, math.inf, 2.0]),
     "reference_features"),
    ("map layers empty", dict(map_layers=[]), "map.layers"),
    ("map short data", dict(map_truncate=True), "map.data"),
    ("map NaN", dict(map_nan=True), "map.data"),
]


@pytest.mark.parametrize("case,change,field", BAD, ids=[b[0] for b in BAD])
def test_bad_requests_are_named(case: str, change: dict[str, Any], field: str, probe: Probe,
                                graph: list[NodeProcess]) -> None:
    change = dict(change)
    fields: dict[str, Any] = dict(start_row=1, start_col=1, horizon=4, mode="per_step", baseline="none",
                                  weights=[0.1, 0.2, 0.3] * 2)
    grid = conv.feature_grid_to_msg(np.zeros((5, 6, 3)), ["a", "b", "c"])
    if "map_layers" in change:
        grid.layers = change.pop("map_layers")
    if change.pop("map_truncate", False):
        grid.data = grid.data[:-1]
    if change.pop("map_nan", False):
        grid.data[7] = math.nan
    fields["map"] = grid
    fields.update(change)
    response = plan(probe, graph, **fields)
    assert not response.success, case
    assert response.message.startswith(field + ":") or response.message.startswith(field + "."), response.message
    assert len(response.path.poses) == 0


def test_plan_without_inputs_is_named() -> None:
    """A planner alone in its own domain (no world, no posterior) names what it lacks, and keeps
    serving."""
    from ird_ros.graph.domains import lease_domain

    args = ["-m", "ird_ros.nodes.planner", "--ros-args", "--params-file", PARAMS]
    with lease_domain() as lease, \
            spawn_node_process(args, domain=lease, name="lonely_planner", ready_text="planner ready") as proc:
        with IrdClient(lease.domain_id, node_name="lonely_probe", processes=[proc]) as ird:
            ird.wait_ready(20.0, services=(names.SRV_PLAN,))
            for mode, baseline, weights, field in (
                ("per_step", "none", [], "weights"),
                ("literal", "none", [], "weights"),
                ("per_step", "none", [0.1, 0.2], "map"),
                ("per_step", "training_features", [0.1, 0.2, 0.3], "reference_features"),
            ):
                req = PlanPath.Request(start_row=0, start_col=0, horizon=3, mode=mode, baseline=baseline,
                                       weights=weights)
                if field == "reference_features":
                    req.map = conv.feature_grid_to_msg(np.zeros((2, 2, 3)), ["a", "b", "c"])
                response = ird.plan(req, timeout=20.0)
                assert response.status is CallStatus.REFUSED and response.field == field, response
                assert response.message.startswith(field + ":"), response.message
            req = PlanPath.Request(map=conv.feature_grid_to_msg(np.zeros((2, 2, 3)), ["a", "b", "c"]), horizon=3,
                                   mode="per_step", baseline="none", weights=[0.1, 0.2, 0.3])
            assert ird.plan(req, timeout=20.0).ok
        proc.stop()
        assert proc.returncode == 0, proc.describe()


@pytest.mark.parametrize("params,field", [
    (["-p", "risk:=cvar"], "risk_level"),  # cvar without its alpha
    (["-p", "risk:=mean_sd", "-p", "risk_level:=1.0", "-p", "replan_on_posterior:=true",
      "-p", "default_mode:=trajectory"], "risk"),  # replans would all be refused
])
def test_a_bad_default_risk_stops_the_planner_at_start_up(params: list[str], field: str) -> None:
    """The default measure is checked once, at start-up (exit code 2 naming the parameter), not
    refused on every request that leaves risk empty."""
    import subprocess
    import sys

    from ird_ros.graph.domains import lease_domain

    with lease_domain() as lease:
        run = subprocess.run([sys.executable, "-m", "ird_ros.nodes.planner", "--ros-args", "--params-file", PARAMS,
                              *params], env=lease.env(), capture_output=True, text=True, timeout=120)
    assert run.returncode == 2, (run.stdout, run.stderr)
    assert f"parameter {field}:" in run.stdout + run.stderr, (run.stdout, run.stderr)
