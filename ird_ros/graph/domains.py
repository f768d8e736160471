"""ROS domains for the graph, its clients and tests: leasing an ID, the environment, a context.

``lease_domain`` takes an exclusive ``flock`` on ``/tmp/ird_ros_domains/domain_<N>.lock`` for
one N in 0..101 (IDs above 101 put DDS ports into Linux's ephemeral port range). Concurrent
test runs, demos and CI on one machine that all lease through this module (or
``scripts/lib/ros_env.sh``, which uses the same lock files) never share a domain. The search
starts at ``IRD_TEST_DOMAIN_BASE`` if set, otherwise at a value derived from the process id, and
each later search of the same process starts after the ID it leased last: an ID comes back to a
process only after the others were tried, so whatever outlived a lease in its domain (a node an
earlier test left in the graph, DDS's memory of a killed participant until its lease expires)
does not meet the next lease's graph. The lock is released when the lease is released or the
process exits.

``ros_env`` is the environment of a process in a private, localhost-only domain and
``ros_context`` an rclpy context in a domain (rclpy is imported only there, so this module
is free to import without ROS).

DDS transport (``dds_env``; ``scripts/lib/ros_env.sh``'s ``ird_dds_env`` applies the same rule
and a test holds the two equal). By default every process of the stack talks over loopback
only: ``FASTRTPS_DEFAULT_PROFILES_FILE`` names ``msgs_config/dds/fastdds_localhost.xml``
(UDPv4 restricted to 127.0.0.1, no shared memory, discovery by unicast to 127.0.0.1) and
``ROS_AUTOMATIC_DISCOVERY_RANGE=SYSTEM_DEFAULT`` leaves discovery to that profile. Not
``LOCALHOST``: with it rmw_fastrtps (Jazzy) appends a UDPv4 transport of its own, which binds
0.0.0.0 and the machine's external address whatever the profile says.

- ``IRD_DDS_NETWORK=1`` (or ``scripts/launch_graph.py --dds-network``): multi-machine use; the
  profile is left out and the range is ``SUBNET`` (ROS's default: multicast on every interface).
- A profile of the user's own (``FASTRTPS_DEFAULT_PROFILES_FILE`` or
  ``FASTDDS_DEFAULT_PROFILES_FILE`` naming another file, or ``SKIP_DEFAULT_XML_FILE=1``) is kept
  as it is, with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``; the transport is then theirs.

Fast DDS reads the profile file once per process, at its first participant: set these
variables before a process's first ``rclpy.init`` (child processes get them through
``ros_env``; ``ros_context`` sets them around its own ``rclpy.init``).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator, Mapping, MutableMapping

from ird_ros.resources import dds_profile

__all__ = [
    "DDS_NETWORK_VAR",
    "DDS_PROFILE",
    "DDS_PROFILE_VAR",
    "DOMAIN_ID_MAX",
    "DOMAIN_LOCK_DIR",
    "DomainLease",
    "check_domain_id",
    "dds_env",
    "dds_network",
    "dds_process_env",
    "domain_banner",
    "lease_domain",
    "ros_env",
    "ros_context",
]

DOMAIN_ID_MAX = 101
"""Largest domain ID handed out (IDs above 101 put DDS ports into the ephemeral range)."""

DOMAIN_LOCK_DIR = Path(os.environ.get("IRD_DOMAIN_LOCK_DIR", "/tmp/ird_ros_domains"))
"""Where the per-domain lock files live (shared with scripts/lib/ros_env.sh)."""

DDS_PROFILE = dds_profile()
"""The loopback-only Fast DDS profile (see the module docstring): package data of ``ird_ros``
(``ird_ros.resources``), so an installed copy finds it from any working directory."""

DDS_PROFILE_VAR = "FASTRTPS_DEFAULT_PROFILES_FILE"
"""The variable Fast DDS 2.14 reads its default profile file from (FASTDDS_... is 3.x's)."""

DDS_NETWORK_VAR = "IRD_DDS_NETWORK"
"""Set to 1 for multi-machine use: no loopback profile, discovery range SUBNET."""

_DDS_VARS = ("ROS_AUTOMATIC_DISCOVERY_RANGE", DDS_PROFILE_VAR, "ROS_LOCALHOST_ONLY")
_TRUE = ("1", "true", "yes", "on")
_FALSE = ("", "0", "false", "no", "off")


def check_domain_id(domain_id: Any, field_name: str = "domain_id") -> int:
    """``domain_id`` as an int in 0..DOMAIN_ID_MAX; else ``ValueError`` naming ``field_name``."""
    try:
        value = int(domain_id)
    except (TypeError, ValueError):
        raise ValueError(f"{field_name} must be an integer in 0..{DOMAIN_ID_MAX}, got {domain_id!r}") from None
    if not 0 <= value <= DOMAIN_ID_MAX:
        raise ValueError(f"{field_name} must be in 0..{DOMAIN_ID_MAX} (higher IDs put DDS ports into "
                         f"the ephemeral port range), got {value}")
    return value


@dataclass
class DomainLease:
    """An exclusively held ROS domain ID plus a private ROS_LOG_DIR.

    Release with ``release()`` or use as a context manager; the lock also goes away when
    the process exits.
    """

    domain_id: int
    log_dir: Path
    _fd: int | None = field(default=None, repr=False)
    _tmp: tempfile.TemporaryDirectory | None = field(default=None, repr=False)

    def env(self, base: Mapping[str, str] | None = None) -> dict[str, str]:
        """An environment (a copy of ``base``, default ``os.environ``) for a process in this domain."""
        return ros_env(self.domain_id, self.log_dir, base)

    def release(self) -> None:
        if self._fd is not None:
            os.close(self._fd)  # closing the descriptor drops the flock
            self._fd = None
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None

    def __enter__(self) -> "DomainLease":
        return self

    def __exit__(self, *exc: object) -> None:
        self.release()


def _try_lock(domain_id: int) -> int | None:
    DOMAIN_LOCK_DIR.mkdir(parents=True, exist_ok=True)
    with contextlib.suppress(OSError):
        os.chmod(DOMAIN_LOCK_DIR, 0o1777)  # shared by every user of the machine
    path = DOMAIN_LOCK_DIR / f"domain_{domain_id}.lock"
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    os.ftruncate(fd, 0)
    os.write(fd, f"{os.getpid()}\n".encode())
    return fd


_next_start: int | None = None
"""Where this process's next default search starts: after the ID it leased last."""


def lease_domain(*, start: int | None = None, log_dir: str | os.PathLike[str] | None = None) -> DomainLease:
    """Lease a free ROS domain ID in 0..101 (see the module docstring).

    ``start``: first candidate (default: after the ID this process leased last; the first time
    ``IRD_TEST_DOMAIN_BASE`` or derived from the pid);
    candidates wrap around 0..101, skipping the current ``ROS_DOMAIN_ID``. ``log_dir``: ROS_LOG_DIR for processes in the domain
    (default: a fresh temporary directory removed on release).
    Raises ``RuntimeError`` when all 102 IDs are held.
    """
    global _next_start
    n = DOMAIN_ID_MAX + 1
    default = start is None
    if start is None:
        base = os.environ.get("IRD_TEST_DOMAIN_BASE")
        start = _next_start if _next_start is not None else int(base) if base else (os.getpid() * 7919) % n
    current = os.environ.get("ROS_DOMAIN_ID", "")
    for i in range(n):
        candidate = (start + i) % n
        if current == str(candidate):
            continue  # this process's own domain (maybe set by hand, without a lock)
        fd = _try_lock(candidate)
        if fd is None:
            continue
        tmp = None
        if log_dir is None:
            tmp = tempfile.TemporaryDirectory(prefix=f"ird_ros_log_d{candidate}_")
            log_dir = tmp.name
        Path(log_dir).mkdir(parents=True, exist_ok=True)
        if default:
            _next_start = (candidate + 1) % n
        return DomainLease(candidate, Path(log_dir), fd, tmp)
    raise RuntimeError(f"all ROS domain IDs 0..{DOMAIN_ID_MAX} are leased (locks in {DOMAIN_LOCK_DIR})")


def domain_banner(domain_id: int, role: str = "this graph") -> str:
    """The two lines every entry point prints once: the one ROS domain it uses (``role``: whose it
    is) and the line a second shell runs to attach to it (``scripts/lib/ros_env.sh`` keeps it)."""
    return (f"ROS_DOMAIN_ID={int(domain_id)} ({role})\n"
            f"attach a second shell: export ROS_DOMAIN_ID={int(domain_id)}; "
            "source scripts/lib/ros_env.sh && ird_ros_env")


def dds_network(env: Mapping[str, str]) -> bool:
    """Whether ``env`` asks for multi-machine DDS (``IRD_DDS_NETWORK``); ``ValueError`` if unreadable."""
    raw = env.get(DDS_NETWORK_VAR, "").lower()
    if raw in _TRUE:
        return True
    if raw in _FALSE:
        return False
    raise ValueError(f"{DDS_NETWORK_VAR} must be one of 1, true, yes, on (multi-machine) or 0, false, no, off, "
                     f"empty (loopback only), got {env[DDS_NETWORK_VAR]!r}")


def dds_env(env: MutableMapping[str, str]) -> MutableMapping[str, str]:
    """Set ``env``'s DDS transport and discovery variables in place (rule: module docstring); returns it."""
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy; the range replaces it
    if env.get(DDS_PROFILE_VAR) == str(DDS_PROFILE):
        del env[DDS_PROFILE_VAR]  # ours, inherited: decided afresh below
    if dds_network(env):
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
    elif (env.get(DDS_PROFILE_VAR) or env.get("FASTDDS_DEFAULT_PROFILES_FILE")
          or env.get("SKIP_DEFAULT_XML_FILE") == "1"):
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # the user's own Fast DDS configuration
    else:
        env[DDS_PROFILE_VAR] = str(DDS_PROFILE)
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SYSTEM_DEFAULT"  # discovery as the profile says
    return env


@contextlib.contextmanager
def dds_process_env(env: Mapping[str, str] | None = None) -> Iterator[None]:
    """Within the block, this process's DDS variables are those of ``env`` (default:
    ``dds_env`` of ``os.environ``): wrap an ``rclpy.init`` with it. The profile only takes
    effect if this is the process's first participant (Fast DDS loads it once)."""
    target = dds_env(dict(os.environ)) if env is None else env
    saved = {key: os.environ.get(key) for key in _DDS_VARS}
    _set_vars(os.environ, {key: target.get(key) for key in _DDS_VARS})
    try:
        yield
    finally:
        _set_vars(os.environ, saved)


def _set_vars(env: MutableMapping[str, str], values: Mapping[str, str | None]) -> None:
    for key, value in values.items():
        if value is None:
            env.pop(key, None)
        else:
            env[key] = value


def ros_env(
    domain_id: int, log_dir: str | os.PathLike[str], base: Mapping[str, str] | None = None
) -> dict[str, str]:
    """A copy of ``base`` (default ``os.environ``) set up for a private domain: loopback-only DDS
    unless ``IRD_DDS_NETWORK=1`` (``dds_env``), ``ROS_DOMAIN_ID`` and ``ROS_LOG_DIR``."""
    env = dds_env(dict(os.environ if base is None else base))
    env["ROS_DOMAIN_ID"] = str(int(domain_id))
    env["ROS_LOG_DIR"] = str(log_dir)
    env.setdefault("PYTHONUNBUFFERED", "1")  # helpers' output shows up as it happens
    return env


@contextlib.contextmanager
def ros_context(domain: DomainLease | int) -> Iterator[Any]:
    """An initialised ``rclpy.context.Context`` in ``domain``, shut down on exit.

    Nodes created with ``context=ctx`` live in that domain, independent of other contexts
    in the same process. Destroy nodes (and shut down executors) before leaving.
    """
    import rclpy
    from rclpy.context import Context

    domain_id = domain.domain_id if isinstance(domain, DomainLease) else int(domain)
    ctx = Context()
    with dds_process_env():
        rclpy.init(context=ctx, domain_id=domain_id)
    try:
        yield ctx
    finally:
        with contextlib.suppress(Exception):
            ctx.try_shutdown()
