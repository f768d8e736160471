"""ird_ros.runtime.offload: the one mapping of a worker job's outcome to a service answer.

With a controllable stand-in pool (busy accounting, every failure kind) and with a real
``WorkerPool`` driven by an rclpy executor (library errors, a dying worker and its replacement).
"""

from __future__ import annotations

import asyncio
import math
import operator
import os
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
