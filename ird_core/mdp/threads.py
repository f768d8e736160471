"""Threads for the MDP passes' chunks (``IRD_THREADS``), internal to ``ird_core.mdp``.

A batch whose work arrays exceed a cache-sized chunk (``passes._CHUNK_BYTES``: on a 64x64 map
with T = 120 one weight per chunk) is cut into chunks that share nothing: each is a pair of
passes on its own weights, with the calling thread's own work arrays
(``linear_passes._work``), and the compiled kernels and numpy's array operations release the
GIL. So chunks can run on threads, and every number is the same as on one thread (each chunk's
arithmetic does not depend on where or when it runs; ``tests/core/test_mdp_threads.py``).

``IRD_THREADS``: a positive integer, or ``auto`` for the machine's CPU count; read on every call,
1 when unset. One thread is the default because the experiments already run one process per
core (``run_experiments.py --workers``): more threads there would only contend. Set it for a
single process on a large map (the inference node, ``scripts/bench_scale.py``).
"""

from __future__ import annotations

import os
import threading
from concurrent.futures import ThreadPoolExecutor
from typing import Callable, Sequence, TypeVar

__all__ = ["threads", "map_chunks"]

T = TypeVar("T")
R = TypeVar("R")

_POOLS: "dict[int, ThreadPoolExecutor]" = {}
_POOLS_LOCK = threading.Lock()
# A forked child inherits the pools but not their threads: it makes its own.
os.register_at_fork(after_in_child=_POOLS.clear)


def threads() -> int:
    """The thread count from ``IRD_THREADS`` (1 when unset or empty).

    Raises:
        ValueError: naming ``IRD_THREADS`` when it is neither ``auto`` nor an integer in [1, 256].
    """
    raw = os.environ.get("IRD_THREADS", "").strip().lower()
    if raw in ("", "1"):
        return 1
    if raw == "auto":
        return max(1, os.cpu_count() or 1)
    try:
        count = int(raw)
    except ValueError:
        raise ValueError(f"IRD_THREADS: expected a positive integer or 'auto', got {raw!r}") from None
    if not 1 <= count <= 256:
        raise ValueError(f"IRD_THREADS: expected an integer in [1, 256] or 'auto', got {count}")
    return count


def _pool(count: int) -> ThreadPoolExecutor:
    with _POOLS_LOCK:
        pool = _POOLS.get(count)
        if pool is None:
            pool = _POOLS[count] = ThreadPoolExecutor(max_workers=count, thread_name_prefix="ird-mdp")
        return pool


def map_chunks(fn: Callable[[T], R], parts: Sequence[T]) -> list[R]:
    """``[fn(p) for p in parts]``, on ``threads()`` threads when there is more than one part.

    ``fn`` must be safe to run on several threads at once (the passes are: work arrays are per
    thread). Exceptions propagate as from the loop.
    """
    count = threads()
    if count <= 1 or len(parts) <= 1:
        return [fn(part) for part in parts]
    return list(_pool(count).map(fn, parts))
