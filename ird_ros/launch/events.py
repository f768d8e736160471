"""The supervisor's vocabulary: child states, output modes, process specs and typed events.

Names follow ``ros2 launch`` where it has one (``respawn``, ``respawn_delay``,
``ProcessStarted``, ``ProcessExited``). Every ``ProcessEvent`` has ``kind`` (an
``EventKind``, whose values are the plain strings callers may compare with), ``name``
(also ``node``), ``pid``, ``index``, ``time`` and a human-readable ``detail``.
"""

from __future__ import annotations

import enum
import signal
from dataclasses import dataclass

__all__ = [
    "ChildState",
    "EventKind",
    "OutputMode",
    "ProcessSpec",
    "ChildInfo",
    "ProcessEvent",
    "ProcessStarted",
    "ProcessReady",
    "ProcessExited",
    "ProcessRespawning",
    "SignalSent",
    "describe_exit",
]


class ChildState(enum.StrEnum):
    PENDING = "pending"
    STARTING = "starting"
    READY = "ready"
    EXITED = "exited"
    RESPAWNING = "respawning"
    STOPPED = "stopped"


class EventKind(enum.StrEnum):
    STARTED = "started"
    READY = "ready"
    DIED = "died"
    RESPAWNING = "respawning"
    STOPPED = "stopped"
    SIGNALLED = "signalled"


class OutputMode(enum.StrEnum):
    PREFIX = "prefix"  # echoed as ``[name] line`` (and kept)
    QUIET = "quiet"  # kept only: ``output(name)``, error messages
    FILES = "files"  # written to ``<log_dir>/<name>.log``


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
class ProcessSpec:
    """One process: ``argv`` to run; restarted ``respawn_delay`` s after it dies if ``respawn``."""

    name: str
    argv: tuple[str, ...]
    respawn: bool = False
    respawn_delay: float = 1.0

    def __post_init__(self) -> None:
        if not self.name:
            raise ValueError("name must not be empty")
        if not self.argv:
            raise ValueError(f"argv of {self.name} must not be empty")
        if not self.respawn_delay >= 0.0:
            raise ValueError(f"respawn_delay must be >= 0, got {self.respawn_delay}")


@dataclass(frozen=True)
class ChildInfo:
    """A snapshot of one child. ``started_at`` is ``time.monotonic()`` of the last start."""

    name: str
    pid: int | None
    state: ChildState
    started_at: float
    ready_after: float | None
    restarts: int
    returncode: int | None


@dataclass(frozen=True)
class ProcessEvent:
    """Something that happened to a child. ``time``: seconds since the supervisor was made."""

    index: int
    time: float
    name: str
    pid: int | None

    @property
    def node(self) -> str:
        """The child's name (the graph launcher's children are ROS nodes)."""
        return self.name

    @property
    def kind(self) -> EventKind:
        raise NotImplementedError

    @property
    def detail(self) -> str:
        return ""


@dataclass(frozen=True)
class ProcessStarted(ProcessEvent):
    restart: int = 0  # 0 for the first start

    @property
    def kind(self) -> EventKind:
        return EventKind.STARTED


@dataclass(frozen=True)
class ProcessReady(ProcessEvent):
    ready_after: float = 0.0  # seconds from start to ready
    restart: int = 0

    @property
    def kind(self) -> EventKind:
        return EventKind.READY

    @property
    def detail(self) -> str:
        return f"{self.ready_after:.2f} s"


@dataclass(frozen=True)
class ProcessExited(ProcessEvent):
    """The process ended with ``returncode`` (negative: killed by that signal).

    ``requested``: it ended after ``stop_processes`` (kind ``stopped``), else it died.
    """

    returncode: int = 0
    requested: bool = False

    @property
    def kind(self) -> EventKind:
        return EventKind.STOPPED if self.requested else EventKind.DIED

    @property
    def detail(self) -> str:
        return describe_exit(self.returncode)


@dataclass(frozen=True)
class ProcessRespawning(ProcessEvent):
    restart: int = 1  # the restart that is coming (1 for the first)
    delay: float = 0.0

    @property
    def kind(self) -> EventKind:
        return EventKind.RESPAWNING

    @property
    def detail(self) -> str:
        return f"restart {self.restart}"


@dataclass(frozen=True)
class SignalSent(ProcessEvent):
    signal: int = 0

    @property
    def kind(self) -> EventKind:
        return EventKind.SIGNALLED

    @property
    def detail(self) -> str:
        return signal.Signals(self.signal).name
