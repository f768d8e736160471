"""Helpers for tests that talk ROS 2: private domains, node processes, discovery waits.

Typical use (see ``tests/conftest.py`` for the fixtures built on this)::

    lease = lease_domain()                      # exclusive ROS_DOMAIN_ID in 0..101
    with ros_context(lease) as ctx:             # rclpy context in that domain
        node = rclpy.create_node("probe", context=ctx)
        with spawn_node_process(["-m", "ird_ros.world"], domain=lease) as proc:
            client = node.create_client(GenerateWorld, "/world/generate")
            wait_for_service(node, client, timeout=20.0, processes=[proc])
            response = call_service(node, client, GenerateWorld.Request(...), timeout=20.0)

Nothing here sleeps: every wait spins the test's node (``spin_once`` with a short
timeout wakes up on any ROS event) until a condition holds or a deadline passes, and then
raises ``TimeoutError`` that includes the output of the helper processes.

Domain IDs: ``lease_domain`` takes an exclusive ``flock`` on
``/tmp/ird_ros_domains/domain_<N>.lock`` for one N in 0..101 (0-101 keeps the DDS ports
out of Linux's ephemeral range). Concurrent test runs, demos and CI on one machine that
all lease through this module (or ``scripts/lib/ros_env.sh``, which uses the same lock
files) never share a domain. The search starts at ``IRD_TEST_DOMAIN_BASE`` if set,
otherwise at a value derived from the process id. The lock is released when the lease
is released or the process exits.

rclpy is imported lazily, so importing this module costs nothing for ROS-free tests.
"""

from __future__ import annotations

import atexit
import collections
import contextlib
import ctypes
import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Mapping, Sequence

__all__ = [
    "running_nodes",
    "DOMAIN_ID_MAX",
    "DOMAIN_LOCK_DIR",
    "DomainLease",
    "lease_domain",
    "ros_env",
    "ros_context",
    "NodeProcess",
    "spawn_node_process",
    "spin_until",
    "wait_for_subscribers",
    "wait_for_publishers",
    "wait_for_service",
    "wait_for_node",
    "call_service",
    "receive_messages",
]

DOMAIN_ID_MAX = 101
"""Largest domain ID handed out (IDs above 101 put DDS ports into the ephemeral range)."""

DOMAIN_LOCK_DIR = Path(os.environ.get("IRD_DOMAIN_LOCK_DIR", "/tmp/ird_ros_domains"))
"""Where the per-domain lock files live (shared with scripts/lib/ros_env.sh)."""


# --------------------------------------------------------------------------- domains


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


def lease_domain(*, start: int | None = None, log_dir: str | os.PathLike[str] | None = None) -> DomainLease:
    """Lease a free ROS domain ID in 0..101 (see the module docstring).

    ``start``: first candidate (default: ``IRD_TEST_DOMAIN_BASE`` or derived from the pid);
    candidates wrap around 0..101, skipping the current ``ROS_DOMAIN_ID``. ``log_dir``: ROS_LOG_DIR for processes in the domain
    (default: a fresh temporary directory removed on release).
    Raises ``RuntimeError`` when all 102 IDs are held.
    """
    n = DOMAIN_ID_MAX + 1
    if start is None:
        base = os.environ.get("IRD_TEST_DOMAIN_BASE")
        start = int(base) if base else (os.getpid() * 7919) % n
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
        return DomainLease(candidate, Path(log_dir), fd, tmp)
    raise RuntimeError(f"all ROS domain IDs 0..{DOMAIN_ID_MAX} are leased (locks in {DOMAIN_LOCK_DIR})")


def ros_env(
    domain_id: int, log_dir: str | os.PathLike[str], base: Mapping[str, str] | None = None
) -> dict[str, str]:
    """A copy of ``base`` (default ``os.environ``) set up for a private, localhost-only domain."""
    env = dict(os.environ if base is None else base)
    env["ROS_DOMAIN_ID"] = str(int(domain_id))
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env.pop("ROS_LOCALHOST_ONLY", None)  # deprecated in Jazzy; the range above replaces it
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
    rclpy.init(context=ctx, domain_id=domain_id)
    try:
        yield ctx
    finally:
        with contextlib.suppress(Exception):
            ctx.try_shutdown()


# --------------------------------------------------------------------------- processes


try:
    _PRCTL: Any = ctypes.CDLL(None, use_errno=True).prctl  # resolved here, not after fork
except (OSError, AttributeError):  # not Linux/glibc
    _PRCTL = None


def _child_setup() -> None:  # pragma: no cover - runs in the child before exec
    # Die with the test process (no orphaned nodes if pytest is killed) ...
    if _PRCTL is not None:
        _PRCTL(1, int(signal.SIGTERM))  # PR_SET_PDEATHSIG
    # ... and react to SIGINT even if the runner was started in the background with SIGINT ignored.
    signal.signal(signal.SIGINT, signal.SIG_DFL)


class NodeProcess:
    """A helper process (typically a ROS node) with its stdout+stderr collected.

    Use ``wait_for_output`` for a readiness line, ``output()`` for diagnostics and ``stop()``
    (or the context manager) to end it: SIGINT, then SIGTERM, then SIGKILL.
    """

    def __init__(self, argv: Sequence[str], env: Mapping[str, str], cwd: str | os.PathLike[str] | None, name: str):
        self.name = name
        self.argv = list(argv)
        self._lines: collections.deque[str] = collections.deque(maxlen=2000)
        self._cond = threading.Condition()
        self.proc = subprocess.Popen(
            self.argv,
            env=dict(env),
            cwd=cwd,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            errors="replace",
            bufsize=1,
            preexec_fn=_child_setup,
        )
        self._reader = threading.Thread(target=self._read, name=f"reader-{name}", daemon=True)
        self._reader.start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            with self._cond:
                self._lines.append(line.rstrip("\n"))
                self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    @property
    def pid(self) -> int:
        return self.proc.pid

    @property
    def returncode(self) -> int | None:
        return self.proc.poll()

    def alive(self) -> bool:
        return self.proc.poll() is None

    def output(self, last: int = 200) -> str:
        """The last ``last`` lines the process printed."""
        with self._cond:
            return "\n".join(list(self._lines)[-last:])

    def describe(self) -> str:
        state = "running" if self.alive() else f"exited with {self.proc.returncode}"
        return f"--- {self.name} (pid {self.pid}, {state}) output:\n{self.output()}"

    def wait_for_output(self, text: str, timeout: float = 30.0) -> str:
        """Block until a line containing ``text`` was printed; return that line.

        Raises ``TimeoutError`` (with the output) on timeout or if the process exits first.
        """
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                for line in self._lines:
                    if text in line:
                        return line
                if self.proc.poll() is not None and not self._reader.is_alive():
                    raise TimeoutError(f"{self.name} exited before printing {text!r}\n{self.describe()}")
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(f"{self.name} did not print {text!r} within {timeout} s\n{self.describe()}")
                self._cond.wait(min(remaining, 0.5))

    def stop(self, timeout: float = 10.0) -> int:
        """End the process (SIGINT, then SIGTERM, then SIGKILL); return its exit code."""
        for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if self.proc.poll() is not None:
                break
            with contextlib.suppress(ProcessLookupError):
                self.proc.send_signal(sig)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout)
        self._reader.join(timeout)
        _LIVE.discard(self)
        return self.proc.returncode

    def __enter__(self) -> "NodeProcess":
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()


_LIVE: set[NodeProcess] = set()


def _stop_all() -> None:
    for proc in list(_LIVE):
        proc.stop(timeout=3.0)


atexit.register(_stop_all)


def spawn_node_process(
    argv: Sequence[str],
    *,
    domain: DomainLease | int,
    log_dir: str | os.PathLike[str] | None = None,
    env: Mapping[str, str] | None = None,
    cwd: str | os.PathLike[str] | None = None,
    name: str | None = None,
    ready_text: str | None = None,
    ready_timeout: float = 30.0,
    python: str | None = None,
) -> NodeProcess:
    """Start ``python argv...`` (this interpreter by default) in ``domain``.

    ``argv`` are the interpreter's arguments, e.g. ``["-m", "ird_ros.world",
    "--ros-args", "--params-file", "msgs_config/params/graph.yaml"]`` or ``[script, ...]``.
    The environment is ``env`` (default ``os.environ``) with ROS_DOMAIN_ID,
    ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and ROS_LOG_DIR set for the domain.
    With ``ready_text``, waits until the process prints a line containing it.
    The child gets SIGTERM if the test process dies.
    """
    if isinstance(domain, DomainLease):
        full_env = domain.env(env)
        if log_dir is not None:
            full_env["ROS_LOG_DIR"] = str(log_dir)
    else:
        if log_dir is None:
            log_dir = os.environ.get("ROS_LOG_DIR") or tempfile.mkdtemp(prefix="ird_ros_log_")
        full_env = ros_env(int(domain), log_dir, env)
    if name is None:
        args = list(argv)
        name = args[1] if len(args) > 1 and args[0] == "-m" else Path(args[0]).stem if args else "python"
    proc = NodeProcess([python or sys.executable, *argv], full_env, cwd, name)
    _LIVE.add(proc)
    if ready_text is not None:
        try:
            proc.wait_for_output(ready_text, ready_timeout)
        except BaseException:
            proc.stop()
            raise
    return proc


# --------------------------------------------------------------------------- waiting


def spin_until(
    node: Any,
    condition: Callable[[], bool],
    *,
    timeout: float,
    what: str = "condition",
    executor: Any = None,
    processes: Sequence[NodeProcess] = (),
) -> None:
    """Spin until ``condition()`` is true.

    Spins ``executor`` if given, else the executor ``node`` belongs to, else a temporary
    single-threaded executor in the node's context. Raises ``TimeoutError`` naming
    ``what`` (with the output of ``processes``) after ``timeout`` seconds, or as soon as
    one of ``processes`` has exited.
    """
    from rclpy.executors import SingleThreadedExecutor

    temporary = None
    if executor is None:
        executor = node.executor
    if executor is None:
        executor = temporary = SingleThreadedExecutor(context=node.context)
        temporary.add_node(node)
    try:
        deadline = time.monotonic() + timeout
        while not condition():
            for proc in processes:
                if not proc.alive():
                    raise TimeoutError(f"waiting for {what}: {proc.name} exited\n{proc.describe()}")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                details = "\n".join(p.describe() for p in processes)
                raise TimeoutError(f"timed out after {timeout} s waiting for {what}\n{details}")
            executor.spin_once(timeout_sec=min(0.05, remaining))
    finally:
        if temporary is not None:
            node.executor = None  # detaches the node from the temporary executor
            temporary.shutdown()


def wait_for_subscribers(node: Any, publisher: Any, count: int = 1, *, timeout: float = 20.0, **kw: Any) -> None:
    """Wait until ``publisher`` has matched at least ``count`` subscriptions."""
    spin_until(
        node,
        lambda: publisher.get_subscription_count() >= count,
        timeout=timeout,
        what=f"{count} subscriber(s) on {publisher.topic_name}",
        **kw,
    )


def wait_for_publishers(node: Any, subscription: Any, count: int = 1, *, timeout: float = 20.0, **kw: Any) -> None:
    """Wait until ``subscription`` has matched at least ``count`` publishers."""
    spin_until(
        node,
        lambda: subscription.get_publisher_count() >= count,
        timeout=timeout,
        what=f"{count} publisher(s) on {subscription.topic_name}",
        **kw,
    )


def wait_for_service(node: Any, client: Any, *, timeout: float = 20.0, **kw: Any) -> None:
    """Wait until the server of ``client`` is discovered."""
    spin_until(node, client.service_is_ready, timeout=timeout, what=f"service {client.srv_name}", **kw)


def wait_for_node(node: Any, name: str, namespace: str = "/", *, timeout: float = 20.0, **kw: Any) -> None:
    """Wait until a node called ``namespace/name`` is in the graph."""
    spin_until(
        node,
        lambda: (name, namespace) in node.get_node_names_and_namespaces(),
        timeout=timeout,
        what=f"node {namespace.rstrip('/')}/{name}",
        **kw,
    )


def call_service(node: Any, client: Any, request: Any, *, timeout: float = 30.0, **kw: Any) -> Any:
    """Wait for the server, call it, and spin until the response arrives; return the response.

    Waiting first matters: a request sent before discovery matched client and server is
    dropped without an error, and the call would hang until ``timeout``.
    """
    wait_for_service(node, client, timeout=timeout, **kw)
    future = client.call_async(request)
    spin_until(node, future.done, timeout=timeout, what=f"response of {client.srv_name}", **kw)
    return future.result()


def receive_messages(
    node: Any,
    msg_type: Any,
    topic: str,
    *,
    count: int = 1,
    qos: Any = None,
    timeout: float = 20.0,
    raw: bool = False,
    **kw: Any,
) -> list[Any]:
    """Subscribe to ``topic`` and spin until ``count`` messages arrived; return them.

    ``qos`` defaults to reliable, transient local, depth 10 (which also receives what was
    published before the subscription matched, from transient-local publishers).
    """
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    if qos is None:
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    received: list[Any] = []
    sub = node.create_subscription(msg_type, topic, received.append, qos, raw=raw)
    try:
        spin_until(node, lambda: len(received) >= count, timeout=timeout, what=f"{count} message(s) on {topic}", **kw)
    finally:
        node.destroy_subscription(sub)
    return received


@contextlib.contextmanager
def running_nodes(domain: "DomainLease", *nodes: tuple[str, Sequence[str]]) -> Iterator[list[NodeProcess]]:
    """Start node processes ``(name, argv)`` together, wait until each logs ``"<name> ready"``,
    stop them at the end (SIGINT) and check that each exited with 0."""
    procs: list[NodeProcess] = []
    try:
        for name, args in nodes:
            procs.append(spawn_node_process(list(args), domain=domain, name=name))
        for proc in procs:
            proc.wait_for_output(f"{proc.name} ready", timeout=60.0)
        yield procs
    finally:
        for proc in procs:
            proc.stop()
    for proc in procs:
        assert proc.returncode == 0, proc.describe()
