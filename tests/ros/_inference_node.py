"""An inference node with small sampler settings, shared by the inference node's tests: the
node passes SAMPLER to the library, so a test can recompute its answer with the same settings."""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Iterator

from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess, spawn_node_process

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
# Small sampler settings keep the suite fast; the node passes them to sample_posterior.
SAMPLER = dict(num_chains=4, warmup=20, thin=1, num_proxy_samples=16)


@contextlib.contextmanager
def small_inference_node(domain: DomainLease) -> Iterator[NodeProcess]:
    """The inference node with SAMPLER, ready; on exit its clean shutdown (code 0) is checked."""
    args = ["-m", "ird_ros.nodes.inference", "--ros-args", "--params-file", PARAMS]
    for key, value in SAMPLER.items():
        args += ["-p", f"{key}:={value}"]
    with spawn_node_process(args, domain=domain, name="inference", ready_text="inference ready") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()
