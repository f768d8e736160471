"""ird_ros.launch.supervisor with real child processes (plain ``python -c`` children, no ROS).

Properties: the stop escalation sends SIGINT, SIGTERM, SIGKILL in that order and on schedule
to a child that ignores the first two; a crashed child is restarted after ``respawn_delay``
and readiness only counts for the current process; a child that keeps dying is started
``1 + respawn_max_retries`` times, then given up; exit events carry the exit code or signal;
PR_SET_PDEATHSIG ends a child when its supervising process is SIGKILLed; the output pump
keeps every line. Liveness (``ird_ros.launch.liveness``, with a fake ping client and clock): a
stopped process is stalled at the next check, a running one whose pings go unanswered for
``ping_timeout`` too, and either recovers only once it runs and answers a ping sent after the
stall; ``describe`` says what the last check saw; ``Supervisor.note`` records only for the
current ready process; a wait for an event ends at once when its ``abort`` raises (the launcher:
when the readiness probe failed), and a timed-out wait for a stalled node carries what its last
liveness check saw. Nothing sleeps: waits are
on supervisor events, output lines and pidfds.
"""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import Iterator

import pytest

from ird_ros.launch import (
    ChildInfo,
    ChildState,
    EventKind,
    ProcessExited,
    ProcessGaveUp,
    ProcessReady,
    ProcessRespawning,
    ProcessSpec,
    ProcessStarted,
    SignalSent,
    Supervisor,
)
from ird_ros.launch.events import ProcessRecovered, ProcessStalled
from ird_ros.launch.liveness import LivenessChecker, process_state
from ird_ros.testing import NodeProcess

ROOT = Path(__file__).resolve().parents[1]

# Installs handlers that report and otherwise ignore SIGINT/SIGTERM, then says so.
STUBBORN = """
import signal
def report(sig, frame):
    print("got " + signal.Signals(sig).name, flush=True)
signal.signal(signal.SIGINT, report)
signal.signal(signal.SIGTERM, report)
print("armed", flush=True)
while True:
    signal.pause()
"""


# Ends on its first SIGINT (KeyboardInterrupt, uncaught: returncode -SIGINT), also when SIGINT comes
# before it waits: the C handler leaves a byte in the wakeup pipe (signal.pause() would block on).
POLITE = """
import os, select, signal
wake_r, wake_w = os.pipe()
os.set_blocking(wake_w, False)
signal.set_wakeup_fd(wake_w)
print("up", flush=True)
while True:
    select.select([wake_r], [], [])
"""

def py(code: str) -> tuple[str, ...]:
    return (sys.executable, "-c", code)


@pytest.fixture
def make() -> Iterator:
    made: list[Supervisor] = []

    def factory(*specs: ProcessSpec, **kw: object) -> Supervisor:
        sup = Supervisor(specs, cwd=ROOT, **kw)  # type: ignore[arg-type]
        made.append(sup)
        sup.start()
        return sup

    yield factory
    for sup in made:
        sup.stop_processes(sup.names, 0.5, 0.5)
        sup.shutdown()


def test_stop_escalates_sigint_sigterm_sigkill_on_schedule(make) -> None:
    sup = make(ProcessSpec("stubborn", py(STUBBORN)))
    sup.wait_for_output("stubborn", "armed", timeout=30)
    pid = sup.info("stubborn").pid
    assert os.getpgid(pid) == pid  # leads its own process group
    sup.stop_processes(["stubborn"], sigterm_timeout=0.4, sigkill_timeout=0.3)

    sent = [e for e in sup.events() if isinstance(e, SignalSent)]
    assert [e.signal for e in sent] == [signal.SIGINT, signal.SIGTERM, signal.SIGKILL]
    assert all(e.pid == pid and e.kind == "signalled" for e in sent)
    eps = 0.05  # the schedule starts a moment before SIGINT goes out
    assert sent[1].time - sent[0].time >= 0.4 - eps
    assert sent[2].time - sent[0].time >= 0.4 + 0.3 - eps
    assert sent[2].time - sent[0].time < 0.4 + 0.3 + 1.0

    exited = sup.wait_for_event(EventKind.STOPPED, "stubborn", timeout=10)
    assert isinstance(exited, ProcessExited) and exited.requested
    assert exited.returncode == -signal.SIGKILL and exited.detail == "killed by SIGKILL"
    assert exited.index > sent[2].index
    # the child really received SIGINT, then SIGTERM (its handlers ran, in that order)
    sup.wait_for_output("stubborn", "got SIGTERM", timeout=10)
    lines = sup.output("stubborn").splitlines()
    assert lines.index("got SIGINT") < lines.index("got SIGTERM")
    assert sup.shutdown()["stubborn"] == -signal.SIGKILL
    assert sup.info("stubborn").state is ChildState.STOPPED


def test_a_child_that_ends_on_sigint_gets_no_further_signal(make) -> None:
    sup = make(ProcessSpec("polite", py(POLITE)))
    sup.wait_for_output("polite", "up", timeout=30)
    sup.stop_processes(["polite"], sigterm_timeout=5.0, sigkill_timeout=5.0)
    sent = [e.signal for e in sup.events() if isinstance(e, SignalSent)]
    assert sent == [signal.SIGINT]
    assert sup.wait_for_event("stopped", "polite").returncode == -signal.SIGINT  # type: ignore[attr-defined]


def test_respawn_after_a_crash_waits_respawn_delay(make, tmp_path: Path) -> None:
    marker = tmp_path / "crashed-once"
    code = (f"import os, signal, sys\nm = {str(marker)!r}\n"
            "if not os.path.exists(m):\n    open(m, 'w').close(); sys.exit(3)\n"
            "print('second life', flush=True)\nsignal.pause()\n")
    sup = make(ProcessSpec("phoenix", py(code), respawn=True, respawn_delay=0.3))
    again = sup.wait_for_event("started", "phoenix", after=1, timeout=30)
    kinds = [(e.kind, e.name) for e in sup.events()]
    assert [k for k, _ in kinds[:4]] == ["started", "died", "respawning", "started"]

    first, died, respawning = sup.events()[:3]
    assert isinstance(first, ProcessStarted) and first.restart == 0
    assert isinstance(died, ProcessExited) and died.returncode == 3 and not died.requested
    assert died.pid == first.pid and died.detail == "exited with code 3"
    assert isinstance(respawning, ProcessRespawning) and respawning.restart == 1 and respawning.delay == 0.3
    assert isinstance(again, ProcessStarted) and again.restart == 1 and again.pid != first.pid
    assert again.time - died.time >= 0.3

    info = sup.info("phoenix")
    assert info.state is ChildState.STARTING and info.restarts == 1 and info.pid == again.pid
    # readiness counts only for the current process
    assert first.pid is not None and sup.mark_ready("phoenix", first.pid) is None
    ready = sup.mark_ready("phoenix", again.pid)
    assert isinstance(ready, ProcessReady) and ready.restart == 1 and ready.kind == "ready"
    assert sup.info("phoenix").state == "ready"
    sup.wait_for_output("phoenix", "second life")


@pytest.mark.parametrize("max_retries", [0, 3])
def test_a_child_that_keeps_dying_is_given_up_after_respawn_max_retries(make, max_retries: int) -> None:
    sup = make(ProcessSpec("doomed", py("import sys; sys.exit(2)"), respawn=True, respawn_delay=0.0,
                           respawn_max_retries=max_retries))
    gave_up = sup.wait_for_event("gave_up", "doomed", timeout=60)
    # the give-up is recorded with the last death: no start can follow it
    events = sup.events()
    assert [e.kind for e in events if isinstance(e, ProcessStarted)] == ["started"] * (1 + max_retries)
    died = [e for e in events if isinstance(e, ProcessExited)]
    assert len(died) == 1 + max_retries and all(e.returncode == 2 and not e.requested for e in died)
    assert [e.will_respawn for e in died] == [True] * max_retries + [False]
    assert len([e for e in events if isinstance(e, ProcessRespawning)]) == max_retries
    assert isinstance(gave_up, ProcessGaveUp) and gave_up.restarts == max_retries
    assert gave_up.index == died[-1].index + 1 and gave_up.kind is EventKind.GAVE_UP
    assert gave_up.detail == f"gave up after {max_retries} restart(s)"
    info = sup.info("doomed")
    assert info.state is ChildState.EXITED and info.restarts == max_retries and info.returncode == 2


def test_no_respawn_after_stop(make) -> None:
    sup = make(ProcessSpec("sleeper", py("import signal; print('up', flush=True); signal.pause()"),
                           respawn=True, respawn_delay=0.0))
    sup.wait_for_output("sleeper", "up", timeout=30)
    sup.stop_processes(["sleeper"], 1.0, 1.0)
    sup.shutdown()
    assert [e.kind for e in sup.events() if not isinstance(e, SignalSent)] == ["started", "stopped"]


@pytest.mark.parametrize(
    ("code", "returncode", "detail"),
    [
        ("import sys; sys.exit(7)", 7, "exited with code 7"),
        ("import sys; sys.exit(0)", 0, "exited with code 0"),
        ("import os, signal; os.kill(os.getpid(), signal.SIGUSR1)", -signal.SIGUSR1, "killed by SIGUSR1"),
    ],
)
def test_exit_events_carry_the_exit_code(make, code: str, returncode: int, detail: str) -> None:
    sup = make(ProcessSpec("short", py(code)))
    ev = sup.wait_for_event("died", "short", timeout=30)
    assert isinstance(ev, ProcessExited)
    assert ev.returncode == returncode and ev.detail == detail and ev.kind is EventKind.DIED
    assert ev.pid == sup.events()[0].pid
    info = sup.info("short")
    assert info.state is ChildState.EXITED and info.returncode == returncode


def test_output_pump_keeps_every_line_in_order(make, tmp_path: Path) -> None:
    code = ("import sys\nfor i in range(200): print(f'line {i}')\n"
            "sys.stdout.flush(); print('to stderr', file=sys.stderr)")
    echoed: list[str] = []
    cond = threading.Condition()

    def echo(line: str) -> None:
        with cond:
            echoed.append(line)
            cond.notify_all()

    sup = make(ProcessSpec("talker", py(code)), output="prefix", echo=echo, tail_lines=500)
    sup.wait_for_event("died", "talker", timeout=30)
    sup.wait_for_output("talker", "to stderr", timeout=10)
    expected = [f"line {i}" for i in range(200)] + ["to stderr"]
    assert sup.output("talker", last=500).splitlines() == expected
    assert sup.output("talker", last=2).splitlines() == expected[-2:]
    with cond:
        assert cond.wait_for(lambda: len(echoed) == len(expected), timeout=10)
    assert echoed == [f"[talker] {line}" for line in expected]

    files = make(ProcessSpec("writer", py(code)), output="files", log_dir=tmp_path)
    files.wait_for_event("died", "writer", timeout=30)
    assert (tmp_path / "writer.log").read_text().splitlines() == expected
    assert files.output("writer") == ""


def test_a_death_is_reported_after_the_last_words(make) -> None:
    """The exit event comes only once the child's pipe is drained: its last line (the reason it
    died) is in the tail when the event is delivered. The pump is held at the first line until
    the test has the event (at most 1 s), so a report that does not wait for EOF is caught."""
    code = ("import sys\nfor i in range(200): print(f'noise {i}')\n"
            "print('No module named nowhere', flush=True); sys.exit(1)")
    released = threading.Event()

    def echo(line: str) -> None:
        if line.endswith("noise 0"):
            released.wait(1.0)

    sup = make(ProcessSpec("dying", py(code)), output="prefix", echo=echo, tail_lines=50)
    ev = sup.wait_for_event("died", "dying", timeout=30)
    last = sup.output("dying", last=1)
    released.set()
    assert isinstance(ev, ProcessExited) and ev.returncode == 1
    assert last == "No module named nowhere"


PARENT = """
import json, signal, sys
from ird_ros.launch import ProcessSpec, Supervisor
sup = Supervisor([ProcessSpec("orphan", (sys.executable, "-c", "import signal; signal.pause()"))])
sup.start()
print(json.dumps({"child": sup.info("orphan").pid}), flush=True)
signal.pause()
"""


def _gone(pid: int, timeout: float) -> bool:
    """Wait on a pidfd (no polling) until ``pid`` has exited; True if it has."""
    try:
        fd = os.pidfd_open(pid)
    except ProcessLookupError:
        return True
    try:
        poller = select.poll()
        poller.register(fd, select.POLLIN)
        return bool(poller.poll(timeout * 1000))
    finally:
        os.close(fd)


def test_pdeathsig_ends_the_child_when_the_supervisor_is_killed() -> None:
    env = dict(os.environ, PYTHONPATH=str(ROOT), PYTHONUNBUFFERED="1")
    parent = NodeProcess([sys.executable, "-c", PARENT], env, ROOT, "parent")
    child = None
    try:
        child = json.loads(parent.wait_for_output('"child"', timeout=30))["child"]
        assert not _gone(child, 0)
        # the child runs in its own session: only PR_SET_PDEATHSIG can tell it that its parent died
        assert os.getsid(child) == child != os.getsid(parent.pid)
        parent.proc.send_signal(signal.SIGKILL)
        parent.proc.wait(timeout=10)
        assert _gone(child, timeout=10)
    finally:
        parent.stop()
        if child is not None and not _gone(child, 0):
            os.killpg(child, signal.SIGKILL)


def test_child_ended_sees_a_zombie_without_reaping_it() -> None:
    from ird_ros.launch.process_groups import child_ended

    proc = subprocess.Popen(py("import signal; signal.pause()"))
    try:
        assert not child_ended(proc.pid)
        proc.kill()
        os.waitid(os.P_PID, proc.pid, os.WEXITED | os.WNOWAIT)  # blocks until it is a zombie
        assert child_ended(proc.pid) and proc.returncode is None  # not reaped by the check
    finally:
        proc.kill()
        assert proc.wait() == -signal.SIGKILL
    assert child_ended(proc.pid)


def test_bad_arguments_name_the_field() -> None:
    with pytest.raises(ValueError, match="respawn_delay"):
        ProcessSpec("x", py("pass"), respawn=True, respawn_delay=-1.0)
    with pytest.raises(ValueError, match="respawn_max_retries"):
        ProcessSpec("x", py("pass"), respawn=True, respawn_max_retries=-2)
    with pytest.raises(ValueError, match="argv"):
        ProcessSpec("x", ())
    with pytest.raises(ValueError, match="output"):
        Supervisor([ProcessSpec("x", py("pass"))], output="loud")
    with pytest.raises(ValueError, match="log_dir"):
        Supervisor([ProcessSpec("x", py("pass"))], output="files")
    with pytest.raises(ValueError, match="duplicate"):
        Supervisor([ProcessSpec("x", py("pass")), ProcessSpec("x", py("pass"))])


def test_supervisor_imports_no_ros() -> None:
    probe = ("import json, sys, ird_ros.launch.supervisor, ird_ros.launch.plan, ird_ros.graph.domains, "
             "ird_ros.waits; "
             "print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'ird_msgs'))))")
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                         capture_output=True, text=True, check=True, timeout=60)
    assert json.loads(out.stdout) == []


# ------------------------------------------------------------------------------ liveness


class FakeFuture:
    def __init__(self) -> None:
        self.answered = False

    def done(self) -> bool:
        return self.answered


class FakeClient:
    """A ping client: ``ready`` says whether the server is discovered; ``sent`` every request's future."""

    def __init__(self) -> None:
        self.ready = True
        self.sent: list[FakeFuture] = []
        self.removed: list[FakeFuture] = []

    def service_is_ready(self) -> bool:
        return self.ready

    def call_async(self, _request: object) -> FakeFuture:
        self.sent.append(FakeFuture())
        return self.sent[-1]

    def remove_pending_request(self, future: FakeFuture) -> None:
        self.removed.append(future)

    def answer_all(self) -> None:
        for future in self.sent:
            future.answered = True


class FakeNode:
    def __init__(self) -> None:
        self.clients: dict[str, FakeClient] = {}

    def create_client(self, _srv_type: object, name: str) -> FakeClient:
        return self.clients.setdefault(name, FakeClient())


class FakeSrv:
    class Request:
        pass


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def ready(name: str, pid: int) -> dict[str, ChildInfo]:
    return {name: ChildInfo(name, pid, ChildState.READY, 0.0, 1.0, 0, None)}


def test_a_stopped_process_is_stalled_until_it_runs_and_answers_again() -> None:
    node, clock = FakeNode(), Clock()
    checker = LivenessChecker(node, period=1.0, ping_timeout=5.0, clock=clock, srv_type=FakeSrv)
    with NodeProcess(py("import signal; print('up', flush=True); signal.pause()"), os.environ, ROOT,
                     "sleeper") as proc:
        proc.wait_for_output("up")
        infos = ready("sleeper", proc.pid)
        assert checker.check(infos) == [] and process_state(proc.pid) in ("S", "R")
        ping = node.clients["/sleeper/get_parameters"]
        assert len(ping.sent) == 1
        os.kill(proc.pid, signal.SIGSTOP)
        try:
            wait_state(proc.pid, "T")
            clock.now += 0.1
            [stalled] = checker.check(infos)
            assert stalled.stalled and stalled.pid == proc.pid and "process stopped (state T" in stalled.reason
            assert checker.stalled() == {"sleeper": clock.now}
            clock.now += 0.5
            ping.answer_all()  # an answer to a ping sent before the stall does not count
            assert checker.check(infos) == []
        finally:
            os.kill(proc.pid, signal.SIGCONT)
        wait_state(proc.pid, "S")
        clock.now += 0.2
        assert checker.check(infos) == []  # running, but no answer to a ping sent since the stall
        clock.now += 1.0
        assert checker.check(infos) == [] and len(ping.sent) == 2
        ping.answer_all()
        clock.now += 0.1
        [recovered] = checker.check(infos)
        assert not recovered.stalled and abs(recovered.stalled_for - 1.8) < 1e-9
        assert checker.stalled() == {} and checker.check(infos) == []


def wait_state(pid: int, state: str) -> None:
    """Block until the child ``pid`` is stopped ("T") or continued ("S"): ``waitid`` reports the
    change (WNOWAIT leaves it to Popen)."""
    flag = os.WSTOPPED if state == "T" else os.WCONTINUED
    os.waitid(os.P_PID, pid, flag | os.WNOWAIT)
    assert (process_state(pid) in ("T", "t")) == (state == "T")


def test_unanswered_pings_make_a_running_node_stalled() -> None:
    node, clock = FakeNode(), Clock()
    checker = LivenessChecker(node, period=1.0, ping_timeout=5.0, clock=clock, state=lambda _pid: "S",
                              srv_type=FakeSrv)
    infos = ready("world", 42)
    changes = []
    for _ in range(12):  # 0 .. 5.5 s after the first check, no answer
        changes += checker.check(infos)
        clock.now += 0.5
    [stalled] = changes
    assert stalled.stalled and "no answer to /world/get_parameters for 5.0 s" in stalled.reason
    assert checker.describe("world") == (
        "process 42 state S; /world/get_parameters discovered; ping outstanding since 0.5 s before; "
        "last answer (or readiness) 5.5 s before; stalled 0.5 s before; pinging participant renewed 0 times "
        "(at the last check)")  # checked at 5.5 s
    assert checker.describe("elsewhere") == "not watched (not ready)"
    ping = node.clients["/world/get_parameters"]
    assert ping.removed == [ping.sent[0]] and len(ping.sent) == 2  # the lost ping was replaced
    ping.answer_all()
    [recovered] = checker.check(infos)
    assert not recovered.stalled
    # another process of the node starts afresh: no report about the old one
    assert checker.check(ready("world", 43)) == [] and checker.stalled() == {}


def test_a_node_without_parameter_service_is_judged_by_its_process_state() -> None:
    node, clock = FakeNode(), Clock()
    states = {"now": "S"}
    checker = LivenessChecker(node, period=1.0, ping_timeout=5.0, clock=clock, state=lambda _pid: states["now"],
                              srv_type=FakeSrv)
    node.create_client(FakeSrv, "/quiet/get_parameters").ready = False
    infos = ready("quiet", 7)
    for _ in range(30):
        assert checker.check(infos) == []
        clock.now += 1.0
    states["now"] = "t"
    assert [c.stalled for c in checker.check(infos)] == [True]
    assert "state t; /quiet/get_parameters never discovered; ping none outstanding" in checker.describe("quiet")
    states["now"] = "R"
    assert [c.stalled for c in checker.check(infos)] == [False]
    with pytest.raises(ValueError, match="ping_timeout"):
        LivenessChecker(node, period=1.0, ping_timeout=1.0, srv_type=FakeSrv)
    with pytest.raises(ValueError, match="period"):
        LivenessChecker(node, period=0.0, srv_type=FakeSrv)


def test_a_node_lost_to_discovery_after_it_runs_again_gets_a_new_pinging_participant() -> None:
    """Fast DDS may never show a continued node to a participant that expired it alone: after
    ``ping_timeout`` s of running without its service, the pinger is renewed (at most once per
    ``ping_timeout``) and the node recovers through the new one; a healthy node is not stalled by it."""
    nodes = [FakeNode()]

    def renew() -> FakeNode:
        nodes.append(FakeNode())
        return nodes[-1]

    clock, states = Clock(), {"world": "S", "rob": "S"}
    checker = LivenessChecker(nodes[0], renew=renew, period=1.0, ping_timeout=5.0, clock=clock,
                              state=lambda pid: states["world" if pid == 1 else "rob"], srv_type=FakeSrv)
    infos = {**ready("world", 1), **ready("rob", 2)}
    answering = ["rob"]  # rob always answers

    def step(seconds: float = 0.5) -> list:
        changes = []
        for _ in range(int(seconds / 0.5)):
            clock.now += 0.5
            changes += checker.check(infos)
            for node in nodes:
                for name in answering:
                    node.create_client(FakeSrv, f"/{name}/get_parameters").answer_all()
        return changes

    assert checker.check(infos) == []
    states["world"] = "T"
    [stalled] = step()
    assert stalled.stalled and stalled.name == "world"
    nodes[0].clients["/world/get_parameters"].ready = False  # the pinger expired it during the stop
    assert step(10.0) == []
    states["world"] = "S"  # continued, but never shown to the old pinger again
    assert step(5.0) == [] and len(nodes) == 1  # seen running at the first of these checks: 4.5 s
    assert step(0.5) == [] and len(nodes) == 2 and checker.renewals == 1
    assert "pinging participant renewed 1 times" in checker.describe("world")
    nodes[1].clients.setdefault("/world/get_parameters", FakeClient()).ready = False  # not seen yet
    assert step(4.5) == [] and len(nodes) == 2  # at most one renewal per ping_timeout
    assert step(0.5) == [] and len(nodes) == 3
    assert step(0.5) == []  # the third one sees it and pings
    nodes[2].clients["/world/get_parameters"].answer_all()
    [recovered] = step()
    assert not recovered.stalled and recovered.name == "world" and checker.stalled() == {}
    answering.append("world")
    assert step(20.0) == [] and len(nodes) == 3  # rob was never stalled, nothing renewed again


def test_liveness_events_are_recorded_for_the_current_ready_process_only(make) -> None:
    seen: list = []
    sup = make(ProcessSpec("n", py("import signal; print('up', flush=True); signal.pause()")), on_event=seen.append)
    sup.wait_for_output("n", "up")
    pid = sup.info("n").pid
    assert sup.note("n", pid, ProcessStalled, reason="x") is None  # starting, not ready
    sup.mark_ready("n", pid)
    assert sup.note("n", pid + 1, ProcessStalled, reason="x") is None  # another process
    stalled = sup.note("n", pid, ProcessStalled, reason="process stopped")
    recovered = sup.note("n", pid, ProcessRecovered, stalled_for=2.0)
    assert stalled.kind is EventKind.STALLED and stalled.detail == "process stopped"
    assert recovered.kind is EventKind.RECOVERED and recovered.detail == "responding again after 2.0 s"
    assert sup.wait_for_event("recovered", "n").index == recovered.index and seen[-2:] == [stalled, recovered]


class StubMonitor:
    """The launcher's view of a readiness monitor: its ``error``, the ``stall_note`` of a node and
    what a starting node lacks (``missing``)."""

    def __init__(self, error: BaseException | None = None, note: str = "", lacks: tuple[str, ...] = ()) -> None:
        self.error, self.note, self.lacks = error, note, lacks

    def stall_note(self, _name: str) -> str:
        return self.note

    def missing(self, _name: str, _pid: int | None) -> list[str]:
        return list(self.lacks)


def test_a_wait_ends_when_abort_raises_and_a_stalled_wait_says_what_was_seen(make) -> None:
    from ird_ros.launch import GraphLauncher, LaunchError

    sup = make(ProcessSpec("n", py("import signal; print('up', flush=True); signal.pause()")))
    sup.wait_for_output("n", "up")

    def boom() -> None:
        raise LookupError("the source is gone")

    done = threading.Event()
    with pytest.raises(LookupError, match="the source is gone"):
        threading.Timer(30.0, done.set).start()  # a hang would still end the test, failing it below
        sup.wait_for_event("recovered", "n", timeout=60.0, abort=boom)
    assert not done.is_set()
    launcher = GraphLauncher.__new__(GraphLauncher)  # only ``_sup`` and ``_monitor`` are used by the wait
    launcher._sup, launcher._monitor = sup, StubMonitor(error=RuntimeError("rclpy context shut down"))
    with pytest.raises(LaunchError, match="readiness probe failed: RuntimeError.'rclpy context shut down'"):
        launcher.wait_for_event("recovered", "n", timeout=60.0)
    assert not done.is_set()
    launcher._monitor = StubMonitor(note="process 7 state S; /n/get_parameters not discovered (was before)")
    with pytest.raises(TimeoutError, match=r"no 'recovered' event for n within 0.2 s; .*; n is stalled: "
                                           r"process 7 state S; /n/get_parameters not discovered \(was before\)"):
        launcher.wait_for_event("recovered", "n", timeout=0.2)
    launcher._monitor = StubMonitor(lacks=("service /n/s not available", "node /n 2 times in the graph"))
    with pytest.raises(TimeoutError) as plain:
        launcher.wait_for_event("recovered", "n", timeout=0.2)
    assert "stalled" not in str(plain.value)
    # n never got ready (the stub supervisor has no probe): the message says what it lacks
    assert str(plain.value).endswith(f"; n (pid {sup.infos()['n'].pid}) is starting and lacks: "
                                     "service /n/s not available; node /n 2 times in the graph"), plain.value


# ---------------------------------------------------------------------- issue 43: start-up stops, output lines


def test_a_child_not_ready_gets_unready_signal_first_and_ends_without_a_traceback(make) -> None:
    """A Python child still importing (no handler of its own yet) that gets SIGINT prints a
    KeyboardInterrupt traceback; the launcher's ``unready_signal=SIGTERM`` ends it silently."""
    importing = "import signal\nprint('importing', flush=True)\nsignal.pause()\n"
    sup = make(ProcessSpec("slow_import", py(importing)))
    sup.wait_for_output("slow_import", "importing", timeout=30)
    sup.stop_processes(["slow_import"], sigterm_timeout=5.0, sigkill_timeout=5.0, unready_signal=signal.SIGTERM)
    sent = [e.signal for e in sup.events() if isinstance(e, SignalSent)]
    assert sent == [signal.SIGTERM]
    assert sup.wait_for_event("stopped", "slow_import").returncode == -signal.SIGTERM  # type: ignore[attr-defined]
    output = sup.output("slow_import")
    assert "Traceback" not in output and "KeyboardInterrupt" not in output, output


def test_the_default_echo_writes_each_line_in_one_piece(monkeypatch: pytest.MonkeyPatch) -> None:
    """Lines from several threads are never glued: each line, newline included, is one write."""
    import io

    from ird_ros.launch import supervisor as sup_mod

    writes: list[str] = []

    class Recorder(io.StringIO):
        def write(self, text: str) -> int:
            writes.append(text)
            return len(text)

    monkeypatch.setattr(sys, "stdout", Recorder())
    sup = Supervisor([ProcessSpec("x", py("pass"))])
    sup._echo("[world] ready")
    sup_mod.print_line("[launcher] node x stalled")
    assert writes == ["[world] ready\n", "[launcher] node x stalled\n"]
