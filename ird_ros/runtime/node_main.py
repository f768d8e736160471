"""Shared process entry point of the IRD nodes, and off-executor work for long computations.

``run_node(factory)`` is the ``main()`` of every node module::

    python -m ird_ros.<module> --ros-args --params-file msgs_config/params/graph.yaml

It restores the default SIGINT handler (a process started with ``&`` from a non-interactive
shell inherits SIGINT *ignored*), makes SIGTERM behave like SIGINT, initialises rclpy with the
command line, creates the node, logs ``<name> ready`` and spins the node in a single-threaded
executor; on SIGINT/SIGTERM it shuts the executor down before destroying the node (whose
``destroy_node`` ends its worker processes) and exits 0. A node that cannot start (bad
parameter) logs ``cannot start: ...`` and exits 2.

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
from typing import Any, Callable, Sequence

from ird_ros.runtime.workers import BrokenProcessPool, WorkerPool

__all__ = ["StartupError", "run_node", "declare", "WorkerPool", "BrokenProcessPool"]


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
) -> Any:
    """Declare a parameter with a descriptor (description, range, allowed values); return its value.

    Ranges are enforced by rclpy (also for values from the params file); ``choices`` are checked
    here (rclpy has no enum constraint) and raise :class:`StartupError`.
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
    if choices is not None and value not in choices:
        raise StartupError(f"parameter {name}: must be one of {list(choices)}, got {value!r}")
    return value


def _raise_keyboard_interrupt(signum: int, frame: Any) -> None:
    raise KeyboardInterrupt(f"signal {signum}")


def run_node(factory: Callable[[], Any], args: Sequence[str] | None = None) -> int:
    """Create a node with ``factory()`` (after ``rclpy.init(args=args)``) and spin it.

    Returns the process exit code: 0 after SIGINT/SIGTERM or an external shutdown, 2 if the
    factory raised (e.g. :class:`StartupError` for a bad parameter).
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

    # A crash inside rclpy/DDS (seen rarely at shutdown under load) then leaves the Python
    # stacks of every thread in the node's output, where the launcher and the tests show it.
    faulthandler.enable()
    # Before rclpy.init: rclpy's own handlers (which wake the executor) chain to these.
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, _raise_keyboard_interrupt)
    rclpy.init(args=list(sys.argv if args is None else args))
    node = None
    executor = None
    try:
        executor = SingleThreadedExecutor()
        try:
            node = factory()
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as exc:  # noqa: BLE001 - bad parameters, missing inputs: say why, exit 2
            rclpy.logging.get_logger("ird_ros").error(f"cannot start: {type(exc).__name__}: {exc}")
            return 2
        executor.add_node(node)
        # The readiness line launchers and tests wait for ("<name> ready").
        node.get_logger().info(f"{node.get_name()} ready")
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        # Ignore further signals while cleaning up, so a second Ctrl-C cannot cut it short.
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if executor is not None:
            with contextlib.suppress(Exception):
                executor.shutdown(timeout_sec=2.0)
        if node is not None:
            with contextlib.suppress(Exception):
                node.destroy_node()
        with contextlib.suppress(Exception):
            rclpy.try_shutdown()
    return 0


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
