"""Shared by the /ird/query and designer DDS tests: a small world (8x8, T = 12, side_effects),
fast sampler settings, and a probe node with the services' clients and the latched inputs."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import rclpy

from ird_msgs.msg import FeatureGrid, ProxyReward, QueryRecord, RewardPosterior, TerrainGrid
from ird_msgs.srv import AnswerQuery, GenerateWorld, InferReward, ProposeQuery
from ird_ros.graph import names
from ird_ros.testing import NodeProcess, call_service, spin_until, wait_for_service

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
SIZE, HORIZON = 8, 12
SAMPLER_ARGS = ["-p", "num_chains:=4", "-p", "warmup:=40", "-p", "thin:=1"]
NUM_SAMPLES = 400


def world_args(seed: int) -> list[str]:
    return ["-p", "condition:=side_effects", "-p", f"height:={SIZE}", "-p", f"width:={SIZE}",
            "-p", f"horizon:={HORIZON}", "-p", f"seed:={seed}"]


def node_args(module: str, extra: list[str]) -> list[str]:
    return ["-m", module, "--ros-args", "--params-file", PARAMS, *extra]


class Probe:
    """The test's node: clients of every service and the latched inputs it needs."""

    def __init__(self, ctx: Any, procs: list[NodeProcess], name: str = "query_test_probe") -> None:
        self.node = rclpy.create_node(name, context=ctx)
        self.procs = list(procs)
        self.clients = {
            name: self.node.create_client(srv, name)
            for name, srv in ((names.SRV_INFER, InferReward), (names.SRV_QUERY, ProposeQuery),
                              (names.SRV_ANSWER, AnswerQuery), (names.SRV_GENERATE, GenerateWorld))
        }
        for client in self.clients.values():
            wait_for_service(self.node, client, processes=procs, timeout=30.0)
        self.latest: dict[str, Any] = {}
        self.records: list[QueryRecord] = []
        self.posteriors: list[RewardPosterior] = []
        latched = names.latched_qos()
        for topic, msg_type in ((names.TOPIC_TRAIN_FEATURES, FeatureGrid), (names.TOPIC_TEST_FEATURES, FeatureGrid),
                                (names.TOPIC_TERRAIN, TerrainGrid), (names.TOPIC_PROXY, ProxyReward)):
            self.node.create_subscription(msg_type, topic, lambda m, t=topic: self.latest.__setitem__(t, m), latched)
        self.node.create_subscription(QueryRecord, names.TOPIC_QUERIES, self.records.append, names.history_qos())
        self.node.create_subscription(RewardPosterior, names.TOPIC_POSTERIOR, self.posteriors.append, latched)

    def spin_until(self, cond: Any, what: str, timeout: float = 60.0) -> None:
        spin_until(self.node, cond, timeout=timeout, what=what, processes=self.procs)

    def call(self, service: str, request: Any, timeout: float = 120.0) -> Any:
        return call_service(self.node, self.clients[service], request, timeout=timeout, processes=self.procs)

    def world(self, stamp_after: Any = None) -> tuple[FeatureGrid, FeatureGrid, ProxyReward]:
        """The latest world's maps and proxy (all of one generation: same header stamp)."""
        def complete() -> bool:
            msgs = [self.latest.get(t) for t in (names.TOPIC_TRAIN_FEATURES, names.TOPIC_TEST_FEATURES,
                                                 names.TOPIC_PROXY)]
            if any(m is None for m in msgs) or len({(m.header.stamp.sec, m.header.stamp.nanosec) for m in msgs}) != 1:
                return False
            return stamp_after is None or msgs[2].header.stamp != stamp_after
        self.spin_until(complete, "a complete world")
        return (self.latest[names.TOPIC_TRAIN_FEATURES], self.latest[names.TOPIC_TEST_FEATURES],
                self.latest[names.TOPIC_PROXY])

    def infer(self, train: FeatureGrid, proxy: ProxyReward, seed: int = 5) -> InferReward.Response:
        req = InferReward.Request(training_map=train, start_row=proxy.start_row, start_col=proxy.start_col,
                                  horizon=proxy.horizon, proxy_weights=proxy.weights, beta=2.0, method="maxent_z",
                                  num_samples=NUM_SAMPLES, seed=seed)
        response = self.call(names.SRV_INFER, req)
        assert response.success, response.message
        return response

    def query(self, proxy: ProxyReward, **kw: Any) -> ProposeQuery.Response:
        req = ProposeQuery.Request(start_row=proxy.test_start_row, start_col=proxy.test_start_col, **kw)
        return self.call(names.SRV_QUERY, req)

    def answer(self, query_id: int, chosen: int, beta: float = 0.0) -> AnswerQuery.Response:
        return self.call(names.SRV_ANSWER, AnswerQuery.Request(query_id=query_id, chosen=chosen, beta=beta,
                                                               answered_by="client"))
