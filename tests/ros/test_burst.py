"""A burst of concurrent /ird/infer clients: every request gets an answer (docs/spec.md section 8).

32 client nodes (each its own DDS participant, as separate client programs would be) discover
the service, then all call it at once. Every call must be answered: a posterior, or
``success: false`` with "busy" and a queue position. Silence is the failure this guards.

Two queues of depth 10 (rclpy's default service QoS) lost answers: the server's request reader
(a burst of 32 requests arriving before the executor took them: 11 answered) and each client's
response reader, which receives the responses to every client of the service (a burst of
immediate "busy" answers pushed a client's own response out before it was taken). The nodes
serve with ``ird_ros.runtime.offload.service_qos()`` and the clients here use it too, as the project's
scripts do.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor

from ird_core.worlds import lavaland
from ird_msgs.srv import InferReward
from ird_ros import conversions as conv
from ird_ros.graph import names
from ird_ros.runtime.offload import service_qos
from ird_ros.testing import DomainLease, NodeProcess, spawn_node_process, spin_until

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
    req = InferReward.Request()
    req.training_map = conv.feature_grid_to_msg(inst.train_features, inst.feature_names)
    req.start_row, req.start_col = inst.train_start
    req.horizon = inst.train_horizon
    req.proxy_weights = conv.weights_to_flat(inst.proxy_weights)
    req.beta, req.method, req.num_samples, req.seed = 2.0, "maxent_z", 8, seed
    return req


def test_every_client_of_a_burst_gets_an_answer(ros_ctx: Any, inference: NodeProcess) -> None:
    inst = lavaland.make_instance("side_effects", 1, size=3, horizon=3)
    executor = SingleThreadedExecutor(context=ros_ctx)
    nodes, clients = [], []
    try:
        for i in range(NUM_CLIENTS):
            node = rclpy.create_node(f"burst_client_{i}", context=ros_ctx)
            executor.add_node(node)
            nodes.append(node)
            clients.append(node.create_client(InferReward, names.SRV_INFER, qos_profile=service_qos()))
        spin_until(nodes[0], lambda: all(c.service_is_ready() for c in clients), timeout=60.0,
                   what="every client to discover /ird/infer", executor=executor, processes=[inference])
        futures = [c.call_async(_request(inst, seed=i)) for i, c in enumerate(clients)]
        spin_until(nodes[0], lambda: all(f.done() for f in futures), timeout=120.0,
                   what=f"answers to {NUM_CLIENTS} concurrent requests", executor=executor, processes=[inference])
        responses = [f.result() for f in futures]
        answered = [r for r in responses if r.success]
        busy = [r for r in responses if not r.success]
        for r in busy:
            assert r.message.startswith("busy") and "queue position" in r.message, r.message
        assert all(r.posterior.num_samples == 8 for r in answered)
        # max_pending = 8: at least that many were computed, and the rest were told why not.
        assert len(answered) >= 8, [r.message for r in busy]
        print(f"{len(answered)} computed, {len(busy)} busy of {NUM_CLIENTS}")
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()


def test_one_client_node_with_a_burst_of_calls(ros_ctx: Any, inference: NodeProcess) -> None:
    """The second report: 32 calls from one client node (its own request and response queues)."""
    inst = lavaland.make_instance("side_effects", 2, size=3, horizon=3)
    node = rclpy.create_node("burst_single_client", context=ros_ctx)
    try:
        client = node.create_client(InferReward, names.SRV_INFER, qos_profile=service_qos())
        spin_until(node, client.service_is_ready, timeout=60.0, what="/ird/infer", processes=[inference])
        futures = [client.call_async(_request(inst, seed=i)) for i in range(NUM_CLIENTS)]
        spin_until(node, lambda: all(f.done() for f in futures), timeout=120.0,
                   what=f"answers to {NUM_CLIENTS} calls of one client", processes=[inference])
        responses = [f.result() for f in futures]
        assert all(r.success or (r.message.startswith("busy") and "queue position" in r.message) for r in responses)
        assert sum(r.success for r in responses) >= 8
    finally:
        node.destroy_node()
