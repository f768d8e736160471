"""A guarded coroutine callback (an action's execute, an async service) that is closed while it
waits, as rclpy's executor closes the tasks still pending when a node shuts down mid-goal, ends
quietly: ``GeneratorExit`` passes the guard (no "failed: GeneratorExit" traceback in the log, no
"coroutine ignored GeneratorExit")."""

from __future__ import annotations

import asyncio
from typing import Any

from ird_ros.runtime.guard import guard_callback, guard_service


class Log:
    def __init__(self) -> None:
        self.errors: list[str] = []

    def error(self, text: str) -> None:
        self.errors.append(text)


class _Pending:
    """An awaitable that never completes (the goal waits for Rob, a worker, an answer)."""

    def __await__(self) -> Any:
        yield self


def _close_mid_wait(coro: Any) -> None:
    assert isinstance(coro.send(None), _Pending)  # suspended in the callback's await
    coro.close()  # what shutting the executor down does to a task still pending


def test_closing_a_guarded_execute_callback_mid_goal_logs_nothing() -> None:
    log = Log()
    finally_ran: list[bool] = []

    async def execute(goal_handle: Any) -> str:
        try:
            await _Pending()
        finally:
            finally_ran.append(True)
        return "done"

    guarded = guard_callback(execute, log, "/ird/navigate execute", lambda _handle: "aborted")
    _close_mid_wait(guarded(object()))
    assert finally_ran == [True] and log.errors == []


def test_closing_a_guarded_async_service_mid_request_logs_nothing() -> None:
    log = Log()

    async def serve(request: Any, response: Any) -> Any:
        await _Pending()
        return response

    guarded = guard_service(serve, log, "/ird/infer")
    _close_mid_wait(guarded(object(), object()))
    assert log.errors == []


def test_a_real_failure_is_still_logged_and_answered() -> None:
    log = Log()

    async def execute(goal_handle: Any) -> str:
        raise RuntimeError("boom")

    guarded = guard_callback(execute, log, "/ird/navigate execute", lambda _handle: "aborted")
    assert asyncio.run(guarded(object())) == "aborted"
    assert len(log.errors) == 1 and "RuntimeError: boom" in log.errors[0]
