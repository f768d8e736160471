"""Shared by the /ird/query and designer DDS tests: a small world (8x8, T = 12, side_effects),
fast sampler settings, and a probe: an IrdClient that collects the conversation with the designer."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ird_ros.client import CallResult, IrdClient, Query, WorldMessages, infer_request, query_request
from ird_ros.conversions import PosteriorData
from ird_ros.graph import names
from ird_ros.testing import NodeProcess

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
SIZE, HORIZON = 8, 12
SAMPLER_ARGS = ["-p", "num_chains:=4", "-p", "warmup:=40", "-p", "thin:=1"]
NUM_SAMPLES = 400
SERVICES = (names.SRV_INFER, names.SRV_QUERY, names.SRV_ANSWER, names.SRV_GENERATE)


def world_args(seed: int) -> list[str]:
    return ["-p", "condition:=side_effects", "-p", f"height:={SIZE}", "-p", f"width:={SIZE}",
            "-p", f"horizon:={HORIZON}", "-p", f"seed:={seed}"]


def node_args(module: str, extra: list[str]) -> list[str]:
    return ["-m", module, "--ros-args", "--params-file", PARAMS, *extra]


class Probe:
    """The test's client of the graph (an ``IrdClient`` whose waits watch ``procs``), collecting
    /ird/queries and /ird/posterior from the start."""

    def __init__(self, ctx: Any, procs: list[NodeProcess], name: str = "query_test_probe") -> None:
        self.ird = IrdClient(context=ctx, node_name=name, processes=procs)
        self.procs = self.ird.processes  # tests add and remove helper processes here
        self.ird.wait_ready(30.0, services=SERVICES)
        self.ird.subscribe(names.TOPIC_QUERIES, names.TOPIC_POSTERIOR)

    def close(self) -> None:
        self.ird.close()

    @property
    def records(self) -> list[Any]:
        """Every /ird/queries record received (ird_msgs/QueryRecord)."""
        return self.ird.received(names.TOPIC_QUERIES)

    @property
    def posteriors(self) -> list[Any]:
        """Every /ird/posterior message received (ird_msgs/RewardPosterior)."""
        return self.ird.received(names.TOPIC_POSTERIOR)

    def spin_until(self, cond: Any, what: str, timeout: float = 60.0) -> None:
        self.ird.spin_until(cond, timeout=timeout, what=what)

    def world(self, other_than: WorldMessages | None = None) -> WorldMessages:
        """The latest world's maps and proxy (all of one generation: same header stamp)."""
        return self.ird.world(other_than=other_than, timeout=60.0)

    def infer(self, world: WorldMessages, seed: int = 5) -> PosteriorData:
        proxy = world.proxy
        request = infer_request(world.train, (proxy.start_row, proxy.start_col), proxy.horizon, proxy.weights,
                                beta=2.0, method="maxent_z", num_samples=NUM_SAMPLES, seed=seed)
        result = self.ird.infer(request, timeout=120.0)
        assert result.ok, result.message
        return result.unwrap()

    def query(self, proxy: Any, **kw: Any) -> CallResult[Query]:
        return self.ird.propose_query(query_request((proxy.test_start_row, proxy.test_start_col), **kw),
                                      timeout=120.0)

    def answer(self, query_id: int, chosen: int, beta: float = 0.0) -> CallResult[PosteriorData]:
        return self.ird.answer(query_id, chosen, beta=beta, answered_by="client", timeout=120.0)
