"""Hostile requests against a running inference node (/ird/infer, /ird/query, /ird/answer): each
is answered ``success: false`` naming the field (and, for a size or work, the limit), before any
work starts, and the node keeps serving (a valid request afterwards succeeds). Small limits are
set through parameters, so the refusal paths run without allocating much. Also: the sampler's time
budget is checked inside the first run (ird_core.posterior.run_until). A worker's death:
tests/ros/test_battery_worker_death.py."""

from __future__ import annotations

import array
import math
import warnings
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import pytest

from ird_core import posterior
from ird_core.posterior import RunUntil
from ird_core.worlds import lavaland
from ird_msgs.msg import FeatureGrid, TrainingWorld
from ird_msgs.srv import InferReward, ProposeQuery
from ird_ros import conversions as conv
from ird_ros.client import CallStatus, IrdClient, infer_request, query_request
from ird_ros.conversions.inference_requests import check_pass_memory
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.runtime.guard import MAX_MESSAGE
from ird_ros.testing import NodeProcess, spawn_node_process

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
SAMPLER = ["-p", "num_chains:=4", "-p", "warmup:=20", "-p", "thin:=1", "-p", "num_proxy_samples:=16"]
LIMITS = {"max_map_values": 2000, "max_training_worlds": 2, "max_request_values": 3000,
          "max_inference_work": 1e8, "max_query_work": 1e4}
SIZE, HORIZON, SAMPLES = 5, 6, 12
SERVICES = (names.SRV_INFER, names.SRV_QUERY, names.SRV_ANSWER)


def _args(limits: dict[str, Any]) -> list[str]:
    args = ["-m", "ird_ros.nodes.inference", "--ros-args", "--params-file", PARAMS, *SAMPLER]
    for key, value in limits.items():
        args += ["-p", f"{key}:={value}"]
    return args


@pytest.fixture(scope="module")
def node(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    with spawn_node_process(_args(LIMITS), domain=ros_domain, name="inference", ready_text="inference ready") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()


@pytest.fixture(scope="module")
def ird(ros_ctx: Any, node: NodeProcess) -> Iterator[IrdClient]:
    with IrdClient(context=ros_ctx, node_name="battery_inference_client", processes=[node]) as client:
        client.wait_ready(30.0, services=SERVICES)
        yield client


@pytest.fixture(scope="module")
def world() -> lavaland.LavalandInstance:
    return lavaland.make_instance("side_effects", 3, size=SIZE, horizon=HORIZON)


def _grid(features: np.ndarray, layers: Any) -> FeatureGrid:
    return conv.feature_grid_to_msg(np.asarray(features, dtype=np.float32), list(layers))


def _valid(world: lavaland.LavalandInstance, **kw: Any) -> InferReward.Request:
    settings = dict(beta=2.0, method="maxent_z", num_samples=SAMPLES, seed=3) | kw
    return infer_request(_grid(world.train_features, world.feature_names), world.train_start, HORIZON,
                         world.proxy_weights, **settings)


def _declared(height: int, width: int, layers: int, values: int = 0) -> FeatureGrid:
    """A grid whose info declares ``height x width x layers`` but carries ``values`` values."""
    msg = FeatureGrid(layers=[f"f{i}" for i in range(layers)])
    msg.info.height, msg.info.width, msg.info.resolution = height, width, 1.0
    msg.data = array.array("f", bytes(4 * values))
    return msg


def _world(world: lavaland.LavalandInstance, size: int = SIZE, horizon: int = HORIZON, **kw: Any) -> TrainingWorld:
    features = np.resize(world.train_features, (size, size, len(world.feature_names)))
    return TrainingWorld(training_map=_grid(features, world.feature_names), start_row=0, start_col=0,
                         horizon=horizon, **kw)


def _set(**fields: Any) -> Callable[[Any, lavaland.LavalandInstance], None]:
    return lambda req, world: [setattr(req, k, v) for k, v in fields.items()] and None


def _assert_refused(result: Any, field: str, limit: str = "") -> None:
    assert result.status is CallStatus.REFUSED, (result.status, result.message)
    assert result.field == field, result.message
    assert limit in result.message, result.message
    assert len(result.message) <= MAX_MESSAGE + 40, len(result.message)


# (case, corruption, field, limit the message names)
INFER: list[tuple[str, Callable[[Any, lavaland.LavalandInstance], None], str, str]] = [
    ("map data beyond max_map_values", lambda r, w: setattr(r, "training_map", _declared(1, 2001, 1, 2001)),
     "training_map.data", "max_map_values=2000"),
    ("map declares 1e10 values", lambda r, w: setattr(r, "training_map", _declared(100000, 100000, 1)),
     "training_map.data", "max_map_values=2000"),
    ("proxy_map beyond max_map_values", lambda r, w: setattr(r, "proxy_map", _declared(50, 50, 1, 2500)),
     "proxy_map.data", "max_map_values=2000"),
    ("proxy_weights longer than any map", _set(proxy_weights=[0.0] * 3000), "proxy_weights", "max_map_values=2000"),
    ("three training worlds", lambda r, w: setattr(r, "training_worlds", [_world(w, 2) for _ in range(3)]),
     "training_worlds", "max_training_worlds=2"),
    ("training worlds' values in all", lambda r, w: setattr(r, "training_worlds", [_world(w, 20), _world(w, 20)]),
     "training_worlds", "max_request_values=3000"),
    ("a training world's huge map", lambda r, w: setattr(r, "training_worlds", [
        TrainingWorld(training_map=_declared(1000, 1000, 4), horizon=HORIZON)]),
     "training_worlds[0].training_map.data", "max_map_values=2000"),
    ("a training world's proxy weights 2e4", lambda r, w: setattr(r, "training_worlds", [
        _world(w, proxy_weights=[2e4, 0.0, 0.0, 0.0])]), "training_worlds[0].proxy_weights", "10000"),
    ("a training world's horizon 0", lambda r, w: setattr(r, "training_worlds", [_world(w, horizon=0)]),
     "training_worlds[0].horizon", "max_horizon=1000"),
    ("a training world's work", lambda r, w: setattr(r, "training_worlds", [_world(w, 20, 1000)]),
     "training_worlds", "max_inference_work=1e+08"),
    ("samples beyond the work", _set(num_samples=20000), "num_samples", "max_inference_work=1e+08"),
    ("samples beyond max_num_samples", _set(num_samples=2**32 - 1), "num_samples", "max_num_samples=100000"),
    ("a 40x40 map at horizon 1000", lambda r, w: (setattr(r, "training_map", _grid(np.zeros((40, 40, 1)), ["a"])),
                                                  setattr(r, "proxy_weights", [1.0]), setattr(r, "horizon", 1000)),
     "training_map", "max_inference_work=1e+08"),
    ("1500 features", lambda r, w: (setattr(r, "training_map", _grid(np.zeros((1, 1, 1500)), [f"f{i}" for i in
                                                                                            range(1500)])),
                                    setattr(r, "proxy_weights", [0.0] * 1500), setattr(r, "start_row", 0),
                                    setattr(r, "start_col", 0)),
     "training_map", "max_inference_work=1e+08"),
    ("horizon beyond max_horizon", _set(horizon=1001), "horizon", "max_horizon=1000"),
    ("duplicate layers", lambda r, w: setattr(r.training_map, "layers", ["a"] * 4), "training_map.layers", ""),
    ("a method of 100000 characters", _set(method="m" * 100000), "method", ""),
    ("beta 1001", _set(beta=1001.0), "beta", ""),
    ("beta NaN", _set(beta=math.nan), "beta", ""),
    ("prior_sigma inf", _set(prior_sigma=math.inf), "prior_sigma", ""),
]


@pytest.mark.parametrize("case,corrupt,field,limit", INFER, ids=[c[0] for c in INFER])
def test_hostile_infer_is_refused_and_the_node_serves_on(case: str, corrupt: Callable, field: str, limit: str,
                                                        ird: IrdClient, node: NodeProcess,
                                                        world: lavaland.LavalandInstance) -> None:
    request = _valid(world)
    corrupt(request, world)
    _assert_refused(ird.infer(request, timeout=60.0), field, limit)
    valid = ird.infer(_valid(world), timeout=120.0)
    assert valid.ok, valid.message
    assert node.alive()


@pytest.fixture(scope="module")
def open_query(ird: IrdClient, world: lavaland.LavalandInstance) -> int:
    """A valid /ird/infer then /ird/query: the evidence the query and answer cases act on."""
    assert ird.infer(_valid(world), timeout=120.0).ok
    result = ird.propose_query(_query(world), timeout=60.0)
    assert result.ok, result.message
    return int(result.response.query_id)


def _query(world: lavaland.LavalandInstance, **kw: Any) -> ProposeQuery.Request:
    settings = dict(horizon=HORIZON, num_options=2, grid=_grid(world.test_features, world.feature_names)) | kw
    return query_request(world.test_start, **settings)


QUERY: list[tuple[str, Callable[[Any, lavaland.LavalandInstance], None], str, str]] = [
    ("map data beyond max_map_values", lambda r, w: setattr(r, "map", _declared(1, 2001, 1, 2001)), "map.data",
     "max_map_values=2000"),
    ("map declares 1e10 values", lambda r, w: setattr(r, "map", _declared(100000, 100000, 4)), "map.data",
     "max_map_values=2000"),
    ("other layers", lambda r, w: setattr(r.map, "layers", ["a", "b", "c", "d"]), "map.layers", ""),
    ("num_options 1e9", _set(num_options=10**9), "num_options", "max_options=8"),
    ("8 options beyond the work", _set(num_options=8), "num_options", "max_query_work=1e+04"),
    ("horizon 1000 beyond the work", _set(horizon=1000), "map", "max_query_work=1e+04"),
    ("horizon beyond max_horizon", _set(horizon=5000), "horizon", "max_horizon=1000"),
    ("a strategy of 100000 characters", _set(strategy="s" * 100000), "strategy", ""),
    ("start off the map", _set(start_row=99), "start_row", ""),
]


@pytest.mark.parametrize("case,corrupt,field,limit", QUERY, ids=[c[0] for c in QUERY])
def test_hostile_query_is_refused_and_the_node_serves_on(case: str, corrupt: Callable, field: str, limit: str,
                                                        ird: IrdClient, world: lavaland.LavalandInstance,
                                                        open_query: int) -> None:
    request = _query(world)
    corrupt(request, world)
    _assert_refused(ird.propose_query(request, timeout=60.0), field, limit)
    assert ird.propose_query(_query(world), timeout=60.0).ok


ANSWER: list[tuple[str, dict[str, Any], str]] = [
    ("beta 1001", dict(beta=1001.0), "beta"),
    ("beta NaN", dict(beta=math.nan), "beta"),
    ("beta inf", dict(beta=math.inf), "beta"),
    ("beta negative", dict(beta=-1.0), "beta"),
    ("chosen out of range", dict(chosen=7), "chosen"),
    ("unknown query_id", dict(query_id=999999), "query_id"),
    ("answered_by of 10000 characters", dict(answered_by="x" * 10000), "answered_by"),
]


@pytest.mark.parametrize("case,fields,field", ANSWER, ids=[c[0] for c in ANSWER])
def test_hostile_answer_is_refused(case: str, fields: dict[str, Any], field: str, ird: IrdClient,
                                   node: NodeProcess, open_query: int) -> None:
    request = dict(query_id=open_query, chosen=0, beta=0.0, answered_by="battery") | fields
    result = ird.answer(request.pop("query_id"), request.pop("chosen"), timeout=60.0, **request)
    _assert_refused(result, field)
    assert node.alive()


def test_after_the_hostile_answers_a_valid_one_is_taken(ird: IrdClient, world: lavaland.LavalandInstance,
                                                        open_query: int) -> None:
    answered = ird.answer(open_query, 1, beta=2.0, answered_by="battery", timeout=120.0)
    assert answered.ok, answered.message
    assert ird.infer(_valid(world), timeout=120.0).ok


def test_one_pass_too_large_for_the_worker_memory_is_named() -> None:
    check_pass_memory("training_map", 100, 100, 1000, 16, 2**30)  # 153 MiB: fits in 1 GiB
    with pytest.raises(ValueError, match=r"^training_map: .* more than worker_memory_mb=1024"):
        check_pass_memory("training_map", 1000, 1000, 1000, 16, 2**30)
    check_pass_memory("training_map", 1000, 1000, 1000, 16, 0)  # 0 = no limit


# --------------------------------------------------------------------------- the time budget


def _sample(num_samples: int, **rule: Any) -> posterior.Posterior:
    inst = lavaland.make_instance("side_effects", 4, size=SIZE, horizon=HORIZON)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return posterior.sample_posterior(inst.proxy_weights, lavaland.train_mdp(inst), 2.0, "maxent_z", num_samples,
                                          1, num_chains=4, warmup=20,
                                          until_converged=RunUntil(r_hat=1.05, min_ess=400.0, **rule))


def test_the_time_budget_is_checked_inside_the_first_run() -> None:
    # 400 samples from 4 chains: 100 per chain, thinned by 2 from a first run of 200 iterations.
    fixed = _sample(400)
    assert fixed.iterations >= 200
    cut = _sample(400, time_budget_s=1e-9)
    assert cut.stop_reason == "time_budget" and cut.iterations == 120  # checked after 120, not at 200
    assert cut.samples.shape == fixed.samples.shape and np.all(np.isfinite(cut.samples))


def test_a_budget_spent_before_the_samples_exist_names_num_samples() -> None:
    with pytest.raises(ValueError, match=r"^num_samples: the time budget of 1e-09 s ran out after 120 iterations "
                                         r"per chain, fewer than the 1000"):
        _sample(4000, time_budget_s=1e-9)


def test_budget_checks_do_not_change_the_draws() -> None:
    free = _sample(2000)  # 500 per chain: one first run
    checked = _sample(2000, time_budget_s=1e9)  # the same run in sub-blocks, budget never spent
    assert np.array_equal(free.samples, checked.samples)
    assert (free.iterations, free.acceptance_rate, free.num_evaluations, free.step_size) == (
        checked.iterations, checked.acceptance_rate, checked.num_evaluations, checked.step_size)
    assert np.array_equal(free.r_hat, checked.r_hat) and np.array_equal(free.ess, checked.ess)
