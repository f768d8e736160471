"""Long service computations in a worker process, with one mapping of failures to answers.

The inference and planner nodes both validate a request, then hand a typed, picklable job to
:class:`Offload` and ``await`` it. Every way that can fail becomes :class:`OffloadError`, whose
message is the service's ``message`` (with ``success: false``):

- :data:`BUSY_PREFIX` ``...`` when ``max_pending`` valid requests are already waiting or running (refused at
  once, the job never queues; the message gives the queue position it would have had);
- the library's own ``ValueError`` message as it is (it starts with the argument's name);
- ``worker_memory_mb: <what> needed more than the worker's N MiB (MemoryError)`` when the job
  ran out of the worker's capped address space (``memory_limit``; the worker lives on);
- ``internal error: the worker process died (...)`` for the job whose worker died; it alone
  fails: the pool replaces the worker and the queued jobs run on the new one;
- ``<what> failed: <ExceptionType>: ...`` for any other exception of the job (for the planner,
  e.g. ``PlanningTimeout``), so the node keeps serving.

Jobs start in arrival order, one per worker at a time (``ird_ros.runtime.workers.WorkerPool``);
a request that has to wait is logged with its queue position and the busy workers' pids.

:func:`service_qos` is the QoS of every IRD service (requests and responses). rclpy's default
(``qos_profile_services_default``) keeps the last 10 requests in the server's request reader
and the last 10 responses in its response writer: a burst of more than 10 requests arriving
before the executor takes them silently drops the oldest, so those clients never get an answer.
The deeper queue keeps a burst until the node answers each request, with a result or at once
with ``busy``.
"""

from __future__ import annotations

from typing import Any, Callable, Sequence, TypeVar

from ird_ros.runtime.workers import BrokenProcessPool, WorkerPool

__all__ = ["BUSY_PREFIX", "Offload", "OffloadError", "SERVICE_QUEUE_DEPTH", "service_qos"]

#: How every "try again later" answer of an IRD service begins (``success: false``); clients
#: recognise it in one place, ``ird_ros.client.results``.
BUSY_PREFIX = "busy"

#: Requests (and responses) a service keeps until the node takes (the client acknowledges)
#: them; a burst up to this size is answered in full.
SERVICE_QUEUE_DEPTH = 1000


def service_qos() -> Any:
    """Reliable, volatile, keep last :data:`SERVICE_QUEUE_DEPTH`: ``create_service(qos_profile=...)``
    of the IRD services, and the profile clients that send bursts should use too."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=SERVICE_QUEUE_DEPTH,
                      reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)

J = TypeVar("J")
R = TypeVar("R")


class OffloadError(Exception):
    """The job did not produce a result; ``str(exc)`` is the answer's message."""


class Offload:
    """A :class:`WorkerPool` plus the pending-request cap and the failure mapping.

    Args:
        what: names the computation in failure messages (``"inference"``, ``"planning"``).
        max_pending: valid requests allowed to wait or run at once.
        max_workers, warm_modules, memory_limit: as ``WorkerPool`` (``memory_limit`` in bytes).
        logger: an rclpy logger; failures other than bad arguments and busy are logged as errors,
            a request that waits for a worker at info.
        pool: a pool to use instead of starting one (tests).
    """

    def __init__(self, what: str, max_pending: int, *, max_workers: int = 1, warm_modules: Sequence[str] = (),
                 memory_limit: int = 0, logger: Any = None, pool: Any = None) -> None:
        if max_pending < 1:
            raise ValueError(f"max_pending: expected >= 1, got {max_pending}")
        self.what = what
        self.max_pending = int(max_pending)
        self.pending = 0
        self._logger = logger
        self.memory_limit = int(memory_limit)
        self._pool = pool if pool is not None else WorkerPool(max_workers, warm_modules=warm_modules,
                                                              memory_limit=memory_limit, on_queued=self._queued)

    def _queued(self, position: int, busy_pids: list[int]) -> None:
        if self._logger is not None:
            self._logger.info(f"{self.what}: a request waits at queue position {position} "
                              f"(busy worker pids {busy_pids})")

    async def run(self, executor: Any, fn: Callable[[J], R], job: J) -> R:
        """``fn(job)`` in a worker process; raises :class:`OffloadError` (see the module doc)."""
        if self.pending >= self.max_pending:
            raise OffloadError(f"{BUSY_PREFIX}: {self.pending} requests are pending (max_pending={self.max_pending}); "
                               f"this one would be queue position {self.pending + 1}: retry later")
        self.pending += 1
        try:
            return await self._pool.submit(executor, fn, job)
        except ValueError as exc:  # the library's validation: the message names the argument
            raise OffloadError(str(exc)) from None
        except BrokenProcessPool as exc:
            raise self._error(f"internal error: the worker process died ({exc})") from None
        except MemoryError as exc:
            limit = f"the worker's {self.memory_limit // 2**20} MiB" if self.memory_limit else "the memory"
            raise self._error(f"worker_memory_mb: {self.what} needed more than {limit} (MemoryError: {exc})") from None
        except Exception as exc:  # noqa: BLE001 - any failure of the job is an answer, not a crash
            raise self._error(f"{self.what} failed: {type(exc).__name__}: {exc}") from None
        finally:
            self.pending -= 1

    def _error(self, message: str) -> OffloadError:
        if self._logger is not None:
            self._logger.error(message)
        return OffloadError(message)

    def shutdown(self) -> None:
        """End the worker processes (queued jobs are cancelled)."""
        self._pool.shutdown()
