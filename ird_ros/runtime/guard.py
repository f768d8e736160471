"""No callback ends a node: every service, subscription, timer and action callback runs in a guard.

rclpy re-raises an exception of any callback out of ``executor.spin()`` (``Executor.spin_once``
raises ``handler.exception()``), which ends the node process: one malformed request would take a
service down for every client. A :class:`GuardedNode` wraps every callback it creates, and the
ones rclpy itself created before (``~/get_type_description``):

- a service callback (plain or ``async``) that raises is answered with a fresh response,
  ``success: false`` and ``message`` = the exception's text for a ``ValueError`` (by the
  project's convention it starts with the field's name: ``beta: ...``) or ``internal error:
  <Type>: <text>`` for anything else (logged with its traceback); a handler that returns
  something other than its response type is answered the same way;
- a subscription or timer callback that raises is logged; the message (tick) is dropped;
- :func:`guarded_action_server` builds an ``ActionServer`` whose goal and cancel callbacks reject
  on an exception and whose execute callback aborts the goal with a result saying why.

Failure messages (raised or returned) are at most :data:`MAX_MESSAGE` characters (a request may
echo a huge field back).
``KeyboardInterrupt``, ``SystemExit``, ``GeneratorExit`` (a pending coroutine closed at shutdown)
and rclpy's ``ExternalShutdownException`` pass through: they end the node on purpose. :func:`unguarded_callbacks` lists what a node left unguarded.
"""

from __future__ import annotations

import functools
import inspect
import time
import traceback
from typing import Any, Callable

from rclpy.node import Node

__all__ = ["MAX_MESSAGE", "GuardedNode", "guard_service", "guard_callback", "guarded_action_server",
           "is_guarded", "unguarded_callbacks", "failure_text"]

#: Longest ``message`` of a failure answer, in characters (the rest is cut and counted).
MAX_MESSAGE = 2000

_MARK = "__ird_guarded__"


def _passes(exc: BaseException) -> bool:
    """Exceptions that end the node on purpose (never turned into answers); ``GeneratorExit`` is
    how a coroutine callback still waiting is closed when its node shuts down mid-goal."""
    from rclpy.executors import ExternalShutdownException

    return isinstance(exc, (ExternalShutdownException, KeyboardInterrupt, SystemExit, GeneratorExit))


def failure_text(exc: BaseException) -> str:
    """The answer's message for ``exc``: a ValueError's own text, else ``internal error: ...``;
    cut to :data:`MAX_MESSAGE` characters."""
    text = str(exc) if isinstance(exc, ValueError) else f"internal error: {type(exc).__name__}: {exc}"
    if len(text) > MAX_MESSAGE:
        text = f"{text[:MAX_MESSAGE]}... ({len(text)} characters)"
    return text


def _mark(wrapper: Callable, original: Callable) -> Callable:
    functools.update_wrapper(wrapper, original, assigned=("__name__", "__qualname__", "__doc__"))
    setattr(wrapper, _MARK, True)
    return wrapper


def is_guarded(callback: Any) -> bool:
    """Whether ``callback`` is one of this module's wrappers."""
    return bool(getattr(callback, _MARK, False))


def _log_error(logger: Any, what: str, exc: BaseException) -> None:
    if logger is not None:
        logger.error(f"{what}: {type(exc).__name__}: {exc}\n{''.join(traceback.format_exception(exc))}")


def guard_service(callback: Callable, logger: Any, name: str,
                  on_answer: "Callable[[], None] | None" = None) -> Callable:
    """``callback(request, response)`` whose exceptions become a ``success: false`` answer;
    ``on_answer()`` runs once the answer (either kind) is ready to be sent."""
    if is_guarded(callback):
        return callback

    def answered(result: Any) -> Any:
        if on_answer is not None:
            on_answer()
        return result

    def failed(response: Any, exc: BaseException) -> Any:
        fresh = type(response)()
        if hasattr(fresh, "success"):
            fresh.success = False
        if hasattr(fresh, "message"):
            fresh.message = failure_text(exc)
        if not isinstance(exc, ValueError):
            _log_error(logger, f"{name} failed", exc)
        return fresh

    def checked(response: Any, result: Any) -> Any:
        if not isinstance(result, type(response)):
            return failed(response, TypeError(f"the handler returned {type(result).__name__}, not a response"))
        message = getattr(result, "message", None)
        if getattr(result, "success", True) is False and isinstance(message, str) and len(message) > MAX_MESSAGE:
            result.message = f"{message[:MAX_MESSAGE]}... ({len(message)} characters)"
        return result

    if inspect.iscoroutinefunction(callback):
        async def guarded_async(request: Any, response: Any) -> Any:
            try:
                return answered(checked(response, await callback(request, response)))
            except BaseException as exc:  # noqa: BLE001 - any failure is an answer (see the module doc)
                if _passes(exc):
                    raise
                return answered(failed(response, exc))

        return _mark(guarded_async, callback)

    def guarded(request: Any, response: Any) -> Any:
        try:
            return answered(checked(response, callback(request, response)))
        except BaseException as exc:  # noqa: BLE001 - any failure is an answer (see the module doc)
            if _passes(exc):
                raise
            return answered(failed(response, exc))

    return _mark(guarded, callback)


def guard_callback(callback: Callable, logger: Any, name: str, on_error: Any = None) -> Callable:
    """A subscription, timer or action callback whose exceptions are logged; the wrapper returns
    ``on_error(args...)`` then (``None`` without it). Keeps the callback's arity (rclpy inspects
    it: a subscription callback takes the message, or the message and its info)."""
    if is_guarded(callback):
        return callback

    def handle(exc: BaseException, args: tuple) -> Any:
        if _passes(exc):
            raise exc
        _log_error(logger, f"{name} failed", exc)
        return on_error(*args) if on_error is not None else None

    if inspect.iscoroutinefunction(callback):
        async def guarded_async(*args: Any) -> Any:
            try:
                return await callback(*args)
            except BaseException as exc:  # noqa: BLE001 - logged, the node keeps spinning
                return handle(exc, args)

        wrapper: Callable = guarded_async
    else:
        def guarded(*args: Any) -> Any:
            try:
                return callback(*args)
            except BaseException as exc:  # noqa: BLE001 - logged, the node keeps spinning
                return handle(exc, args)

        wrapper = guarded
    # Same signature as the callback, so rclpy's arity checks see what the callback takes.
    with_signature = _mark(wrapper, callback)
    try:
        with_signature.__signature__ = inspect.signature(callback)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        pass
    return with_signature


class GuardedNode(Node):
    """An rclpy ``Node`` whose services, subscriptions and timers are guarded (module doc).

    ``last_answer`` is the ``time.monotonic()`` at which a service created with
    ``create_service`` last had its answer ready (``None`` before the first): ``run_node`` keeps
    the node's participant alive for a moment after it (``ANSWER_LINGER``). rclpy's own
    services (parameters, type descriptions) do not count.
    """

    def __init__(self, node_name: str, **kwargs: Any) -> None:
        self.last_answer: float | None = None
        self._own_services = False  # rclpy's __init__ creates its parameter services through create_service
        super().__init__(node_name, **kwargs)
        self._own_services = True
        for service in self.services:  # created by rclpy itself, not through create_service
            if not is_guarded(service.callback):
                service.callback = guard_service(service.callback, self.get_logger(), service.srv_name)

    def create_service(self, srv_type: Any, srv_name: str, callback: Callable, **kwargs: Any) -> Any:
        on_answer = self._answered if self._own_services else None
        guarded = guard_service(callback, self.get_logger(), srv_name, on_answer=on_answer)
        return super().create_service(srv_type, srv_name, guarded, **kwargs)

    def _answered(self) -> None:
        self.last_answer = time.monotonic()

    def create_subscription(self, msg_type: Any, topic: str, callback: Callable, qos_profile: Any,
                            **kwargs: Any) -> Any:
        guarded = guard_callback(callback, self.get_logger(), f"subscription {topic}")
        return super().create_subscription(msg_type, topic, guarded, qos_profile, **kwargs)

    def create_timer(self, timer_period_sec: float, callback: Callable, *args: Any, **kwargs: Any) -> Any:
        guarded = guard_callback(callback, self.get_logger(), f"timer {getattr(callback, '__name__', callback)}")
        return super().create_timer(timer_period_sec, guarded, *args, **kwargs)


def action_qos() -> dict[str, Any]:
    """The QoS keyword arguments of an IRD action's three services (goal, cancel, result), for
    ``ActionServer`` and ``ActionClient`` alike: ``ird_ros.runtime.offload.service_qos()`` (reliable,
    keep last ``SERVICE_QUEUE_DEPTH``). rclpy's default keeps 10 requests in the server's readers
    and 10 responses in each client's reader (which receives the responses to every client of the
    action): a burst of 50 goals lost most of its answers (issue 43)."""
    from ird_ros.runtime.offload import service_qos

    return {f"{kind}_service_qos_profile": service_qos() for kind in ("goal", "cancel", "result")}


def guarded_action_server(node: Any, action_type: Any, action_name: str, *, execute_callback: Callable,
                          goal_callback: Callable, cancel_callback: Callable, **kwargs: Any) -> Any:
    """An ``rclpy.action.ActionServer`` whose callbacks are guarded: an exception in the goal or
    cancel callback rejects; in the execute callback it aborts the goal (if still active) and the
    result's ``status`` / ``message`` (when the result has them) say ``aborted`` / ``internal error``.
    Its goal, cancel and result services use :func:`action_qos` unless ``kwargs`` name their own
    (a client needs the same depth: ``ird_ros.client.navigation.make_action_client``)."""
    from rclpy.action import ActionServer, CancelResponse, GoalResponse

    logger = node.get_logger()

    def aborted(goal_handle: Any) -> Any:
        try:
            if goal_handle.is_active:
                goal_handle.abort()
        except Exception as exc:  # noqa: BLE001 - the goal may be finished already
            _log_error(logger, f"{action_name}: could not abort the goal", exc)
        result = action_type.Result()
        if hasattr(result, "status"):
            result.status = "aborted"
        if hasattr(result, "message"):
            result.message = "internal error: the goal failed (see the node's log)"
        return result

    return ActionServer(
        node, action_type, action_name,
        execute_callback=guard_callback(execute_callback, logger, f"{action_name} execute", aborted),
        goal_callback=guard_callback(goal_callback, logger, f"{action_name} goal",
                                     lambda _goal: GoalResponse.REJECT),
        cancel_callback=guard_callback(cancel_callback, logger, f"{action_name} cancel",
                                       lambda _handle: CancelResponse.REJECT),
        handle_accepted_callback=guard_callback(lambda goal_handle: goal_handle.execute(), logger,
                                                f"{action_name} accepted", aborted),
        **{**action_qos(), **kwargs})


def unguarded_callbacks(node: Any) -> list[str]:
    """Every service, subscription, timer and action-server callback of ``node`` that is not
    guarded, as ``"<kind> <name>"`` (empty: nothing a request or message raises reaches the executor)."""
    from rclpy.action import ActionServer

    out = [f"service {s.srv_name}" for s in node.services if not is_guarded(s.callback)]
    out += [f"subscription {s.topic_name}" for s in node.subscriptions if not is_guarded(s.callback)]
    out += [f"timer {t.callback!r}" for t in node.timers if not is_guarded(t.callback)]
    for waitable in node.waitables:
        if isinstance(waitable, ActionServer):
            for attribute in ("_goal_callback", "_cancel_callback", "_execute_callback", "_handle_accepted_callback"):
                if not is_guarded(getattr(waitable, attribute)):
                    out.append(f"action {attribute.strip('_')}")
    return out
