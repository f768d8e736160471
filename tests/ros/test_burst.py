"""A burst of concurrent /ird/infer clients: every request gets an answer (docs/spec.md section 8).

32 client nodes (each its own DDS participant, as separate client programs would be) discover
the service, then all call it at once. Every call must be answered: a posterior, or
``success: false`` with "busy" and a queue position. Silence is the failure this guards.

Two queues of depth 10 (rclpy's default service QoS) lost answers: the server's request reader
(a burst arriving before the executor took it lost the oldest requests) and each client's
response reader, which receives the responses to every client of the service (a burst of
immediate "busy" answers pushed a client's own response out before it was taken). The nodes
serve with ``ird_ros.runtime.offload.service_qos()`` and ``ird_ros.client.IrdClient`` (the clients
here, as every program of the project) calls with it too.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import pytest
from rclpy.executors import SingleThreadedExecutor

from ird_core.worlds import lavaland
from ird_msgs.srv import InferReward
from ird_ros import conversions as conv
from ird_ros.client import CallStatus, IrdClient, infer_request
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess, spawn_node_process

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
NUM_CLIENTS = 32


@pytest.fixture(scope="module")
def inference(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    args = ["-m", "ird_ros.nodes.inference", "--ros-args", "--params-file", PARAMS,
            "-p", "num_chains:=2", "-p", "warmup:=10", "-p", "thin:=1", "-p", "max_pending:=8"]
    with spawn_node_process(args, domain=ros_domain, name="inference", ready_text="inference ready") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()


def _request(inst: lavaland.LavalandInstance, seed: int) -> InferReward.Request:
    return infer_request(conv.feature_grid_to_msg(inst.train_features, inst.feature_names), inst.train_start,
                         inst.train_horizon, inst.proxy_weights, beta=2.0, method="maxent_z", num_samples=8, seed=seed)


def test_every_client_of_a_burst_gets_an_answer(ros_ctx: Any, inference: NodeProcess) -> None:
    inst = lavaland.make_instance("side_effects", 1, size=3, horizon=3)
    executor = SingleThreadedExecutor(context=ros_ctx)
    clients: list[IrdClient] = []
    try:
        for i in range(NUM_CLIENTS):
            clients.append(IrdClient(context=ros_ctx, node_name=f"burst_client_{i}", executor=executor,
                                     processes=[inference]))
        clients[0].spin_until(lambda: all(c.is_ready(names.SRV_INFER) for c in clients), timeout=60.0,
                              what="every client to discover /ird/infer")
        pending = [c.infer_async(_request(inst, seed=i)) for i, c in enumerate(clients)]
        clients[0].spin_until(lambda: all(p.done() for p in pending), timeout=120.0,
                              what=f"answers to {NUM_CLIENTS} concurrent requests")
        results = [p.result() for p in pending]
        answered = [r for r in results if r.ok]
        busy = [r for r in results if not r.ok]
        for r in busy:
            assert r.status is CallStatus.BUSY and "queue position" in r.message, r.message
        assert all(r.response.posterior.num_samples == 8 and r.unwrap().samples.shape[0] == 8 for r in answered)
        # max_pending = 8: at least that many were computed, and the rest were told why not.
        assert len(answered) >= 8, [r.message for r in busy]
        print(f"{len(answered)} computed, {len(busy)} busy of {NUM_CLIENTS}")
    finally:
        for client in clients:
            client.close()
        executor.shutdown()


def test_one_client_node_with_a_burst_of_calls(ros_ctx: Any, inference: NodeProcess) -> None:
    """The second report: 32 calls from one client node (its own request and response queues)."""
    inst = lavaland.make_instance("side_effects", 2, size=3, horizon=3)
    with IrdClient(context=ros_ctx, node_name="burst_single_client", processes=[inference]) as ird:
        ird.wait_ready(60.0, services=(names.SRV_INFER,))
        pending = [ird.infer_async(_request(inst, seed=i)) for i in range(NUM_CLIENTS)]
        ird.spin_until(lambda: all(p.done() for p in pending), timeout=120.0,
                       what=f"answers to {NUM_CLIENTS} calls of one client")
        results = [p.result() for p in pending]
        assert all(r.ok or (r.status is CallStatus.BUSY and "queue position" in r.message) for r in results)
        assert sum(r.ok for r in results) >= 8
