"""The supervisor's vocabulary: child states, output modes, process specs and typed events.

Names follow ``ros2 launch`` where it has one (``respawn``, ``respawn_delay``,
``ProcessStarted``, ``ProcessExited``). Every ``ProcessEvent`` has ``kind`` (an
``EventKind``, whose values are the plain strings callers may compare with), ``name``
(also ``node``), ``pid``, ``index``, ``time`` and a human-readable ``detail``.

A child that dies is followed by exactly one of: ``ProcessRespawning`` (it will be started
again) or, when its spec's ``respawn_max_retries`` restarts are used up, ``ProcessGaveUp``;
a child without ``respawn`` gets neither.

A ready child that stops responding (``ird_ros.launch.liveness``: its process is stopped, or it
does not answer a parameter request in time) gets ``ProcessStalled``; the same process
responding again gets ``ProcessRecovered``. The two alternate, starting with ``ProcessStalled``.
"""

from __future__ import annotations

import enum
import signal
from dataclasses import dataclass
from typing import Literal

__all__ = [
    "ChildState",
    "EventKind",
    "OutputMode",
    "OutputChoice",
    "parse_output_mode",
    "ProcessSpec",
    "UNLIMITED_RETRIES",
    "check_max_retries",
    "ChildInfo",
    "ProcessEvent",
    "ProcessStarted",
    "ProcessReady",
    "ProcessExited",
    "ProcessRespawning",
    "ProcessGaveUp",
    "SignalSent",
    "ProcessStalled",
    "ProcessRecovered",
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
    GAVE_UP = "gave_up"
    STOPPED = "stopped"
    SIGNALLED = "signalled"
    STALLED = "stalled"
    RECOVERED = "recovered"


class OutputMode(enum.StrEnum):
    PREFIX = "prefix"  # echoed as ``[name] line`` (and kept)
    QUIET = "quiet"  # kept only: ``output(name)``, error messages
    FILES = "files"  # written to ``<log_dir>/<name>.log``


OutputChoice = OutputMode | Literal["prefix", "quiet", "files"]
"""An output mode, or its value."""


def parse_output_mode(value: OutputChoice) -> OutputMode:
    """``value`` as an ``OutputMode``; ``ValueError`` naming the three choices otherwise."""
    try:
        return OutputMode(value)
    except ValueError:
        raise ValueError(f"output must be prefix, quiet or files, got {value!r}") from None


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


UNLIMITED_RETRIES = -1
"""``respawn_max_retries`` value for no limit (as in ``ros2 launch``)."""


@dataclass(frozen=True)
class ProcessSpec:
    """One process: ``argv`` to run; restarted ``respawn_delay`` s after it dies if ``respawn``,
    at most ``respawn_max_retries`` times in all (``UNLIMITED_RETRIES``: no limit); after that
    it stays ``exited`` and a ``ProcessGaveUp`` event says so."""

    name: str
    argv: tuple[str, ...]
    respawn: bool = False
    respawn_delay: float = 1.0
    respawn_max_retries: int = UNLIMITED_RETRIES

    def __post_init__(self) -> None:
        if not self.name:
            raise ValueError("name must not be empty")
        if not self.argv:
            raise ValueError(f"argv of {self.name} must not be empty")
        if not self.respawn_delay >= 0.0:
            raise ValueError(f"respawn_delay must be >= 0, got {self.respawn_delay}")
        check_max_retries(self.respawn_max_retries)

    def may_restart(self, restarts: int) -> bool:
        """Whether a child that has been restarted ``restarts`` times is started again."""
        limit = self.respawn_max_retries
        return self.respawn and (limit == UNLIMITED_RETRIES or restarts < limit)


def check_max_retries(value: object, field: str = "respawn_max_retries") -> int:
    """``value`` as a retry limit (an int >= -1, -1 for no limit); else ``ValueError`` naming ``field``."""
    if isinstance(value, bool) or not isinstance(value, int) or value < UNLIMITED_RETRIES:
        raise ValueError(f"{field} must be an integer >= 0, or -1 for no limit, got {value!r}")
    return value


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

    ``requested``: it ended after ``stop_processes`` (kind ``stopped``), else it died;
    ``will_respawn``: it died and will be started again (a ``ProcessRespawning`` follows).
    """

    returncode: int = 0
    requested: bool = False
    will_respawn: bool = False

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
class ProcessGaveUp(ProcessEvent):
    """A child that died is not started again: its ``restarts`` used up ``respawn_max_retries``."""

    restarts: int = 0

    @property
    def kind(self) -> EventKind:
        return EventKind.GAVE_UP

    @property
    def detail(self) -> str:
        return f"gave up after {self.restarts} restart(s)"


@dataclass(frozen=True)
class SignalSent(ProcessEvent):
    signal: int = 0

    @property
    def kind(self) -> EventKind:
        return EventKind.SIGNALLED

    @property
    def detail(self) -> str:
        return signal.Signals(self.signal).name


@dataclass(frozen=True)
class ProcessStalled(ProcessEvent):
    """A ready child stopped responding: ``reason`` says how it was seen."""

    reason: str = ""

    @property
    def kind(self) -> EventKind:
        return EventKind.STALLED

    @property
    def detail(self) -> str:
        return self.reason


@dataclass(frozen=True)
class ProcessRecovered(ProcessEvent):
    """A stalled child responds again, ``stalled_for`` seconds after it was seen stalled."""

    stalled_for: float = 0.0

    @property
    def kind(self) -> EventKind:
        return EventKind.RECOVERED

    @property
    def detail(self) -> str:
        return f"responding again after {self.stalled_for:.1f} s"
