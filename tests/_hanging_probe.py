"""Stand-in liveness probe processes for tests/test_liveness_process.py (importable by a spawned child)."""

from __future__ import annotations

import ctypes
from typing import Any


def hang_holding_the_gil(conn: Any, *_args: Any) -> None:
    """Read the first request, then block forever in C *holding the GIL* (``PyDLL`` keeps it),
    like the ping that stayed inside Fast DDS's shared-memory transport."""
    conn.recv()
    ctypes.PyDLL(None).pause()


def answer_nothing_stalled(conn: Any, *_args: Any) -> None:
    """A probe that answers every request at once: no transitions, nothing stalled."""
    while conn.recv() is not None:
        conn.send(([], {}, {}, 0))
