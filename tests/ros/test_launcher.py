"""ird_ros.launch.GraphLauncher / scripts/launch_graph.py: start, readiness, death reports, respawn, stop.

Every graph runs in a domain leased by the launcher itself (``private_domain``). The
stand-in table (tests/ros/_standin_node.py: the real node table, each node replaced by a
fast stand-in with the same names, topics, types, QoS and services) exercises the process
supervision; the real nodes run in ``test_cli_real_graph`` once all their modules exist.
Nothing sleeps: waits are on launcher events, process exits (pidfd) and output lines.
"""

from __future__ import annotations

import os
import select
import signal
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
import yaml
from _standin_node import STANDIN_SPECS

from ird_ros.bags import storage
from ird_ros.graph import DEFAULT_NODES, domains, names
from ird_ros.launch import GraphLauncher, LaunchError
from ird_ros.testing import NodeProcess

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "launch_graph.py"
ALL = list(DEFAULT_NODES)


def _running(pid: int) -> bool:
    """True while ``pid`` exists and is not a zombie."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def wait_pids_gone(pids: list[int], timeout: float) -> list[int]:
    """Wait (pidfd, no polling sleeps) until every pid has exited; return those still running."""
    deadline = time.monotonic() + timeout
    for pid in pids:
        try:
            fd = os.pidfd_open(pid)
        except ProcessLookupError:
            continue
        try:
            poller = select.poll()
            poller.register(fd, select.POLLIN)
            poller.poll(max(0.0, deadline - time.monotonic()) * 1000)
        finally:
            os.close(fd)
    return [p for p in pids if _running(p)]


def test_api_ready_death_report_respawn_and_stop(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    lines: list[str] = []
    with GraphLauncher(specs=STANDIN_SPECS, record_dir=bag, private_domain=True, respawn=["rob"],
                       respawn_delay=0.2, output="quiet", echo=lines.append) as graph:
        ready = graph.wait_ready(timeout=90)
        assert set(ready) == set(ALL) | {"recorder"}
        table = graph.status_table()
        for name in ready:
            row = next(line for line in table.splitlines() if line.startswith(name + " "))
            assert " ready " in row and str(graph.pids()[name]) in row
        first_pids = graph.pids()
        assert all(_running(pid) for pid in first_pids.values())
        # loopback-only transport (stronger than discovery range LOCALHOST, see ird_ros.graph.domains)
        assert graph.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
        assert graph.env[domains.DDS_PROFILE_VAR] == str(domains.DDS_PROFILE)
        assert 0 <= graph.domain_id <= 101

        # SIGKILL rob (respawn on): reported, restarted, ready again with new endpoints
        mark = len(graph.events())
        os.killpg(first_pids["rob"], signal.SIGKILL)
        died = graph.wait_for_event("died", "rob", after=mark)
        assert died.detail == "killed by SIGKILL" and died.pid == first_pids["rob"]
        graph.wait_for_event("respawning", "rob", after=mark)
        again = graph.wait_for_event("ready", "rob", after=mark, timeout=60)
        assert again.pid != first_pids["rob"] and _running(again.pid)
        assert any("node rob" in line and "killed by SIGKILL" in line for line in lines)

        # SIGKILL world (no respawn): reported, stays down
        mark = len(graph.events())
        os.killpg(first_pids["world"], signal.SIGKILL)
        assert graph.wait_for_event("died", "world", after=mark).detail == "killed by SIGKILL"
        # a second rob cycle takes longer than the respawn delay a wrong world respawn would use
        os.killpg(again.pid, signal.SIGKILL)
        graph.wait_for_event("ready", "rob", after=mark, timeout=60)
        assert not [e for e in graph.events()[mark:] if e.node == "world" and e.kind in ("respawning", "started")]
        assert graph.state("world") == "exited"
        last_pids = graph.pids()
    assert graph.stop_duration is not None and graph.stop_duration < 5.0
    every_pid = set(first_pids.values()) | set(last_pids.values()) | {again.pid}
    assert not [p for p in every_pid if _running(p)]
    topics = {t.topic: t.count for t in storage.summarize(bag)}
    assert topics[names.TOPIC_PROXY] == 1
    assert topics[names.TOPIC_PLAN] >= 1


def test_readiness_timeout_names_what_is_missing() -> None:
    specs = [replace(s, services=s.services + ("/no/such/service",)) if s.name == "rob" else s for s in STANDIN_SPECS]
    with GraphLauncher(specs=specs, nodes=["world", "rob"], private_domain=True, output="quiet") as graph:
        graph.wait_ready(timeout=60, nodes=["world"])
        deadline = time.monotonic() + 60
        while True:  # until rob is in the graph, the error says "node /rob not in the graph"
            with pytest.raises(LaunchError) as err:
                graph.wait_ready(timeout=1)
            if "/no/such/service" in str(err.value) or time.monotonic() > deadline:
                break
        assert graph.state("world") == "ready" and graph.state("rob") == "starting"
    text = str(err.value)
    assert "rob" in text and "service /no/such/service not available" in text
    assert "world" not in text.split("\n", 1)[1]


def test_a_node_that_dies_at_start_fails_fast() -> None:
    specs = [replace(s, module="ird_ros.no_such_module", script=None) if s.name == "inference" else s
             for s in STANDIN_SPECS]
    with GraphLauncher(specs=specs, nodes=["world", "inference"], private_domain=True, output="quiet") as graph:
        t0 = time.monotonic()
        with pytest.raises(LaunchError) as err:
            graph.wait_ready(timeout=60)
        assert time.monotonic() - t0 < 30
    assert "inference" in str(err.value) and "exited with code 1" in str(err.value)
    assert "No module named" in str(err.value)


def test_a_node_that_keeps_dying_is_given_up_after_respawn_max_retries() -> None:
    specs = [replace(s, module="ird_ros.no_such_module", script=None) if s.name == "inference" else s
             for s in STANDIN_SPECS]
    lines: list[str] = []
    with GraphLauncher(specs=specs, nodes=["world", "inference"], private_domain=True, output="quiet",
                       respawn=["inference"], respawn_delay=0.0, respawn_max_retries=2, echo=lines.append) as graph:
        gave_up = graph.wait_for_event("gave_up", "inference", timeout=60)
        with pytest.raises(LaunchError) as err:
            graph.wait_ready(timeout=60)
        starts = [e for e in graph.events() if e.node == "inference" and e.kind == "started"]
        assert len(starts) == 3 and gave_up.index > starts[-1].index
        assert graph.state("inference") == "exited"
    assert "inference" in str(err.value) and "exited with code 1" in str(err.value)
    assert any("node inference: gave up after 2 restart(s)" in line for line in lines)
    assert sum("; respawning in 0 s" in line for line in lines) == 2


def test_unknown_node_and_existing_record_dir_are_refused(tmp_path: Path) -> None:
    with pytest.raises(LaunchError, match="unknown node"):
        GraphLauncher(specs=STANDIN_SPECS, nodes=["world", "nope"])
    with pytest.raises(LaunchError, match="already exists"):
        GraphLauncher(specs=STANDIN_SPECS, record_dir=tmp_path)
    with pytest.raises(LaunchError, match="respawn names"):
        GraphLauncher(specs=STANDIN_SPECS, nodes=["world"], respawn=["rob"])


# ------------------------------------------------------------------------------- the CLI


def _start_cli(tmp_path: Path, extra: list[str]) -> tuple[NodeProcess, dict[str, int]]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(Path(__file__).parent), str(ROOT)])
    env["PYTHONUNBUFFERED"] = "1"
    argv = [sys.executable, str(SCRIPT), "--private-domain", "--output", "quiet", *extra]
    proc = NodeProcess(argv, env, ROOT, "launch_graph")
    proc.wait_for_output("graph ready after", timeout=180)
    pids = {}
    for line in proc.output(last=2000).splitlines():
        if line.startswith("[launcher] started "):
            _, _, name, _, pid = line.split()
            pids[name] = int(pid)
    return proc, pids


def _cli_sigint_run(tmp_path: Path, extra: list[str], expected_nodes: list[str]) -> dict[str, Any]:
    bag = tmp_path / "bag"
    t0 = time.monotonic()
    proc, pids = _start_cli(tmp_path, [*extra, "--record", str(bag)])
    ready_s = time.monotonic() - t0
    try:
        assert sorted(pids) == sorted(expected_nodes + ["recorder"])
        assert all(_running(p) for p in pids.values())
        out = proc.output(last=2000)
        for name in pids:
            assert any(line.startswith(name + " ") and " ready " in line for line in out.splitlines())
        t1 = time.monotonic()
        proc.proc.send_signal(signal.SIGINT)
        code = proc.proc.wait(timeout=15)
        stop_s = time.monotonic() - t1
    finally:
        proc.stop()
    assert code == 0, proc.output()
    assert not [p for p in pids.values() if _running(p)], proc.output()
    assert stop_s < 6.0  # the children within 5 s, plus the launcher's own exit
    line = next(x for x in proc.output(last=2000).splitlines() if x.startswith("[launcher] stopped "))
    assert float(line.split(" in ")[1].split()[0]) < 5.0
    topics = {t.topic: t.count for t in storage.summarize(bag)}
    assert topics.get(names.TOPIC_PROXY, 0) >= 1
    print(f"\n[timing] {extra[:2]} ready after {ready_s:.2f} s (launcher start to ready), SIGINT to exit {stop_s:.2f} s")
    return {"ready_s": ready_s, "stop_s": stop_s, "topics": topics}


def test_cli_standins_sigint_stops_everything(tmp_path: Path) -> None:
    _cli_sigint_run(tmp_path, ["--node-table", "_standin_node:STANDIN_SPECS"], ALL)


def test_cli_real_graph(tmp_path: Path) -> None:
    result = _cli_sigint_run(tmp_path, [], ALL)
    for topic in (names.TOPIC_TRAIN_FEATURES, names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN):
        assert result["topics"].get(topic, 0) >= 1


def test_cli_sigkill_of_the_launcher_leaves_no_orphans(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    proc, pids = _start_cli(tmp_path, ["--node-table", "_standin_node:STANDIN_SPECS", "--nodes", "world,rob",
                                       "--record", str(bag)])
    try:
        proc.proc.send_signal(signal.SIGKILL)
        proc.proc.wait(timeout=10)
        # PR_SET_PDEATHSIG: every child got SIGTERM when the launcher died
        assert wait_pids_gone(list(pids.values()), timeout=10) == []
    finally:
        proc.stop()
        for pid in pids.values():
            if _running(pid):
                os.killpg(pid, signal.SIGKILL)
    # the recorder closed its bag on that SIGTERM
    assert storage.summarize(bag)[0].topic.startswith("/")


def test_cli_sigterm_and_respawn_from_params_file(tmp_path: Path) -> None:
    params = tmp_path / "graph.yaml"
    data = yaml.safe_load((ROOT / "msgs_config" / "params" / "graph.yaml").read_text())
    data.setdefault("launcher", {}).setdefault("ros__parameters", {}).update(respawn=["world"], respawn_delay=0.1)
    params.write_text(yaml.safe_dump(data))
    proc, pids = _start_cli(tmp_path, ["--node-table", "_standin_node:STANDIN_SPECS", "--nodes", "world,rob",
                                       "--params", str(params)])
    try:
        os.killpg(pids["world"], signal.SIGKILL)
        proc.wait_for_output("node world (pid", timeout=30)
        line = proc.wait_for_output("ready again after", timeout=60)
        assert "node world" in line and "restart 1" in line
        new_pid = int(line.split("(pid ")[1].split(")")[0])
        assert new_pid != pids["world"] and _running(new_pid)
        proc.proc.send_signal(signal.SIGTERM)
        assert proc.proc.wait(timeout=15) == 0
    finally:
        proc.stop()
    assert "SIGTERM received" in proc.output()
    assert not [p for p in [*pids.values(), new_pid] if _running(p)]
