"""What every ``ird`` verb shares: the parser (one-line errors), the domain options, errors with
their exit status, and the client node that joins the graph's domain.

Exit status (``ird_ros.cli`` module docstring): :data:`EXIT_OK`, :data:`EXIT_FAILED` (no graph, a goal
or call that did not succeed), :data:`EXIT_USAGE` (bad input, named), :data:`EXIT_INTERRUPTED` (Ctrl-C).
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys
from typing import Any, Iterator, NoReturn

from ird_ros.arg_types import seconds, seconds_or_zero
from ird_ros.graph.domains import DOMAIN_ID_MAX, check_domain_id, domain_banner

__all__ = [
    "EXIT_OK",
    "EXIT_FAILED",
    "EXIT_USAGE",
    "EXIT_INTERRUPTED",
    "CliError",
    "CliParser",
    "add_domain_options",
    "add_spin_time",
    "resolve_domain",
    "client",
    "no_graph",
    "say",
    "restore_sigint",
    "waiting_note",
]

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130

DEFAULT_TIMEOUT = 30.0
"""Seconds a verb waits to discover the graph (and what it asks for) before it gives up."""


class CliError(Exception):
    """A failure to report as one line ``ird VERB: message`` with exit status ``code``."""

    def __init__(self, message: str, code: int = EXIT_FAILED) -> None:
        super().__init__(message)
        self.code = code


class CliParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line naming the option (exit 2), not usage + error."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _domain_id(text: str) -> int:
    try:
        return check_domain_id(text, "--domain-id")
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc).removeprefix("--domain-id ")) from None


def add_spin_time(parser: argparse.ArgumentParser, what: str) -> None:
    """``--spin-time S``: seconds without a change before the view of the graph counts as complete."""
    parser.add_argument("--spin-time", type=seconds_or_zero, default=0.5, metavar="S",
                        help=f"seconds without a change in the graph before {what} (default 0.5)")


def add_domain_options(parser: argparse.ArgumentParser, *, timeout: float | None = DEFAULT_TIMEOUT) -> None:
    """``--domain-id N`` (the graph's domain) and, unless ``timeout`` is None, ``--timeout S`` (discovery)."""
    parser.add_argument("--domain-id", type=_domain_id, default=None, metavar="N",
                        help=f"ROS domain of the graph, 0..{DOMAIN_ID_MAX}, as the launcher printed it "
                             "(default: ROS_DOMAIN_ID, else 0)")
    if timeout is None:
        return
    parser.add_argument("--timeout", type=seconds, default=timeout, metavar="S",
                        help=f"seconds to discover the graph before giving up with exit 1 (default {timeout:g})")


def resolve_domain(args: argparse.Namespace) -> int:
    """``--domain-id``, else ``ROS_DOMAIN_ID`` (checked: :class:`CliError` exit 2 naming it), else 0."""
    if args.domain_id is not None:
        return int(args.domain_id)
    try:
        return check_domain_id(os.environ.get("ROS_DOMAIN_ID") or 0, "ROS_DOMAIN_ID")
    except ValueError as exc:
        raise CliError(str(exc), EXIT_USAGE) from None


def say(text: str) -> None:
    """One line on stderr (the banner, notes, errors: stdout is the verb's output)."""
    print(text, file=sys.stderr, flush=True)


@contextlib.contextmanager
def client(args: argparse.Namespace, verb: str) -> Iterator[Any]:
    """An ``IrdClient`` in the verb's domain (node ``_ird_<verb>_<pid>``: hidden, as ``ros2``'s own),
    after printing the domain banner on stderr.

    The client's node belongs to one single-threaded executor for the verb's lifetime, which every
    wait spins (``ird_ros.waits.spin_until`` spins the node's executor). It is built before the verb
    prints anything a person answers with Ctrl-C: a SIGINT inside an executor's constructor (a
    temporary one per wait, otherwise) leaves a half-built object whose ``__del__`` prints a traceback.
    """
    from rclpy.executors import SingleThreadedExecutor

    from ird_ros.client import IrdClient

    domain = resolve_domain(args)
    say(domain_banner(domain, "searched for the graph"))
    with IrdClient(domain, node_name=f"_ird_{verb}_{os.getpid()}") as ird:
        executor = SingleThreadedExecutor(context=ird.node.context)
        try:
            executor.add_node(ird.node)
            yield ird
        finally:
            executor.remove_node(ird.node)
            executor.shutdown()


def no_graph(domain_id: int, what: str) -> CliError:
    """Exit 1, one line: ``what`` was not found in ``domain_id``, and how to pick the graph's domain."""
    return CliError(f"{what} in ROS_DOMAIN_ID={domain_id}: start one there (ird-launch --domain-id {domain_id}) "
                    "or pass the domain a launcher printed (--domain-id N, or export ROS_DOMAIN_ID=N)")


def waiting_note(verb: str, timeout: float) -> Any:
    """A ``discovery.settle`` note: one stderr line saying what the view of the graph still lacks."""
    def note(missing: list[str]) -> None:
        shown = "; ".join(missing[:4]) + (f"; and {len(missing) - 4} more" if len(missing) > 4 else "")
        say(f"ird {verb}: waiting (up to --timeout {timeout:g} s) for: {shown}")
    return note


def restore_sigint() -> None:
    """Ctrl-C raises ``KeyboardInterrupt`` even when the shell started this process with SIGINT
    ignored (``&`` in a non-interactive shell); leaves a handler of the caller's (tests) alone."""
    with contextlib.suppress(ValueError):  # not the main thread: leave signals alone
        if signal.getsignal(signal.SIGINT) in (signal.SIG_IGN, signal.SIG_DFL):
            signal.signal(signal.SIGINT, signal.default_int_handler)
