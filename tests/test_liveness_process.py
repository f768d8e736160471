"""The liveness probe runs in a process of its own (issue 43: a ping stuck in Fast DDS's
shared-memory transport held the GIL and froze the launcher for 60 minutes, SIGINT included).
Properties: a probe that hangs forever, holding its GIL, never blocks the caller's checks nor the
supervisor, and is replaced after ``hang_timeout``; a second SIGINT ends a launcher whose stop
hangs, within a deadline, killing its children."""

from __future__ import annotations

import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from ird_ros.launch import ChildInfo, ChildState, EventKind, ProcessSpec, Supervisor
from ird_ros.launch.liveness import LivenessProcess

sys.path.insert(0, str(Path(__file__).resolve().parent))
import _hanging_probe  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_a_probe_that_hangs_holding_its_gil_blocks_neither_the_checks_nor_the_supervisor() -> None:
    clock = Clock()
    probe = LivenessProcess(0, {}, hang_timeout=15.0, target=_hanging_probe.hang_holding_the_gil, clock=clock)
    crasher = ProcessSpec("phoenix", (sys.executable, "-c", "import sys; sys.exit(3)"), respawn=True,
                          respawn_delay=0.05, respawn_max_retries=2)
    sup = Supervisor([crasher])
    sup.start()
    try:
        first_pid = probe.pid
        infos = {"phoenix": ChildInfo("phoenix", 1, ChildState.READY, 0.0, 0.1, 0, None)}
        for _ in range(50):  # the request went out; the probe hangs on it
            t0 = time.monotonic()
            assert probe.check(infos) == []
            assert time.monotonic() - t0 < 0.5  # never waits for the probe
        # the supervisor goes on meanwhile: the child dies, is respawned twice, is given up
        sup.wait_for_event(EventKind.GAVE_UP, "phoenix", timeout=30)
        assert probe.restarts == 0 and probe.hung is None
        clock.now = 15.0  # no answer for hang_timeout: the probe process is replaced
        assert probe.check(infos) == []
        assert probe.restarts == 1 and probe.pid != first_pid
        assert probe.hung is not None and "did not answer for 15.0 s" in probe.hung
        assert probe.stalled() == {}
    finally:
        probe.close()
        sup.stop_processes(sup.names, 0.5, 0.5)
        sup.shutdown()


def test_an_answering_probe_is_kept() -> None:
    clock = Clock()
    probe = LivenessProcess(0, {}, hang_timeout=5.0, target=_hanging_probe.answer_nothing_stalled, clock=clock)
    try:
        infos = {"world": ChildInfo("world", 1, ChildState.READY, 0.0, 0.1, 0, None)}
        for step in range(1, 4):
            probe.check(infos)  # the request goes out (the answer to the previous one is read)
            assert probe._conn.poll(30)  # the probe answered
            clock.now = 100.0 * step  # long past hang_timeout: an answer in the pipe still counts
        assert probe.check(infos) == [] and probe.restarts == 0 and probe.hung is None
    finally:
        probe.close()
    assert not probe._proc.is_alive()


STUCK_STOP = """
import os, select, signal, sys, threading
from ird_ros.launch import launcher as L
from ird_ros.graph.nodes import NodeSpec

class StuckSupervisor(L.Supervisor):
    def stop_processes(self, *args, **kwargs):
        print("stopping", flush=True)
        threading.Event().wait()  # a stop that never ends (what a frozen probe did)

L.Supervisor = StuckSupervisor
spec = NodeSpec(name="sleeper", module="unused", script={script!r})
graph = L.GraphLauncher(nodes=["sleeper"], specs=[spec], private_domain=True, output="quiet")
graph.start()
# Wait for SIGINT without a race: Python's C handler writes to the wakeup pipe whichever thread the
# kernel delivers SIGINT to, and a SIGINT that arrives before select() leaves its byte there
# (signal.pause() blocked forever when SIGINT came just before it or went to another thread).
wake_r, wake_w = os.pipe()
os.set_blocking(wake_w, False)
signal.set_wakeup_fd(wake_w)
try:
    print("child", graph.pids()["sleeper"], flush=True)
    while True:  # KeyboardInterrupt is raised once select() returns
        select.select([wake_r], [], [])
        os.read(wake_r, 64)
except KeyboardInterrupt:
    graph.stop()
"""


def _wait_exit(pid: int, timeout: float) -> bool:
    """Wait for a process that is not our child to exit: its pidfd turns readable (no polling)."""
    try:
        fd = os.pidfd_open(pid)
    except ProcessLookupError:
        return True
    try:
        return bool(select.select([fd], [], [], timeout)[0])
    finally:
        os.close(fd)


def test_a_second_sigint_ends_a_launcher_whose_stop_hangs(tmp_path: Path) -> None:
    sleeper = tmp_path / "sleeper.py"
    sleeper.write_text("import signal\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\n"
                       "signal.signal(signal.SIGTERM, signal.SIG_IGN)\nsignal.pause()\n")
    proc = subprocess.Popen([sys.executable, "-c", STUCK_STOP.format(script=str(sleeper))], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        line = proc.stdout.readline()
        assert line.startswith("child "), (line, proc.stderr.read() if proc.poll() is not None else "")
        child = int(line.split()[1])
        proc.send_signal(signal.SIGINT)
        assert proc.stdout.readline() == "stopping\n"  # the stop began, and hangs
        t0 = time.monotonic()
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=10)
        assert time.monotonic() - t0 < 5.0
        assert code == 130
        err = proc.stderr.read() if proc.stderr else ""
        assert "Traceback" not in err and "SIGINT during the stop: killed the nodes' process groups (1)" in err, err
        exited = _wait_exit(child, timeout=10.0)
        assert exited and not _alive(child)  # SIGKILLed with its group, although it ignores SIGINT and SIGTERM
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[0] != b"Z"
    except OSError:
        return False
