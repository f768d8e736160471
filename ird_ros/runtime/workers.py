"""Worker processes for the long computations of the IRD services, one job per worker at a time.

``WorkerPool`` runs picklable functions in worker processes (spawn start method: the node
process runs DDS threads that must not be forked) and hands each result to an ``async`` rclpy
callback as an awaitable rclpy Future (see :mod:`ird_ros.runtime.node_main` for the mechanics).

Invariants:

- Every worker is a ``concurrent.futures.ProcessPoolExecutor`` of ONE process that is given ONE
  job at a time; the other jobs wait in the pool's own FIFO queue and start in submission order,
  at most ``max_workers`` at once. (A ``ProcessPoolExecutor`` marks every job it holds broken
  when one of its processes dies, so a queued job of another client would fail with the job that
  killed the worker.)
- A job whose worker dies (a crash, SIGKILL, the OOM killer) fails alone, with
  ``BrokenProcessPool``; that worker is replaced by a fresh one (warmed like the first) before
  it takes the next queued job. A worker found dead while idle is replaced at the next job.
- ``memory_limit`` (bytes, 0 = none) caps each worker's address space (``RLIMIT_AS``): a job that
  would exceed it gets ``MemoryError`` and the worker lives on.
- ``warm_modules`` are imported in every worker before it takes a job (the constructor waits
  for the first workers), and their ``warm_up()`` called if they have one.
- ``on_queued(position, busy_pids)`` (optional) is called when a job has to wait because every
  worker is busy: its queue position (1 = next) and the pids of the busy workers.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import multiprocessing
import os
import signal
import threading
from collections import deque
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

from ird_ros.launch.process_groups import set_parent_death_signal

__all__ = ["WorkerPool", "BrokenProcessPool"]


def _worker_init(memory_limit: int = 0, node_pid: int | None = None) -> None:  # pragma: no cover - worker process
    # Ctrl-C in a terminal signals the whole process group: the node ends its workers itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if memory_limit > 0:
        # An allocation past the limit raises MemoryError in the job (answered as a failure);
        # the node and the other workers keep their memory.
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (memory_limit, memory_limit))
    # Die with the node, even if it is SIGKILLed (Linux PR_SET_PDEATHSIG); a node that died
    # while this worker was still starting (before this line) never signals it, so the worker
    # then exits at once instead of living on as an orphan.
    set_parent_death_signal(signal.SIGTERM, node_pid)


def _warm(modules: Sequence[str]) -> int:  # pragma: no cover - runs in the worker process
    import importlib

    for name in modules:
        hook = getattr(importlib.import_module(name), "warm_up", None)
        if callable(hook):  # e.g. ird_core.mdp.warm_up: load the compiled passes now
            hook()
    return 0


def _pids(executor: concurrent.futures.ProcessPoolExecutor | None) -> list[int]:
    """The process ids of an executor's workers (Python 3.11 keeps them in ``_processes``)."""
    return sorted((getattr(executor, "_processes", None) or {}).keys()) if executor is not None else []


@dataclass
class _Job:
    future: concurrent.futures.Future
    fn: Callable[..., Any]
    args: tuple
    kwargs: dict


@dataclass
class _Slot:
    """One worker: its single-process executor, and whether it holds a job (or warms up)."""

    executor: concurrent.futures.ProcessPoolExecutor | None = None
    busy: bool = False
    job: _Job | None = field(default=None, repr=False)


class WorkerPool:
    """Worker processes taking one job each at a time from a FIFO queue (see the module doc)."""

    def __init__(self, max_workers: int = 1, warm_modules: Sequence[str] = (), memory_limit: int = 0,
                 on_queued: Callable[[int, list[int]], None] | None = None) -> None:
        if max_workers < 1:
            raise ValueError(f"max_workers must be >= 1, got {max_workers}")
        self._memory_limit = int(memory_limit)
        self._warm_modules = tuple(warm_modules)
        self._on_queued = on_queued
        self._lock = threading.Lock()
        self._queue: deque[_Job] = deque()
        self._closed = False
        executors = [self._new_executor() for _ in range(int(max_workers))]
        self._slots = [_Slot(executor=executor) for executor in executors]
        if self._warm_modules:
            # Start every worker now and wait until it has imported the modules, so the node is
            # ready (and the first request fast) once the constructor returns.
            warming = [executor.submit(_warm, self._warm_modules) for executor in executors]
            for future in warming:
                future.result(timeout=120.0)

    def _new_executor(self) -> concurrent.futures.ProcessPoolExecutor:
        return concurrent.futures.ProcessPoolExecutor(
            max_workers=1, mp_context=multiprocessing.get_context("spawn"),
            initializer=_worker_init, initargs=(self._memory_limit, os.getpid()))

    # ------------------------------------------------------------------ submitting

    def submit_concurrent(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> concurrent.futures.Future:
        """Queue ``fn(*args, **kwargs)``; return its ``concurrent.futures.Future`` (blocking callers, tests)."""
        future: concurrent.futures.Future = concurrent.futures.Future()
        with self._lock:
            if self._closed:
                raise RuntimeError("WorkerPool is shut down")
            self._queue.append(_Job(future, fn, args, kwargs))
            waiting = None if any(not s.busy for s in self._slots) else len(self._queue)
            busy = [pid for s in self._slots if s.busy for pid in _pids(s.executor)]
        if waiting is not None and self._on_queued is not None:
            self._on_queued(waiting, busy)
        self._dispatch()
        return future

    def submit(self, executor: Any, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Queue ``fn(*args, **kwargs)``; return an awaitable ``rclpy.task.Future``.

        ``executor`` is the rclpy executor that runs the awaiting coroutine (``node.executor``);
        it is woken when the result is in. The Future's result is the function's return value,
        or it raises the function's exception (``BrokenProcessPool`` if its worker died).
        """
        from rclpy.task import Future

        result = Future(executor=executor)
        cfut = self.submit_concurrent(fn, *args, **kwargs)

        def done(cf: concurrent.futures.Future) -> None:  # runs in a pool thread
            try:
                value = cf.result()
            except BaseException as exc:  # noqa: BLE001 - handed to the awaiting coroutine
                result.set_exception(exc)
            else:
                result.set_result(value)
            if executor is not None:
                executor.wake()

        cfut.add_done_callback(done)
        return result

    def queued(self) -> int:
        """Jobs waiting for a worker (not counting the running ones)."""
        with self._lock:
            return len(self._queue)

    def worker_pids(self) -> list[int]:
        """The process ids of the live workers."""
        with self._lock:
            return [pid for slot in self._slots for pid in _pids(slot.executor)]

    # ------------------------------------------------------------------ running

    def _dispatch(self) -> None:
        """Hand queued jobs to idle workers, in queue order."""
        while True:
            with self._lock:
                if self._closed or not self._queue:
                    return
                slot = next((s for s in self._slots if not s.busy), None)
                if slot is None:
                    return
                job = self._queue.popleft()
                if not job.future.set_running_or_notify_cancel():
                    continue  # cancelled while it waited
                slot.busy, slot.job = True, job
            self._start(slot, job)

    def _start(self, slot: _Slot, job: _Job) -> None:
        for attempt in (1, 2):
            try:
                assert slot.executor is not None
                inner = slot.executor.submit(job.fn, *job.args, **job.kwargs)
                break
            except BrokenProcessPool as exc:  # the worker died while idle: a fresh one takes the job
                if attempt == 2:
                    self._finish(slot, job, exc)
                    return
                self._discard(slot.executor)
                slot.executor = self._new_executor()
            except BaseException as exc:  # noqa: BLE001 - e.g. the pool is shutting down
                self._finish(slot, job, exc)
                return
        inner.add_done_callback(lambda f: self._done(slot, job, f))

    def _done(self, slot: _Slot, job: _Job, inner: concurrent.futures.Future) -> None:
        """A job's worker answered (a pool thread): settle it, replace a dead worker, go on."""
        try:
            value = inner.result()
        except BaseException as exc:  # noqa: BLE001 - handed to the job's future
            if isinstance(exc, BrokenProcessPool) and not self._closed:
                self._replace(slot)  # the slot stays busy until the new worker is warm
                self._settle(job, exc)
                return
            self._finish(slot, job, exc)
            return
        self._finish(slot, job, None, value)

    def _finish(self, slot: _Slot, job: _Job, exc: BaseException | None, value: Any = None) -> None:
        with self._lock:
            slot.busy, slot.job = False, None
        self._settle(job, exc, value)
        self._dispatch()

    @staticmethod
    def _settle(job: _Job, exc: BaseException | None, value: Any = None) -> None:
        if job.future.done():
            return
        if exc is not None:
            job.future.set_exception(exc)
        else:
            job.future.set_result(value)

    def _replace(self, slot: _Slot) -> None:
        """A fresh worker for ``slot`` (busy meanwhile); queued jobs resume once it is warm."""
        self._discard(slot.executor)
        slot.executor = self._new_executor()
        if not self._warm_modules:
            self._free(slot)
            return
        warming = slot.executor.submit(_warm, self._warm_modules)
        warming.add_done_callback(lambda f: self._warmed(slot, f))

    def _warmed(self, slot: _Slot, warming: concurrent.futures.Future) -> None:
        if not warming.cancelled() and isinstance(warming.exception(), BrokenProcessPool) and not self._closed:
            self._discard(slot.executor)  # died warming up: the next job gets an unwarmed worker
            slot.executor = self._new_executor()
        self._free(slot)

    def _free(self, slot: _Slot) -> None:
        with self._lock:
            slot.busy, slot.job = False, None
        self._dispatch()

    @staticmethod
    def _discard(executor: concurrent.futures.ProcessPoolExecutor | None) -> None:
        """Terminate an executor's workers (Python 3.11 has no way to stop a running task) and drop it."""
        if executor is None:
            return
        processes = list((getattr(executor, "_processes", None) or {}).values())
        for proc in processes:
            with contextlib.suppress(Exception):
                proc.terminate()
        executor.shutdown(wait=False, cancel_futures=True)
        for proc in processes:
            with contextlib.suppress(Exception):
                proc.join(2.0)

    def shutdown(self) -> None:
        """Cancel the queued jobs, terminate the workers (their jobs fail), return."""
        with self._lock:
            self._closed = True
            queued, self._queue = list(self._queue), deque()
            executors = [slot.executor for slot in self._slots]
            for slot in self._slots:
                slot.executor = None
        for job in queued:
            job.future.cancel()
        for executor in executors:
            self._discard(executor)
