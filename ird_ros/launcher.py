"""Start, watch and stop the IRD graph: one process per node (no ``ros2 launch`` here).

CLI: ``scripts/launch_graph.py`` (see its ``--help``). Python::

    from ird_ros.launcher import GraphLauncher

    with GraphLauncher(nodes=["world", "inference"], record_dir="bags/run1",
                       private_domain=True, respawn=["world"]) as graph:
        graph.wait_ready(timeout=60)        # raises LaunchError naming what is missing
        print(graph.status_table())
        ...                                 # talk to the nodes in graph.domain_id
    # leaving the block stops every process (SIGINT, SIGTERM, SIGKILL within 5 s)

Processes. Each node runs as ``<python> -m <module> --ros-args --params-file <params>``
(the node table is ``ird_ros.graph.NODES``), with this process's environment plus
``ROS_DOMAIN_ID`` (and, for a private domain, ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and
``ROS_LOG_DIR``). Every child is the leader of its own process group (``setsid``), so a signal
to the group also reaches the node's worker processes; it starts with SIGINT/SIGTERM at their
default dispositions (a launcher started with ``&`` has SIGINT ignored, which children would
inherit) and with ``PR_SET_PDEATHSIG=SIGTERM``, so it is told to stop even when the launcher
is killed with SIGKILL. Children are spawned from one long-lived supervisor thread because
the kernel ties PDEATHSIG to the thread that forked the child, not to the process.

Recording. With ``record_dir`` a ``recorder`` node (``ird_ros.recorder``) is started too, with
``-p output_dir:=<record_dir>``; its topics come from the params file's ``recorder`` section
(empty = all topics) unless ``record_topics`` is given. It is stopped last, after the other
nodes are gone, so the bag holds everything they published.

Readiness, decided by a probe node (``launcher``) in this process that polls the ROS graph
(no fixed sleeps; every check repeats until it holds or the timeout passes). A node is ready
when all of these hold:

1. its process is running;
2. its name is in the graph (``get_node_names_and_namespaces``);
3. every service of its ``services`` is listed for it (``get_service_names_and_types_by_node``);
4. every topic of its ``publishes`` has a publisher endpoint owned by it
   (``get_publishers_info_by_topic``); after a respawn the endpoint must be a new one (a GID
   not seen before: DDS keeps a SIGKILLed node's endpoints in the graph until its lease
   expires, about 20 s);
5. a message arrived on every topic of its ``ready_topics`` after the node (re)started
   (latched topics: the probe subscribes transient local). Skipped, with a warning, when a
   node it needs (``after``) is not launched, as it would never come.

The recorder is ready when it is in the graph, subscribes to every topic that the launched
nodes publish and it is configured to record, and, for each of those topics that is latched
(transient local) and on which the probe itself received a message, its ``/recorder/status``
counts at least one recorded message (so stopping right after "ready" still leaves the
current maps, proxy and plan in the bag). ``wait_ready`` keeps applying that last condition
after the recorder was first ready, for latched messages the probe receives later. ``wait_ready`` fails with ``LaunchError``
listing, per node, what is still missing (or how a process died, with its last output).

Death and respawn. A child that exits while the graph runs is reported (exit code or
signal). Nodes listed in ``respawn`` (the argument, ``--respawn``, or the params file's
``launcher`` section) are started again after ``respawn_delay`` seconds and go through
readiness again. The recorder is never respawned (its bag folder exists by then).

Params file ``launcher`` section (same layout as the nodes' sections, so rcl accepts the file)::

    launcher:
      ros__parameters:
        respawn: [rob, world]   # nodes to restart when they die (default: none)
        respawn_delay: 1.0      # seconds before a restart (default 1.0)

Stopping (``stop()``, leaving the ``with`` block, or SIGINT/SIGTERM to the CLI): the nodes'
process groups get SIGINT, then SIGTERM after 1.5 s, then SIGKILL after 2.5 s; the recorder
then gets the same (its deadlines end at 4.5 s). Everything is gone within 5 s.
"""

from __future__ import annotations

import collections
import contextlib
import ctypes
import os
import queue
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping, Sequence

__all__ = [
    "LaunchError",
    "LaunchSpec",
    "GraphLauncher",
    "Event",
    "REPO_ROOT",
    "RECORDER",
    "graph_specs",
    "read_params_sections",
    "describe_exit",
]

REPO_ROOT = Path(__file__).resolve().parents[1]
RECORDER = "recorder"
PROBE_NODE = "launcher"

# Stop schedule (seconds after stop() starts).
NODES_SIGTERM_AT = 1.5
NODES_SIGKILL_AT = 2.5
RECORDER_SIGTERM_AFTER = 1.0  # after the recorder got SIGINT
RECORDER_SIGKILL_AT = 4.5
STOP_BUDGET = 5.0


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


def graph_specs() -> list[LaunchSpec]:
    """The project's nodes, from ``ird_ros.graph.NODES``."""
    from ird_ros import graph

    return [
        LaunchSpec(
            name=n.name,
            module=n.module,
            publishes=tuple(n.publishes),
            services=tuple(n.services),
            ready_topics=tuple(n.ready_topics),
            after=tuple(n.after),
        )
        for n in graph.NODES
    ]


def default_params_file() -> Path:
    try:
        from ird_ros import graph

        return REPO_ROOT / graph.PARAMS_FILE
    except ImportError:  # pragma: no cover
        return REPO_ROOT / "msgs_config" / "params" / "graph.yaml"


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


def describe_exit(code: int | None) -> str:
    """``exited with code 2`` / ``killed by SIGKILL`` / ``running``."""
    if code is None:
        return "running"
    if code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with code {code}"


@dataclass(frozen=True)
class Event:
    """Something that happened to a node: kind is started, ready, died, respawning or stopped."""

    index: int
    time: float
    kind: str
    node: str
    pid: int | None
    detail: str = ""


@dataclass
class _Child:
    spec: LaunchSpec
    respawn: bool
    proc: subprocess.Popen | None = None
    state: str = "pending"  # pending, starting, ready, exited, respawning, stopped
    started_at: float = 0.0  # monotonic
    ready_after: float | None = None
    restarts: int = 0
    returncode: int | None = None
    tail: collections.deque = field(default_factory=lambda: collections.deque(maxlen=60))
    missing: list[str] = field(default_factory=list)
    old_gids: set = field(default_factory=set)
    gids: set = field(default_factory=set)
    skip_ready_topics: bool = False

    @property
    def pid(self) -> int | None:
        return None if self.proc is None else self.proc.pid


try:
    _PRCTL: Any = ctypes.CDLL(None, use_errno=True).prctl
except (OSError, AttributeError):  # pragma: no cover - not Linux/glibc
    _PRCTL = None
_PR_SET_PDEATHSIG = 1


def _make_child_setup(parent_pid: int) -> Callable[[], None]:
    def setup() -> None:  # pragma: no cover - runs in the child between fork and exec
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        if _PRCTL is not None:
            _PRCTL(_PR_SET_PDEATHSIG, int(signal.SIGTERM))
        if os.getppid() != parent_pid:  # the launcher died before prctl took effect
            os._exit(1)

    return setup


def _group_alive(pgid: int) -> bool:
    """True while a process of group ``pgid`` runs (zombies do not count).

    A node's helper processes (multiprocessing's resource tracker, pool workers) are
    re-parented to init when the node exits; their zombies stay in the group until init
    reaps them (over a second in some containers, never in others), and ``killpg(pgid, 0)``
    counts zombies. So the group's members are read from ``/proc/<pid>/stat``.
    """
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # pragma: no cover
        return True
    try:
        entries = os.listdir("/proc")
    except OSError:  # pragma: no cover - no procfs: trust killpg
        return True
    for entry in entries:
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat", "rb") as f:
                fields = f.read().rsplit(b")", 1)[1].split()
        except OSError:
            continue
        # fields after "(comm)": state, ppid, pgrp, ...
        if int(fields[2]) == pgid and fields[0] != b"Z":
            return True
    return False


def _signal_group(pgid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, sig)


@contextlib.contextmanager
def _temp_env(values: Mapping[str, str]) -> Iterator[None]:
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


class GraphLauncher:
    """Runs graph nodes as processes, decides readiness, reports deaths, respawns, stops.

    Args:
        nodes: node names to start (default: every node of ``ird_ros.graph``, or of ``specs``).
        params: ROS params file passed to every node (default ``msgs_config/params/graph.yaml``).
        record_dir: if set, also run the recorder, writing a bag into this (new) folder.
        record_topics: topics to record (default: the params file's ``recorder.topics``,
            empty = all).
        domain_id: ROS domain of the graph (default: ``ROS_DOMAIN_ID`` of this process, else 0).
        private_domain: lease a free domain in 0..101 (``ird_ros.testing.lease_domain``), with
            ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and a private ``ROS_LOG_DIR``.
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
        if output not in ("prefix", "quiet", "files"):
            raise ValueError(f"output must be prefix, quiet or files, got {output!r}")
        if private_domain and domain_id is not None:
            raise ValueError("give either domain_id or private_domain, not both")
        self.params = Path(params) if params is not None else default_params_file()
        if params is not None and not self.params.is_file():
            raise LaunchError(f"params file {self.params} not found")
        sections = read_params_sections(self.params)
        table = list(specs) if specs is not None else graph_specs()
        by_name = {s.name: s for s in table}
        names = list(nodes) if nodes is not None else [s.name for s in table]
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

        self.record_dir = Path(record_dir).resolve() if record_dir is not None else None
        if self.record_dir is not None and self.record_dir.exists():
            raise LaunchError(f"record dir {self.record_dir} already exists: choose a new folder")
        rec_params = sections.get(RECORDER, {})
        if record_topics is None:
            record_topics = [t for t in (rec_params.get("topics") or []) if t]
        self.record_topics = list(record_topics)
        self.record_exclude = set(rec_params.get("exclude_topics") or ["/rosout", "/parameter_events"])

        self._children: dict[str, _Child] = {}
        for n in names:
            spec = by_name[n]
            self._children[n] = _Child(spec=spec, respawn=n in respawn_set)
        for child in self._children.values():
            missing_deps = [d for d in child.spec.after if d not in self._children]
            if missing_deps and child.spec.ready_topics:
                child.skip_ready_topics = True
        if self.record_dir is not None:
            ros_args = ["-p", f"output_dir:={self.record_dir}"]
            if record_topics is not None and self.record_topics:
                ros_args += ["-p", "topics:=[" + ",".join(self.record_topics) + "]"]
            rec_spec = by_name.get(RECORDER) or LaunchSpec(name=RECORDER, module="ird_ros.recorder")
            rec_spec = replace(rec_spec, ros_args=tuple(rec_spec.ros_args) + tuple(ros_args))
            # not respawned: its output folder exists after the first start
            self._children[RECORDER] = _Child(spec=rec_spec, respawn=False)

        self.output = output
        self.python = python or sys.executable
        self.cwd = Path(cwd) if cwd is not None else REPO_ROOT
        self._echo = echo or (lambda line: print(line, flush=True))
        self._base_env = dict(os.environ if env is None else env)
        self._private = private_domain
        self._lease: Any = None
        self._log_tmp: tempfile.TemporaryDirectory | None = None
        self._domain_id = domain_id
        self._log_dir = Path(log_dir) if log_dir is not None else None
        self._notes = ["the recorder is never respawned (its bag folder exists after the first start)"] \
            if RECORDER in respawn_set else []

        self._lock = threading.RLock()
        self._cond = threading.Condition(self._lock)
        self._events: list[Event] = []
        self._commands: queue.Queue = queue.Queue()
        self._supervisor: threading.Thread | None = None
        self._probe_thread: threading.Thread | None = None
        self._probe_error: BaseException | None = None
        # after the recorder is ready, latched messages the probe got later must reach the bag
        self._recorder_lagging: list[str] = []
        self._stopping = False
        self._started = False
        self._stopped = False
        self._t0 = 0.0
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
        return list(self._children)

    def pids(self) -> dict[str, int | None]:
        with self._lock:
            return {n: c.pid for n, c in self._children.items()}

    def state(self, name: str) -> str:
        with self._lock:
            return self._children[name].state

    def output(self, name: str, last: int = 60) -> str:
        """The last lines a node printed (modes prefix and quiet)."""
        with self._lock:
            return "\n".join(list(self._children[name].tail)[-last:])

    def events(self) -> list[Event]:
        with self._lock:
            return list(self._events)

    # ------------------------------------------------------------------ start

    def __enter__(self) -> "GraphLauncher":
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def _setup_environment(self) -> None:
        env = dict(self._base_env)
        if self._private:
            from ird_ros.testing import lease_domain

            self._lease = lease_domain(log_dir=self._log_dir)
            self._domain_id = self._lease.domain_id
            self._log_dir = Path(self._lease.log_dir)
            env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
            env.pop("ROS_LOCALHOST_ONLY", None)
        else:
            if self._domain_id is None:
                self._domain_id = int(env.get("ROS_DOMAIN_ID") or 0)
            if self._log_dir is None and env.get("ROS_LOG_DIR"):
                self._log_dir = Path(env["ROS_LOG_DIR"])
        if not 0 <= int(self._domain_id) <= 232:
            raise LaunchError(f"domain id {self._domain_id} out of range (use 0..101)")
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

    def start(self) -> None:
        """Start the probe and every node process (returns at once; see ``wait_ready``)."""
        if self._started:
            raise LaunchError("already started")
        self._started = True
        self._t0 = time.monotonic()
        try:
            self._setup_environment()
            for note in self._notes:
                self._say(f"note: {note}")
            for child in self._children.values():
                if child.skip_ready_topics:
                    deps = [d for d in child.spec.after if d not in self._children]
                    self._say(f"note: {child.spec.name} needs {', '.join(deps)} (not launched): "
                              f"not waiting for {', '.join(child.spec.ready_topics)}")
            self._start_probe()
            self._supervisor = threading.Thread(target=self._supervise, name="launcher-supervisor", daemon=True)
            self._supervisor.start()
            done = threading.Event()
            errors: list[BaseException] = []
            self._commands.put(("spawn_all", (done, errors)))
            done.wait()
            if errors:
                raise LaunchError(f"cannot start the nodes: {errors[0]}") from errors[0]
        except BaseException:
            self.stop()
            raise

    def _say(self, text: str) -> None:
        self._echo(f"[launcher] {text}")

    def _argv(self, spec: LaunchSpec) -> list[str]:
        head = [self.python, spec.script] if spec.script else [self.python, "-m", spec.module]
        tail = ["--ros-args"]
        if self.params.is_file():
            tail += ["--params-file", str(self.params)]
        return head + tail + list(spec.ros_args)

    def _spawn(self, child: _Child) -> None:
        """Start a child process (supervisor thread only: PDEATHSIG follows the forking thread)."""
        spec = child.spec
        stdout: Any
        if self.output == "files":
            assert self._log_dir is not None
            stdout = open(self._log_dir / f"{spec.name}.log", "ab")  # noqa: SIM115 - closed below
        else:
            stdout = subprocess.PIPE
        try:
            proc = subprocess.Popen(
                self._argv(spec),
                env=self._env,
                cwd=self.cwd,
                stdin=subprocess.DEVNULL,
                stdout=stdout,
                stderr=subprocess.STDOUT,
                start_new_session=True,
                preexec_fn=_make_child_setup(os.getpid()),
            )
        finally:
            if self.output == "files":
                stdout.close()
        with self._lock:
            child.proc = proc
            child.state = "starting"
            child.started_at = time.monotonic()
            child.ready_after = None
            child.returncode = None
            child.missing = ["process started"]
            self._event("started", spec.name, proc.pid)
        if proc.stdout is not None:
            threading.Thread(target=self._pump, args=(child, proc), name=f"out-{spec.name}", daemon=True).start()
        threading.Thread(target=self._waiter, args=(child, proc), name=f"wait-{spec.name}", daemon=True).start()

    def _pump(self, child: _Child, proc: subprocess.Popen) -> None:
        assert proc.stdout is not None
        name = child.spec.name
        for raw in proc.stdout:
            line = raw.decode("utf-8", "replace").rstrip("\n")
            with self._lock:
                child.tail.append(line)
            if self.output == "prefix":
                self._echo(f"[{name}] {line}")

    def _waiter(self, child: _Child, proc: subprocess.Popen) -> None:
        code = proc.wait()
        self._commands.put(("exited", (child, proc, code)))

    def _event(self, kind: str, node: str, pid: int | None, detail: str = "") -> None:
        with self._cond:
            self._events.append(Event(len(self._events), time.monotonic() - self._t0, kind, node, pid, detail))
            self._cond.notify_all()

    # ------------------------------------------------------------------ supervisor

    def _supervise(self) -> None:
        pending: list[tuple[float, _Child]] = []  # (due time, child) respawns
        while True:
            timeout = None
            if pending:
                timeout = max(0.0, min(t for t, _ in pending) - time.monotonic())
            try:
                cmd, arg = self._commands.get(timeout=timeout)
            except queue.Empty:
                cmd, arg = "tick", None
            if cmd == "quit":
                return
            if cmd == "spawn_all":
                done, errors = arg
                try:
                    for child in self._children.values():
                        self._spawn(child)
                except BaseException as exc:  # noqa: BLE001 - reported by start()
                    errors.append(exc)
                done.set()
            elif cmd == "exited":
                child, proc, code = arg
                self._on_exit(child, proc, code, pending)
            now = time.monotonic()
            due = [c for t, c in pending if t <= now]
            pending[:] = [(t, c) for t, c in pending if t > now]
            for child in due:
                # under the lock: stop() sets _stopping and then collects the processes
                with self._lock:
                    if self._stopping:
                        continue
                    try:
                        self._spawn(child)
                    except Exception as exc:  # noqa: BLE001
                        self._say(f"{child.spec.name}: respawn failed: {exc}")
                        child.state = "exited"

    def _on_exit(self, child: _Child, proc: subprocess.Popen, code: int, pending: list) -> None:
        name = child.spec.name
        with self._lock:
            if child.proc is not proc:
                return
            child.returncode = code
            if self._stopping:
                child.state = "stopped"
                self._event("stopped", name, proc.pid, describe_exit(code))
                return
            child.state = "exited"
            # endpoints of the dead instance may linger in the graph: remember their GIDs
            child.old_gids |= child.gids
            self._event("died", name, proc.pid, describe_exit(code))
            respawn = child.respawn
        self._say(f"node {name} (pid {proc.pid}) {describe_exit(code)}"
                  + (f"; respawning in {self.respawn_delay:g} s" if respawn else ""))
        if not respawn and self.output != "prefix":
            tail = self.output_tail(child)
            if tail:
                self._say(f"last output of {name}:\n{tail}")
        if respawn:
            with self._lock:
                child.state = "respawning"
                child.restarts += 1
                self._event("respawning", name, proc.pid, f"restart {child.restarts}")
            pending.append((time.monotonic() + self.respawn_delay, child))

    def output_tail(self, child: _Child, last: int = 15) -> str:
        with self._lock:
            return "\n".join(list(child.tail)[-last:])

    # ------------------------------------------------------------------ readiness probe

    def _start_probe(self) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.signals import SignalHandlerOptions

        self._ctx = Context()
        keys = {k: self._env[k] for k in ("ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_LOG_DIR") if k in self._env}
        with _temp_env(keys):
            rclpy.init(context=self._ctx, domain_id=int(self._domain_id),
                       signal_handler_options=SignalHandlerOptions.NO)
            self._probe = rclpy.create_node(PROBE_NODE, context=self._ctx, start_parameter_services=False,
                                            enable_rosout=False)
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        self._executor = SingleThreadedExecutor(context=self._ctx)
        self._executor.add_node(self._probe)
        self._probe_subs: dict[str, Any] = {}
        self._received: dict[str, float] = {}  # topic -> monotonic time of the last message
        self._latched: dict[str, bool] = {}  # topic -> every publisher offers transient local
        self._recorder_counts: dict[str, int] = {}
        if RECORDER in self._children:
            import json

            from std_msgs.msg import String

            from ird_ros.recorder import STATUS_TOPIC

            def status(msg: Any) -> None:
                with contextlib.suppress(ValueError, AttributeError):
                    self._recorder_counts = dict(json.loads(msg.data)["counts"])

            self._probe.create_subscription(String, STATUS_TOPIC, status, QoSProfile(
                history=HistoryPolicy.KEEP_LAST, depth=1, reliability=ReliabilityPolicy.RELIABLE,
                durability=DurabilityPolicy.TRANSIENT_LOCAL))
        self._probe_thread = threading.Thread(target=self._probe_loop, name="launcher-probe", daemon=True)
        self._probe_thread.start()

    def _probe_loop(self) -> None:
        try:
            while True:
                with self._lock:
                    if self._stopping:
                        return
                self._executor.spin_once(timeout_sec=0.05)
                self._check_readiness()
                rec = self._children.get(RECORDER)
                if rec is not None and rec.state == "ready":
                    lag = self._recorder_lag()
                    with self._cond:
                        self._recorder_lagging = lag
                        self._cond.notify_all()
        except BaseException as exc:  # noqa: BLE001 - surfaced by wait_ready
            with self._cond:
                if not self._stopping:
                    self._probe_error = exc
                self._cond.notify_all()

    def _watch_topic(self, topic: str) -> None:
        """Subscribe (raw, QoS matching the publishers) once the topic's type is visible."""
        import importlib

        from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

        types = dict(self._probe.get_topic_names_and_types()).get(topic)
        infos = self._probe.get_publishers_info_by_topic(topic)
        if not types or not infos:
            return
        pkg, kind, name = types[0].split("/")
        msg_class = getattr(importlib.import_module(f"{pkg}.{kind}"), name)
        transient = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos)
        reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
        qos = QoSProfile(
            history=HistoryPolicy.KEEP_LAST,
            depth=1,
            reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
            durability=DurabilityPolicy.TRANSIENT_LOCAL if transient else DurabilityPolicy.VOLATILE,
        )

        def got(_raw: bytes) -> None:
            self._received[topic] = time.monotonic()

        self._probe_subs[topic] = self._probe.create_subscription(msg_class, topic, got, qos, raw=True)
        self._latched[topic] = transient

    def _expected_recorded(self) -> list[str]:
        topics: set[str] = set()
        for name, child in self._children.items():
            if name != RECORDER:
                topics.update(child.spec.publishes)
        if self.record_topics:
            topics &= set(self.record_topics)
        return sorted(topics - self.record_exclude)

    def _check_readiness(self) -> None:
        with self._lock:
            todo = [c for c in self._children.values() if c.state == "starting"]
        if not todo:
            return
        probe = self._probe
        present = set(probe.get_node_names_and_namespaces())
        for child in todo:
            if child.proc is None or child.proc.poll() is not None:
                continue  # the waiter reports it
            try:
                missing, gids = self._missing(child, present)
            except Exception as exc:  # noqa: BLE001 - e.g. the node left the graph meanwhile
                missing, gids = [f"graph query failed: {exc}"], set()
            self._update(child, missing, gids)

    def _missing(self, child: _Child, present: set) -> tuple[list[str], set]:
        """What ``child`` still lacks to be ready (empty list: ready) and its new publisher GIDs."""
        probe = self._probe
        spec = child.spec
        missing: list[str] = []
        gids: set = set()
        if (spec.name, "/") not in present:
            missing.append(f"node /{spec.name} not in the graph")
        else:
            if spec.services:
                served = {s for s, _t in probe.get_service_names_and_types_by_node(spec.name, "/")}
                missing += [f"service {s} not available" for s in spec.services if s not in served]
            for topic in spec.publishes:
                own = [i for i in probe.get_publishers_info_by_topic(topic)
                       if i.node_name == spec.name and i.node_namespace == "/"]
                new = {tuple(i.endpoint_gid) for i in own} - child.old_gids
                if not new:
                    missing.append(f"no publisher of {topic} from /{spec.name}"
                                   + (" (new instance)" if own else ""))
                gids |= new
            if not child.skip_ready_topics:
                for topic in spec.ready_topics:
                    if topic not in self._probe_subs:
                        self._watch_topic(topic)
                    if self._received.get(topic, -1.0) < child.started_at:
                        missing.append(f"no message on {topic} yet")
            if spec.name == RECORDER:
                for topic in self._expected_recorded():
                    subs = probe.get_subscriptions_info_by_topic(topic)
                    if not any(i.node_name == RECORDER for i in subs):
                        missing.append(f"not subscribed to {topic}")
                        continue
                    if topic not in self._probe_subs:
                        self._watch_topic(topic)
                missing += self._recorder_lag()
        return missing, gids

    def _recorder_lag(self) -> list[str]:
        """Latched messages that exist (the probe received one) but are not in the bag yet."""
        return [
            f"latched message on {topic} not recorded yet"
            for topic in self._expected_recorded()
            if self._latched.get(topic) and topic in self._received and self._recorder_counts.get(topic, 0) == 0
        ]

    def _update(self, child: _Child, missing: list[str], gids: set) -> None:
        spec = child.spec
        with self._cond:
            if child.state != "starting":
                return
            child.missing = missing
            child.gids = gids
            if not missing:
                child.state = "ready"
                child.ready_after = time.monotonic() - child.started_at
                self._event("ready", spec.name, child.pid, f"{child.ready_after:.2f} s")
                if child.restarts:
                    self._say(f"node {spec.name} (pid {child.pid}) ready again after "
                              f"{child.ready_after:.2f} s (restart {child.restarts})")
            self._cond.notify_all()

    def wait_ready(self, timeout: float = 60.0, nodes: Iterable[str] | None = None) -> dict[str, float]:
        """Block until every node (or ``nodes``) is ready; return seconds to ready per node.

        Raises ``LaunchError`` naming, per node, what is missing when ``timeout`` passes, or
        at once when a node that will not be respawned died.
        """
        if not self._started:
            raise LaunchError("start() first")
        names = list(nodes) if nodes is not None else list(self._children)
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                if self._probe_error is not None:
                    raise LaunchError(f"readiness probe failed: {self._probe_error!r}") from self._probe_error
                children = [self._children[n] for n in names]
                dead = [c for c in children if c.state in ("exited", "stopped")]
                if dead:
                    raise LaunchError("node(s) died before becoming ready:\n" + "\n".join(
                        f"  {c.spec.name} (pid {c.pid}) {describe_exit(c.returncode)}; last output:\n"
                        + "\n".join("    " + line for line in list(c.tail)[-15:]) for c in dead))
                if all(c.state == "ready" for c in children) and not (
                    RECORDER in names and self._recorder_lagging
                ):
                    return {c.spec.name: float(c.ready_after or 0.0) for c in children}
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    lines = []
                    for c in children:
                        if c.state != "ready":
                            what = "; ".join(c.missing) or c.state
                            lines.append(f"  {c.spec.name} (pid {c.pid}, {c.state}): {what}")
                        elif c.spec.name == RECORDER and self._recorder_lagging:
                            lines.append(f"  {RECORDER}: " + "; ".join(self._recorder_lagging))
                    raise LaunchError(f"graph not ready after {timeout:g} s:\n" + "\n".join(lines))
                self._cond.wait(min(remaining, 0.5))

    def wait_for_event(self, kind: str, node: str, *, after: int = 0, timeout: float = 30.0) -> Event:
        """The first event of ``kind`` for ``node`` with index >= ``after`` (waits for it)."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for ev in self._events[after:]:
                    if ev.kind == kind and ev.node == node:
                        return ev
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(f"no {kind!r} event for {node} within {timeout:g} s; events: "
                                       f"{[(e.kind, e.node) for e in self._events]}")
                self._cond.wait(min(remaining, 0.5))

    def all_exited(self) -> bool:
        """True when no node runs and none will be respawned."""
        with self._lock:
            return all(c.state in ("exited", "stopped") for c in self._children.values())

    # ------------------------------------------------------------------ status

    def status_table(self) -> str:
        with self._lock:
            rows = [("node", "pid", "state", "ready after", "restarts", "info")]
            for name, c in self._children.items():
                ready = f"{c.ready_after:.2f} s" if c.ready_after is not None else "-"
                info = ""
                if c.state in ("exited", "stopped", "respawning"):
                    info = describe_exit(c.returncode)
                elif c.state == "starting":
                    info = "; ".join(c.missing)
                rows.append((name, str(c.pid or "-"), c.state, ready, str(c.restarts), info))
        widths = [max(len(r[i]) for r in rows) for i in range(5)]
        lines = ["  ".join(r[i].ljust(widths[i]) for i in range(5)) + "  " + r[5] for r in rows]
        return "\n".join(line.rstrip() for line in lines)

    # ------------------------------------------------------------------ stop

    def stop(self) -> dict[str, int | None]:
        """Stop every process (see the module docstring); idempotent. Returns exit codes."""
        if self._stopped:
            return {n: c.returncode for n, c in self._children.items()}
        self._stopped = True
        t0 = time.monotonic()
        with self._cond:
            self._stopping = True
            self._cond.notify_all()
            procs = {n: c.proc for n, c in self._children.items() if c.proc is not None}
        nodes = {n: p for n, p in procs.items() if n != RECORDER}
        recorder = {n: p for n, p in procs.items() if n == RECORDER}

        def alive(group: dict[str, subprocess.Popen]) -> list[int]:
            return [p.pid for p in group.values() if _group_alive(p.pid)]

        def escalate(group: dict[str, subprocess.Popen], start: float, term_at: float, kill_at: float) -> None:
            for pid in alive(group):
                _signal_group(pid, signal.SIGINT)
            sent_term = False
            while alive(group):
                now = time.monotonic() - start
                if now >= kill_at:
                    for pid in alive(group):
                        _signal_group(pid, signal.SIGKILL)
                    break
                if now >= term_at and not sent_term:
                    for pid in alive(group):
                        _signal_group(pid, signal.SIGTERM)
                    sent_term = True
                self._wait_a_moment(group)
            deadline = start + STOP_BUDGET + 1.0
            while alive(group) and time.monotonic() < deadline:  # SIGKILL'd: wait for the reaper
                self._wait_a_moment(group)

        escalate(nodes, t0, NODES_SIGTERM_AT, NODES_SIGKILL_AT)
        if recorder:
            start = time.monotonic()
            kill_at = max(RECORDER_SIGKILL_AT - (start - t0), 0.5)
            escalate(recorder, start, min(RECORDER_SIGTERM_AFTER, kill_at - 0.5), kill_at)
        self.stop_duration = time.monotonic() - t0

        # shut down the probe, the supervisor, the lease
        if self._probe_thread is not None:
            self._probe_thread.join(2.0)
        with contextlib.suppress(Exception):
            if getattr(self, "_executor", None) is not None:
                self._executor.shutdown(timeout_sec=1.0)
        with contextlib.suppress(Exception):
            if getattr(self, "_probe", None) is not None:
                self._probe.destroy_node()
        with contextlib.suppress(Exception):
            if getattr(self, "_ctx", None) is not None:
                self._ctx.try_shutdown()
        if self._supervisor is not None:
            # let the waiters' exit reports through, then end the supervisor
            deadline = time.monotonic() + 2.0
            with self._cond:
                while time.monotonic() < deadline and any(
                    c.proc is not None and c.state not in ("stopped", "exited") and c.proc.poll() is not None
                    for c in self._children.values()
                ):
                    self._cond.wait(0.05)
            self._commands.put(("quit", None))
            self._supervisor.join(2.0)
        with self._lock:
            for c in self._children.values():
                if c.proc is not None:
                    c.returncode = c.proc.poll()
                    if c.state not in ("exited",):
                        c.state = "stopped"
        if self._lease is not None:
            self._lease.release()
            self._lease = None
        if self._log_tmp is not None:
            with contextlib.suppress(Exception):
                self._log_tmp.cleanup()
            self._log_tmp = None
        return {n: c.returncode for n, c in self._children.items()}

    def _wait_a_moment(self, group: dict[str, subprocess.Popen]) -> None:
        """Wait up to 20 ms for a process exit (woken early by the waiter's event)."""
        with self._cond:
            self._cond.wait(0.02)
