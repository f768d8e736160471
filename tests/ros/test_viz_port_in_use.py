"""A second live view on a port in use (issue 43): the launcher says which port and names
--viz-port; with --viz-port 0 it prints the port the live view got."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "launch_graph.py"


def _launch(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, str(SCRIPT), "--private-domain", "--nodes", "viz", "--timeout", "90",
                           "--output", "quiet", "--run-for", "0", *args], capture_output=True, text=True,
                          timeout=300, cwd=ROOT)


def test_a_port_in_use_names_viz_port_and_port_zero_prints_the_bound_port() -> None:
    with socket.create_server(("127.0.0.1", 0)) as busy:
        port = busy.getsockname()[1]
        run = _launch("--viz-port", str(port))
    assert run.returncode == 1, run.stdout
    assert f"port: cannot listen on 127.0.0.1:{port}" in run.stderr and "--viz-port N" in run.stderr, run.stderr
    run = _launch("--viz-port", "0")
    assert run.returncode == 0, run.stderr
    (line,) = [x for x in run.stdout.splitlines() if x.startswith("[launcher] live view: ws://127.0.0.1:")]
    bound = int(line.split("ws://127.0.0.1:")[1].split()[0])
    assert bound > 0
