"""Is a ready node still responding? Stall detection for the launcher (issue: a node stopped with
SIGSTOP looked ready while every request sent to it was lost).

``LivenessChecker.check(infos)`` is called by ``ird_ros.launch.readiness.ReadinessMonitor`` from
the probe's thread after every spin; for every ``ready`` child it decides:

- **stalled** when its process is stopped (``/proc/<pid>/stat`` state ``T`` or ``t``: SIGSTOP,
  SIGTSTP, a debugger), seen at the next check; or when it has not answered a parameter
  request (``/<name>/get_parameters``, served by every rclpy node's executor) for
  ``ping_timeout`` s (a frozen executor, a process starved of CPU, a node that dropped out of
  DDS discovery while its process runs);
- **recovered** when the same process runs again (not stopped) and answered a ping sent after
  it was seen stalled.

Pings: one outstanding request per node, sent every ``period`` s while the node's parameter
service is discovered (a request sent while the server is gone is lost, so an unanswered ping is
replaced, never waited on forever). A node whose parameter service was never seen is judged by
its process state alone. Each transition is returned once; the two alternate per process,
stalled first. Nothing here sleeps; the caller's spin paces the checks.

Renewal. A node stopped for longer than the DDS participant lease (20 s) is dropped by the
pinging participant; when it runs again, Fast DDS may never show its endpoints to that
participant again: if the node's side did not also expire the pinger (its lease check raced with
the traffic buffered while it was stopped), it still counts the pinger's endpoint discovery as
acknowledged and never resends it (eProsima/Fast-DDS#155, #457: re-discovery after a lease
expired on one side only; seen here under load in 1 of ~10 runs of ``tests/ros/test_stalls.py``,
65 s and more without the service). So when a stalled node's process has run again for
``ping_timeout`` s and its parameter service is still not discovered, ``renew`` (given by the
caller) replaces the pinging participant with a new one, which every node discovers afresh; at
most once per ``ping_timeout`` s.

A process of its own (``LivenessProcess``). The pings, their participant and the checker run in a
child process, not in the launcher: a ping once blocked inside Fast DDS's shared-memory transport
while holding the GIL, and froze the launcher for 60 minutes (supervisor, reports and its SIGINT
handler included). The launcher's side only sends the children's states down a pipe and reads the
answers without waiting (one request in flight); a probe process that has not answered for
``hang_timeout`` s is killed (SIGKILL needs no cooperation) and started afresh, which the caller
reports. Whatever the probe does, the launcher keeps running.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Mapping

from ird_ros.graph import names
from ird_ros.launch.events import ChildInfo, ChildState

__all__ = ["LivenessChecker", "LivenessProcess", "Transition", "process_state", "STOPPED_STATES", "PING_PERIOD",
           "PING_TIMEOUT", "HANG_TIMEOUT"]

STOPPED_STATES = frozenset("Tt")
"""``/proc/<pid>/stat`` states of a process that does not run until continued."""
PING_PERIOD = 1.0
"""Seconds between pings of one node."""
PING_TIMEOUT = 10.0
"""Seconds without an answered ping after which a running node counts as stalled."""
HANG_TIMEOUT = 15.0
"""Seconds without an answer from the probe process after which it is killed and started again."""


def process_state(pid: int) -> str | None:
    """The one-letter state of ``pid`` from ``/proc/<pid>/stat`` (``R``, ``S``, ``T``, ...), None if gone."""
    try:
        with open(f"/proc/{pid}/stat", "rb") as f:
            return f.read().rsplit(b")", 1)[1].split()[0].decode()
    except (OSError, IndexError):
        return None


@dataclass(frozen=True)
class Transition:
    """A change of one process: ``stalled`` True (with ``reason``) or False (recovered after ``stalled_for`` s)."""

    name: str
    pid: int
    stalled: bool
    reason: str = ""
    stalled_for: float = 0.0


@dataclass
class _Watch:
    pid: int
    since: float  # first seen ready
    answered_at: float  # last answered ping (or ``since``)
    sent_at: float | None = None
    future: Any = None
    served: bool = False  # its parameter service was discovered at least once
    visible: bool = False  # its parameter service was discovered at the last check
    state: str | None = None  # its process state at the last check
    checked_at: float = 0.0
    stalled_at: float | None = None
    resumed_at: float | None = None  # first check that saw it running again while stalled


class LivenessChecker:
    """Stall and recovery detection for ready children (see the module docstring).

    Args:
        node: an rclpy node that creates the ping clients; spun by the caller.
        renew: replaces the pinging participant and returns its new node (None: never renewed).
        period: seconds between pings of one node.
        ping_timeout: seconds without an answer after which a running node is stalled.
        clock: monotonic seconds; state: ``process_state``; srv_type: the ping's service type
            (default ``rcl_interfaces/srv/GetParameters``); tests pass stand-ins.
    """

    def __init__(self, node: Any, *, renew: Callable[[], Any] | None = None, period: float = PING_PERIOD,
                 ping_timeout: float = PING_TIMEOUT,
                 clock: Callable[[], float] = time.monotonic,
                 state: Callable[[int], str | None] = process_state, srv_type: Any = None) -> None:
        if not period > 0.0:
            raise ValueError(f"period must be > 0 s, got {period!r}")
        if not ping_timeout > period:
            raise ValueError(f"ping_timeout must be > period ({period:g} s), got {ping_timeout!r}")
        self._node = node
        self._renew = renew
        self.renewals = 0
        self.period = float(period)
        self.ping_timeout = float(ping_timeout)
        self._clock = clock
        self._state = state
        if srv_type is None:
            from rcl_interfaces.srv import GetParameters as srv_type
        self._srv_type = srv_type
        self._clients: dict[str, Any] = {}
        self._watches: dict[str, _Watch] = {}

    def _client(self, name: str) -> Any:
        if name not in self._clients:
            self._clients[name] = self._node.create_client(self._srv_type, f"/{name}/get_parameters")
        return self._clients[name]

    def check(self, infos: Mapping[str, ChildInfo]) -> list[Transition]:
        """Ping the ready children and return the stall/recovery transitions since the last call."""
        now = self._clock()
        changes: list[Transition] = []
        for name, info in infos.items():
            watch = self._watches.get(name)
            if info.state is not ChildState.READY or info.pid is None:
                if watch is not None:
                    self._drop(name, watch)
                continue
            if watch is None or watch.pid != info.pid:
                if watch is not None:
                    self._drop(name, watch)
                watch = self._watches[name] = _Watch(info.pid, now, now)
            change = self._check_one(name, watch, now)
            if change is not None:
                changes.append(change)
        if self._renew is not None and any(self._lost_to_discovery(w, now) for w in self._watches.values()):
            self._renew_participant(now)
        return changes

    def _lost_to_discovery(self, watch: _Watch, now: float) -> bool:
        return (watch.resumed_at is not None and now - watch.resumed_at >= self.ping_timeout
                and watch.served and not watch.visible)

    def _renew_participant(self, now: float) -> None:
        """A new pinging participant: pings start afresh; running nodes get ``ping_timeout`` s to be
        discovered by it before their silence counts."""
        assert self._renew is not None
        self._clients.clear()  # they belong to the old node
        self._node = self._renew()
        self.renewals += 1
        for watch in self._watches.values():
            watch.future = watch.sent_at = None
            if watch.stalled_at is None:
                watch.answered_at = now
            elif watch.resumed_at is not None:
                watch.resumed_at = now

    def _check_one(self, name: str, watch: _Watch, now: float) -> Transition | None:
        client = self._client(name)
        if watch.future is not None and watch.future.done():
            if watch.sent_at is not None and (watch.stalled_at is None or watch.sent_at >= watch.stalled_at):
                watch.answered_at = now
            watch.future = None
        elif watch.future is not None and now - (watch.sent_at or now) >= self.ping_timeout:
            client.remove_pending_request(watch.future)  # lost, or never to be answered: ask again
            watch.future = None
        watch.visible = client.service_is_ready()
        if watch.future is None and watch.visible:
            watch.served = True
            if watch.sent_at is None or now - watch.sent_at >= self.period:
                watch.future = client.call_async(self._srv_type.Request())
                watch.sent_at = now
        state = watch.state = self._state(watch.pid)
        watch.checked_at = now
        stopped = state in STOPPED_STATES
        silent = watch.served and now - watch.answered_at >= self.ping_timeout
        if watch.stalled_at is None:
            if not (stopped or silent):
                return None
            watch.stalled_at = now
            reason = (f"process stopped (state {state}: SIGSTOP, SIGTSTP or a debugger); requests sent to it "
                      "now may be lost" if stopped else
                      f"no answer to /{name}/get_parameters for {now - watch.answered_at:.1f} s "
                      "(executor blocked, process starved, or out of DDS discovery)")
            return Transition(name, watch.pid, True, reason=reason)
        if stopped or state is None:
            watch.resumed_at = None
            return None
        if watch.resumed_at is None:
            watch.resumed_at = now
        if watch.served and watch.answered_at < watch.stalled_at:
            return None
        stalled_for, watch.stalled_at, watch.resumed_at = now - watch.stalled_at, None, None
        return Transition(name, watch.pid, False, stalled_for=stalled_for)

    def _drop(self, name: str, watch: _Watch) -> None:
        if watch.future is not None and not watch.future.done():
            self._client(name).remove_pending_request(watch.future)
        del self._watches[name]

    def describe(self, name: str) -> str:
        """What the last check of ``name`` saw, for a report of a stall that does not end:
        process state, whether the parameter service is discovered, the pings' times."""
        watch = self._watches.get(name)
        if watch is None:
            return "not watched (not ready)"
        now = watch.checked_at

        def ago(t: float | None) -> str:
            return "never" if t is None else f"{now - t:.1f} s before"

        service = f"/{name}/get_parameters"
        seen = "discovered" if watch.visible else ("not discovered (was before)" if watch.served else "never discovered")
        pending = f"outstanding since {ago(watch.sent_at)}" if watch.future is not None else "none outstanding"
        return (f"process {watch.pid} state {watch.state or 'gone'}; {service} {seen}; ping {pending}; "
                f"last answer (or readiness) {ago(watch.answered_at)}; stalled {ago(watch.stalled_at)}; "
                f"pinging participant renewed {self.renewals} times (at the last check)")

    def stalled(self) -> dict[str, float]:
        """Names of the children stalled now, with the monotonic time each was seen stalled."""
        return {n: w.stalled_at for n, w in self._watches.items() if w.stalled_at is not None}


# ------------------------------------------------------------------------ participants (rclpy contexts)

PING_NODE = names.NODE_LAUNCHER_PING


@contextlib.contextmanager
def _temp_env(values: Mapping[str, str]) -> Iterator[None]:
    """``os.environ`` updated with ``values`` inside the block (rclpy.init reads ROS_* there)."""
    old = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _open_participant(name: str, domain_id: int, env: Mapping[str, str]) -> tuple[Any, Any, Any]:
    """A node ``name`` in an rclpy context (a DDS participant) of its own, and its executor."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    ctx = Context()
    keys = {k: env[k] for k in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOG_DIR") if k in env}
    with _temp_env(keys):
        rclpy.init(context=ctx, domain_id=int(domain_id), signal_handler_options=SignalHandlerOptions.NO)
        node = rclpy.create_node(name, context=ctx, start_parameter_services=False, enable_rosout=False)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    return ctx, node, executor


def _close_participant(ctx: Any, node: Any, executor: Any) -> None:
    with contextlib.suppress(Exception):
        executor.shutdown(timeout_sec=1.0)
    with contextlib.suppress(Exception):
        node.destroy_node()
    with contextlib.suppress(Exception):
        ctx.try_shutdown()


class PingParticipant:
    """The liveness pings' node (``launcher_ping``) in a participant of its own, so that ``renew``
    can replace it with a new participant (``ird_ros.launch.liveness``: renewal) without touching
    the readiness probe's subscriptions and history. Not thread-safe: one thread uses it."""

    def __init__(self, domain_id: int, env: Mapping[str, str]) -> None:
        self._domain_id, self._env = domain_id, dict(env)
        self._ctx, self.node, self._executor = _open_participant(PING_NODE, domain_id, env)

    def spin(self, callbacks: int) -> None:
        """Handle up to ``callbacks`` ready events (ping answers) without waiting."""
        for _ in range(callbacks):
            self._executor.spin_once(timeout_sec=0.0)

    def renew(self) -> Any:
        """Close this participant, open a new one; return its node."""
        self.close()
        self._ctx, self.node, self._executor = _open_participant(PING_NODE, self._domain_id, self._env)
        return self.node

    def close(self) -> None:
        _close_participant(self._ctx, self.node, self._executor)


# ------------------------------------------------------------------------ the probe's own process


def serve(conn: Any, domain_id: int, env: Mapping[str, str], period: float, ping_timeout: float) -> None:
    """The probe process: a ``LivenessChecker`` pinging from a ``PingParticipant`` of this process.
    Each request is the children's ``{name: ChildInfo}`` (None: end); each answer is
    ``(transitions, stalled, notes, renewals)``. Ctrl-C is the launcher's business: this process
    ignores SIGINT (a terminal's Ctrl-C reaches it too) and ends when the launcher's end of the
    pipe closes."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ.update(env)  # the graph's domain, DDS profile and log folder, before rclpy loads
    pinger = PingParticipant(domain_id, env)
    checker = LivenessChecker(pinger.node, renew=pinger.renew, period=period, ping_timeout=ping_timeout)
    try:
        while (infos := conn.recv()) is not None:
            pinger.spin(len(infos))
            changes = checker.check(infos)
            stalled = checker.stalled()
            conn.send((changes, stalled, {name: checker.describe(name) for name in stalled}, checker.renewals))
    except (EOFError, OSError, KeyboardInterrupt):
        pass  # the launcher closed the pipe or went away
    finally:
        pinger.close()


class LivenessProcess:
    """``LivenessChecker``'s calls, answered by a process of its own (see the module docstring).

    ``check(infos)`` never waits: it returns the transitions of the last answer that came in (if
    any) and sends the new states when no request is in flight. Args are ``LivenessChecker``'s;
    ``hang_timeout``: seconds without an answer before the process is replaced; ``target``: the
    process's function (``serve``; tests pass one that hangs); ``clock``: monotonic seconds.
    """

    def __init__(self, domain_id: int, env: Mapping[str, str], *, period: float = PING_PERIOD,
                 ping_timeout: float = PING_TIMEOUT, hang_timeout: float = HANG_TIMEOUT,
                 target: Callable[..., None] = serve, clock: Callable[[], float] = time.monotonic) -> None:
        if not ping_timeout > period > 0.0:
            raise ValueError(f"expected ping_timeout > period > 0, got {ping_timeout!r}, {period!r}")
        if not hang_timeout > 0.0:
            raise ValueError(f"hang_timeout must be > 0 s, got {hang_timeout!r}")
        self._mp = multiprocessing.get_context("spawn")
        self._args = (int(domain_id), dict(env), float(period), float(ping_timeout))
        self.hang_timeout = float(hang_timeout)
        self._target = target
        self._clock = clock
        self.restarts = 0
        self.renewals = 0
        self.hung: str | None = None  # why the last process was replaced (for the caller to report once)
        self._stalled: dict[str, float] = {}
        self._notes: dict[str, str] = {}
        self._start()

    @property
    def pid(self) -> int | None:
        return self._proc.pid

    def _start(self) -> None:
        parent, child = self._mp.Pipe()
        self._proc = self._mp.Process(target=self._target, args=(child, *self._args), name="ird-liveness", daemon=True)
        self._proc.start()
        child.close()
        self._conn = parent
        self._asked_at: float | None = None
        self._answered_at = self._clock()

    def _replace(self, why: str) -> None:
        self.close()
        self.restarts += 1
        self.hung = why
        self._start()

    def check(self, infos: Mapping[str, Any]) -> list[Transition]:
        """The transitions the probe process reported since the last call; never blocks."""
        now = self._clock()
        changes: list[Transition] = []
        if self._asked_at is not None:
            try:
                answered = self._conn.poll(0)
                reply = self._conn.recv() if answered else None
            except (EOFError, OSError):
                self._replace(f"the liveness probe process (pid {self._proc.pid}) ended "
                              f"(exit code {self._proc.exitcode})")
                return changes
            if reply is not None:
                changes, self._stalled, self._notes, self.renewals = reply
                self._asked_at, self._answered_at = None, now
            elif now - self._asked_at >= self.hang_timeout:
                self._replace(f"the liveness probe process (pid {self._proc.pid}) did not answer for "
                              f"{now - self._asked_at:.1f} s (stuck, e.g. in the DDS transport): killed and "
                              "started again")
                return changes
        if self._asked_at is None:
            try:
                self._conn.send(dict(infos))  # one request in flight: the pipe never fills, send never waits
                self._asked_at = now
            except (BrokenPipeError, OSError):
                self._replace(f"the liveness probe process (pid {self._proc.pid}) ended "
                              f"(exit code {self._proc.exitcode})")
        return changes

    def stalled(self) -> dict[str, float]:
        """As ``LivenessChecker.stalled``, as of the probe's last answer."""
        return dict(self._stalled)

    def describe(self, name: str) -> str:
        """As ``LivenessChecker.describe``, as of the probe's last answer."""
        return self._notes.get(name, "not stalled at the probe's last answer")

    def close(self) -> None:
        """End the probe process (asked first; killed if it does not end within 2 s)."""
        with contextlib.suppress(Exception):
            self._conn.send(None)
        self._proc.join(2.0)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join(5.0)
        with contextlib.suppress(Exception):
            self._conn.close()
