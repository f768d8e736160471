"""``ird graph``: the nodes, topics, services and actions of the running graph.

    ird graph                 # every section, topics and services with their types
    ird graph topics -t       # one section, one name per line (``ros2 topic list [-t]``)
    ird graph --all           # also hidden names and every node's standard ROS services and topics
    ird graph --wait-for navigator,/ird/navigate   # first wait until these are in the graph

Waits until its view of the graph is complete (``ird_ros.cli.discovery.settle``): every node of the
records that runs shows what it publishes, reads and serves, what it reads from the default graph
has a publisher, every endpoint's node is known, and nothing changed for --spin-time seconds.
DDS never says it has shown everything: a script that needs a name names it with --wait-for (exit
1 naming what did not come within --timeout). A view still incomplete at --timeout (a graph of
fewer nodes than the default: --timeout 5 shortens the wait) is printed with a note on stderr
naming what is missing; no node at all: exit 1.

Managed (lifecycle) nodes are listed with their state, asked from ``/<node>/get_state``
(``/world  active``; ``unconfigured`` or ``inactive`` while the launcher has not activated them,
``?`` if the node did not answer within a second). ``--all`` also lists their lifecycle services.
"""

from __future__ import annotations

import argparse
import contextlib
from typing import Any

from ird_ros.cli import discovery
from ird_ros.cli.common import (
    EXIT_OK,
    CliError,
    add_domain_options,
    add_spin_time,
    client,
    no_graph,
    resolve_domain,
    say,
    waiting_note,
)

__all__ = ["add_parser", "run", "render", "SECTIONS"]

SECTIONS = ("nodes", "topics", "services", "actions")


def add_parser(verbs: Any) -> None:
    parser = verbs.add_parser("graph", help="list the nodes, topics, services and actions of the graph",
                              description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("section", nargs="?", choices=SECTIONS, default=None,
                        help="print only this section, one name per line (default: every section)")
    parser.add_argument("-t", "--show-types", action="store_true",
                        help="with a section: add each name's type, as NAME [TYPE]")
    parser.add_argument("-a", "--all", action="store_true",
                        help="also hidden names (_action internals, CLI nodes) and every node's standard "
                             "parameter and type-description services, /rosout and /parameter_events")
    add_spin_time(parser, "the view counts as complete")
    parser.add_argument("--wait-for", type=_names, default=(), metavar="NAME[,NAME...]",
                        help="first wait until each of these nodes, topics, services or actions is in the graph")
    add_domain_options(parser)
    parser.set_defaults(run=run)


def _names(text: str) -> tuple[str, ...]:
    return tuple(name.strip() for name in text.split(",") if name.strip())


def _entry(name: str, types: tuple[str, ...]) -> str:
    return f"{name} [{', '.join(types)}]"


def render(view: discovery.GraphView, section: str | None = None, *, show_types: bool = False,
           states: dict[str, str] | None = None) -> list[str]:
    """The lines ``ird graph`` prints for ``view``: every section with a header and counts, or one
    section's names (with ``show_types``, ``NAME [TYPE]``); ``states``: managed nodes' lifecycle states."""
    states = states or {}
    width = max((len(n) for n in view.nodes), default=0)

    def node_line(name: str) -> str:
        return f"{name.ljust(width)}  {states[name]}" if name in states else name

    if section == "nodes":
        return [node_line(n) for n in view.nodes]
    if section is not None:
        entries = getattr(view, section)
        return [_entry(n, t) if show_types else n for n, t in entries]
    lines = [f"nodes ({len(view.nodes)}):", *(f"  {node_line(n)}" for n in view.nodes)]
    for name in SECTIONS[1:]:
        entries = getattr(view, name)
        lines += [f"{name} ({len(entries)}):", *(f"  {_entry(n, t)}" for n, t in entries)]
    return lines


def run(args: argparse.Namespace) -> int:
    with client(args, "graph") as ird:
        try:
            view, missing = discovery.settle(ird, timeout=args.timeout, quiet=args.spin_time,
                                             expect=args.wait_for, note=waiting_note("graph", args.timeout))
        except TimeoutError:
            raise no_graph(resolve_domain(args), f"no node found within {args.timeout:g} s") from None
        absent = discovery.missing_names(view, args.wait_for)
        if absent:
            raise CliError(f"--wait-for: not in the graph of ROS_DOMAIN_ID={ird.domain_id} after {args.timeout:g} s: "
                           f"{', '.join(absent)}")
        if missing:
            say(f"ird graph: the view is incomplete after {args.timeout:g} s, missing: {'; '.join(missing)}")
        states = lifecycle_states(ird.node, view) if args.section in (None, "nodes") else {}
        for line in render(view.shown(everything=args.all), args.section, show_types=args.show_types,
                           states=states):
            print(line, flush=True)
    return EXIT_OK


def lifecycle_states(node: Any, view: discovery.GraphView, timeout: float = 1.0) -> dict[str, str]:
    """``{node: state label}`` of every node of ``view`` that serves ``<node>/get_state`` (all asked
    at once; ``?`` for one that did not answer within ``timeout`` seconds)."""
    from lifecycle_msgs.srv import GetState

    from ird_ros.waits import spin_until

    served = {name for name, _types in view.services}
    clients = {n: node.create_client(GetState, f"{n}/get_state") for n in view.nodes if f"{n}/get_state" in served}
    futures: dict[str, Any] = {}
    try:
        with contextlib.suppress(TimeoutError):
            spin_until(node, lambda: all(c.service_is_ready() for c in clients.values()), timeout=timeout)
        futures = {n: c.call_async(GetState.Request()) for n, c in clients.items() if c.service_is_ready()}
        with contextlib.suppress(TimeoutError):
            spin_until(node, lambda: all(f.done() for f in futures.values()), timeout=timeout)
        return {n: (str(futures[n].result().current_state.label) if n in futures and futures[n].done()
                    and futures[n].result() is not None else "?") for n in clients}
    finally:
        for c in clients.values():
            node.destroy_client(c)
