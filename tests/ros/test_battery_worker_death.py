"""A worker killed while it computes a request fails that request only (ird_ros.runtime.workers):
the requests queued behind it, of the same client and of another, run on the fresh worker and
succeed, and the inference node goes on serving."""

from __future__ import annotations

import os
import re
import signal
from typing import Any, Iterator

from pathlib import Path

import numpy as np
import pytest

from ird_core.worlds import lavaland
from ird_msgs.srv import InferReward
from ird_ros import conversions as conv
from ird_ros.client import CallStatus, IrdClient, infer_request
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess, spawn_node_process

PARAMS = str(Path(__file__).resolve().parents[2] / "msgs_config" / "params" / "graph.yaml")
# Fixed-length chains (thin set: no time budget), default limits: the long request below fits.
ARGS = ["-m", "ird_ros.nodes.inference", "--ros-args", "--params-file", PARAMS, "-p", "num_chains:=4",
        "-p", "warmup:=20", "-p", "thin:=1"]


def _request(inst: lavaland.LavalandInstance, num_samples: int, seed: int) -> InferReward.Request:
    grid = conv.feature_grid_to_msg(inst.train_features.astype("float32"), inst.feature_names)
    return infer_request(grid, inst.train_start, inst.train_horizon, inst.proxy_weights, beta=1.0, method="maxent_z",
                         num_samples=num_samples, seed=seed)


@pytest.fixture
def node(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    with spawn_node_process(ARGS, domain=ros_domain, name="inference", ready_text="inference ready") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()


def _parent(pid: int) -> int:
    with open(f"/proc/{pid}/stat") as stat:
        return int(stat.read().rsplit(")", 1)[1].split()[1])


def test_a_killed_worker_fails_only_the_request_it_ran(ros_ctx: Any, node: NodeProcess) -> None:
    small = lavaland.make_instance("side_effects", 3, size=5, horizon=6)
    big = lavaland.make_instance("latent_raw", 0, size=15, horizon=30, obs_dim=50)
    long_request = _request(big, 20000, 1)  # 5000 iterations per chain of 4: minutes, unless its worker is killed
    with IrdClient(context=ros_ctx, node_name="worker_death_client", processes=[node]) as ird, \
            IrdClient(context=ros_ctx, node_name="worker_death_other_client", processes=[node]) as other:
        ird.wait_ready(30.0, services=(names.SRV_INFER,))
        other.wait_ready(30.0, services=(names.SRV_INFER,))
        victim = ird.infer_async(long_request, timeout=30.0)
        # The same client's next request reaches the node after the long one (one writer, in
        # order): once it has to queue, the long request is in the worker.
        follower = ird.infer_async(_request(small, 12, 4), timeout=30.0)
        line = node.wait_for_output("inference: a request waits at queue position 1", timeout=60.0)
        innocent = other.infer_async(_request(small, 12, 5), timeout=30.0)  # another client's, queued too
        node.wait_for_output("inference: a request waits at queue position 2", timeout=60.0)
        pid = int(re.search(r"busy worker pids \[(\d+)\]", line).group(1))
        assert _parent(pid) == node.pid  # the node's own worker, nothing else
        os.kill(pid, signal.SIGKILL)
        ird.spin_until(victim.done, timeout=120.0, what="the killed request's answer")
        failed = victim.result()
        assert failed.status is CallStatus.FAILED, failed.message
        assert failed.message.startswith("internal error: the worker process died"), failed.message
        other.spin_until(innocent.done, timeout=120.0, what="the other client's queued request")
        assert innocent.result().ok, innocent.result().message
        ird.spin_until(follower.done, timeout=120.0, what="the same client's queued request")
        assert follower.result().ok, follower.result().message
        assert np.all(np.isfinite(follower.result().unwrap().samples))
        assert ird.infer(_request(small, 12, 6), timeout=120.0).ok  # and the node goes on
        assert node.alive()
