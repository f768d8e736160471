"""A non-linear hypothesis space in the graph, over real DDS: a world node with ``hypothesis:=rff``
and ``novelty_feature:=true`` publishes the experiments' hypothesis maps
(``HypothesisSpace.apply``) beside the unchanged sensors' maps and poses /ird/infer in that
space; the inference node's posterior is the library's on those maps, and the planner plans it
on /world/hypothesis/test_features, scaled and referenced on /world/hypothesis/train_features,
while the literal plan stays on the sensors' map."""

from __future__ import annotations

import math
import warnings
from typing import Any, Iterator

import numpy as np
import pytest
from _inference_node import PARAMS, SAMPLER, small_inference_node

from ird_core import planning, posterior
from ird_core.hypothesis import NOVELTY_FEATURE, HypothesisSpace
from ird_core.mdp import GridMDP
from ird_core.worlds import lavaland
from ird_msgs.msg import ProxyReward
from ird_msgs.srv import InferReward, PlanPath
from ird_ros import conversions as conv
from ird_ros.client import IrdClient
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.jobs.inference import InferenceJob, job_observations
from ird_ros.stamps import stamp_text
from ird_ros.testing import NodeProcess
from ird_ros.testing import running_nodes as running
from ird_ros.waits import spin_until

H, W, T, OBS, SEED, D = 7, 7, 8, 8, 4, 12
SPACE = HypothesisSpace("rff", D, True)
HYPOTHESIS_TOPICS = (names.TOPIC_HYPOTHESIS_TRAIN_FEATURES, names.TOPIC_HYPOTHESIS_TEST_FEATURES)
WORLD_TOPICS = (names.TOPIC_TRAIN_FEATURES, names.TOPIC_TEST_FEATURES, names.TOPIC_TRAIN_PROXY_FEATURES,
                *HYPOTHESIS_TOPICS, names.TOPIC_INFER_REQUEST, names.TOPIC_TERRAIN_FEATURES)


def f32(a: np.ndarray) -> np.ndarray:
    return np.asarray(a).astype(np.float32).astype(np.float64)


@pytest.fixture(scope="module")
def graph(ros_domain: DomainLease) -> Iterator[list[NodeProcess]]:
    world_args = ["-m", "ird_ros.nodes.world", "--ros-args", "--params-file", PARAMS, "-p", "condition:=latent_raw",
                  "-p", f"seed:={SEED}", "-p", f"height:={H}", "-p", f"width:={W}", "-p", f"horizon:={T}",
                  "-p", f"obs_dim:={OBS}", "-p", "hypothesis:=rff", "-p", f"rff_features:={D}",
                  "-p", "novelty_feature:=true"]
    perception_args = ["-m", "ird_ros.nodes.perception", "--ros-args", "--params-file", PARAMS]
    planner_args = ["-m", "ird_ros.nodes.planner", "--ros-args", "--params-file", PARAMS]
    with small_inference_node(ros_domain) as inference, \
            running(ros_domain, ("world", world_args), ("perception", perception_args),
                    ("planner", planner_args)) as procs:
        yield [inference, *procs]


@pytest.fixture(scope="module")
def ird(ros_ctx: Any, graph: list[NodeProcess]) -> Iterator[IrdClient]:
    with IrdClient(context=ros_ctx, node_name="hypothesis_probe", processes=graph) as client:
        client.subscribe(names.TOPIC_PROXY, *WORLD_TOPICS)
        client.wait_ready(30.0, services=(names.SRV_INFER, names.SRV_PLAN, names.SRV_GENERATE))
        yield client


def _instances() -> tuple[lavaland.LavalandInstance, lavaland.LavalandInstance]:
    raw = lavaland.make_instance("latent_raw", SEED, size=(H, W), horizon=T, obs_dim=OBS)
    return raw, SPACE.apply(raw)


def _generation(ird: IrdClient, graph: list[NodeProcess]) -> tuple[ProxyReward, dict[str, Any]]:
    """The world's proxy and every world topic's message of its generation (same stamp)."""
    out: dict[str, Any] = {}

    def complete() -> bool:
        proxies = ird.received(names.TOPIC_PROXY)
        if not proxies:
            return False
        stamp = proxies[-1].header.stamp
        out.clear()
        for topic in WORLD_TOPICS:
            found = [m for m in ird.received(topic)
                     if (m.training_map.header.stamp if topic == names.TOPIC_INFER_REQUEST else m.header.stamp) == stamp]
            if not found:
                return False
            out[topic] = found[-1]
        return True

    spin_until(ird.node, complete, timeout=30.0, what="a whole generation", processes=graph)
    return ird.received(names.TOPIC_PROXY)[-1], out


def test_the_world_publishes_the_hypothesis_space_beside_the_sensors(ird: IrdClient, graph: list[NodeProcess]) -> None:
    proxy, msgs = _generation(ird, graph)
    raw, hyp = _instances()
    assert hyp.feature_names == (*(f"rff_{i:03d}" for i in range(D)), NOVELTY_FEATURE)
    assert hyp.test_features[..., -1].any(), "no novel test cell: the seed tests nothing"
    for topic, values, layers in (
        (names.TOPIC_HYPOTHESIS_TRAIN_FEATURES, hyp.train_features, hyp.feature_names),
        (names.TOPIC_HYPOTHESIS_TEST_FEATURES, hyp.test_features, hyp.feature_names),
        # The sensors' maps and the proxy's are what they are without the hypothesis space.
        (names.TOPIC_TRAIN_FEATURES, raw.train_features, raw.feature_names),
        (names.TOPIC_TEST_FEATURES, raw.test_features, raw.feature_names),
        (names.TOPIC_TRAIN_PROXY_FEATURES, raw.proxy_train_features, raw.proxy_feature_names),
    ):
        grid = conv.feature_grid_from_msg(msgs[topic])
        assert grid.layers == layers, topic
        np.testing.assert_array_equal(grid.features, values.astype(np.float32), err_msg=topic)
    assert tuple(proxy.feature_names) == raw.proxy_feature_names
    np.testing.assert_array_equal(np.asarray(proxy.weights), raw.proxy_weights)
    # /ird/infer is posed in the hypothesis space, the proxy's behaviour on its own features.
    request = msgs[names.TOPIC_INFER_REQUEST]
    training, proxy_map = conv.feature_grid_from_msg(request.training_map), conv.feature_grid_from_msg(request.proxy_map)
    assert training.layers == hyp.feature_names and proxy_map.layers == raw.feature_names
    np.testing.assert_array_equal(training.features, hyp.train_features.astype(np.float32))
    np.testing.assert_array_equal(proxy_map.features, raw.proxy_train_features.astype(np.float32))


def test_infer_and_plan_in_the_hypothesis_space(ird: IrdClient, graph: list[NodeProcess]) -> None:
    proxy, msgs = _generation(ird, graph)
    gen = stamp_text(proxy.header.stamp)
    raw, hyp = _instances()
    request: InferReward.Request = msgs[names.TOPIC_INFER_REQUEST]
    request.beta, request.method, request.num_samples, request.seed = 3.0, "maxent_z", 10, 17
    response = ird.call(names.SRV_INFER, request, timeout=120.0).response
    assert response.success, response.message
    got = conv.posterior_from_msg(response.posterior)
    assert got.feature_names == hyp.feature_names

    # The library's posterior on the same (float32) maps, built as the node builds it.
    train = GridMDP(f32(hyp.train_features), hyp.train_start, hyp.train_horizon)
    job = InferenceJob(train, train.with_features(f32(raw.proxy_train_features)), raw.proxy_weights, 3.0,
                       "maxent_z", 10, 17, None, posterior.SamplerSettings(**SAMPLER))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a tiny run: only equality matters
        expected = posterior.sample_joint_posterior(job_observations(job), 3.0, "maxent_z", 10, 17, None, **SAMPLER)
    np.testing.assert_array_equal(got.samples, expected.samples)

    # The planner plans that posterior on the hypothesis test map, scaled and referenced on the
    # hypothesis training map.
    rounded = lavaland.LavalandInstance(**{**{f: getattr(hyp, f) for f in hyp.__dataclass_fields__},
                                           "train_features": f32(hyp.train_features),
                                           "proxy_train_features": f32(hyp.proxy_train_features)})
    f_ref = posterior.proxy_feature_expectations(rounded) / (T + 1)
    scaled = planning.normalise_samples(got.samples, f32(hyp.train_features))
    plan_expected = planning.plan_path(GridMDP(f32(hyp.test_features), hyp.test_start, T), scaled, "per_step",
                                       "training_features", f_ref)
    posted = stamp_text(response.posterior.header.stamp)
    fields = dict(start_row=proxy.test_start_row, start_col=proxy.test_start_col, horizon=proxy.test_horizon,
                  mode="per_step", baseline="training_features")
    wanted = (f"map={names.TOPIC_HYPOTHESIS_TEST_FEATURES}@{gen}",
              f"sample_scale=training_spread@{names.TOPIC_HYPOTHESIS_TRAIN_FEATURES}@{gen}",
              f"{names.TOPIC_HYPOTHESIS_TRAIN_FEATURES}@{gen}", posted)
    plan = _plan_when(ird, graph, lambda m: all(w in m for w in wanted), **fields)
    assert list(zip(plan.rows, plan.cols)) == list(plan_expected.cells)
    assert math.isclose(plan.objective, plan_expected.objective, rel_tol=1e-9, abs_tol=1e-9)

    # The literal plan is the proxy's on the sensors' map, as without the hypothesis space.
    literal = _plan_when(ird, graph, lambda m: f"map={names.TOPIC_TEST_FEATURES}@{gen}" in m,
                         **{**fields, "mode": "literal", "baseline": "none"})
    literal_expected = planning.plan_path(GridMDP(f32(raw.test_features), raw.test_start, T),
                                          raw.proxy_weights[None], "literal")
    assert list(zip(literal.rows, literal.cols)) == list(literal_expected.cells)


def _plan_when(ird: IrdClient, graph: list[NodeProcess], ready: Any, **fields: Any) -> PlanPath.Response:
    """Call /ird/plan until its message names the expected inputs (latched topics reach the
    planner asynchronously): no sleeping, each call is a real plan."""
    last: list[PlanPath.Response] = []

    def attempt() -> bool:
        req = PlanPath.Request()
        for key, value in fields.items():
            setattr(req, key, value)
        last.append(ird.call(names.SRV_PLAN, req, timeout=60.0).response)
        return last[-1].success and ready(last[-1].message)

    spin_until(ird.node, attempt, timeout=30.0, what="a plan on the expected inputs", processes=graph)
    return last[-1]
