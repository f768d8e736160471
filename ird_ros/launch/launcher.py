"""Start, watch and stop the IRD graph: one process per node (``ros2 launch`` has no wheel).

CLI: ``scripts/launch_graph.py`` (see its ``--help``). Python::

    from ird_ros.launch.launcher import GraphLauncher

    with GraphLauncher(nodes=["world", "inference"], record_dir="bags/run1",
                       private_domain=True, respawn=["world"]) as graph:
        graph.wait_ready(timeout=60)        # raises LaunchError naming what is missing
        print(graph.status_table())
        ...                                 # talk to the nodes in graph.domain_id
    # leaving the block stops every process (SIGINT, SIGTERM, SIGKILL within 5 s)

Three layers: ``ird_ros.launch.supervisor`` runs the processes (ROS-free: spawn, output, respawn,
stop escalation, PR_SET_PDEATHSIG; why not ``ros2 launch`` is said there),
``ird_ros.launch.readiness`` decides from the ROS graph when a node is ready, and this module sets up
the domain and the environment, turns the node table into processes and ties the two together.

Processes. Each node runs as ``<python> -m <module> --ros-args --params-file <params>``
(the node table is ``ird_ros.graph.NODES``), with this process's environment plus
``ROS_DOMAIN_ID``, ``ROS_LOG_DIR`` and the DDS transport of ``ird_ros.graph.domains.dds_env``:
loopback only (a Fast DDS profile bound to 127.0.0.1) unless ``IRD_DDS_NETWORK=1`` in the
environment (``--dds-network`` of the CLI) asks for multi-machine use; the probe's own
participant gets the same. Each child leads its own process group, has SIGINT/SIGTERM at
their defaults and gets SIGTERM if the launcher dies, even by SIGKILL (see
``ird_ros.launch.supervisor``).

Recording. With ``record_dir`` a ``recorder`` node (``ird_ros.nodes.recorder``) is started too, with
``-p output_dir:=<record_dir>``; its topics come from the params file's ``recorder`` section
(empty = all topics) unless ``record_topics`` is given. It is stopped last, after the other
nodes are gone, so the bag holds everything they published.

Readiness, decided by a probe node (``launcher``) in this process that polls the ROS graph
(no fixed sleeps; every check repeats until it holds or the timeout passes): a node is ready
when its process runs and it passes ``ird_ros.launch.readiness`` (in the graph, its services listed,
its publishers new, a message on its ``ready_topics`` since it started; ``ready_topics`` are
skipped, with a note, when a node it needs (``after``) is not launched, as they would never
come). The recorder is ready when it subscribes to every topic the launched nodes publish and
it records, and every latched message the probe received is counted in its bag;
``wait_ready`` keeps applying that last condition after the recorder was first ready, for
latched messages the probe receives later. ``wait_ready`` fails with ``LaunchError`` listing,
per node, what is still missing (or how a process died, with its last output).

Death and respawn. A child that exits while the graph runs is reported (exit code or
signal). Nodes listed in ``respawn`` (the argument, ``--respawn``, or the params file's
``launcher`` section) are started again after ``respawn_delay`` seconds and go through
readiness again. The recorder is never respawned (its bag folder exists by then).

Params file ``launcher`` section (same layout as the nodes' sections, so rcl accepts the file)::

    launcher:
      ros__parameters:
        respawn: [rob, world]   # nodes to restart when they die (default: none)
        respawn_delay: 1.0      # seconds before a restart (default 1.0)

Domain. ``private_domain`` leases a free ID in 0..101 (``ird_ros.graph.domains.lease_domain``);
otherwise ``domain_id``, else the inherited ``ROS_DOMAIN_ID`` (default 0), which must also be
in 0..101: higher IDs put the DDS ports into Linux's ephemeral port range.

Stopping (``stop()``, leaving the ``with`` block, or SIGINT/SIGTERM to the CLI): the nodes'
process groups get SIGINT, then SIGTERM after 1.5 s, then SIGKILL after 2.5 s; the recorder
then gets the same (its deadlines end at 4.5 s). Everything is gone within 5 s.
"""

from __future__ import annotations

import contextlib
import os
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

from ird_ros.graph.domains import DomainLease, check_domain_id, dds_env, dds_network, dds_process_env, lease_domain
from ird_ros.launch.supervisor import (
    ChildInfo,
    ChildState,
    EventKind,
    OutputMode,
    ProcessEvent,
    ProcessExited,
    ProcessReady,
    ProcessSpec,
    Supervisor,
    describe_exit,
)

__all__ = [
    "LaunchError",
    "LaunchSpec",
    "GraphLauncher",
    "Event",
    "EventKind",
    "ChildState",
    "REPO_ROOT",
    "RECORDER",
    "graph_specs",
    "default_params_file",
    "read_params_sections",
    "describe_exit",
]

REPO_ROOT = Path(__file__).resolve().parents[2]
RECORDER = "recorder"

# Stop schedule (seconds after stop() starts).
NODES_SIGTERM_AT = 1.5
NODES_SIGKILL_AT = 2.5
RECORDER_SIGTERM_AFTER = 1.0  # after the recorder got SIGINT
RECORDER_SIGKILL_AT = 4.5

Event = ProcessEvent
"""What happened to a node: ``kind`` (an ``EventKind``: started, ready, died, respawning,
stopped, signalled), ``node``, ``pid``, ``detail``, ``index``, ``time``."""


class LaunchError(RuntimeError):
    """The graph could not be started or did not become ready (the message says why)."""


@dataclass(frozen=True)
class LaunchSpec:
    """How to run one node and when it counts as ready (see the module docstring).

    ``module`` runs as ``python -m module``; ``script`` (if set) runs as ``python script``
    instead. ``ros_args`` are appended after ``--ros-args --params-file FILE``.
    """

    name: str
    module: str
    publishes: tuple[str, ...] = ()
    services: tuple[str, ...] = ()
    ready_topics: tuple[str, ...] = ()
    after: tuple[str, ...] = ()
    script: str | None = None
    ros_args: tuple[str, ...] = ()
    default: bool = True  # started when no node list is given


def graph_specs(*, optional: bool = False) -> list[LaunchSpec]:
    """The project's nodes, from ``ird_ros.graph.NODES``: those started by default, and with
    ``optional`` also those started only on request (the designer)."""
    from ird_ros import graph

    return [
        LaunchSpec(
            name=n.name,
            module=n.module,
            publishes=tuple(n.publishes),
            services=tuple(n.services),
            ready_topics=tuple(n.ready_topics),
            after=tuple(n.after),
            default=n.default,
        )
        for n in graph.NODES
        if optional or n.default
    ]


def default_params_file() -> Path:
    from ird_ros import graph

    return REPO_ROOT / graph.PARAMS_FILE


def read_params_sections(path: str | os.PathLike[str] | None) -> dict[str, dict[str, Any]]:
    """``{node_name: ros__parameters dict}`` of a ROS params file (empty if no file)."""
    if path is None or not Path(path).is_file():
        return {}
    import yaml

    data = yaml.safe_load(Path(path).read_text(encoding="utf-8")) or {}
    out: dict[str, dict[str, Any]] = {}
    for key, value in data.items():
        if isinstance(value, dict):
            params = value.get("ros__parameters")
            if isinstance(params, dict):
                out[str(key).lstrip("/")] = params
    return out


class GraphLauncher:
    """Runs graph nodes as processes, decides readiness, reports deaths, respawns, stops.

    Args:
        nodes: node names to start (default: every node of ``ird_ros.graph``, or of ``specs``).
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
        specs: a node table other than ``ird_ros.graph``'s (tests, stand-ins).
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
        specs: Sequence[LaunchSpec] | None = None,
        output: str = "prefix",
        log_dir: str | os.PathLike[str] | None = None,
        echo: Callable[[str], None] | None = None,
        python: str | None = None,
        cwd: str | os.PathLike[str] | None = None,
        env: Mapping[str, str] | None = None,
    ) -> None:
        try:
            self.output_mode = OutputMode(output)
        except ValueError:
            raise ValueError(f"output must be prefix, quiet or files, got {output!r}") from None
        if private_domain and domain_id is not None:
            raise ValueError("give either domain_id or private_domain, not both")
        if domain_id is not None:
            domain_id = check_domain_id(domain_id, "domain_id")
        self.params = Path(params) if params is not None else default_params_file()
        if params is not None and not self.params.is_file():
            raise LaunchError(f"params file {self.params} not found")
        sections = read_params_sections(self.params)
        table = list(specs) if specs is not None else graph_specs(optional=True)
        by_name = {s.name: s for s in table}
        names = list(nodes) if nodes is not None else [s.name for s in table if s.default]
        unknown = [n for n in names if n not in by_name]
        if unknown:
            raise LaunchError(f"unknown node(s) {unknown}; known: {sorted(by_name)}")
        if len(set(names)) != len(names):
            raise LaunchError(f"node list has duplicates: {names}")

        launcher_params = sections.get("launcher", {})
        respawn_set = set(respawn) | set(launcher_params.get("respawn", []) or [])
        unknown = sorted(respawn_set - set(names) - {RECORDER})
        if unknown:
            raise LaunchError(f"respawn names node(s) not launched: {unknown}")
        self.respawn_delay = float(
            respawn_delay if respawn_delay is not None else launcher_params.get("respawn_delay", 1.0)
        )
        if not self.respawn_delay >= 0.0:
            raise ValueError(f"respawn_delay must be >= 0, got {self.respawn_delay}")

        self.record_dir = Path(record_dir).resolve() if record_dir is not None else None
        if self.record_dir is not None and self.record_dir.exists():
            raise LaunchError(f"record dir {self.record_dir} already exists: choose a new folder")
        rec_params = sections.get(RECORDER, {})
        if record_topics is None:
            record_topics = [t for t in (rec_params.get("topics") or []) if t]
        self.record_topics = list(record_topics)
        self.record_exclude = set(rec_params.get("exclude_topics") or ["/rosout", "/parameter_events"])

        self._specs: dict[str, LaunchSpec] = {n: by_name[n] for n in names}
        # a node whose inputs come from a node that is not launched never gets its ready topics
        self._skip_ready_topics = {
            n for n, s in self._specs.items() if s.ready_topics and any(d not in self._specs for d in s.after)
        }
        if self.record_dir is not None:
            ros_args = ["-p", f"output_dir:={self.record_dir}"]
            if record_topics is not None and self.record_topics:
                ros_args += ["-p", "topics:=[" + ",".join(self.record_topics) + "]"]
            rec_spec = by_name.get(RECORDER) or LaunchSpec(name=RECORDER, module="ird_ros.nodes.recorder")
            self._specs[RECORDER] = replace(rec_spec, ros_args=tuple(rec_spec.ros_args) + tuple(ros_args))
        # not the recorder: its output folder exists after the first start
        self._respawn = {n for n in respawn_set if n in self._specs and n != RECORDER}

        self.python = python or sys.executable
        self.cwd = Path(cwd) if cwd is not None else REPO_ROOT
        self._echo = echo or (lambda line: print(line, flush=True))
        self._base_env = dict(os.environ if env is None else env)
        dds_network(self._base_env)  # a bad IRD_DDS_NETWORK fails here, naming the variable
        self._private = private_domain
        self._lease: DomainLease | None = None
        self._log_tmp: tempfile.TemporaryDirectory | None = None
        self._domain_id = domain_id
        self._log_dir = Path(log_dir) if log_dir is not None else None
        self._env: dict[str, str] = {}
        self._notes = ["the recorder is never respawned (its bag folder exists after the first start)"] \
            if RECORDER in respawn_set else []

        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        self._sup: Supervisor | None = None
        self._monitor: Any = None  # ird_ros.launch.readiness.ReadinessMonitor (imports rclpy)
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
        """The environment of the children (domain, discovery range, log dir)."""
        return dict(self._env)

    @property
    def node_names(self) -> list[str]:
        return list(self._specs)

    def _infos(self) -> dict[str, ChildInfo]:
        if self._sup is None:
            return {n: ChildInfo(n, None, ChildState.PENDING, 0.0, None, 0, None) for n in self._specs}
        return self._sup.infos()

    def pids(self) -> dict[str, int | None]:
        return {n: i.pid for n, i in self._infos().items()}

    def state(self, name: str) -> ChildState:
        return self._infos()[name].state

    def output(self, name: str, last: int = 60) -> str:
        """The last lines a node printed (modes prefix and quiet)."""
        return "" if self._sup is None else self._sup.output(name, last)

    def events(self) -> list[Event]:
        return [] if self._sup is None else self._sup.events()

    # ------------------------------------------------------------------ start

    def __enter__(self) -> "GraphLauncher":
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _setup_environment(self) -> None:
        if self._private:
            self._lease = lease_domain(log_dir=self._log_dir)
            self._domain_id = self._lease.domain_id
            self._log_dir = Path(self._lease.log_dir)
            env = self._lease.env(self._base_env)
        else:
            env = dict(self._base_env)
            if self._domain_id is None:
                try:
                    self._domain_id = check_domain_id(env.get("ROS_DOMAIN_ID") or 0, "ROS_DOMAIN_ID")
                except ValueError as exc:
                    raise LaunchError(str(exc)) from None
            if self._log_dir is None and env.get("ROS_LOG_DIR"):
                self._log_dir = Path(env["ROS_LOG_DIR"])
            dds_env(env)
        if self._log_dir is None:
            self._log_tmp = tempfile.TemporaryDirectory(prefix="ird_launch_log_")
            self._log_dir = Path(self._log_tmp.name)
        self._log_dir.mkdir(parents=True, exist_ok=True)
        env["ROS_DOMAIN_ID"] = str(self._domain_id)
        env["ROS_LOG_DIR"] = str(self._log_dir)
        env["PYTHONUNBUFFERED"] = "1"
        # children import this checkout's ird_ros (and tests' stand-ins) even if not installed
        env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
        self._env = env

    def _argv(self, spec: LaunchSpec) -> tuple[str, ...]:
        head = [self.python, spec.script] if spec.script else [self.python, "-m", spec.module]
        tail = ["--ros-args"]
        if self.params.is_file():
            tail += ["--params-file", str(self.params)]
        return tuple(head + tail + list(spec.ros_args))

    def start(self) -> None:
        """Start the probe and every node process (returns at once; see ``wait_ready``)."""
        if self._started:
            raise LaunchError("already started")
        self._started = True
        try:
            self._setup_environment()
            for note in self._notes:
                self._say(f"note: {note}")
            for name in self._skip_ready_topics:
                spec = self._specs[name]
                deps = [d for d in spec.after if d not in self._specs]
                self._say(f"note: {name} needs {', '.join(deps)} (not launched): "
                          f"not waiting for {', '.join(spec.ready_topics)}")
            self._sup = Supervisor(
                [ProcessSpec(n, self._argv(s), respawn=n in self._respawn, respawn_delay=self.respawn_delay)
                 for n, s in self._specs.items()],
                env=self._env, cwd=self.cwd, output=self.output_mode, log_dir=self._log_dir, echo=self._echo,
                on_event=self._on_event,
            )
            from ird_ros.launch.readiness import ReadinessMonitor  # imports rclpy

            with dds_process_env(self._env):  # the probe's participant talks like the children
                self._monitor = ReadinessMonitor(
                    self._sup, self._specs, self.domain_id, self._env, skip_ready_topics=self._skip_ready_topics,
                    recorder=RECORDER if RECORDER in self._specs else None, recorded=self._expected_recorded(),
                    on_change=self._notify)
            self._monitor.start()
            try:
                self._sup.start()
            except Exception as exc:
                raise LaunchError(f"cannot start the nodes: {exc}") from exc
        except BaseException:
            self.stop()
            raise

    def _say(self, text: str) -> None:
        self._echo(f"[launcher] {text}")

    def _on_event(self, ev: ProcessEvent) -> None:
        """Report deaths and restarts; wake ``wait_ready`` (runs outside the supervisor's lock)."""
        if isinstance(ev, ProcessExited) and not ev.requested:
            respawn = ev.name in self._respawn
            self._say(f"node {ev.name} (pid {ev.pid}) {ev.detail}"
                      + (f"; respawning in {self.respawn_delay:g} s" if respawn else ""))
            if not respawn and self.output_mode is not OutputMode.PREFIX and self._sup is not None:
                tail = self._sup.output(ev.name, 15)
                if tail:
                    self._say(f"last output of {ev.name}:\n{tail}")
        elif isinstance(ev, ProcessReady) and ev.restart:
            self._say(f"node {ev.name} (pid {ev.pid}) ready again after {ev.ready_after:.2f} s "
                      f"(restart {ev.restart})")
        self._notify()

    def _expected_recorded(self) -> list[str]:
        """Topics the recorder must record: what the launched nodes publish, filtered."""
        topics: set[str] = set()
        for name, spec in self._specs.items():
            if name != RECORDER:
                topics.update(spec.publishes)
        if self.record_topics:
            topics &= set(self.record_topics)
        return sorted(topics - self.record_exclude)

    def _notify(self) -> None:
        with self._cond:
            self._cond.notify_all()

    def wait_ready(self, timeout: float = 60.0, nodes: Iterable[str] | None = None) -> dict[str, float]:
        """Block until every node (or ``nodes``) is ready; return seconds to ready per node.

        Raises ``LaunchError`` naming, per node, what is missing when ``timeout`` passes, or
        at once when a node that will not be respawned died.
        """
        if not self._started or self._sup is None or self._monitor is None:
            raise LaunchError("start() first")
        names = list(nodes) if nodes is not None else list(self._specs)
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                error = self._monitor.error
                if error is not None:
                    raise LaunchError(f"readiness probe failed: {error!r}") from error
                infos = self._sup.infos()
                # after the recorder is ready, latched messages the probe got later must reach the bag
                lagging = self._monitor.recorder_lag() if RECORDER in names else []
                children = [infos[n] for n in names]
                dead = [c for c in children if c.state in (ChildState.EXITED, ChildState.STOPPED)]
                if dead:
                    raise LaunchError("node(s) died before becoming ready:\n" + "\n".join(
                        f"  {c.name} (pid {c.pid}) {describe_exit(c.returncode)}; last output:\n"
                        + "\n".join("    " + line for line in self._sup.output(c.name, 15).splitlines())
                        for c in dead))
                if all(c.state is ChildState.READY for c in children) and not lagging:
                    return {c.name: float(c.ready_after or 0.0) for c in children}
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    lines = []
                    for c in children:
                        if c.state is not ChildState.READY:
                            what = "; ".join(self._monitor.missing(c.name, c.pid)) or c.state
                            lines.append(f"  {c.name} (pid {c.pid}, {c.state}): {what}")
                        elif c.name == RECORDER and lagging:
                            lines.append(f"  {RECORDER}: " + "; ".join(lagging))
                    raise LaunchError(f"graph not ready after {timeout:g} s:\n" + "\n".join(lines))
                self._cond.wait(min(remaining, 0.5))

    def wait_for_event(self, kind: EventKind | str, node: str, *, after: int = 0, timeout: float = 30.0) -> Event:
        """The first event of ``kind`` for ``node`` with index >= ``after`` (waits for it)."""
        if self._sup is None:
            raise LaunchError("start() first")
        return self._sup.wait_for_event(kind, node, after=after, timeout=timeout)

    def all_exited(self) -> bool:
        """True when no node runs and none will be respawned."""
        return all(i.state in (ChildState.EXITED, ChildState.STOPPED) for i in self._infos().values())

    # ------------------------------------------------------------------ status

    def status_table(self) -> str:
        infos = self._infos()
        rows = [("node", "pid", "state", "ready after", "restarts", "info")]
        for name, c in infos.items():
            ready = f"{c.ready_after:.2f} s" if c.ready_after is not None else "-"
            info = ""
            if c.state in (ChildState.EXITED, ChildState.STOPPED, ChildState.RESPAWNING):
                info = describe_exit(c.returncode)
            elif c.state is ChildState.STARTING:
                info = "; ".join(self._monitor.missing(name, c.pid)) if self._monitor is not None else ""
            rows.append((name, str(c.pid or "-"), c.state.value, ready, str(c.restarts), info))
        widths = [max(len(r[i]) for r in rows) for i in range(5)]
        lines = ["  ".join(r[i].ljust(widths[i]) for i in range(5)) + "  " + r[5] for r in rows]
        return "\n".join(line.rstrip() for line in lines)

    # ------------------------------------------------------------------ stop

    def stop(self) -> dict[str, int | None]:
        """Stop every process (see the module docstring); idempotent. Returns exit codes."""
        if self._stopped:
            return {n: i.returncode for n, i in self._infos().items()}
        self._stopped = True
        t0 = time.monotonic()
        codes: dict[str, int | None] = {n: None for n in self._specs}
        if self._sup is not None:
            nodes = [n for n in self._specs if n != RECORDER]
            self._sup.stop_processes(nodes, NODES_SIGTERM_AT, NODES_SIGKILL_AT - NODES_SIGTERM_AT)
            if RECORDER in self._specs:
                kill_at = max(RECORDER_SIGKILL_AT - (time.monotonic() - t0), 0.5)
                term_at = min(RECORDER_SIGTERM_AFTER, kill_at - 0.5)
                self._sup.stop_processes([RECORDER], term_at, kill_at - term_at)
        self.stop_duration = time.monotonic() - t0

        if self._monitor is not None:
            self._monitor.close()
        if self._sup is not None:
            codes = self._sup.shutdown()
        if self._lease is not None:
            self._lease.release()
            self._lease = None
        if self._log_tmp is not None:
            with contextlib.suppress(Exception):
                self._log_tmp.cleanup()
            self._log_tmp = None
        return codes
