"""Run, watch, respawn and stop child processes (no ROS in here: no rclpy, no ird_msgs).

Why not ``ros2 launch``: this project installs ROS 2 Jazzy from the ``ros-jazzy-*`` wheels on
PyPI, which carry rclpy and the interfaces but no ``launch`` / ``launch_ros`` packages and no
``ros2`` CLI. The part of ``ros2 launch`` the graph needs (run processes, pump their output,
restart the ones that die, stop everything in order) is this module; its vocabulary is
borrowed from there: ``respawn``, ``respawn_delay``, ``sigterm_timeout``, ``sigkill_timeout``
and process events (``ProcessStarted``, ``ProcessExited``, ...). Deciding when a ROS node is
ready is ``ird_ros.launch.readiness``'s job; it tells the supervisor with ``mark_ready``. The
vocabulary (states, specs, typed events) lives in ``ird_ros.launch.events``.

Processes. Every child is the leader of its own process group (``setsid``), so a signal to
the group also reaches the child's own workers. It starts with SIGINT/SIGTERM at their default
dispositions and with ``PR_SET_PDEATHSIG=SIGTERM`` (``ird_ros.launch.process_groups``), so it is
told to stop even when the supervising process is killed with SIGKILL. Children are spawned
from one long-lived thread because the kernel ties PDEATHSIG to the thread that forked the
child, not to the process.

States (``ChildState``): pending -> starting -> ready (``mark_ready``); a child that dies is
``exited``, then, if its spec says ``respawn``, ``respawning`` for ``respawn_delay`` seconds and
``starting`` again, at most ``respawn_max_retries`` times in all (-1: no limit): one that keeps
dying, e.g. with exit code 2 on a bad parameter, is started ``1 + respawn_max_retries`` times,
then stays ``exited`` (event ``ProcessGaveUp``). One that ends after ``stop_processes`` is ``stopped``.

Stopping (``stop_processes(names, sigterm_timeout, sigkill_timeout)``): the process groups get
SIGINT, SIGTERM ``sigterm_timeout`` s later, SIGKILL ``sigkill_timeout`` s after that; every
signal sent is a ``SignalSent`` event. ``unready_signal`` replaces the first SIGINT for children
not ``ready`` yet: a Python process still importing its modules has no handler of its own, and
SIGINT would print a ``KeyboardInterrupt`` traceback from wherever the import was, while SIGTERM's
default action ends it silently (the launcher's nodes handle both alike once they run).

Longer than 450 lines: spawning, output pumps, exit reports, respawns and the stop escalation all
change the same children's states under one lock; apart, the lock would have to be shared.
"""

from __future__ import annotations

import collections
import contextlib
import enum
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Callable, Iterable, Mapping, Sequence, TypeVar

from ird_ros.launch.events import (ChildInfo, ChildState, EventKind, OutputChoice, OutputMode, ProcessEvent,
                                   ProcessExited, ProcessGaveUp, ProcessReady, ProcessRespawning, ProcessSpec,
                                   ProcessStarted, SignalSent, parse_output_mode)
from ird_ros.launch.process_groups import child_ended, child_preexec, group_alive

__all__ = ["Supervisor", "print_line"]

_PRINT_LOCK = threading.Lock()


def print_line(line: str) -> None:
    """Print ``line`` to stdout in one write, flushed: the output pumps of several children and the
    launcher's own reports print from their own threads, and ``print`` writes the text and its
    newline separately, so two nodes' lines could be glued together between the two writes."""
    with _PRINT_LOCK:
        sys.stdout.write(line + "\n")
        sys.stdout.flush()


_T = TypeVar("_T")

REAP_TIMEOUT = 3.0
"""Seconds to wait, after SIGKILL, for the killed groups to be gone."""
PUMP_DRAIN_TIMEOUT = 2.0
"""Seconds an exit report waits for the child's output pipe to reach EOF."""


class _Command(enum.Enum):
    SPAWN_ALL = enum.auto()
    EXITED = enum.auto()
    QUIT = enum.auto()


@dataclass
class _Child:
    spec: ProcessSpec
    proc: subprocess.Popen | None = None
    state: ChildState = ChildState.PENDING
    started_at: float = 0.0
    ready_after: float | None = None
    restarts: int = 0
    returncode: int | None = None
    tail: collections.deque = field(default_factory=collections.deque)

    def info(self) -> ChildInfo:
        pid = None if self.proc is None else self.proc.pid
        return ChildInfo(self.spec.name, pid, self.state, self.started_at, self.ready_after,
                         self.restarts, self.returncode)


# ------------------------------------------------------------------------ the supervisor


class Supervisor:
    """Runs ``specs`` as child processes (see the module docstring).

    Args:
        specs: the processes, started in this order by ``start()``.
        env: their environment (default: this process's).
        cwd: their working directory.
        output: what happens to their stdout+stderr (``OutputMode`` or its value).
        log_dir: the folder of the ``files`` output mode.
        echo: receives ``[name] line`` in ``prefix`` mode (default: print).
        on_event: called with every event, outside the supervisor's lock, in the thread
            that caused it (the supervisor thread, or the caller of ``mark_ready``).
        tail_lines: lines of output kept per child.
    """

    def __init__(
        self,
        specs: Sequence[ProcessSpec],
        *,
        env: Mapping[str, str] | None = None,
        cwd: str | os.PathLike[str] | None = None,
        output: OutputChoice = OutputMode.QUIET,
        log_dir: str | os.PathLike[str] | None = None,
        echo: Callable[[str], None] | None = None,
        on_event: Callable[[ProcessEvent], None] | None = None,
        tail_lines: int = 60,
    ) -> None:
        self.output_mode = parse_output_mode(output)
        if self.output_mode is OutputMode.FILES and log_dir is None:
            raise ValueError("log_dir is needed for output='files'")
        names = [s.name for s in specs]
        if len(set(names)) != len(names):
            raise ValueError(f"specs: duplicate names in {names}")
        self._children = {s.name: _Child(s, tail=collections.deque(maxlen=tail_lines)) for s in specs}
        self._env = dict(os.environ if env is None else env)
        self._cwd = cwd
        self._log_dir = Path(log_dir) if log_dir is not None else None
        self._echo = echo or print_line
        self._on_event = on_event
        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        self._events: list[ProcessEvent] = []
        self._commands: queue.Queue[tuple[_Command, Any]] = queue.Queue()
        self._thread: threading.Thread | None = None
        self._stopping = False
        self._t0 = time.monotonic()

    # -------------------------------------------------------------- queries

    @property
    def names(self) -> list[str]:
        return list(self._children)

    @property
    def stopping(self) -> bool:
        with self._lock:
            return self._stopping

    def info(self, name: str) -> ChildInfo:
        with self._lock:
            return self._children[name].info()

    def infos(self) -> dict[str, ChildInfo]:
        with self._lock:
            return {n: c.info() for n, c in self._children.items()}

    def output(self, name: str, last: int = 60) -> str:
        """The last ``last`` lines ``name`` printed (modes prefix and quiet)."""
        with self._lock:
            return "\n".join(list(self._children[name].tail)[-last:])

    def events(self) -> list[ProcessEvent]:
        with self._lock:
            return list(self._events)

    def wait_for_event(self, kind: EventKind | str, name: str, *, after: int = 0,
                       timeout: float = 30.0, abort: Callable[[], None] = lambda: None) -> ProcessEvent:
        """The first event of ``kind`` for ``name`` with index >= ``after`` (waits for it); what
        ``abort()`` raises (called at least every 0.5 s, lock held) ends the wait."""
        kind = EventKind(kind)
        return self._wait_for(
            lambda: next((e for e in self._events[after:] if e.kind == kind and e.name == name), None), timeout,
            lambda: f"no {kind.value!r} event for {name} within {timeout:g} s; events: "
                    f"{[(e.kind.value, e.name) for e in self._events]}", abort)

    def wait_for_output(self, name: str, text: str, timeout: float = 30.0) -> str:
        """The first kept line of ``name`` containing ``text`` (waits for it)."""
        tail = self._children[name].tail
        return self._wait_for(
            lambda: next((line for line in tail if text in line), None), timeout,
            lambda: f"{name} did not print {text!r} within {timeout:g} s:\n" + "\n".join(tail))

    def _wait_for(self, find: Callable[[], _T | None], timeout: float, failure: Callable[[], str],
                  abort: Callable[[], None] = lambda: None) -> _T:
        """``find()``'s first non-None answer (called with the lock held; waits for changes);
        ``TimeoutError(failure())`` after ``timeout`` s; ``abort()`` before every wait."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while (found := find()) is None:
                abort()
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(failure())
                self._cond.wait(min(remaining, 0.5))
            return found

    # -------------------------------------------------------------- events

    def _record(self, make: Callable[..., ProcessEvent], child: _Child, **fields: Any) -> ProcessEvent:
        """Append an event (lock held); the caller hands it to ``_deliver`` after unlocking."""
        pid = None if child.proc is None else child.proc.pid
        ev = make(index=len(self._events), time=time.monotonic() - self._t0, name=child.spec.name,
                  pid=pid, **fields)
        self._events.append(ev)
        self._cond.notify_all()
        return ev

    def _deliver(self, events: Iterable[ProcessEvent]) -> None:
        if self._on_event is not None:
            for ev in events:
                self._on_event(ev)

    # -------------------------------------------------------------- start

    def start(self) -> None:
        """Start the supervisor thread and every process; raise the first spawn error."""
        if self._thread is not None:
            raise RuntimeError("already started")
        self._thread = threading.Thread(target=self._run, name="supervisor", daemon=True)
        self._thread.start()
        done = threading.Event()
        errors: list[BaseException] = []
        self._commands.put((_Command.SPAWN_ALL, (done, errors)))
        done.wait()
        if errors:
            raise errors[0]

    def mark_ready(self, name: str, pid: int) -> ProcessReady | None:
        """Mark ``name`` ready if it is still the starting process ``pid`` (else None)."""
        with self._cond:
            child = self._children[name]
            if child.state is not ChildState.STARTING or child.proc is None or child.proc.pid != pid:
                return None
            child.state = ChildState.READY
            child.ready_after = time.monotonic() - child.started_at
            ev = self._record(ProcessReady, child, ready_after=child.ready_after, restart=child.restarts)
        self._deliver([ev])
        return ev  # type: ignore[return-value]

    def note(self, name: str, pid: int, make: Callable[..., ProcessEvent], **fields: Any) -> ProcessEvent | None:
        """Record and deliver an event ``make(**fields)`` of the ready process ``pid`` of ``name``
        (liveness reports); None, and nothing recorded, if ``name`` is no longer that ready process."""
        with self._cond:
            child = self._children[name]
            if child.state is not ChildState.READY or child.proc is None or child.proc.pid != pid:
                return None
            ev = self._record(make, child, **fields)
        self._deliver([ev])
        return ev

    def _spawn(self, child: _Child) -> ProcessEvent:
        """Start a child process (supervisor thread only: PDEATHSIG follows the forking thread).

        Returns its ``ProcessStarted`` event, for the caller to deliver once it holds no lock.
        """
        spec = child.spec
        stdout: Any
        if self.output_mode is OutputMode.FILES:
            assert self._log_dir is not None
            stdout = open(self._log_dir / f"{spec.name}.log", "ab")  # noqa: SIM115 - closed below
        else:
            stdout = subprocess.PIPE
        try:
            proc = subprocess.Popen(
                list(spec.argv),
                env=self._env,
                cwd=self._cwd,
                stdin=subprocess.DEVNULL,
                stdout=stdout,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                preexec_fn=child_preexec(os.getpid()),
            )
        finally:
            if self.output_mode is OutputMode.FILES:
                stdout.close()
        with self._cond:
            child.proc = proc
            child.state = ChildState.STARTING
            child.started_at = time.monotonic()
            child.ready_after = None
            child.returncode = None
            ev = self._record(ProcessStarted, child, restart=child.restarts)
        pump = None
        if proc.stdout is not None:
            pump = threading.Thread(target=self._pump, args=(child, proc.stdout), name=f"out-{spec.name}",
                                    daemon=True)
            pump.start()
        threading.Thread(target=self._wait_exit, args=(child, proc, pump), name=f"wait-{spec.name}",
                         daemon=True).start()
        return ev

    def _pump(self, child: _Child, stream: IO[bytes]) -> None:
        name = child.spec.name
        for raw in stream:
            line = raw.decode("utf-8", "replace").rstrip("\n")
            with self._cond:
                child.tail.append(line)
                self._cond.notify_all()
            if self.output_mode is OutputMode.PREFIX:
                self._echo(f"[{name}] {line}")

    def _wait_exit(self, child: _Child, proc: subprocess.Popen, pump: threading.Thread | None) -> None:
        code = proc.wait()
        # Report the exit only after the child's last words are in the tail: under load the
        # pump lags behind the exit, and "exited with code 1; last output:" with nothing after
        # it hides why a node died. Bounded, because a grandchild may still hold the pipe open.
        if pump is not None:
            pump.join(PUMP_DRAIN_TIMEOUT)
        self._commands.put((_Command.EXITED, (child, proc, code)))

    # -------------------------------------------------------------- the supervisor thread

    def _run(self) -> None:
        pending: list[tuple[float, _Child]] = []  # (due time, child) respawns
        while True:
            timeout = max(0.0, min(t for t, _ in pending) - time.monotonic()) if pending else None
            try:
                cmd, arg = self._commands.get(timeout=timeout)
            except queue.Empty:
                cmd, arg = None, None
            if cmd is _Command.QUIT:
                return
            if cmd is _Command.SPAWN_ALL:
                self._spawn_all(*arg)
            elif cmd is _Command.EXITED:
                self._on_exit(*arg, pending)
            now = time.monotonic()
            for child in [c for t, c in pending if t <= now]:
                self._respawn(child)
            pending[:] = [(t, c) for t, c in pending if t > now]

    def _spawn_all(self, done: threading.Event, errors: list[BaseException]) -> None:
        try:
            for child in self._children.values():
                self._deliver([self._spawn(child)])
        except BaseException as exc:  # noqa: BLE001 - raised by start()
            errors.append(exc)
        done.set()

    def _respawn(self, child: _Child) -> None:
        with self._lock:  # stop_processes sets _stopping, then collects the processes
            if self._stopping:
                return
            try:
                result: ProcessEvent | str = self._spawn(child)
            except Exception as exc:  # noqa: BLE001 - the child stays exited
                child.state = ChildState.EXITED
                result = f"[supervisor] {child.spec.name}: respawn failed: {exc}"
        if isinstance(result, str):
            self._echo(result)
        else:
            self._deliver([result])

    def _on_exit(self, child: _Child, proc: subprocess.Popen, code: int, pending: list) -> None:
        events = []
        with self._cond:
            if child.proc is not proc:
                return
            child.returncode = code
            if self._stopping:
                child.state = ChildState.STOPPED
                events.append(self._record(ProcessExited, child, returncode=code, requested=True))
            else:
                events += self._record_death(child, code, pending)
        self._deliver(events)

    def _record_death(self, child: _Child, code: int, pending: list) -> list[ProcessEvent]:
        """Events of an unrequested exit (lock held): restart ``child`` if its spec allows."""
        spec = child.spec
        respawn = spec.may_restart(child.restarts)
        child.state = ChildState.RESPAWNING if respawn else ChildState.EXITED
        events = [self._record(ProcessExited, child, returncode=code, requested=False, will_respawn=respawn)]
        if respawn:
            child.restarts += 1
            events.append(self._record(ProcessRespawning, child, restart=child.restarts, delay=spec.respawn_delay))
            pending.append((time.monotonic() + spec.respawn_delay, child))
        elif spec.respawn:
            events.append(self._record(ProcessGaveUp, child, restarts=child.restarts))
        return events

    # -------------------------------------------------------------- stop

    def _signal(self, targets: Sequence[_Child], sig: int) -> None:
        events = []
        for child in targets:
            assert child.proc is not None
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(child.proc.pid, sig)
            with self._cond:
                events.append(self._record(SignalSent, child, signal=int(sig)))
        self._deliver(events)

    def stop_processes(self, names: Iterable[str], sigterm_timeout: float, sigkill_timeout: float, *,
                       unready_signal: int = signal.SIGINT) -> None:
        """Stop the process groups of ``names``: SIGINT, SIGTERM, SIGKILL (see the docstring);
        ``unready_signal`` is the first signal of a child that is not ``ready``.

        From the first call on nothing is respawned and exits are ``stopped``. Returns when
        the groups are gone (or ``REAP_TIMEOUT`` s after SIGKILL).
        """
        if sigterm_timeout < 0 or sigkill_timeout < 0:
            raise ValueError(f"sigterm_timeout and sigkill_timeout must be >= 0, got "
                             f"{sigterm_timeout}, {sigkill_timeout}")
        start = time.monotonic()
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
            group = [self._children[n] for n in names if self._children[n].proc is not None]

        def alive() -> list[_Child]:
            return [c for c in group if c.proc is not None and group_alive(c.proc.pid)]

        first = alive()
        self._signal([c for c in first if c.state is ChildState.READY], signal.SIGINT)
        self._signal([c for c in first if c.state is not ChildState.READY], unready_signal)
        sent_term = False
        kill_at = sigterm_timeout + sigkill_timeout
        while alive():
            now = time.monotonic() - start
            if now >= kill_at:
                self._signal(alive(), signal.SIGKILL)
                break
            if now >= sigterm_timeout and not sent_term:
                self._signal(alive(), signal.SIGTERM)
                sent_term = True
            self._wait_a_moment()
        deadline = start + kill_at + REAP_TIMEOUT
        while alive() and time.monotonic() < deadline:
            self._wait_a_moment()

    def _wait_a_moment(self) -> None:
        with self._cond:  # up to 20 ms, woken early by an exit event
            self._cond.wait(0.02)

    def shutdown(self, timeout: float = PUMP_DRAIN_TIMEOUT + 3.0) -> dict[str, int | None]:
        """After ``stop_processes``: let the exit report of every ended child through (up to
        ``timeout`` s), end the thread; return exit codes. Children not ``exited`` are ``stopped``."""
        with self._cond:
            self._stopping = True
        if self._thread is not None:
            deadline = time.monotonic() + timeout
            with self._cond:
                while time.monotonic() < deadline and any(
                    c.proc is not None and c.state in (ChildState.STARTING, ChildState.READY)
                    and child_ended(c.proc.pid) for c in self._children.values()
                ):
                    self._cond.wait(0.05)
            self._commands.put((_Command.QUIT, None))
            self._thread.join(timeout)
        with self._lock:
            for c in self._children.values():
                if c.proc is not None:
                    c.returncode = c.proc.poll()
                    if c.state is not ChildState.EXITED:
                        c.state = ChildState.STOPPED
            return {n: c.returncode for n, c in self._children.items()}
