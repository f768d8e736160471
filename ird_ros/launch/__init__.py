"""Starting the graph: a launch plan (what runs, ``plan``), its execution (``GraphLauncher``),
the ROS-free process supervisor and its vocabulary, and the rclpy readiness probe, which is
also the managed nodes' lifecycle manager (``lifecycle_driver``: configure, then activate).

Layers, each importing only those below it: ``events`` (states, specs, typed events) and
``process_groups`` (child set-up) <- ``supervisor`` (processes) <- ``lifecycle_driver``,
``liveness`` <- ``graph_view`` (a second reading of the graph) <- ``readiness`` (the ROS graph) and ``plan`` (``ird_ros.graph``'s node table made concrete) <- ``launcher`` (executes a plan).
"""

from __future__ import annotations

from ird_ros.launch.events import (
    UNLIMITED_RETRIES,
    ChildInfo,
    ChildState,
    EventKind,
    OutputChoice,
    OutputMode,
    ProcessEvent,
    ProcessExited,
    ProcessGaveUp,
    ProcessReady,
    ProcessRespawning,
    ProcessSpec,
    ProcessStarted,
    SignalSent,
    describe_exit,
)
from ird_ros.launch.launcher import Event, GraphLauncher
from ird_ros.launch.plan import (
    LAUNCHER_DEFAULTS,
    LAUNCHER_SECTION,
    RECORDER,
    DomainRequest,
    LaunchError,
    LaunchPlan,
    PlannedNode,
    default_params_file,
    plan_launch,
    read_params_sections,
)
from ird_ros.launch.process_groups import (
    child_preexec,
    group_alive,
    set_parent_death_signal,
)
from ird_ros.launch.readiness import GraphProbe, ReadinessMonitor
from ird_ros.launch.supervisor import Supervisor

__all__ = [
    "GraphLauncher",
    "Event",
    "LaunchError",
    "LaunchPlan",
    "PlannedNode",
    "DomainRequest",
    "plan_launch",
    "default_params_file",
    "read_params_sections",
    "RECORDER",
    "LAUNCHER_SECTION",
    "LAUNCHER_DEFAULTS",
    "Supervisor",
    "GraphProbe",
    "ReadinessMonitor",
    "ChildInfo",
    "ChildState",
    "EventKind",
    "OutputChoice",
    "OutputMode",
    "ProcessEvent",
    "ProcessExited",
    "ProcessGaveUp",
    "ProcessReady",
    "ProcessRespawning",
    "ProcessSpec",
    "ProcessStarted",
    "SignalSent",
    "UNLIMITED_RETRIES",
    "describe_exit",
    "child_preexec",
    "group_alive",
    "set_parent_death_signal",
]
