"""Helpers for tests that talk ROS 2: private domains, node processes, discovery waits.

Typical use (see ``tests/conftest.py`` for the fixtures built on this)::

    lease = lease_domain()                      # ird_ros.graph.domains: a ROS_DOMAIN_ID in 0..101
    with spawn_node_process(["-m", "ird_ros.nodes.world"], domain=lease) as proc, \
            IrdClient(lease.domain_id, processes=[proc]) as ird:
        ird.wait_ready(20.0, services=(names.SRV_GENERATE,))
        result = ird.generate_world("side_effects", 3)

Nothing here sleeps: every wait spins a node until a condition holds or a deadline passes, and
then raises ``TimeoutError`` that includes the output of the helper processes.

This module adds the helper processes (``NodeProcess``, ``spawn_node_process``, ``running_nodes``)
and is for tests only: no production module imports it. Domains come from
``ird_ros.graph.domains``, waits from ``ird_ros.waits``, and the client of the graph is
``ird_ros.client.IrdClient``.

rclpy is imported lazily (when a test makes a context or a node), so ROS-free tests never load it.
"""

from __future__ import annotations

import atexit
import collections
import contextlib
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Iterator, Mapping, Sequence

from ird_ros.graph.domains import DomainLease, ros_env
from ird_ros.launch.process_groups import child_preexec

__all__ = ["running_nodes", "NodeProcess", "spawn_node_process"]

# --------------------------------------------------------------------------- processes


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
            preexec_fn=child_preexec(os.getpid()),
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

    ``argv`` are the interpreter's arguments, e.g. ``["-m", "ird_ros.nodes.world",
    "--ros-args", "--params-file", "msgs_config/params/graph.yaml"]`` or ``[script, ...]``.
    The environment is ``env`` (default ``os.environ``) with ROS_DOMAIN_ID,
    loopback-only DDS (``domains.dds_env``) and ROS_LOG_DIR set for the domain.
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
