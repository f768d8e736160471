"""Start, watch and stop the IRD graph: one process per node (``ros2 launch`` has no wheel).

CLI: ``scripts/launch_graph.py`` (see its ``--help``). Python::

    from ird_ros.launch import GraphLauncher

    with GraphLauncher(nodes=["world", "inference"], record_dir="bags/run1",
                       private_domain=True, respawn=["world"]) as graph:
        graph.wait_ready(timeout=60)        # raises LaunchError naming what is missing
        print(graph.status_table())
        ...                                 # talk to the nodes in graph.domain_id
    # leaving the block stops every process (SIGINT, SIGTERM, SIGKILL within 5 s)

A description plus an execution: ``GraphLauncher(...)`` builds a ``LaunchPlan``
(``ird_ros.launch.plan``: start order, command lines, params file, respawn set and limits,
recorder arguments, domain; every argument is checked there, before anything runs) and
``start()`` executes it (``GraphLauncher.from_plan`` executes a plan built elsewhere). The
execution uses ``ird_ros.launch.supervisor`` for the processes (ROS-free: spawn, output,
respawn, stop escalation, PR_SET_PDEATHSIG; why not ``ros2 launch`` is said there) and
``ird_ros.launch.readiness`` to decide from the ROS graph when a node is ready; this module
sets up the domain and ties the two together.

Processes. Each node runs with the plan's command line and environment (loopback-only DDS
unless ``IRD_DDS_NETWORK=1``, ``--dds-network`` of the CLI; the probe's own participant gets
the same). Each child leads its own process group, has SIGINT/SIGTERM at their defaults and
gets SIGTERM if the launcher dies, even by SIGKILL.

Recording. With ``record_dir`` a ``recorder`` node (``ird_ros.nodes.recorder``) is started last.
It is stopped last, after the other nodes are gone, so the bag holds everything they published.

Lifecycle and readiness. The graph's nodes are managed (lifecycle) nodes, started with
``autostart:=false``: unconfigured. A probe node (``launcher``) in this process is their
lifecycle manager (``ird_ros.launch.lifecycle_driver``, from the readiness thread): it
configures every node as soon as its lifecycle services are discovered, activates the recorder
first, and each other node once the recorder is ready (subscribed to everything it records:
nothing is published before) and the nodes in its ``after`` are ready. A managed node is ready
when its activate transition succeeded and a message arrived on its ``ready_topics`` since it
started (unless the plan skips them). A failed transition (``configure failed: parameter ...``)
fails ``wait_ready`` at once with ``LaunchError`` naming the node and the reason it logged; the
node stays up, unconfigured, until the launcher stops it. Stand-ins (``script`` specs) are not
managed: they are ready when the ROS graph shows them (``ird_ros.launch.readiness``: in the
graph, their services listed, their publishers new, the ready topics). The recorder is ready
when it is active, subscribes to every topic the launched nodes publish and it records, and
every latched message the probe received is counted in its bag; ``wait_ready`` keeps applying
that last condition after the recorder was first ready, for latched messages the probe receives
later. ``wait_ready`` fails with ``LaunchError`` listing, per node, what is still missing (or
how a process died, with its last output).

Stalls. Every ready node is watched (``ird_ros.launch.liveness``, from the probe's thread): a
node whose process is stopped (SIGSTOP, a debugger) or that answers no parameter request for
10 s is reported once as ``[launcher] node NAME (pid N) stalled: <how it was seen>`` with a
``stalled`` event, and when it responds again as ``... responding again after X s`` with a
``recovered`` event; ``status_table`` shows ``stalled`` meanwhile. DDS drops requests sent to a
node that stays stopped for its lease (20 s); ``ird_ros.client.IrdClient`` resends or fails them.
The pings come from a participant of their own, replaced by a new one when a continued node's
service stays undiscovered for 10 s (a Fast DDS re-discovery gap, see the liveness module).

Death and respawn. A child that exits while the graph runs is reported (exit code or
signal). Nodes in the plan's respawn set are started again after ``respawn_delay`` seconds
and go through readiness again, at most ``respawn_max_retries`` times each; a node that keeps
dying (e.g. exit code 2 on a bad parameter) is then reported as given up and stays down.

Domain. ``private_domain`` leases a free ID in 0..101 (``ird_ros.graph.domains.lease_domain``)
with a private ``ROS_LOG_DIR``; otherwise ``domain_id``, else the inherited ``ROS_DOMAIN_ID``
(default 0), which must also be in 0..101: higher IDs put the DDS ports into Linux's
ephemeral port range.

Stopping (``stop()``, leaving the ``with`` block, or SIGINT/SIGTERM to the CLI): the nodes'
process groups get SIGINT, on which each node runs its own shutdown transition (deactivate,
then clean up: worker pools end, the recorder closes its bag; ``ird_ros.runtime.node_main``),
which is what calling deactivate and cleanup through the services would do, without a round
trip per node inside the 5 s budget; SIGTERM after 1.5 s, then SIGKILL after 2.5 s; the recorder
then gets the same (its deadlines end at 4.5 s). Everything is gone within 5 s. A SIGINT or
SIGTERM while the stop runs (a second Ctrl-C) kills every node's process group at once and ends
the process (exit 130), whatever the stop was waiting for. A node not ready
yet gets SIGTERM instead of the first SIGINT: it may still be importing its modules, before
``ird_ros.runtime.node_main`` installs its handler, and SIGINT would print a ``KeyboardInterrupt``
traceback (Ctrl-C during start-up, a readiness timeout); SIGTERM ends it silently, or cleanly
once the handler runs.

Longer than 450 lines: one class whose start, readiness, reports, status and stop (with its hard
stop on a second signal) share the plan, the domain lease and the supervisor; split, each part
would reach into the others' state.
"""

from __future__ import annotations

import contextlib
import os
import signal
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable, Iterable, Mapping, Sequence

from ird_ros.graph.domains import DomainLease, dds_process_env, lease_domain
from ird_ros.graph.nodes import NodeSpec
from ird_ros.launch.events import (
    ChildInfo,
    ChildState,
    EventKind,
    OutputChoice,
    OutputMode,
    ProcessEvent,
    ProcessExited,
    ProcessGaveUp,
    ProcessReady,
    ProcessRecovered,
    ProcessStalled,
    describe_exit,
)
from ird_ros.launch.plan import RECORDER, LaunchError, LaunchPlan, plan_launch
from ird_ros.launch.readiness import ReadinessMonitor
from ird_ros.launch.supervisor import Supervisor, print_line

__all__ = ["GraphLauncher", "Event"]

# Stop schedule (seconds after stop() starts).
NODES_SIGTERM_AT = 1.5
NODES_SIGKILL_AT = 2.5
RECORDER_SIGTERM_AFTER = 1.0  # after the recorder got SIGINT
RECORDER_SIGKILL_AT = 4.5
REASON_WAIT = 5.0  # seconds wait_ready waits for a failed node's logged reason

Event = ProcessEvent
"""What happened to a node: ``kind`` (an ``EventKind``: started, ready, died, respawning,
gave_up, stopped, signalled, stalled, recovered), ``node``, ``pid``, ``detail``, ``index``, ``time``."""


class GraphLauncher:
    """Runs a ``LaunchPlan``: node processes, readiness, death reports, respawns, stop.

    The keywords are ``ird_ros.launch.plan.plan_launch``'s:

    Args:
        nodes: node names to start (default: every default node of ``ird_ros.graph``, or of ``specs``).
        params: ROS params file passed to every node (default ``msgs_config/params/graph.yaml``).
        record_dir: if set, also run the recorder, writing a bag into this (new) folder.
        record_topics: topics to record (default: the params file's ``recorder.topics``,
            empty = all).
        domain_id: ROS domain of the graph, 0..101 (default: ``ROS_DOMAIN_ID`` of this
            process, else 0).
        private_domain: lease a free domain in 0..101 (``ird_ros.graph.domains.lease_domain``), with
            a private ``ROS_LOG_DIR``.
        respawn: node names to restart when they die (added to the params file's list).
        respawn_delay: seconds before a restart (default: params file, else 1.0).
        respawn_max_retries: restarts of one node before it is given up (-1: no limit;
            default: params file, else 5).
        specs: a node table other than ``ird_ros.graph.NODES`` (tests, stand-ins).
        output: children's stdout+stderr: ``"prefix"`` (printed as ``[name] line``),
            ``"quiet"`` (kept, shown in errors and ``output(name)``) or ``"files"``
            (``<log_dir>/<name>.log``).
        log_dir: ROS_LOG_DIR for the children and the folder for ``output="files"``.
        echo: where the launcher's own messages go (default: print to stdout).
        python: interpreter for the children (default: this one).
        cwd: working directory of the children (default: the repository root).
        env: the children's base environment (default: this process's).
    """

    def __init__(
        self,
        nodes: Sequence[str] | None = None,
        params: str | os.PathLike[str] | None = None,
        record_dir: str | os.PathLike[str] | None = None,
        record_topics: Sequence[str] | None = None,
        domain_id: int | None = None,
        private_domain: bool = False,
        respawn: Iterable[str] = (),
        respawn_delay: float | None = None,
        specs: Sequence[NodeSpec] | None = None,
        output: OutputChoice = OutputMode.PREFIX,
        log_dir: str | os.PathLike[str] | None = None,
        echo: Callable[[str], None] | None = None,
        python: str | None = None,
        cwd: str | os.PathLike[str] | None = None,
        env: Mapping[str, str] | None = None,
        respawn_max_retries: int | None = None,
    ) -> None:
        plan = plan_launch(
            nodes=nodes, params=params, record_dir=record_dir, record_topics=record_topics, domain_id=domain_id,
            private_domain=private_domain, respawn=respawn, respawn_delay=respawn_delay,
            respawn_max_retries=respawn_max_retries, specs=specs, output=output, log_dir=log_dir, python=python,
            cwd=cwd, env=env)
        self._adopt(plan, echo)

    @classmethod
    def from_plan(cls, plan: LaunchPlan, echo: Callable[[str], None] | None = None) -> "GraphLauncher":
        """A launcher that executes ``plan`` (built by ``plan_launch``)."""
        launcher = cls.__new__(cls)
        launcher._adopt(plan, echo)
        return launcher

    def _adopt(self, plan: LaunchPlan, echo: Callable[[str], None] | None) -> None:
        self.plan = plan
        self._echo = echo or print_line
        self._cond = threading.Condition(threading.RLock())
        self._lease: DomainLease | None = None
        self._log_tmp: tempfile.TemporaryDirectory | None = None
        self._domain_id: int | None = None
        self._env: dict[str, str] = {}
        self._sup: Supervisor | None = None
        self._monitor: ReadinessMonitor | None = None
        self._started = False
        self._stopped = False
        self.stop_duration: float | None = None

    # ------------------------------------------------------------------ properties

    @property
    def domain_id(self) -> int:
        assert self._domain_id is not None, "start() first"
        return self._domain_id

    @property
    def env(self) -> dict[str, str]:
        """The environment of the children (domain, DDS transport, log dir)."""
        return dict(self._env)

    @property
    def node_names(self) -> list[str]:
        return self.plan.names

    def _infos(self) -> dict[str, ChildInfo]:
        if self._sup is None:
            return {n: ChildInfo(n, None, ChildState.PENDING, 0.0, None, 0, None) for n in self.plan.names}
        return self._sup.infos()

    def pids(self) -> dict[str, int | None]:
        return {n: i.pid for n, i in self._infos().items()}

    def state(self, name: str) -> ChildState:
        return self._infos()[name].state

    def output(self, name: str, last: int = 60) -> str:
        """The last lines a node printed: its output pump's (modes prefix and quiet), else the end of
        ``<log_dir>/<name>.log`` (mode files: no pump reads the file; a death report needs it)."""
        if self._sup is None:
            return ""
        if self.plan.output is OutputMode.FILES:
            return _file_tail(Path(self._env["ROS_LOG_DIR"]) / f"{name}.log", last)
        return self._sup.output(name, last)

    def events(self) -> list[Event]:
        return [] if self._sup is None else self._sup.events()

    # ------------------------------------------------------------------ start

    def __enter__(self) -> "GraphLauncher":
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def start(self) -> None:
        """Start the probe and every node process (returns at once; see ``wait_ready``)."""
        if self._started:
            raise LaunchError("already started")
        self._started = True
        try:
            log_dir = self._open_domain()
            for note in self.plan.notes:
                self._say(f"note: {note}")
            self._sup = Supervisor(self.plan.process_specs(), env=self._env, cwd=self.plan.cwd,
                                   output=self.plan.output, log_dir=log_dir, echo=self._echo, on_event=self._on_event)
            self._monitor = self._start_probe(self._sup)
            try:
                self._sup.start()
            except Exception as exc:
                raise LaunchError(f"cannot start the nodes: {exc}") from exc
        except BaseException:
            self.stop()
            raise

    def _open_domain(self) -> Path:
        """Lease or take the domain, make the log folder, set the children's environment; return the folder."""
        plan = self.plan
        log_dir = plan.log_dir
        if plan.domain.private:
            self._lease = lease_domain(log_dir=log_dir)
            self._domain_id, log_dir = self._lease.domain_id, Path(self._lease.log_dir)
        else:
            self._domain_id = plan.domain.fixed_id(plan.base_env)
            if log_dir is None and plan.base_env.get("ROS_LOG_DIR"):
                log_dir = Path(plan.base_env["ROS_LOG_DIR"])
        if log_dir is None:
            self._log_tmp = tempfile.TemporaryDirectory(prefix="ird_launch_log_")
            log_dir = Path(self._log_tmp.name)
        log_dir.mkdir(parents=True, exist_ok=True)
        self._env = plan.environment(self._domain_id, log_dir)
        return log_dir

    def _start_probe(self, supervisor: Supervisor) -> ReadinessMonitor:
        with dds_process_env(self._env):  # the probe's participant talks like the children
            monitor = ReadinessMonitor(
                supervisor, self.plan.specs, self.domain_id, self._env,
                skip_ready_topics=self.plan.skipped_ready_topics,
                recorder=RECORDER if self.plan.has_recorder else None, recorded=self.plan.recorded_topics,
                on_change=self._notify, on_note=self._say, managed=self.plan.managed)
        monitor.start()
        return monitor

    def _say(self, text: str) -> None:
        self._echo(f"[launcher] {text}")

    def _on_event(self, ev: ProcessEvent) -> None:
        """Report deaths, restarts and give-ups; wake ``wait_ready`` (runs outside the supervisor's lock)."""
        if isinstance(ev, ProcessExited) and not ev.requested:
            self._say(f"node {ev.name} (pid {ev.pid}) {ev.detail}"
                      + (f"; respawning in {self.plan.respawn_delay:g} s" if ev.will_respawn else ""))
            if not ev.will_respawn and self.plan.output is not OutputMode.PREFIX and self._sup is not None:
                tail = self.output(ev.name, 15)
                if tail:
                    self._say(f"last output of {ev.name}:\n{tail}")
        elif isinstance(ev, ProcessGaveUp):
            self._say(f"node {ev.name}: {ev.detail} (respawn_max_retries {self.plan.respawn_max_retries}); "
                      "not respawned again")
        elif isinstance(ev, ProcessStalled):
            self._say(f"node {ev.name} (pid {ev.pid}) stalled: {ev.detail}")
        elif isinstance(ev, ProcessRecovered):
            self._say(f"node {ev.name} (pid {ev.pid}) {ev.detail}")
        elif isinstance(ev, ProcessReady) and ev.restart:
            self._say(f"node {ev.name} (pid {ev.pid}) ready again after {ev.ready_after:.2f} s "
                      f"(restart {ev.restart})")
        self._notify()

    def _notify(self) -> None:
        with self._cond:
            self._cond.notify_all()

    # ------------------------------------------------------------------ readiness

    def wait_ready(self, timeout: float = 60.0, nodes: Iterable[str] | None = None) -> dict[str, float]:
        """Block until every node (or ``nodes``) is ready; return seconds to ready per node.

        Raises ``LaunchError`` naming, per node, what is missing when ``timeout`` passes, or
        at once when a node that will not be respawned died.
        """
        if not self._started or self._sup is None or self._monitor is None:
            raise LaunchError("start() first")
        sup, monitor = self._sup, self._monitor
        names = list(nodes) if nodes is not None else self.plan.names
        deadline = time.monotonic() + timeout
        failed_at: dict[str, float] = {}
        with self._cond:
            while True:
                if monitor.error is not None:
                    raise LaunchError(f"readiness probe failed: {monitor.error!r}") from monitor.error
                infos = sup.infos()
                # after the recorder is ready, latched messages the probe got later must reach the bag
                lagging = monitor.recorder_lag() if RECORDER in names else []
                children = [infos[n] for n in names]
                dead = [c for c in children if c.state in (ChildState.EXITED, ChildState.STOPPED)]
                if dead:
                    raise LaunchError(self._death_report(dead))
                failed = [(c, monitor.failure(c.name, c.pid)) for c in children if monitor.failure(c.name, c.pid)]
                if failed:
                    # The reason is in the node's log, which its output pump may read a moment after
                    # the transition's answer came: wait for it (at most REASON_WAIT seconds).
                    first = failed_at.setdefault(failed[0][0].name, time.monotonic())
                    reasons = [self._failure_reason(c, what) for c, what in failed]
                    if all(reasons) or time.monotonic() - first > REASON_WAIT:
                        raise LaunchError("node(s) failed a lifecycle transition:\n" + "\n".join(
                            f"  {c.name} (pid {c.pid}): {what}: {reason or '(see its output)'}"
                            for (c, what), reason in zip(failed, reasons)))
                if all(c.state is ChildState.READY for c in children) and not lagging:
                    return {c.name: float(c.ready_after or 0.0) for c in children}
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise LaunchError(f"graph not ready after {timeout:g} s:\n" + self._missing_report(children, lagging))
                self._cond.wait(min(remaining, 0.5))

    def _death_report(self, dead: Sequence[ChildInfo]) -> str:
        assert self._sup is not None
        return "node(s) died before becoming ready:\n" + "\n".join(
            f"  {c.name} (pid {c.pid}) {describe_exit(c.returncode)}; last output:\n"
            + "\n".join("    " + line for line in self.output(c.name, 15).splitlines())
            for c in dead)

    def _failure_reason(self, c: ChildInfo, what: str) -> str:
        """The reason node ``c`` logged for its failed transition (``<what>: <reason>``), or ""."""
        logged = [line for line in self.output(c.name, 200).splitlines() if f"{what}:" in line]
        return logged[-1].split(f"{what}:", 1)[1].strip() if logged else ""

    def _missing_report(self, children: Sequence[ChildInfo], lagging: Sequence[str]) -> str:
        assert self._monitor is not None
        lines = []
        for c in children:
            if c.state is not ChildState.READY:
                what = "; ".join(self._monitor.missing(c.name, c.pid)) or c.state
                lines.append(f"  {c.name} (pid {c.pid}, {c.state}): {what}")
                printed = self.output(c.name, 3).splitlines()
                lines += ["    last output: " + (printed[0] if printed else "(none)")] + ["    " + p for p in printed[1:]]
            elif c.name == RECORDER and lagging:
                lines.append(f"  {RECORDER}: " + "; ".join(lagging))
        return "\n".join(lines)

    def wait_for_event(self, kind: EventKind | str, node: str, *, after: int = 0, timeout: float = 30.0) -> Event:
        """The first event of ``kind`` for ``node`` with index >= ``after`` (waits for it).

        Raises ``LaunchError`` at once if the readiness probe (the source of ``ready``, ``stalled``
        and ``recovered``) failed; the ``TimeoutError`` of a node that is stalled says what its
        last liveness check saw, of a node still starting what it lacks to be ready."""
        if self._sup is None:
            raise LaunchError("start() first")
        monitor = self._monitor

        def probe_failed() -> None:
            if monitor is not None and monitor.error is not None:
                raise LaunchError(f"readiness probe failed: {monitor.error!r}") from monitor.error

        try:
            return self._sup.wait_for_event(kind, node, after=after, timeout=timeout, abort=probe_failed)
        except TimeoutError as exc:
            note = monitor.stall_note(node) if monitor is not None else ""
            if note:
                raise TimeoutError(f"{exc}; {node} is stalled: {note}") from None
            info = self._infos().get(node)
            if monitor is None or info is None or info.state is not ChildState.STARTING:
                raise
            lacks = "; ".join(monitor.missing(node, info.pid))
            raise TimeoutError(f"{exc}; {node} (pid {info.pid}) is starting and lacks: {lacks}") from None

    def all_exited(self) -> bool:
        """True when no node runs and none will be respawned."""
        return all(i.state in (ChildState.EXITED, ChildState.STOPPED) for i in self._infos().values())

    # ------------------------------------------------------------------ status

    def status_table(self) -> str:
        infos = self._infos()
        stalled = self._monitor.stalled() if self._monitor is not None else {}
        rows = [("node", "pid", "state", "ready after", "restarts", "info")]
        for name, c in infos.items():
            ready = f"{c.ready_after:.2f} s" if c.ready_after is not None else "-"
            info = ""
            if c.state in (ChildState.EXITED, ChildState.STOPPED, ChildState.RESPAWNING):
                info = describe_exit(c.returncode)
            elif c.state is ChildState.STARTING:
                info = "; ".join(self._monitor.missing(name, c.pid)) if self._monitor is not None else ""
            state = "stalled" if c.state is ChildState.READY and name in stalled else c.state.value
            rows.append((name, str(c.pid or "-"), state, ready, str(c.restarts), info))
        widths = [max(len(r[i]) for r in rows) for i in range(5)]
        lines = ["  ".join(r[i].ljust(widths[i]) for i in range(5)) + "  " + r[5] for r in rows]
        return "\n".join(line.rstrip() for line in lines)

    # ------------------------------------------------------------------ stop

    def stop(self) -> dict[str, int | None]:
        """Stop every process (see the module docstring); idempotent. Returns exit codes."""
        if self._stopped:
            return {n: i.returncode for n, i in self._infos().items()}
        self._stopped = True
        restore = self._interrupt_ends_the_stop()
        try:
            return self._stop()
        finally:
            restore()

    def _interrupt_ends_the_stop(self) -> Callable[[], None]:
        """While ``stop()`` runs (in the main thread), SIGINT (a second Ctrl-C: the first one usually
        started the stop) and SIGTERM kill every node's process group with SIGKILL and end this
        process at once, exit 130 (143), with one line on stderr; returns what restores the
        previous handlers. The handler uses no lock and no thread: nothing in the stop can delay it.
        """
        if threading.current_thread() is not threading.main_thread():
            return lambda: None
        groups = [pid for pid in self.pids().values() if pid is not None]

        def hard_stop(signum: int, _frame: object) -> None:
            for pgid in groups:
                with contextlib.suppress(OSError):
                    os.killpg(pgid, signal.SIGKILL)
            with contextlib.suppress(OSError):
                os.write(2, f"\n[launcher] {signal.Signals(signum).name} during the stop: killed the nodes' "
                            f"process groups ({len(groups)}) and exited\n".encode())
            os._exit(128 + signum)

        previous = {sig: signal.signal(sig, hard_stop) for sig in (signal.SIGINT, signal.SIGTERM)}

        def restore() -> None:
            for sig, handler in previous.items():
                signal.signal(sig, handler if handler is not None else signal.SIG_DFL)

        return restore

    def _stop(self) -> dict[str, int | None]:
        t0 = time.monotonic()
        codes: dict[str, int | None] = {n: None for n in self.plan.names}
        if self._sup is not None:
            self._sup.stop_processes([n for n in self.plan.names if n != RECORDER], NODES_SIGTERM_AT,
                                     NODES_SIGKILL_AT - NODES_SIGTERM_AT, unready_signal=signal.SIGTERM)
            if self.plan.has_recorder:
                kill_at = max(RECORDER_SIGKILL_AT - (time.monotonic() - t0), 0.5)
                term_at = min(RECORDER_SIGTERM_AFTER, kill_at - 0.5)
                self._sup.stop_processes([RECORDER], term_at, kill_at - term_at, unready_signal=signal.SIGTERM)
        self.stop_duration = time.monotonic() - t0
        if self._monitor is not None:
            self._monitor.close()
        if self._sup is not None:
            codes = self._sup.shutdown()
        self._release_domain()
        return codes

    def _release_domain(self) -> None:
        if self._lease is not None:
            self._lease.release()
            self._lease = None
        if self._log_tmp is not None:
            with contextlib.suppress(Exception):
                self._log_tmp.cleanup()
            self._log_tmp = None


def _file_tail(path: Path, last: int, max_bytes: int = 64 * 1024) -> str:
    """The last ``last`` lines of the file's last ``max_bytes`` bytes ("" if it cannot be read)."""
    try:
        with open(path, "rb") as fh:
            fh.seek(max(0, os.fstat(fh.fileno()).st_size - max_bytes))
            data = fh.read(max_bytes)
    except OSError:
        return ""
    return "\n".join(data.decode("utf-8", "replace").splitlines()[-last:])
