"""Shared process entry point of the IRD nodes, and off-executor work for long computations.

``run_node(factory)`` is the ``main()`` of every node module::

    python -m ird_ros.<module> --ros-args --params-file msgs_config/params/graph.yaml

Life cycle and its invariants:

- Signals: rclpy is initialised with ``SignalHandlerOptions.NO`` (rclpy installs no handler of
  its own) and ``run_node`` installs one handler for SIGINT and SIGTERM, also when the process
  inherited SIGINT *ignored* (a process started with ``&`` from a non-interactive shell).
- Start-up (``rclpy.init``, ``factory()``, and for a managed node with ``autostart`` its
  configure and activate transitions, ``ird_ros.runtime.lifecycle``): the first signal raises
  ``KeyboardInterrupt``, so a slow start-up (worker warm-up) can be cut short; the node never
  served, exit 0. A factory that raises anything else (bad parameter, missing input), or a
  transition that fails, logs ``cannot start: ...``, exit 2. A managed node without
  ``autostart`` (the launcher's) spins unconfigured, waiting for its transitions.
- Serving: after start-up, a signal only *records* the request to stop: no
  exception is ever raised inside rclpy's executor or inside a callback, so the callback that
  is running when the signal arrives finishes (and answers). The main loop runs
  ``executor.spin_once(timeout_sec=0.1)`` until a stop was requested or the context was shut
  down externally. A Python signal handler runs on the main thread between two bytecodes: in a
  running callback it only records; while ``spin_once`` waits (in C) it runs when the wait
  returns, so the stop is acted on within 0.1 s of an idle node's signal.
- A node that answered a request of its own services within the last ``ANSWER_LINGER`` (1 s)
  waits, without serving, until that second has passed: its answer may still be on its way
  (:func:`linger_after_answer`).
- Clean-up runs with the executor idle (no callback executing, nothing waiting in a wait set):
  ``executor.shutdown()``, then a managed node's shutdown transition (deactivate, clean up),
  then ``node.destroy_node()`` (which ends the node's worker
  processes) only if the shutdown reported that no callback was outstanding, then
  ``rclpy.try_shutdown()``; exit 0. Further signals during clean-up are recorded and ignored.
- The process then ends with :func:`exit_process` (no interpreter finalisation).

``WorkerPool`` (:mod:`ird_ros.runtime.workers`, re-exported here) runs picklable functions in
worker processes and hands the result to an ``async`` rclpy callback as an awaitable rclpy Future,
so a long computation (MCMC, MILP) never blocks the executor: parameter services and other
callbacks keep being served while it runs.
Processes rather than threads because the MCMC holds the GIL in Python loops. Mechanics: the
service callback is a coroutine; ``await pool.submit(fn, ...)`` suspends it; the pool's
completion callback (a pool thread) sets the rclpy Future's result and wakes the executor
(``Executor.wake()``, a guard condition), and the executor resumes the coroutine on its own
thread. The executor re-checks a suspended coroutine only when it wakes up, so nothing polls.
The service must live in its own callback group (e.g. a ``ReentrantCallbackGroup``): rclpy
holds a callback's group until its coroutine finishes, so a suspended request in the node's
default (mutually exclusive) group would block the parameter services and every subscription.
"""

from __future__ import annotations

import contextlib
import faulthandler
import os
import signal
import sys
import time
from typing import Any, Callable, Sequence

from ird_ros.runtime.workers import BrokenProcessPool, WorkerPool

__all__ = ["StartupError", "run_node", "declare", "ANSWER_LINGER", "linger_after_answer", "WorkerPool",
           "BrokenProcessPool"]


class StartupError(Exception):
    """Raised by a node factory for a configuration error (logged, exit code 2)."""


def declare(
    node: Any,
    name: str,
    default: Any,
    description: str,
    *,
    min_value: float | None = None,
    max_value: float | None = None,
    choices: Sequence[str] | None = None,
    read_only: bool = False,
    check_choices: bool = True,
) -> Any:
    """Declare a parameter with a descriptor (description, range, allowed values); return its value.

    Ranges are enforced by rclpy (also for values from the params file); ``choices`` are checked
    here (rclpy has no enum constraint) and raise :class:`StartupError` (unless ``check_choices``
    is false: a managed node checks them when it is configured).
    """
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor

    descriptor = ParameterDescriptor(description=description, read_only=read_only)
    if choices is not None:
        descriptor.additional_constraints = "one of: " + ", ".join(choices)
    if min_value is not None or max_value is not None:
        if isinstance(default, bool):
            raise TypeError("a bool parameter has no range")
        if isinstance(default, int):
            descriptor.integer_range = [IntegerRange(
                from_value=int(min_value if min_value is not None else -(2**63)),
                to_value=int(max_value if max_value is not None else 2**63 - 1), step=0)]
        else:
            descriptor.floating_point_range = [FloatingPointRange(
                from_value=float(min_value if min_value is not None else -sys.float_info.max),
                to_value=float(max_value if max_value is not None else sys.float_info.max), step=0.0)]
    value = node.declare_parameter(name, default, descriptor).value
    if check_choices and choices is not None and value not in choices:
        raise StartupError(f"parameter {name}: must be one of {list(choices)}, got {value!r}")
    return value


class _StopRequest:
    """The SIGINT/SIGTERM handler of ``run_node`` and what it recorded.

    ``requested`` becomes True at the first signal and stays True. While ``interrupting`` (the
    start-up phase) the *first* signal also raises ``KeyboardInterrupt``; afterwards, and for
    every later signal, the handler only records, so it can never cut the clean-up short nor
    interrupt rclpy's executor.
    """

    def __init__(self) -> None:
        self.requested = False
        self.interrupting = True

    def __call__(self, signum: int, frame: Any) -> None:
        first = not self.requested
        self.requested = True
        if first and self.interrupting:
            raise KeyboardInterrupt(f"signal {signum}")


def run_node(factory: Callable[[], Any], args: Sequence[str] | None = None) -> int:
    """Create a node with ``factory()`` (after ``rclpy.init(args=args)``) and spin it until
    SIGINT/SIGTERM or an external shutdown (the life cycle in the module doc).

    Returns the process exit code: 0 after SIGINT/SIGTERM or an external shutdown, 2 if the
    factory raised (e.g. :class:`StartupError` for a bad parameter).
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    # A crash inside rclpy/DDS (seen rarely at shutdown under load) then leaves the Python
    # stacks of every thread in the node's output, where the launcher and the tests show it.
    faulthandler.enable()
    stop = _StopRequest()
    node = None
    executor = None
    try:
        signal.signal(signal.SIGINT, stop)
        signal.signal(signal.SIGTERM, stop)
        rclpy.init(args=list(sys.argv if args is None else args),
                   signal_handler_options=SignalHandlerOptions.NO)
        executor = SingleThreadedExecutor()
        try:
            node = factory()
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as exc:  # noqa: BLE001 - bad parameters, missing inputs: say why, exit 2
            rclpy.logging.get_logger("ird_ros").error(f"cannot start: {type(exc).__name__}: {exc}")
            return 2
        executor.add_node(node)
        if not _started(node):
            rclpy.logging.get_logger("ird_ros").error(f"cannot start: {node.transition_error}")
            return 2
        # From here on a signal only sets stop.requested (checked between two spin_once calls).
        stop.interrupting = False
        if not stop.requested:
            while not stop.requested and executor.context.ok():
                executor.spin_once(timeout_sec=0.1)
            linger_after_answer(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        stop.interrupting = False
        _clean_up(node, executor)
    return 0


def _started(node: Any) -> bool:
    """Bring ``node`` up as far as it goes on its own; False when a transition failed.

    A managed node (``ird_ros.runtime.lifecycle``) with ``autostart`` is configured and activated
    here (it logs ``<name> ready``); without it, it waits, unconfigured, for a lifecycle manager
    (the launcher). Any other node logs the readiness line ``<name> ready`` launchers and tests
    wait for.
    """
    if not hasattr(node, "trigger_activate"):  # not a lifecycle node
        node.get_logger().info(f"{node.get_name()} ready")
        return True
    if node.autostart:
        return start_up(node)
    node.get_logger().info(f"{node.get_name()} unconfigured: waiting for configure and activate "
                           f"(/{node.get_name()}/change_state)")
    return True


def start_up(node: Any) -> bool:
    """Configure and activate the managed ``node`` in this thread (``autostart``); False if a
    transition failed (``node.transition_error`` says why)."""
    from rclpy.lifecycle import TransitionCallbackReturn

    for what, trigger in (("configure", node.trigger_configure), ("activate", node.trigger_activate)):
        if trigger() != TransitionCallbackReturn.SUCCESS:
            if not node.transition_error:
                node.transition_error = f"{what} failed"
            return False
    return True


#: Seconds a stopping node keeps its DDS participant after its last answer (see
#: :func:`linger_after_answer`).
ANSWER_LINGER = 1.0


def linger_after_answer(node: Any, linger: float = ANSWER_LINGER) -> float:
    """Wait, without serving, until ``linger`` seconds after ``node.last_answer``; return the wait.

    rmw_fastrtps writes a service's answer without waiting for its acknowledgement, and rclpy
    offers no way to wait for one. A node that is destroyed right after answering removes its
    participant, and a client that learns of the removal before it has processed the answer
    drops the answer (a reader keeps data only from writers it knows). Keeping the participant
    for ``linger`` seconds lets a loaded client take the answer first.
    Nodes without ``last_answer`` (not a ``GuardedNode``), or whose last answer is older than
    ``linger``, do not wait.
    """
    last = getattr(node, "last_answer", None)
    if last is None:
        return 0.0
    remaining = last + linger - time.monotonic()
    if remaining <= 0:
        return 0.0
    time.sleep(remaining)
    return remaining


def _clean_up(node: Any, executor: Any) -> None:
    """Shut the (idle) executor down, destroy the node if nothing is outstanding, shut rclpy down."""
    import rclpy

    idle = True
    if executor is not None:
        try:
            idle = executor.shutdown(timeout_sec=5.0)
        except Exception as exc:  # noqa: BLE001 - say so; the process ends anyway
            idle = False
            rclpy.logging.get_logger("ird_ros").error(f"executor shutdown failed: {type(exc).__name__}: {exc}")
    if node is not None:
        if idle:
            if hasattr(node, "trigger_shutdown"):  # a managed node: deactivate and clean up first
                with contextlib.suppress(Exception):
                    node.trigger_shutdown()
            with contextlib.suppress(Exception):
                node.destroy_node()
        else:  # destroying entities a callback may still use is what crashes rclpy
            rclpy.logging.get_logger("ird_ros").warning(
                "a callback was still running at shutdown: the node is left to the process exit")
    with contextlib.suppress(Exception):
        rclpy.try_shutdown()


def exit_process(code: int) -> None:
    """End a node process with ``code`` right after ``run_node`` cleaned up.

    Skips the interpreter's finalisation: with the node, executor and context already shut
    down, letting Python tear down the remaining rclpy/DDS objects at exit occasionally
    crashed the process (SIGSEGV after a clean stop, seen in the perception tests).
    """
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


# --------------------------------------------------------------------------- worker processes
# WorkerPool lives in ird_ros.runtime.workers (one job per worker at a time); re-exported here.


class Arrivals:
    """Lets an async service callback wait, without blocking the executor, until a latched
    input arrives: under load a request can reach a node before DDS has delivered the latched
    map it defaults to, and a short bounded wait answers it instead of refusing it.

    ``notify()`` from the input's subscription callback; ``await wait(timeout)`` in the service
    callback (True when something arrived, False at the timeout).
    """

    def __init__(self, node: Any) -> None:
        self._node = node
        self._waiters: list[Any] = []

    def notify(self) -> None:
        waiters, self._waiters = self._waiters, []
        for future in waiters:
            if not future.done():
                future.set_result(True)

    async def wait(self, timeout: float) -> bool:
        from rclpy.task import Future

        future = Future()
        self._waiters.append(future)
        timer = self._node.create_timer(timeout, lambda: future.done() or future.set_result(False))
        try:
            return bool(await future)
        finally:
            self._node.destroy_timer(timer)
