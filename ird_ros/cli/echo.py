"""``ird echo TOPIC``: print the messages of a topic of the graph, its type discovered from the graph.

    ird echo /world/proxy --once              # the latest proxy (latched topics give it at once)
    ird echo /rob/status -n 5                 # five of Rob's statuses, then exit
    ird echo /world/proxy --field weights     # one field (a dotted path: header.stamp.sec)
    ird echo /world/test_features --no-arr    # arrays as <sequence of N values>

Each message is printed as YAML followed by ``---`` (``ros2 topic echo``'s layout); arrays longer
than --truncate-length are cut (``'...'``). The topic's type comes from the graph: a topic of the
graph's records (docs/architecture.md) is waited for up to --timeout (exit 1 if no node has it by
then), any other name until the view of the graph is complete (``ird graph``). Its QoS is the
graph's own for the graph's topics (latched ones give their latest message to a late reader,
``/ird/queries`` its recent history), else what its publishers offer (reliable and transient local
only when every publisher is). Without --once or -n it runs until Ctrl-C (exit 130).
A topic the graph does not have, or a field its type does not have: one line naming it, exit 2.
"""

from __future__ import annotations

import argparse
from typing import Any

from ird_ros.cli import discovery, messages
from ird_ros.cli.common import (
    EXIT_OK,
    EXIT_USAGE,
    CliError,
    add_domain_options,
    add_spin_time,
    client,
    no_graph,
    resolve_domain,
    say,
    waiting_note,
)
from ird_ros.graph import names

__all__ = ["add_parser", "run", "topic_name", "choose_qos"]


def _count(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number of messages, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"expected at least 1 message, got {value}")
    return value


def _length(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"expected a length >= 0, got {text!r}")
    return value


def add_parser(verbs: Any) -> None:
    parser = verbs.add_parser("echo", help="print the messages of a topic",
                              description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("topic", help="the topic, e.g. /world/proxy (a leading / may be left out)")
    count = parser.add_mutually_exclusive_group()
    count.add_argument("--once", action="store_const", const=1, dest="count", help="print one message and exit")
    count.add_argument("-n", "--count", type=_count, default=None, metavar="N", help="print N messages and exit")
    parser.add_argument("--field", default=None, metavar="PATH",
                        help="print only this field of each message, a dotted path (e.g. header.stamp)")
    parser.add_argument("--no-arr", action="store_true", help="print arrays as <sequence of N values>")
    parser.add_argument("--truncate-length", type=_length, default=128, metavar="L",
                        help="print at most L values of an array, then '...' (default 128; 0: every value)")
    add_spin_time(parser, "a topic that is not there counts as unknown")
    add_domain_options(parser)
    parser.set_defaults(run=run)


def topic_name(text: str) -> str:
    """``text`` as a full topic name (a leading ``/`` added); :class:`CliError` exit 2 if it is not one."""
    from rclpy.exceptions import InvalidTopicNameException
    from rclpy.validate_full_topic_name import validate_full_topic_name

    name = text if text.startswith("/") else f"/{text}"
    try:
        validate_full_topic_name(name)
    except InvalidTopicNameException as exc:
        reason = str(exc).split(": ", 1)[-1].splitlines()[0].rstrip(":")
        raise CliError(f"topic {text!r} is not a valid topic name: {reason}", EXIT_USAGE) from None
    return name


def choose_qos(node: Any, topic: str) -> Any:
    """The graph's QoS for its own topics; else reliable / transient local only if every publisher is
    (``ros2 topic echo``'s rule), keep last 10."""
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    if topic in names.TOPIC_QOS:
        kind = names.TOPIC_QOS[topic]
        return names.stream_qos(100) if kind == names.STREAM else names.qos_for(topic)
    offered = [info.qos_profile for info in node.get_publishers_info_by_topic(topic)]
    reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    latched = bool(offered) and all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    return QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)


def _discover_type(ird: Any, topic: str, args: argparse.Namespace) -> str:
    """The topic's type as the graph has it, waiting until it appears or the view is complete."""
    domain = resolve_domain(args)
    found: list[str] = []

    def appeared() -> bool:
        found[:] = discovery.snapshot(ird.node).topic_types(topic)
        return bool(found)

    if not appeared() and topic in names.TOPIC_TYPES:  # a topic of the graph's records: it may come late
        try:
            ird.spin_until(appeared, timeout=args.timeout, what=f"{topic} in the graph")
        except TimeoutError:
            raise no_graph(domain, f"no node publishes or reads {topic} within {args.timeout:g} s") from None
    elif not found:
        try:
            view, _ = discovery.settle(ird, timeout=args.timeout, quiet=args.spin_time,
                                       note=waiting_note("echo", args.timeout))
        except TimeoutError:
            raise no_graph(domain, f"no node found within {args.timeout:g} s to ask for {topic}") from None
        found[:] = view.topic_types(topic)
        if not found:
            known = [name for name, _ in view.shown().topics]
            raise CliError(f"unknown topic {topic}: no node in ROS_DOMAIN_ID={domain} publishes or reads it "
                           f"(its topics: {', '.join(known) or 'none'})", EXIT_USAGE)
    if len(found) > 1:
        say(f"ird echo: {topic} has several types in the graph ({', '.join(found)}); reading it as {found[0]}")
    return found[0]


def run(args: argparse.Namespace) -> int:
    topic = topic_name(args.topic)
    with client(args, "echo") as ird:
        type_name = _discover_type(ird, topic, args)
        try:
            msg_class = messages.message_class(type_name)
            if args.field is not None:
                messages.check_field(msg_class, args.field, type_name)
        except ValueError as exc:
            raise CliError(f"{topic}: {exc}", EXIT_USAGE) from None
        received: list[Any] = []
        subscription = ird.node.create_subscription(msg_class, topic, received.append, choose_qos(ird.node, topic))
        say(f"ird echo: reading {topic} [{type_name}]")
        printed = 0

        def print_new() -> bool:
            nonlocal printed
            while received and (args.count is None or printed < args.count):
                msg = received.pop(0)
                value = msg if args.field is None else messages.get_field(msg, args.field)
                print(messages.to_yaml(value, truncate=args.truncate_length, no_arr=args.no_arr), flush=True)
                print("---", flush=True)
                printed += 1
            return args.count is not None and printed >= args.count

        try:  # spins the verb's executor, built before this line (cli.common.client)
            ird.spin_until(print_new, timeout=float("inf"), what=f"messages on {topic}")
        finally:
            ird.node.destroy_subscription(subscription)
    return EXIT_OK
