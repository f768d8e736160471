"""ird_ros.runtime.offload: the one mapping of a worker job's outcome to a service answer.

With a controllable stand-in pool (busy accounting, every failure kind) and with a real
``WorkerPool`` driven by an rclpy executor (library errors, a dying worker and its replacement);
a worker killed while it runs a job fails that job only: the queued jobs run on its replacement
and the other workers' jobs go on.
"""

from __future__ import annotations

import asyncio
import math
import operator
import os
import signal
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable, Iterator

import pytest

from ird_ros.runtime.offload import Offload, OffloadError
from ird_ros.waits import spin_until


class _Pool:
    """A pool whose jobs finish when the test says so (asyncio futures)."""

    def __init__(self) -> None:
        self.submitted: list[tuple[Callable[..., Any], Any, asyncio.Future]] = []
        self.shut = False
        self._arrived = asyncio.Event()

    def submit(self, executor: Any, fn: Callable[..., Any], job: Any) -> asyncio.Future:
        future = asyncio.get_running_loop().create_future()
        self.submitted.append((fn, job, future))
        self._arrived.set()
        return future

    async def until_submitted(self, n: int) -> None:
        """Wait (on the event loop, no timer) until ``n`` jobs were submitted."""
        while len(self.submitted) < n:
            self._arrived.clear()
            await self._arrived.wait()

    def shutdown(self) -> None:
        self.shut = True


class _Log:
    def __init__(self) -> None:
        self.errors: list[str] = []

    def error(self, message: str) -> None:
        self.errors.append(message)


async def _outcome(offload: Offload, job: Any) -> Any:
    try:
        return await offload.run(None, abs, job)
    except OffloadError as exc:
        return exc


@pytest.mark.parametrize("raised,message,logged", [
    (ValueError("beta: expected a finite number >= 0"), "beta: expected a finite number >= 0", False),
    (BrokenProcessPool("gone"), "internal error: the worker process died (gone)", True),
    (RuntimeError("no luck"), "planning failed: RuntimeError: no luck", True),
])
def test_failures_become_messages(raised: BaseException, message: str, logged: bool) -> None:
    async def scenario() -> None:
        pool, log = _Pool(), _Log()
        offload = Offload("planning", 2, logger=log, pool=pool)
        task = asyncio.ensure_future(_outcome(offload, -3))
        await pool.until_submitted(1)
        assert offload.pending == 1 and pool.submitted[0][1] == -3
        pool.submitted[0][2].set_exception(raised)
        result = await task
        assert isinstance(result, OffloadError) and str(result) == message
        assert offload.pending == 0
        assert log.errors == ([message] if logged else [])

    asyncio.run(scenario())


def test_busy_refuses_at_once_and_frees_slots() -> None:
    async def scenario() -> None:
        pool = _Pool()
        offload = Offload("inference", 2, pool=pool)
        first = asyncio.ensure_future(_outcome(offload, 1))
        second = asyncio.ensure_future(_outcome(offload, 2))
        await pool.until_submitted(2)
        refused = await _outcome(offload, 3)
        assert isinstance(refused, OffloadError)
        assert str(refused) == ("busy: 2 requests are pending (max_pending=2); this one would be queue position 3: "
                                "retry later")
        assert [job for _, job, _ in pool.submitted] == [1, 2]  # the refused job never queued
        pool.submitted[0][2].set_result("one")
        assert await first == "one" and offload.pending == 1
        third = asyncio.ensure_future(_outcome(offload, 4))
        await pool.until_submitted(3)
        assert [job for _, job, _ in pool.submitted] == [1, 2, 4]
        pool.submitted[1][2].set_result("two")
        pool.submitted[2][2].set_result("four")
        assert (await second, await third, offload.pending) == ("two", "four", 0)
        offload.shutdown()
        assert pool.shut

    asyncio.run(scenario())


def test_max_pending_must_be_positive() -> None:
    with pytest.raises(ValueError, match="^max_pending"):
        Offload("x", 0, pool=_Pool())


@pytest.fixture(scope="module")
def real(ros_ctx: Any) -> Iterator[tuple[Offload, Any, Any]]:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    node = rclpy.create_node("offload_test", context=ros_ctx)
    executor = SingleThreadedExecutor(context=ros_ctx)
    executor.add_node(node)
    offload = Offload("job", 4, logger=node.get_logger())
    yield offload, node, executor
    offload.shutdown()
    executor.shutdown()
    node.destroy_node()


def _run(real: tuple[Offload, Any, Any], fn: Callable[[Any], Any], job: Any) -> Any:
    """``offload.run(fn, job)`` as a coroutine task of a real rclpy executor; its outcome."""
    offload, node, executor = real
    task = executor.create_task(_outcome_with(offload, executor, fn, job))
    spin_until(node, task.done, timeout=60.0, what="the offloaded job", executor=executor)
    return task.result()


async def _outcome_with(offload: Offload, executor: Any, fn: Callable[[Any], Any], job: Any) -> Any:
    try:
        return await offload.run(executor, fn, job)
    except OffloadError as exc:
        return exc


def test_real_worker_pool(real: tuple[Offload, Any, Any]) -> None:
    assert _run(real, abs, -2) == 2
    bad = _run(real, math.sqrt, -1.0)  # a ValueError raised in the worker: its message as it is
    assert isinstance(bad, OffloadError) and str(bad) == "math domain error"
    other = _run(real, operator.neg, "x")
    assert isinstance(other, OffloadError) and str(other).startswith("job failed: TypeError: ")
    died = _run(real, os._exit, 3)
    assert isinstance(died, OffloadError) and str(died).startswith("internal error: the worker process died")
    assert _run(real, abs, -5) == 5  # a new worker took over
    assert real[0].pending == 0


def test_warm_modules_warm_up_hook_loads_the_compiled_passes_before_any_request() -> None:
    """A warm module's ``warm_up()`` runs in every worker at start-up: with ``ird_core.mdp`` the
    compiled MDP kernels are loaded before the first job (a fresh worker that had only imported
    the module would report kernels without any compiled signature)."""
    from ird_core.mdp import linear_kernels
    from ird_ros.runtime.node_main import WorkerPool

    if not linear_kernels.available():
        pytest.skip("numba is pinned in requirements.txt")
    probe = ("[len(k.signatures) for k in __import__('ird_core.mdp.linear_kernels', fromlist=['compiled'])"
             ".compiled()]")
    warm = WorkerPool(1, warm_modules=("ird_core.mdp",))
    cold = WorkerPool(1, warm_modules=("ird_core.mdp.linear_kernels",))  # no warm_up hook
    try:
        assert all(n >= 1 for n in warm.submit_concurrent(eval, probe).result(timeout=120))
        assert cold.submit_concurrent(eval, probe).result(timeout=120) == [0, 0, 0]
    finally:
        warm.shutdown()
        cold.shutdown()


# --------------------------------------------------------------------------- a worker's death


def _hold(pid_fifo: str, go_fifo: str = "") -> int:
    """A job that tells the test its worker's pid (a FIFO: the test's read blocks until the job
    runs), then waits until the test says go (or is killed); returns its pid."""
    with open(pid_fifo, "w") as out:
        out.write(f"{os.getpid()}\n")
    if go_fifo:
        with open(go_fifo) as go:
            go.read()
    else:
        signal.pause()  # until the test kills this worker
    return os.getpid()


def _fifo(tmp_path: Any, name: str) -> str:
    path = str(tmp_path / name)
    os.mkfifo(path)
    return path


def _running_pid(pid_fifo: str) -> int:
    with open(pid_fifo) as handle:  # blocks until the job runs in its worker
        return int(handle.readline())


def test_a_dying_worker_fails_only_its_own_job(tmp_path: Any) -> None:
    from ird_ros.runtime.node_main import WorkerPool

    queued: list[tuple[int, list[int]]] = []
    pool = WorkerPool(1, warm_modules=("numpy",), on_queued=lambda position, pids: queued.append((position, pids)))
    try:
        fifo = _fifo(tmp_path, "a")
        victim = pool.submit_concurrent(_hold, fifo)
        pid = _running_pid(fifo)
        assert pool.worker_pids() == [pid]
        innocent = pool.submit_concurrent(abs, -7)  # another client's job, queued behind the victim
        assert queued == [(1, [pid])] and pool.queued() == 1
        os.kill(pid, signal.SIGKILL)
        assert innocent.result(timeout=120) == 7  # run by the fresh worker
        with pytest.raises(BrokenProcessPool):
            victim.result(timeout=120)
        assert pid not in pool.worker_pids() and len(pool.worker_pids()) == 1
        assert pool.submit_concurrent(abs, -8).result(timeout=60) == 8
    finally:
        pool.shutdown()


def test_a_dying_worker_spares_the_other_workers_jobs(tmp_path: Any) -> None:
    from ird_ros.runtime.node_main import WorkerPool

    pool = WorkerPool(2)
    try:
        first, second, go = _fifo(tmp_path, "first"), _fifo(tmp_path, "second"), _fifo(tmp_path, "go")
        victim = pool.submit_concurrent(_hold, first)
        victim_pid = _running_pid(first)
        neighbour = pool.submit_concurrent(_hold, second, go)
        neighbour_pid = _running_pid(second)
        queued = [pool.submit_concurrent(abs, -i) for i in range(1, 4)]
        assert pool.queued() == 3
        os.kill(victim_pid, signal.SIGKILL)
        with pytest.raises(BrokenProcessPool):
            victim.result(timeout=120)
        assert [job.result(timeout=120) for job in queued] == [1, 2, 3]
        with open(go, "w") as release:
            release.write("go")
        assert neighbour.result(timeout=120) == neighbour_pid  # the other worker's job lived on
    finally:
        pool.shutdown()


def test_shutdown_cancels_the_queue_and_ends_the_running_job(tmp_path: Any) -> None:
    from concurrent.futures import CancelledError

    from ird_ros.runtime.node_main import WorkerPool

    pool = WorkerPool(1)
    fifo = _fifo(tmp_path, "held")
    running = pool.submit_concurrent(_hold, fifo)
    _running_pid(fifo)
    waiting = pool.submit_concurrent(abs, -1)
    pool.shutdown()
    with pytest.raises(CancelledError):
        waiting.result(timeout=60)
    with pytest.raises(BrokenProcessPool):
        running.result(timeout=60)
    with pytest.raises(RuntimeError, match="shut down"):
        pool.submit_concurrent(abs, -1)


def _start_worker(node_pid: int) -> int:
    """Run a worker's initializer in a fresh spawned process told that its node is ``node_pid``;
    return the process's exit code."""
    import multiprocessing

    from ird_ros.runtime.workers import _worker_init

    process = multiprocessing.get_context("spawn").Process(target=_worker_init, args=(0, node_pid))
    process.start()
    process.join(60.0)
    assert process.exitcode is not None, "the worker's initializer did not return"
    return process.exitcode


def test_a_worker_whose_node_is_already_gone_exits_instead_of_living_on() -> None:
    # The node that started it is this process: the initializer arms the death signal and returns.
    assert _start_worker(os.getpid()) == 0
    # A worker whose node died before the initializer ran has been re-parented: its parent is not
    # the node it was started for, and it exits at once (PR_SET_PDEATHSIG would never fire).
    assert _start_worker(os.getpid() + 1_000_000) == 1
