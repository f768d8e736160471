"""/ird/infer with several training worlds over real DDS: the joint posterior of all the worlds,
exactly, and validation errors naming ``training_worlds[i].<field>``."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import pytest
from _inference_node import SAMPLER, small_inference_node

from ird_core import posterior as core_inference
from ird_core.mdp import GridMDP
from ird_core.posterior import SamplerSettings
from ird_core.worlds import lavaland, world_file
from ird_msgs.msg import TrainingWorld
from ird_msgs.srv import InferReward
from ird_ros import conversions as conv
from ird_ros.client import IrdClient
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.jobs.inference import ExtraWorld, InferenceJob, job_observations
from ird_ros.testing import NodeProcess

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def node(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    with small_inference_node(ros_domain) as proc:
        yield proc


@pytest.fixture(scope="module")
def call(ros_ctx: Any, node: NodeProcess) -> Iterator[Callable[[InferReward.Request], InferReward.Response]]:
    with IrdClient(context=ros_ctx, node_name="training_worlds_client", processes=[node]) as ird:
        ird.wait_ready(30.0, services=(names.SRV_INFER,))
        # The raw answer: the tests read every field of the message.
        yield lambda req: ird.call(names.SRV_INFER, req, timeout=60.0).response


def _world_msg(world: lavaland.TrainingWorld, names_: tuple[str, ...], proxy_names: tuple[str, ...] | None,
               weights: bool = True) -> TrainingWorld:
    msg = TrainingWorld()
    msg.training_map = conv.feature_grid_to_msg(world.features, names_)
    if proxy_names is not None:
        msg.proxy_map = conv.feature_grid_to_msg(world.proxy_features, proxy_names)
    msg.start_row, msg.start_col = world.start
    msg.horizon = world.horizon
    if weights:
        msg.proxy_weights = conv.weights_to_flat(world.proxy_weights)
    return msg


def _request(inst: lavaland.LavalandInstance, method: str, *, proxy_map: bool = False) -> InferReward.Request:
    req = InferReward.Request()
    req.training_map = conv.feature_grid_to_msg(inst.train_features, inst.feature_names)
    if proxy_map:
        req.proxy_map = conv.feature_grid_to_msg(inst.proxy_train_features, inst.proxy_feature_names)
    req.start_row, req.start_col = inst.train_start
    req.horizon = inst.train_horizon
    req.proxy_weights = conv.weights_to_flat(inst.proxy_weights)
    req.beta, req.method, req.num_samples, req.seed = 3.0, method, 10, 17
    proxy_names = inst.proxy_feature_names if proxy_map else None
    req.training_worlds = [_world_msg(w, inst.feature_names, proxy_names) for w in inst.extra_training_worlds]
    return req


def _joint(observations: list, method: str) -> core_inference.Posterior:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # tiny runs: only equality matters
        return core_inference.sample_joint_posterior(observations, 3.0, method, 10, 17, None, **SAMPLER)


@pytest.mark.parametrize("method", core_inference.METHODS)
def test_two_file_worlds_give_the_joint_posterior(method: str, call: Callable) -> None:
    inst = world_file.load_world(ROOT / "worlds" / "two_training_worlds.yaml")  # indicators: float32-exact
    response = call(_request(inst, method))
    assert response.success, response.message
    expected = _joint(core_inference.proxy_observations(inst), method)
    got = conv.posterior_from_msg(response.posterior)
    np.testing.assert_array_equal(got.samples, expected.samples)
    np.testing.assert_array_equal(got.proxy_weights, inst.proxy_weights)
    # The second world is evidence: without it the posterior differs.
    single = _joint(core_inference.proxy_observations(inst)[:1], method)
    assert not np.array_equal(single.samples, expected.samples)
    # An empty world list keeps the single-proxy posterior.
    req = _request(inst, method)
    req.training_worlds = []
    alone = call(req)
    assert alone.success, alone.message
    np.testing.assert_array_equal(conv.posterior_from_msg(alone.posterior).samples, single.samples)


@pytest.mark.parametrize("method", core_inference.METHODS)
def test_proxy_maps_of_several_worlds(method: str, call: Callable) -> None:
    base = lavaland.make_instance("latent_classifier", 2, size=5, horizon=5, obs_dim=6)
    f32 = lambda a: np.asarray(a, dtype=np.float32).astype(np.float64)  # noqa: E731  (the message's precision)
    second = lavaland.TrainingWorld(base.test_labels, f32(base.test_features), f32(base.proxy_test_features),
                                    base.test_start, base.test_horizon, base.proxy_weights * 0.5)
    inst = lavaland.LavalandInstance(**{**{f: getattr(base, f) for f in base.__dataclass_fields__},
                                        "train_features": f32(base.train_features),
                                        "proxy_train_features": f32(base.proxy_train_features),
                                        "extra_training_worlds": (second,)})
    response = call(_request(inst, method, proxy_map=True))
    assert response.success, response.message
    train = GridMDP(inst.train_features, inst.train_start, inst.train_horizon)
    sec = GridMDP(second.features, second.start, second.horizon)
    job = InferenceJob(train, train.with_features(inst.proxy_train_features), inst.proxy_weights, 3.0, method, 10,
                       17, None,  # the node's default: the calibrated sigma, resolved by the library
                       SamplerSettings(**SAMPLER),
                       (ExtraWorld(sec, sec.with_features(second.proxy_features), second.proxy_weights),))
    observations = job_observations(job)  # N = SamplerSettings(**SAMPLER).num_proxy_samples
    # The node's per-world proxy terms are lavaland's.
    reference = core_inference.proxy_observations(inst, num_proxy_samples=SAMPLER["num_proxy_samples"], seed=17)
    for mine, theirs in zip(observations, reference, strict=True):
        np.testing.assert_allclose(mine.proxy_features, theirs.proxy_features, rtol=1e-10, atol=1e-10)
        if method == "sample_z":
            np.testing.assert_allclose(mine.proxy_sample_features, theirs.proxy_sample_features, rtol=1e-10,
                                       atol=1e-10)
    np.testing.assert_array_equal(conv.posterior_from_msg(response.posterior).samples,
                                  _joint(observations, method).samples)


def _edit(field: str, value: Any) -> Callable[[TrainingWorld], None]:
    return lambda world: setattr(world, field, value)


def _other_layers(world: TrainingWorld) -> None:
    world.training_map.layers = [f"x{i}" for i in range(len(world.training_map.layers))]


BAD_WORLDS = [
    (_edit("start_row", 99), "training_worlds[0].start_row"),
    (_edit("start_col", 99), "training_worlds[0].start_col"),
    (_edit("horizon", 0), "training_worlds[0].horizon"),
    (_edit("proxy_weights", [1.0, 2.0]), "training_worlds[0].proxy_weights"),
    (_edit("proxy_weights", [np.nan, 0.0, 0.0, 0.0]), "training_worlds[0].proxy_weights"),
    (_other_layers, "training_worlds[0].training_map.layers"),
]


@pytest.mark.parametrize("edit, field", BAD_WORLDS)
def test_bad_training_worlds_name_the_field(edit: Callable, field: str, call: Callable) -> None:
    inst = world_file.load_world(ROOT / "worlds" / "two_training_worlds.yaml")
    req = _request(inst, "maxent_z")
    edit(req.training_worlds[0])
    response = call(req)
    assert not response.success
    assert response.message.startswith(field), response.message


def test_empty_world_proxy_weights_are_the_requests(call: Callable) -> None:
    inst = world_file.load_world(ROOT / "worlds" / "two_training_worlds.yaml")
    req = _request(inst, "maxent_z")
    req.training_worlds = [_world_msg(inst.extra_training_worlds[0], inst.feature_names, None, weights=False)]
    response = call(req)
    assert response.success, response.message
    np.testing.assert_array_equal(conv.posterior_from_msg(response.posterior).samples,
                                  _joint(core_inference.proxy_observations(inst), "maxent_z").samples)
