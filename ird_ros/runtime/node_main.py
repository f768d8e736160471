"""Shared process entry point of the IRD nodes, and off-executor work for long computations.

``run_node(factory)`` is the ``main()`` of every node module::

    python -m ird_ros.<module> --ros-args --params-file msgs_config/params/graph.yaml

It restores the default SIGINT handler (a process started with ``&`` from a non-interactive
shell inherits SIGINT *ignored*), makes SIGTERM behave like SIGINT, initialises rclpy with the
command line, creates the node, logs ``<name> ready`` and spins the node in a single-threaded
executor; on SIGINT/SIGTERM it shuts the executor down before destroying the node (whose
``destroy_node`` ends its worker processes) and exits 0. A node that cannot start (bad
parameter) logs ``cannot start: ...`` and exits 2.

``WorkerPool`` runs picklable functions in worker processes and hands the result to an
``async`` rclpy callback as an awaitable rclpy Future, so a long computation (MCMC, MILP) never
blocks the executor: parameter services and other callbacks keep being served while it runs.
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

import concurrent.futures
import contextlib
import faulthandler
import multiprocessing
import os
import signal
import sys
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable, Sequence

from ird_ros.launch.process_groups import set_parent_death_signal

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


def _worker_init(memory_limit: int = 0) -> None:  # pragma: no cover - runs in the worker process
    # Ctrl-C in a terminal signals the whole process group: the node ends its workers itself.
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if memory_limit > 0:
        # An allocation past the limit raises MemoryError in the job (answered as a failure);
        # the node and the other workers keep their memory.
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (memory_limit, memory_limit))
    # Die with the node, even if it is SIGKILLed (Linux PR_SET_PDEATHSIG).
    set_parent_death_signal(signal.SIGTERM)


def _warm(modules: Sequence[str]) -> int:  # pragma: no cover - runs in the worker process
    import importlib

    for name in modules:
        hook = getattr(importlib.import_module(name), "warm_up", None)
        if callable(hook):  # e.g. ird_core.mdp.warm_up: load the compiled passes now
            hook()
    return 0


class WorkerPool:
    """A ``ProcessPoolExecutor`` (spawn start method) whose results rclpy coroutines can await.

    ``max_workers`` computations run at once; further submissions queue in FIFO order.
    ``warm_modules`` are imported in every worker at start-up (the constructor waits for it), and
    their ``warm_up()`` called if they have one, so the first request does not pay for the
    process start, the imports or loading the compiled MDP passes (``ird_core.mdp.warm_up``).
    A worker that dies (``BrokenProcessPool``) is replaced on the next submit. ``memory_limit``
    (bytes, 0 = none) caps each worker's address space (``RLIMIT_AS``): a job that would exceed
    it gets ``MemoryError``.
    """

    def __init__(self, max_workers: int = 1, warm_modules: Sequence[str] = (), memory_limit: int = 0) -> None:
        if max_workers < 1:
            raise ValueError(f"max_workers must be >= 1, got {max_workers}")
        self._memory_limit = int(memory_limit)
        self._max_workers = int(max_workers)
        self._warm_modules = tuple(warm_modules)
        self._pool: concurrent.futures.ProcessPoolExecutor | None = None
        self._start()

    def _start(self) -> None:
        # spawn, not fork: the node process runs DDS threads that must not be forked.
        self._pool = concurrent.futures.ProcessPoolExecutor(
            max_workers=self._max_workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_worker_init,
            initargs=(self._memory_limit,),
        )
        if self._warm_modules:
            # Start every worker now and wait until it has imported the modules, so the node is
            # ready (and the first request fast) once the constructor returns.
            warming = [self._pool.submit(_warm, self._warm_modules) for _ in range(self._max_workers)]
            for future in warming:
                future.result(timeout=120.0)

    def submit_concurrent(self, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> concurrent.futures.Future:
        """Submit and return the ``concurrent.futures.Future`` (blocking callers, tests)."""
        if self._pool is None:
            raise RuntimeError("WorkerPool is shut down")
        try:
            return self._pool.submit(fn, *args, **kwargs)
        except BrokenProcessPool:
            self._kill()
            self._start()
            return self._pool.submit(fn, *args, **kwargs)

    def submit(self, executor: Any, fn: Callable[..., Any], *args: Any, **kwargs: Any) -> Any:
        """Submit ``fn(*args, **kwargs)``; return an awaitable ``rclpy.task.Future``.

        ``executor`` is the rclpy executor that runs the awaiting coroutine (``node.executor``);
        it is woken when the result is in. The Future's result is the function's return value,
        or it raises the function's exception (``BrokenProcessPool`` if the worker died).
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

    def _kill(self) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        # Python 3.11 has no public way to stop a running task: terminate the workers.
        processes = list((getattr(pool, "_processes", None) or {}).values())
        for proc in processes:
            with contextlib.suppress(Exception):
                proc.terminate()
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in processes:
            with contextlib.suppress(Exception):
                proc.join(2.0)

    def shutdown(self) -> None:
        """Cancel queued work, terminate running workers, return at once."""
        self._kill()


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
