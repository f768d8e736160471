"""The launch plan: everything the launcher will run, decided before any process starts.

``plan_launch(...)`` turns the launcher's arguments, the node table (``ird_ros.graph.NODES``,
docs/spec.md section 6) and the params file into a ``LaunchPlan``. It is pure: no process, no
ROS import, no domain lease; it only reads the params file and looks whether the record folder
exists. ``ird_ros.launch.launcher.GraphLauncher`` executes a plan, as ``ros2 launch``'s
``ExecuteLocal`` executes a process description.

What a plan fixes:

- Start order: the given node list (default: the table's nodes marked ``default``), reordered
  only so that every node starts after the launched nodes in its ``after``; the recorder, when
  recording, comes last (and is stopped last, so its bag holds everything).
- Command line of a node: ``<python> -m <module>`` (``<python> <script>`` if the spec has a
  script), then ``--ros-args --params-file <params>`` (without the file when the default params
  file does not exist), then ``-p autostart:=false`` for a managed node (``is_managed``: the
  launcher drives its lifecycle), then the spec's ``ros_args``. The recorder gets ``-p
  output_dir:=<record_dir>`` and, when topics are chosen, ``-p topics:=[a,b]``.
- Params file: ``params`` if given (it must exist), else ``msgs_config/params/graph.yaml``.
- Respawn: the union of ``respawn`` and the params file's ``launcher.respawn``; each must be a
  launched node. The recorder is never respawned (its bag folder exists after the first start;
  a note says so). ``respawn_delay`` and ``respawn_max_retries``: the argument, else the params
  file, else ``LAUNCHER_DEFAULTS``.
- Recording: ``record_topics``, else the params file's ``recorder.topics`` (empty: every topic).
  The recorder must record what the launched nodes publish, minus ``recorder.exclude_topics``
  (default: /rosout, /parameter_events), and only the chosen topics if there are any.
- The ``ready_topics`` of a node that needs (``after``) a node that is not launched are not
  waited for (they would never come; a note says so).
- Environment of every child (``LaunchPlan.environment``, once the domain is known): the base
  environment (default: this process's) with ``ROS_DOMAIN_ID``, ``ROS_LOG_DIR``, the DDS
  transport of ``ird_ros.graph.domains.dds_env``, ``PYTHONUNBUFFERED=1`` and this checkout
  first on ``PYTHONPATH`` (children import this checkout's ``ird_ros`` even if not installed).
- Domain (``DomainRequest``): a leased one (``private``), a given one, or the inherited
  ``ROS_DOMAIN_ID`` (default 0); every ID is in 0..101.

Params file ``launcher`` section (the nodes' layout, so rcl accepts the file)::

    launcher:
      ros__parameters:
        respawn: [rob, world]     # nodes to restart when they die (default: none)
        respawn_delay: 1.0        # seconds before a restart
        respawn_max_retries: 5    # restarts of one node before the launcher gives up (-1: no limit)
"""

from __future__ import annotations

import os
import sys
from dataclasses import dataclass, field, replace
from pathlib import Path
from types import MappingProxyType
from typing import Any, Iterable, Mapping, Sequence

from ird_core.output_paths import folder_problem
from ird_ros.graph import names
from ird_ros.graph.domains import check_domain_id, dds_network, ros_env
from ird_ros.graph.nodes import NODES, RECORDER_SPEC, NodeSpec, is_managed
from ird_ros.launch.events import (
    OutputChoice,
    OutputMode,
    ProcessSpec,
    check_max_retries,
    parse_output_mode,
)
from ird_ros.resources import graph_params

__all__ = [
    "LaunchError",
    "LaunchPlan",
    "PlannedNode",
    "DomainRequest",
    "plan_launch",
    "with_viz_port",
    "default_params_file",
    "read_params_sections",
    "REPO_ROOT",
    "RECORDER",
    "LAUNCHER_SECTION",
    "LAUNCHER_DEFAULTS",
]

REPO_ROOT = Path(__file__).resolve().parents[2]
"""The folder holding the ``ird_ros`` package (the checkout, or site-packages when installed):
put on the children's PYTHONPATH so they import the same copy."""
RECORDER = names.NODE_RECORDER
LAUNCHER_SECTION = "launcher"
LAUNCHER_DEFAULTS: Mapping[str, Any] = MappingProxyType(
    {"respawn": (), "respawn_delay": 1.0, "respawn_max_retries": 5})
"""The launcher's settings when neither the arguments nor the params file give them (the
params file repeats them; ``tests/test_graph_params.py`` keeps the two in step)."""
DEFAULT_RECORD_EXCLUDE = ("/rosout", "/parameter_events")


class LaunchError(RuntimeError):
    """The graph could not be started or did not become ready (the message says why)."""


def default_params_file() -> Path:
    """The graph's params file (``ird_ros.graph.PARAMS_FILE``), package data of ``ird_ros``
    (``ird_ros.resources``): found from any working directory, installed or in a checkout."""
    return graph_params()


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


@dataclass(frozen=True)
class DomainRequest:
    """Which ROS domain the graph runs in: ``private`` (lease a free one), ``domain_id``, or,
    with neither, the inherited ``ROS_DOMAIN_ID`` (default 0)."""

    private: bool = False
    domain_id: int | None = None

    def __post_init__(self) -> None:
        if self.private and self.domain_id is not None:
            raise ValueError("give either domain_id or private_domain, not both")
        if self.domain_id is not None:
            object.__setattr__(self, "domain_id", check_domain_id(self.domain_id, "domain_id"))

    def fixed_id(self, base_env: Mapping[str, str]) -> int:
        """The ID of a domain that is not leased: ``domain_id``, else ``ROS_DOMAIN_ID`` of ``base_env``."""
        if self.domain_id is not None:
            return self.domain_id
        try:
            return check_domain_id(base_env.get("ROS_DOMAIN_ID") or 0, "ROS_DOMAIN_ID")
        except ValueError as exc:
            raise LaunchError(str(exc)) from None


@dataclass(frozen=True)
class PlannedNode:
    """One process of the plan: its spec, full command line, and what the launcher does about it."""

    spec: NodeSpec
    argv: tuple[str, ...]
    respawn: bool = False
    wait_ready_topics: bool = True

    @property
    def name(self) -> str:
        return self.spec.name


@dataclass(frozen=True)
class LaunchPlan:
    """What ``GraphLauncher`` runs (see the module docstring). ``nodes`` are in start order."""

    nodes: tuple[PlannedNode, ...]
    params_file: Path | None
    respawn_delay: float
    respawn_max_retries: int
    record_dir: Path | None
    record_topics: tuple[str, ...]
    recorded_topics: tuple[str, ...]
    domain: DomainRequest
    log_dir: Path | None
    output: OutputMode
    cwd: Path
    base_env: Mapping[str, str] = field(default_factory=dict, repr=False)
    notes: tuple[str, ...] = ()

    @property
    def names(self) -> list[str]:
        return [n.name for n in self.nodes]

    @property
    def specs(self) -> dict[str, NodeSpec]:
        return {n.name: n.spec for n in self.nodes}

    @property
    def has_recorder(self) -> bool:
        return any(n.name == RECORDER for n in self.nodes)

    @property
    def respawned(self) -> frozenset[str]:
        return frozenset(n.name for n in self.nodes if n.respawn)

    @property
    def managed(self) -> frozenset[str]:
        """Nodes the launcher drives through their lifecycle transitions (``is_managed``)."""
        return frozenset(n.name for n in self.nodes if is_managed(n.spec))

    @property
    def skipped_ready_topics(self) -> frozenset[str]:
        return frozenset(n.name for n in self.nodes if not n.wait_ready_topics)

    def process_specs(self) -> list[ProcessSpec]:
        """The supervisor's processes, in start order."""
        return [ProcessSpec(n.name, n.argv, respawn=n.respawn, respawn_delay=self.respawn_delay,
                            respawn_max_retries=self.respawn_max_retries) for n in self.nodes]

    def environment(self, domain_id: int, log_dir: Path) -> dict[str, str]:
        """The environment of every child in domain ``domain_id`` with ROS logs in ``log_dir``."""
        env = ros_env(domain_id, log_dir, self.base_env)
        env["PYTHONUNBUFFERED"] = "1"
        inherited = [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
        env["PYTHONPATH"] = os.pathsep.join([str(REPO_ROOT), *inherited])
        return env


def plan_launch(
    *,
    nodes: Sequence[str] | None = None,
    params: str | os.PathLike[str] | None = None,
    record_dir: str | os.PathLike[str] | None = None,
    record_topics: Sequence[str] | None = None,
    domain_id: int | None = None,
    private_domain: bool = False,
    respawn: Iterable[str] = (),
    respawn_delay: float | None = None,
    respawn_max_retries: int | None = None,
    specs: Sequence[NodeSpec] | None = None,
    output: OutputChoice = OutputMode.PREFIX,
    log_dir: str | os.PathLike[str] | None = None,
    python: str | None = None,
    cwd: str | os.PathLike[str] | None = None,
    env: Mapping[str, str] | None = None,
) -> LaunchPlan:
    """The plan for these arguments (``GraphLauncher``'s; see its docstring and this module's).

    Raises ``ValueError`` for a bad argument value and ``LaunchError`` for arguments that do
    not fit the node table, the params file or the file system.
    """
    output_mode = parse_output_mode(output)
    domain = DomainRequest(private_domain, domain_id)
    params_file = _params_file(params)
    sections = read_params_sections(params_file)
    table = {s.name: s for s in (specs if specs is not None else NODES)}
    order = _start_order(_requested_nodes(nodes, table), table)
    settings = {**LAUNCHER_DEFAULTS, **sections.get(LAUNCHER_SECTION, {})}
    respawned, notes = _respawned(set(respawn) | set(settings["respawn"] or ()), order)
    delay, max_retries = _respawn_limits(respawn_delay, respawn_max_retries, settings)
    record_path = _record_dir(record_dir)
    recorder_params = sections.get(RECORDER, {})
    topics = tuple(record_topics if record_topics is not None else [t for t in recorder_params.get("topics") or [] if t])
    base_env = dict(os.environ if env is None else env)
    dds_network(base_env)  # a bad IRD_DDS_NETWORK fails here, naming the variable

    python = python or sys.executable
    planned = [PlannedNode(table[n], _argv(table[n], python, params_file), respawn=n in respawned,
                           wait_ready_topics=not _needs_missing_node(table[n], order)) for n in order]
    notes += [_skip_note(table[p.name], order) for p in planned if not p.wait_ready_topics]
    recorded: tuple[str, ...] = ()
    if record_path is not None:
        recorder = _recorder_spec(table.get(RECORDER, RECORDER_SPEC), record_path, topics)
        planned.append(PlannedNode(recorder, _argv(recorder, python, params_file)))
        exclude = recorder_params.get("exclude_topics") or DEFAULT_RECORD_EXCLUDE
        recorded = _recorded_topics([table[n] for n in order], topics, exclude)
    return LaunchPlan(
        nodes=tuple(planned), params_file=params_file, respawn_delay=delay, respawn_max_retries=max_retries,
        record_dir=record_path, record_topics=topics, recorded_topics=recorded, domain=domain,
        log_dir=_log_dir(log_dir), output=output_mode,
        cwd=Path(cwd) if cwd is not None else Path.cwd(), base_env=MappingProxyType(base_env), notes=tuple(notes))


def with_viz_port(specs: Sequence[NodeSpec] | None, port: int) -> list[NodeSpec]:
    """Node specs (default: the graph's) whose viz node listens on ``port`` (``-p port:=N`` after
    the params file; 0 = any free port, which ``/viz/status`` names). ``ValueError`` naming
    ``--viz-port`` for a port outside 0..65535."""
    if not 0 <= int(port) <= 65535:
        raise ValueError(f"--viz-port: must be in 0..65535 (0 = any free port), got {port}")
    arg = ("-p", f"port:={int(port)}")
    return [replace(s, ros_args=(*s.ros_args, *arg)) if s.name == names.NODE_VIZ else s
            for s in (specs if specs is not None else NODES)]


def _params_file(params: str | os.PathLike[str] | None) -> Path | None:
    """The given file (which must exist), else the default one if it exists, else None."""
    if params is None:
        default = default_params_file()
        return default if default.is_file() else None
    path = Path(params)
    if not path.is_file():
        raise LaunchError(f"params file {path} not found")
    return path


def _requested_nodes(nodes: Sequence[str] | None, table: Mapping[str, NodeSpec]) -> list[str]:
    requested = list(nodes) if nodes is not None else [s.name for s in table.values() if s.default]
    unknown = [n for n in requested if n not in table]
    if unknown:
        raise LaunchError(f"unknown node(s) {unknown}; known: {sorted(table)}")
    if len(set(requested)) != len(requested):
        raise LaunchError(f"node list has duplicates: {requested}")
    return requested


def _start_order(requested: list[str], table: Mapping[str, NodeSpec]) -> list[str]:
    """``requested`` reordered (stably) so that each node follows the launched nodes it is ``after``."""
    launched = set(requested)
    order: list[str] = []
    waiting = list(requested)
    while waiting:
        first = next((n for n in waiting if all(d in order or d not in launched for d in table[n].after)), None)
        if first is None:
            raise LaunchError(f"nodes wait for each other ('after'), none can start first: {waiting}")
        order.append(first)
        waiting.remove(first)
    return order


def _respawned(requested: set[str], launched: list[str]) -> tuple[frozenset[str], list[str]]:
    """The nodes to respawn, and the notes to print about the request."""
    unknown = sorted(requested - set(launched) - {RECORDER})
    if unknown:
        raise LaunchError(f"respawn names node(s) not launched: {unknown}")
    notes = ["the recorder is never respawned (its bag folder exists after the first start)"] \
        if RECORDER in requested else []
    return frozenset(requested - {RECORDER}), notes


def _record_dir(record_dir: str | os.PathLike[str] | None) -> Path | None:
    if record_dir is None:
        return None
    path = Path(record_dir).resolve()
    if path.exists():
        raise LaunchError(f"record dir {path} already exists: choose a new folder")
    problem = folder_problem(path)
    if problem:
        raise LaunchError(f"record dir {path}: {problem}")
    return path


def _log_dir(log_dir: str | os.PathLike[str] | None) -> Path | None:
    if log_dir is None:
        return None
    path = Path(log_dir)
    problem = folder_problem(path)
    if problem:
        raise LaunchError(f"log dir {path}: {problem}")
    return path


def _respawn_limits(delay: float | None, max_retries: int | None, settings: Mapping[str, Any]) -> tuple[float, int]:
    """``respawn_delay`` and ``respawn_max_retries``: the arguments, else the params file's settings."""
    delay = float(delay if delay is not None else settings["respawn_delay"])
    if not delay >= 0.0:
        raise ValueError(f"respawn_delay must be >= 0, got {delay}")
    return delay, check_max_retries(max_retries if max_retries is not None else settings["respawn_max_retries"])


def _argv(spec: NodeSpec, python: str, params_file: Path | None) -> tuple[str, ...]:
    """The full command line of ``spec`` (see the module docstring)."""
    head = (python, spec.script) if spec.script else (python, "-m", spec.module)
    params_args = ("--params-file", str(params_file)) if params_file is not None else ()
    managed = ("-p", "autostart:=false") if is_managed(spec) else ()
    return (*head, "--ros-args", *params_args, *managed, *spec.ros_args)


def _needs_missing_node(spec: NodeSpec, launched: list[str]) -> bool:
    """A node with ``ready_topics`` whose inputs come from a node that is not launched."""
    return bool(spec.ready_topics) and any(d not in launched for d in spec.after)


def _skip_note(spec: NodeSpec, launched: list[str]) -> str:
    missing = [d for d in spec.after if d not in launched]
    return (f"{spec.name} needs {', '.join(missing)} (not launched): "
            f"not waiting for {', '.join(spec.ready_topics)}")


def _recorder_spec(spec: NodeSpec, record_dir: Path, topics: Sequence[str]) -> NodeSpec:
    args = ["-p", f"output_dir:={record_dir}"]
    if topics:
        args += ["-p", "topics:=[" + ",".join(topics) + "]"]
    return replace(spec, ros_args=(*spec.ros_args, *args))


def _recorded_topics(launched: Sequence[NodeSpec], chosen: Sequence[str], exclude: Iterable[str]) -> tuple[str, ...]:
    """Topics the recorder must record: what the launched nodes publish, filtered."""
    topics = {t for spec in launched for t in spec.publishes}
    if chosen:
        topics &= set(chosen)
    return tuple(sorted(topics - set(exclude)))
