"""Process life cycle of the nodes (ird_ros.runtime.node_main): clean exit 0 on SIGINT and SIGTERM, also
when started with SIGINT ignored (``cmd &`` from a non-interactive shell), with the inference
worker processes gone, even in the middle of a long inference."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Iterator

import pytest

from ird_core.worlds import lavaland
from ird_ros import conversions as conv
from ird_ros import graph
from ird_ros.client import IrdClient, infer_request
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.waits import wait_for_node

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")


class Background:
    """``python -m module`` started like ``cmd &`` from a script: SIGINT ignored, own process group."""

    def __init__(self, module: str, domain: DomainLease, *extra: str) -> None:
        self.lines: list[str] = []
        self.ready = threading.Event()
        self.proc = subprocess.Popen(
            [sys.executable, "-m", module, "--ros-args", "--params-file", PARAMS, *extra],
            env=domain.env(), cwd=ROOT, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
            text=True, preexec_fn=lambda: (signal.signal(signal.SIGINT, signal.SIG_IGN), os.setpgrp()))
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip())
            if line.rstrip().endswith(" ready"):
                self.ready.set()

    def output(self) -> str:
        return "\n".join(self.lines[-50:])

    def children(self) -> list[int]:
        pids = []
        for task in Path(f"/proc/{self.proc.pid}/task").iterdir():
            pids += [int(p) for p in (task / "children").read_text().split()]
        return pids

    def kill(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()


@pytest.fixture
def started() -> Iterator[list[Background]]:
    procs: list[Background] = []
    yield procs
    for p in procs:
        p.kill()


def _all_exit(pids: list[int], timeout: float = 10.0) -> bool:
    """Wait (on pidfds, no polling) until every process in ``pids`` has terminated."""
    deadline = time.monotonic() + timeout
    for pid in pids:
        try:
            fd = os.pidfd_open(pid)
        except ProcessLookupError:
            continue  # gone already
        try:
            ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
            if not ready:
                return False
        finally:
            os.close(fd)
    return True


def test_nodes_exit_0_on_signal_even_with_sigint_ignored(ros_domain: DomainLease, ros_node: Any,
                                                         started: list[Background]) -> None:
    """Every node of the graph, all started at once like ``cmd &``, then signalled together:
    SIGINT and SIGTERM alternately (every node runs the same ``run_node``; the inference node
    also gets SIGTERM mid-inference in the next test)."""
    procs = {spec.name: Background(spec.module, ros_domain, *(["-p", "height:=5", "-p", "width:=5"]
                                                              if spec.name == "world" else []))
             for spec in graph.NODES}
    started.extend(procs.values())
    for name, bg in procs.items():
        assert bg.ready.wait(60.0), f"{name}:\n{bg.output()}"
        wait_for_node(ros_node, name, timeout=30.0)
    workers = {name: bg.children() for name, bg in procs.items()}
    for name, pids in workers.items():  # inference and planner compute in worker processes
        assert (len(pids) >= 1) == (name in ("inference", "planner")), (name, pids)
    signals = {}
    for i, (name, bg) in enumerate(procs.items()):
        signals[name] = (signal.SIGINT, signal.SIGTERM)[i % 2]
        bg.proc.send_signal(signals[name])
    for name, bg in procs.items():
        assert bg.proc.wait(timeout=15.0) == 0, f"{name} ({signals[name].name}):\n{bg.output()}"
        assert "Traceback" not in bg.output(), f"{name}:\n{bg.output()}"
        assert _all_exit(workers[name]), (name, workers[name])


def test_sigterm_during_a_long_inference(ros_domain: DomainLease, ros_ctx: Any, started: list[Background]) -> None:
    bg = Background("ird_ros.nodes.inference", ros_domain)
    started.append(bg)
    assert bg.ready.wait(60.0), bg.output()
    with IrdClient(context=ros_ctx, node_name="sigterm_client") as ird:
        ird.wait_ready(30.0, services=(names.SRV_INFER,))
        inst = lavaland.make_instance("latent_raw", 0, size=15, horizon=30)
        req = infer_request(conv.feature_grid_to_msg(inst.train_features, inst.feature_names), inst.train_start,
                            inst.train_horizon, inst.proxy_weights, beta=1.0, method="maxent_z", num_samples=100000,
                            seed=1)
        pending = ird.infer_async(req)
        t0 = time.monotonic()
        ird.spin_until(lambda: time.monotonic() - t0 > 1.0, timeout=5.0, what="the inference to be under way")
        workers = bg.children()
        assert workers and not pending.done()
        t0 = time.monotonic()
        bg.proc.send_signal(signal.SIGTERM)
        assert bg.proc.wait(timeout=15.0) == 0, bg.output()
        took = time.monotonic() - t0
        assert took < 5.0, took
        assert _all_exit(workers), workers
