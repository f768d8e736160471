"""A child process in a group of its own that is told when its parent dies (Linux).

``child_preexec`` is the ``preexec_fn`` of every process the supervisor starts (and of the
tests' node processes): SIGINT/SIGTERM at their default dispositions (a parent started with
``&`` has SIGINT ignored, which children would inherit) and ``PR_SET_PDEATHSIG=SIGTERM``, so
the child is told to stop even when its parent is killed with SIGKILL. ``group_alive`` says
whether a process group still has a live (non-zombie) member; ``child_ended`` whether a child
has ended, without reaping it. No ROS in here.
"""

from __future__ import annotations

import ctypes
import os
import signal
from typing import Any, Callable

__all__ = ["set_parent_death_signal", "child_preexec", "group_alive", "child_ended"]

try:
    _PRCTL: Any = ctypes.CDLL(None, use_errno=True).prctl  # resolved here, not after fork
except (OSError, AttributeError):  # pragma: no cover - not Linux/glibc
    _PRCTL = None
_PR_SET_PDEATHSIG = 1


def set_parent_death_signal(sig: int = signal.SIGTERM, parent_pid: int | None = None) -> None:
    """Have the kernel send ``sig`` to this process when its parent dies (Linux ``prctl``).

    With ``parent_pid``, exit at once if the parent is already gone (it died before the call
    took effect, and the signal would never come). A no-op where ``prctl`` does not exist.
    """
    if _PRCTL is not None:
        _PRCTL(_PR_SET_PDEATHSIG, int(sig))
    if parent_pid is not None and os.getppid() != parent_pid:
        os._exit(1)


def child_preexec(parent_pid: int) -> Callable[[], None]:
    """A ``preexec_fn``: default SIGINT/SIGTERM handling and SIGTERM when ``parent_pid`` dies."""

    def setup() -> None:  # pragma: no cover - runs in the child between fork and exec
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        set_parent_death_signal(signal.SIGTERM, parent_pid)

    return setup


def group_alive(pgid: int) -> bool:
    """True while a process of group ``pgid`` runs (zombies do not count).

    A child's helper processes (multiprocessing's resource tracker, pool workers) are
    re-parented to init when the child exits; their zombies stay in the group until init
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


def child_ended(pid: int) -> bool:
    """True once this process's child ``pid`` has ended: a zombie, or already reaped.

    Unlike ``Popen.poll``, which answers None while another thread blocks in ``Popen.wait``
    (it cannot take the Popen's wait lock), this asks the kernel without reaping (``WNOWAIT``).
    """
    try:
        return os.waitid(os.P_PID, pid, os.WEXITED | os.WNOHANG | os.WNOWAIT) is not None
    except ChildProcessError:  # reaped already
        return True
