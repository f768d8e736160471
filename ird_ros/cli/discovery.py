"""What a running graph holds, as its own discovery shows it, and when that view is complete.

A new participant learns the graph piece by piece (a process, then its nodes' names, each node's
topics and services as DDS matches their endpoints), and DDS never says that it has seen
everything. :func:`settle` spins the client until

- some node other than the client is in the domain, and
- a node of the graph's records is, when the launcher's own nodes (``names.LAUNCHER_NODES``) are
  there (a launched graph runs launched nodes; DDS finds participants one by one, and a launcher
  helper or another client is often found before the graph's nodes), and
- every name in ``expect`` (nodes, topics, services, actions) is there, and
- every node of the graph's records (``ird_ros.graph.NODES``) that is there shows what the records
  say it publishes, reads and serves (and the navigator its action), and each topic it reads that
  a node of the default graph publishes has a publisher (the default graph is connected that way,
  so one of its nodes seen means all are waited for; a graph launched with fewer nodes waits until
  ``timeout`` and is reported incomplete), and the node of every topic endpoint is known, and
- nothing changed for ``quiet`` seconds (the ``ros2`` CLI's ``--spin-time`` without a daemon), or
  for ``FOREIGN_QUIET`` seconds when no node of the records is there (a graph of other nodes has no
  records to complete, so only a longer quiet covers the participants not found yet).
  Other processes are covered only by these rules: a caller that must see one names it in ``expect``.

Hidden names (a part starting with ``_``: action internals, ``ird``'s and ``ros2``'s own nodes) and
every node's standard ROS services and topics (parameters, type descriptions, ``/rosout``,
``/parameter_events``) are left out of a :class:`GraphView` unless asked for (``ird graph --all``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from ird_ros.graph import NODES, NODES_BY_NAME, names

__all__ = ["FOREIGN_QUIET", "GraphView", "snapshot", "missing_from_records", "missing_names", "settle", "is_hidden",
           "is_infrastructure", "NODE_ACTIONS"]

FOREIGN_QUIET = 3.0
"""Seconds without change that complete a view holding no node of the records (module docstring)."""

NODE_ACTIONS: dict[str, tuple[str, ...]] = {names.NODE_NAVIGATOR: (names.ACTION_NAVIGATE,)}
"""Actions each node of the records serves (a node record has no action field; the architecture
page's generator reads the same from the node modules)."""

_NODE_SERVICES = ("describe_parameters", "get_parameter_types", "get_parameters", "get_type_description",
                  "list_parameters", "set_parameters", "set_parameters_atomically",
                  # a managed node's lifecycle services and topic (ird_ros.runtime.lifecycle)
                  "change_state", "get_state", "get_available_states", "get_available_transitions",
                  "get_transition_graph", "transition_event")
_INFRA_TOPICS = ("/rosout", "/parameter_events")

Entry = tuple[str, tuple[str, ...]]


def is_hidden(name: str) -> bool:
    """Whether a node, topic or service name is hidden by ROS's convention (a part starts with ``_``)."""
    return any(part.startswith("_") for part in name.split("/") if part)


def is_infrastructure(name: str, node_names: set[str]) -> bool:
    """Whether ``name`` is a standard topic of every ROS process or a node's standard service or
    topic (parameters, type description, lifecycle)."""
    if name in _INFRA_TOPICS:
        return True
    head, _, tail = name.rpartition("/")
    return tail in _NODE_SERVICES and head in node_names


@dataclass(frozen=True)
class GraphView:
    """One look at the graph: full node names, and (name, types) of topics, services and actions."""

    nodes: tuple[str, ...]
    topics: tuple[Entry, ...]
    services: tuple[Entry, ...]
    actions: tuple[Entry, ...]
    published: frozenset[str] = frozenset()  # the topics with a publisher

    def shown(self, *, everything: bool = False) -> "GraphView":
        """Without hidden names and standard ROS infrastructure (unless ``everything``)."""
        if everything:
            return self
        nodes = set(self.nodes)

        def keep(entries: tuple[Entry, ...]) -> tuple[Entry, ...]:
            return tuple(e for e in entries if not is_hidden(e[0]) and not is_infrastructure(e[0], nodes))

        return GraphView(tuple(n for n in self.nodes if not is_hidden(n)), keep(self.topics), keep(self.services),
                         keep(self.actions), self.published)

    def topic_types(self, topic: str) -> tuple[str, ...]:
        """The types ``topic`` has in the graph (empty if it is not there)."""
        return next((types for name, types in self.topics if name == topic), ())


def _full_name(name: str, namespace: str) -> str:
    return f"{namespace.rstrip('/')}/{name}"


def snapshot(node: Any) -> GraphView:
    """The graph as ``node``'s participant sees it now (sorted)."""
    from rclpy.action.graph import get_action_names_and_types

    def entries(pairs: list[tuple[str, list[str]]]) -> tuple[Entry, ...]:
        return tuple(sorted((name, tuple(types)) for name, types in pairs))

    nodes = tuple(sorted(_full_name(n, ns) for n, ns in node.get_node_names_and_namespaces()))
    topics = entries(node.get_topic_names_and_types())
    published = frozenset(name for name, _ in topics if node.count_publishers(name))
    return GraphView(nodes, topics, entries(node.get_service_names_and_types()),
                     entries(get_action_names_and_types(node)), published)


_DEFAULT_PUBLISHED = frozenset(t for spec in NODES if spec.default for t in spec.publishes)


def missing_from_records(view: GraphView) -> list[str]:
    """What the records say the graph's nodes in ``view`` publish, read, serve or act on that ``view``
    lacks, and the topics they read from a node of the default graph that no publisher offers yet
    (its node not seen: a graph of fewer nodes keeps these missing)."""
    topics = {name for name, _ in view.topics}
    services = {name for name, _ in view.services}
    actions = {name for name, _ in view.actions}
    missing = []
    for full in view.nodes:
        spec = NODES_BY_NAME.get(full.lstrip("/"))
        if spec is None:
            continue
        missing += [f"{full}: topic {t}" for t in (*spec.publishes, *spec.subscribes) if t not in topics]
        missing += [f"{full}: service {s}" for s in spec.services if s not in services]
        missing += [f"{full}: action {a}" for a in NODE_ACTIONS.get(spec.name, ()) if a not in actions]
        missing += [f"{full} reads {t}: no publisher yet" for t in spec.subscribes
                    if t in _DEFAULT_PUBLISHED and t in topics and t not in view.published]
    return missing


def missing_names(view: GraphView, expect: Iterable[str]) -> list[str]:
    """The names of ``expect`` (a leading ``/`` optional) that are no node, topic, service or action
    of ``view``."""
    present = {*view.nodes, *(n for entries in (view.topics, view.services, view.actions) for n, _ in entries)}
    return [name for name in expect if (name if name.startswith("/") else f"/{name}") not in present]


def _unknown_owners(node: Any, view: GraphView) -> list[str]:
    """Topic endpoints whose node is not (yet) in ``view``'s node list."""
    nodes = set(view.nodes)
    unknown = []
    for topic, _ in view.topics:
        for info in (*node.get_publishers_info_by_topic(topic), *node.get_subscriptions_info_by_topic(topic)):
            owner = _full_name(info.node_name, info.node_namespace)
            if info.node_name and owner not in nodes:
                unknown.append(f"{owner}: an endpoint on {topic}")
    return unknown


@dataclass
class _Settling:
    own: str
    quiet: float
    expect: tuple[str, ...]
    note: Callable[[list[str]], None] | None = None
    note_after: float = 3.0
    view: GraphView | None = None
    changed_at: float = 0.0
    started: float = field(default_factory=time.monotonic)

    def others(self) -> list[str]:
        return [n for n in (self.view.nodes if self.view else ()) if n != self.own]

    def _other_names(self) -> set[str]:
        return {n.lstrip("/") for n in self.others()}

    def quiet_needed(self) -> float | None:
        """Seconds without change that complete the view now; None while it cannot be complete."""
        others = self._other_names()
        if not others:
            return None
        return self.quiet if others & NODES_BY_NAME.keys() else max(self.quiet, FOREIGN_QUIET)

    def launched_unseen(self) -> list[str]:
        """What a launched graph lacks while only the launcher's own nodes of it are found."""
        others = self._other_names()
        if others & set(names.LAUNCHER_NODES) and not others & NODES_BY_NAME.keys():
            return ["the launched nodes (only the launcher's own nodes are in the graph)"]
        return []

    def missing(self, node: Any) -> list[str]:
        assert self.view is not None
        return (missing_names(self.view, self.expect) or self.launched_unseen() or missing_from_records(self.view)
                or _unknown_owners(node, self.view))

    def done(self, node: Any) -> bool:
        view = snapshot(node)
        now = time.monotonic()
        if view != self.view:
            self.view, self.changed_at = view, now
        needed = self.quiet_needed()
        if needed is None:
            return False
        missing = self.missing(node)
        if missing and self.note is not None and now - self.started >= self.note_after:
            self.note(missing)
            self.note = None  # once
        return not missing and now - self.changed_at >= needed


def settle(ird: Any, *, timeout: float, quiet: float = 0.5, expect: Iterable[str] = (),
           note: Callable[[list[str]], None] | None = None) -> tuple[GraphView, list[str]]:
    """Spin ``ird`` (an ``IrdClient``) until its view of the graph is complete (module docstring), at
    most ``timeout`` s. Returns the view and what it still misses (empty when complete): first the
    names of ``expect`` not there, else what the records say and the view lacks. ``note(missing)``
    is called once if the view is still incomplete after 3 s.

    Raises:
        ClientTimeout: no node other than the client appeared within ``timeout``.
    """
    from ird_ros.client import ClientTimeout

    own = _full_name(ird.node.get_name(), ird.node.get_namespace())
    state = _Settling(own, quiet, tuple(expect), note)
    try:
        ird.spin_until(lambda: state.done(ird.node), timeout=timeout, what="a complete view of the graph")
    except ClientTimeout:
        if not state.others():
            raise
    assert state.view is not None
    return state.view, state.missing(ird.node)
