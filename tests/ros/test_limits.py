"""The planner's limits over real DDS (docs/spec.md section 8): sizes refused before work starts with
the field and the limit named, out-of-range numbers named, a trajectory plan bounded by
``time_limit`` and answered as a fallback, and a short plan never waiting behind a long one; and
the worker memory cap (``RLIMIT_AS``) of the planning and the inference workers."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest

from ird_core import planning
from ird_core.mdp import GridMDP
from ird_core.worlds import lavaland
from ird_msgs.srv import PlanPath
from ird_ros import conversions as conv
from ird_ros.client import CallResult, CallStatus, IrdClient, Plan, plan_request
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess, spawn_node_process

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
TIME_LIMIT = 3.0


@pytest.fixture(scope="module")
def planner(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    args = ["-m", "ird_ros.nodes.planner", "--ros-args", "--params-file", PARAMS, "-p", f"time_limit:={TIME_LIMIT}"]
    with spawn_node_process(args, domain=ros_domain, name="planner", ready_text="planner ready") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()


@pytest.fixture(scope="module")
def client(ros_ctx: Any, planner: NodeProcess) -> Iterator[IrdClient]:
    with IrdClient(context=ros_ctx, node_name="limits_client", processes=[planner]) as ird:
        ird.wait_ready(30.0, services=(names.SRV_PLAN,))
        yield ird


def _request(features: np.ndarray, layers: tuple[str, ...], start: tuple[int, int], horizon: int,
             weights: np.ndarray, mode: str, baseline: str = "none") -> PlanPath.Request:
    grid = conv.feature_grid_to_msg(features, layers)
    return plan_request(start, horizon, mode, baseline, weights=weights, grid=grid)


@pytest.fixture(scope="module")
def small() -> lavaland.LavalandInstance:
    return lavaland.make_instance("side_effects", 3, size=5, horizon=6)


def _call(client: IrdClient, planner: NodeProcess, req: PlanPath.Request) -> CallResult[Plan]:
    return client.plan(req, timeout=60.0)


def test_plan_work_is_refused_before_it_starts(client: Any, planner: NodeProcess,
                                               small: lavaland.LavalandInstance) -> None:
    d = small.test_features.shape[2]
    weights = np.random.default_rng(0).normal(size=(200_000, d))
    req = _request(small.test_features, small.feature_names, small.test_start, 1000, weights, "per_step")
    response = _call(client, planner, req)
    assert response.status is CallStatus.REFUSED and response.field == "weights", response
    assert response.message.startswith("weights: 200000 samples x horizon 1000"), response.message
    assert "max_plan_work=5e+07" in response.message


@pytest.mark.parametrize("weights,mode", [([1e308] * 4, "per_step"), ([1e308, -1e308, 1e308, -1e308], "literal"),
                                          ([2e4, 0.0, 0.0, 0.0], "trajectory")])
def test_out_of_range_weights_are_named(client: Any, planner: NodeProcess, small: lavaland.LavalandInstance,
                                        weights: list[float], mode: str) -> None:
    req = _request(small.test_features, small.feature_names, small.test_start, 6, np.array(weights), mode)
    response = _call(client, planner, req)
    assert response.status is CallStatus.REFUSED and response.field == "weights", response
    assert response.message.startswith("weights: a value of magnitude"), response.message


def test_huge_map_values_are_named(client: Any, planner: NodeProcess, small: lavaland.LavalandInstance) -> None:
    req = _request(np.full((5, 5, 4), 1e30), small.feature_names, (0, 0), 6, np.ones(4), "literal")
    response = _call(client, planner, req)
    assert response.status is CallStatus.REFUSED and response.field == "map.data", response
    assert response.message.startswith("map.data: a value of magnitude 1e+30"), response.message


def test_long_trajectory_does_not_delay_a_per_step_plan(client: IrdClient, planner: NodeProcess) -> None:
    inst = lavaland.make_instance("latent_raw", 0, size=15, horizon=30, obs_dim=50)
    weights = np.random.default_rng(0).normal(size=(16, inst.test_features.shape[2]))
    # The reliability report's slow case (log_z: no proof within the time limit on the core).
    long_req = _request(inst.test_features, inst.feature_names, inst.test_start, 30, weights, "trajectory", "log_z")
    short_req = _request(inst.test_features, inst.feature_names, inst.test_start, 30, weights, "per_step", "log_z")
    order: list[str] = []
    long_pending = client.plan_async(long_req)
    long_pending.add_done_callback(lambda: order.append("trajectory"))
    short_pending = client.plan_async(short_req)
    short_pending.add_done_callback(lambda: order.append("per_step"))
    client.spin_until(lambda: len(order) == 2, timeout=120.0, what="both plans")
    assert order == ["per_step", "trajectory"]
    short, long = short_pending.result(), long_pending.result()
    assert short.ok, short.message
    assert long.ok, long.message
    mdp = GridMDP(inst.test_features.astype(np.float32).astype(np.float64), inst.test_start, 30)
    cells = list(long.unwrap().cells)
    # Whatever the solver reached, the objective reported is the path's exact objective.
    assert long.unwrap().objective == pytest.approx(planning.path_objective(mdp, cells, weights, "trajectory", "log_z"),
                                           rel=1e-9, abs=1e-9)
    if "FALLBACK" in long.message:
        assert f"time_limit: {TIME_LIMIT} s passed" in long.message
    print(long.message)


def _allocate(megabytes: int) -> int:
    return int(np.ones(megabytes * 2**20 // 8).sum())


def test_worker_memory_limit_fails_the_job_not_the_pool() -> None:
    from ird_ros.runtime.node_main import WorkerPool

    pool = WorkerPool(1, warm_modules=("numpy",), memory_limit=1024 * 2**20)
    try:
        with pytest.raises(MemoryError):
            pool.submit_concurrent(_allocate, 2048).result(timeout=60.0)
        # The same worker (not a replacement) computes the next job within the limit.
        assert pool.submit_concurrent(_allocate, 64).result(timeout=60.0) == 64 * 2**20 // 8
    finally:
        pool.shutdown()


def test_empty_condition_keeps_the_current_one(ros_domain: DomainLease, ros_ctx: Any) -> None:
    args = ["-m", "ird_ros.nodes.world", "--ros-args", "--params-file", PARAMS, "-p", "condition:=reward_hacking",
            "-p", "height:=5", "-p", "width:=5", "-p", "horizon:=4"]
    with spawn_node_process(args, domain=ros_domain, name="world", ready_text="world ready") as world:
        with IrdClient(context=ros_ctx, node_name="limits_world_client", processes=[world]) as ird:
            response = ird.generate_world("", 5, timeout=30.0)
    assert response.ok and response.message.startswith("generated reward_hacking seed 5"), response.message


def test_map_size_is_refused_by_name(client: Any, planner: NodeProcess) -> None:
    req = _request(np.zeros((1000, 1000, 6)), tuple(f"f{i}" for i in range(6)), (0, 0), 1, np.ones(6), "literal")
    response = _call(client, planner, req)
    assert response.status is CallStatus.REFUSED and response.field == "map.data", response
    assert response.message == "map.data: 6000000 values exceed max_map_values=5000000"


def test_inference_workers_are_memory_capped(ros_domain: DomainLease, ros_ctx: Any) -> None:
    """A request within every up-front limit whose MDP tables do not fit in the worker's capped
    address space fails naming worker_memory_mb; the worker and the node serve on."""
    from ird_ros.client import infer_request

    args = ["-m", "ird_ros.nodes.inference", "--ros-args", "--params-file", PARAMS, "-p", "worker_memory_mb:=1024",
            "-p", "num_chains:=2", "-p", "warmup:=20", "-p", "thin:=1"]
    small = lavaland.make_instance("side_effects", 3, size=5, horizon=6)
    valid = infer_request(conv.feature_grid_to_msg(small.train_features, small.feature_names), small.train_start, 6,
                          small.proxy_weights, beta=1.0, method="maxent_z", num_samples=8, seed=0)
    # One weight's pass keeps two 1001 x 191 x 191 float64 tables (584 MiB, under the cap by
    # itself): with the worker's own ~520 MiB it does not fit in 1024 MiB. Its work, 2 chains x
    # 21 iterations x 64 leapfrog steps x 3.6e7, is under max_inference_work (2e11).
    big = infer_request(conv.feature_grid_to_msg(np.ones((190, 190, 1)), ("a",)), (0, 0), 1000, [1.0], beta=1.0,
                        method="maxent_z", num_samples=1, seed=0)
    with spawn_node_process(args, domain=ros_domain, name="inference", ready_text="inference ready") as node, \
            IrdClient(context=ros_ctx, node_name="limits_inference_client", processes=[node]) as ird:
        ird.wait_ready(30.0, services=(names.SRV_INFER,))
        refused = ird.infer(big, timeout=120.0)
        assert not refused.ok and refused.message.startswith(
            "worker_memory_mb: inference needed more than the worker's 1024 MiB (MemoryError"), refused.message
        assert ird.infer(valid, timeout=120.0).ok
        assert node.alive()
    assert node.returncode == 0, node.describe()
