"""/ird/infer runs the chains until they converge (target_r_hat, min_ess) or a bound stops them,
whatever the number of samples asked for; an unconverged answer names the bound."""

from __future__ import annotations

import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from ird_core import posterior as core_inference
from ird_core.mdp import GridMDP
from ird_core.posterior import RunUntil
from ird_core.worlds import lavaland
from ird_msgs.srv import InferReward
from ird_ros import conversions as conv
from ird_ros.client import IrdClient
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import spawn_node_process

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
# No thin: the node's default run-until-converged applies. With this short warm-up the
# fixed-length run (120 iterations per chain) of the request below has split R-hat 1.135.
SAMPLER = dict(num_chains=4, warmup=5, num_proxy_samples=16)
NUM_SAMPLES, SEED, BETA = 12, 1, 2.0
#: The unit-temperature designer with a unit prior (given in the request): the seed's premise holds there.
UNIT = core_inference.MAXENT_OBSERVATION_MODEL
# graph.yaml's defaults (tests/test_graph_params.py ties them to the node's table).
DEFAULT_RULE = dict(r_hat=1.05, min_ess=400.0, max_iterations=2000, time_budget_s=60.0)


@pytest.fixture(scope="module")
def world() -> lavaland.LavalandInstance:
    return lavaland.make_instance("reward_hacking", 1, size=5, horizon=6)


def _request(inst: lavaland.LavalandInstance) -> InferReward.Request:
    req = InferReward.Request()
    req.training_map = conv.feature_grid_to_msg(inst.train_features, inst.feature_names)
    req.start_row, req.start_col = inst.train_start
    req.horizon = inst.train_horizon
    req.proxy_weights = conv.weights_to_flat(inst.proxy_weights)
    req.beta, req.method, req.num_samples, req.seed = BETA, "maxent_z", NUM_SAMPLES, SEED
    req.prior_sigma, req.designer_temperature = 1.0, 1.0  # UNIT, the setting the premise was found in
    return req


def _core(inst: lavaland.LavalandInstance, **kwargs: Any) -> core_inference.Posterior:
    """What the node computes with: the message's float32 map values as float64."""
    features = inst.train_features.astype(np.float32).astype(np.float64)
    mdp = GridMDP(features, inst.train_start, inst.train_horizon)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return core_inference.sample_posterior(inst.proxy_weights, mdp, BETA, "maxent_z", NUM_SAMPLES, SEED, 1.0,
                                               observation_model=UNIT, **SAMPLER, **kwargs)


def _infer(ros_ctx: Any, ros_domain: DomainLease, req: InferReward.Request, **params: Any) -> InferReward.Response:
    args = ["-m", "ird_ros.nodes.inference", "--ros-args", "--params-file", PARAMS]
    for key, value in {**SAMPLER, **params}.items():
        args += ["-p", f"{key}:={value}"]
    with spawn_node_process(args, domain=ros_domain, name="inference", ready_text="inference ready") as proc:
        with IrdClient(context=ros_ctx, node_name="infer_converged_client", processes=[proc]) as ird:
            ird.wait_ready(30.0, services=(names.SRV_INFER,))
            return ird.call(names.SRV_INFER, req, timeout=120.0).response  # the raw answer: every field is checked


def _assert_same(response: InferReward.Response, expected: core_inference.Posterior) -> None:
    got = conv.posterior_from_msg(response.posterior)
    assert np.array_equal(got.samples, expected.samples)
    assert (got.r_hat_max, got.ess_min, got.acceptance_rate) == (
        expected.r_hat_max, expected.ess_min, expected.acceptance_rate)
    assert got.converged == expected.converged


@pytest.fixture(scope="module")
def old_default(world: lavaland.LavalandInstance) -> core_inference.Posterior:
    post = _core(world)
    assert post.r_hat_max > 1.1 and not post.converged  # the premise: the fixed-length run did not mix
    return post


def test_a_request_the_fixed_run_left_unmixed_comes_back_converged(
        ros_ctx: Any, ros_domain: DomainLease, world: lavaland.LavalandInstance,
        old_default: core_inference.Posterior) -> None:
    response = _infer(ros_ctx, ros_domain, _request(world))
    assert response.success, response.message
    post = response.posterior
    assert post.converged and post.r_hat_max <= 1.05 and post.ess_min >= 400.0
    assert post.num_samples == NUM_SAMPLES
    assert "converged after" in response.message and "not converged" not in response.message
    # Exactly the library's run-until with the node's parameters (deterministic for the seed).
    expected = _core(world, until_converged=RunUntil(**DEFAULT_RULE))
    assert expected.stop_reason == "converged" and expected.iterations > old_default.iterations
    _assert_same(response, expected)


def test_a_spent_budget_is_named_in_the_message(ros_ctx: Any, ros_domain: DomainLease,
                                                world: lavaland.LavalandInstance,
                                                old_default: core_inference.Posterior) -> None:
    # A 1 us budget is spent by the first run whatever the machine: it is never extended.
    response = _infer(ros_ctx, ros_domain, _request(world), time_budget=1e-6)
    assert response.success, response.message
    assert not response.posterior.converged
    assert "not converged: time budget 1e-06 s spent after 120 iterations per chain" in response.message
    assert f"R-hat {old_default.r_hat_max:.3f} (target <= 1.05)" in response.message
    expected = _core(world, until_converged=RunUntil(**{**DEFAULT_RULE, "time_budget_s": 1e-6}))
    assert np.array_equal(expected.samples, old_default.samples)  # the first run, kept as it is
    _assert_same(response, expected)
