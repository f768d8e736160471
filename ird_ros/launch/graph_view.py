"""A second reading of the ROS graph, from a fresh DDS participant, for a node the readiness
probe's own reading keeps lacking.

Why. rmw_fastrtps (Jazzy) learns which node owns which endpoint from ``ros_discovery_info``
messages: each participant publishes its whole node-and-endpoint list again after every entity it
creates. The reader of that topic keeps one sample for all writers together (KEEP_LAST 1, no
key), so when two participants' lists arrive together one of them can be dropped, and the
reader's graph keeps that participant's older list until it creates another entity
(ros2/rmw_fastrtps#792: "some services are discovered, some not"). A node built from one burst
of entities never publishes again, so the probe's reading would stay wrong. (The CI failure first
read as this race had another cause, a destroyed lifecycle node left in a reused domain: see
``ird_ros.runtime.lifecycle.ManagedNode.destroy_node``; the race is upstream's report, not
reproduced here.)

A participant opened later receives every writer's last list afresh (the topic is transient
local), so ``SecondView`` opens one (node ``launcher_view``) when a starting node has lacked only
graph entries (not in the graph, a service, a publisher) for ``SECOND_VIEW_AFTER`` seconds, asks
it once it is ``SETTLE`` seconds old, and replaces it every ``LIFETIME`` seconds while some node
still needs it (its own reading can lose a list the same way, independently). It is closed as
soon as no starting node needs it. Only the graph listing comes from it: what a node published
(ready topics, the recorder's counts) is still judged by the probe's subscriptions.

Graph caches are filled by DDS's own threads, so the view's node is never spun.
"""

from __future__ import annotations

import time
from typing import Any, Callable, Mapping

from ird_ros.graph import names
from ird_ros.launch.liveness import _close_participant, _open_participant

__all__ = ["GRAPH_ITEMS", "LIFETIME", "SECOND_VIEW_AFTER", "SETTLE", "VIEW_NODE", "SecondView", "graph_only"]

VIEW_NODE = names.NODE_LAUNCHER_VIEW
SECOND_VIEW_AFTER = 5.0
"""Seconds a starting node may lack only graph entries before a second view is asked."""
SETTLE = 1.0
"""Seconds a new view gets to discover the graph before it is asked."""
LIFETIME = 15.0
"""Seconds after which a view still needed is replaced by a new one."""
GRAPH_ITEMS = ("node /", "service ", "no publisher of ")
"""Beginnings of the readiness probe's answers (``GraphProbe.missing``) that a graph listing decides."""


def graph_only(missing: list[str]) -> bool:
    """Whether ``missing`` is non-empty and names only graph entries (``GRAPH_ITEMS``)."""
    return bool(missing) and all(item.startswith(GRAPH_ITEMS) for item in missing)


class SecondView:
    """At most one fresh participant reading the graph (see the module docstring); one thread uses it.

    Args:
        domain_id, env: the graph's domain and the children's environment.
        settle, lifetime: ``SETTLE`` and ``LIFETIME`` (seconds).
        clock: monotonic seconds (tests may pass their own).
    """

    def __init__(self, domain_id: int, env: Mapping[str, str], *, settle: float = SETTLE,
                 lifetime: float = LIFETIME, clock: Callable[[], float] = time.monotonic) -> None:
        self._domain_id, self._env = domain_id, dict(env)
        self._settle, self._lifetime, self._clock = settle, lifetime, clock
        self._open: tuple[Any, Any, Any] | None = None
        self._opened_at = 0.0
        self._asked = False
        self.opened = 0
        """How many views were opened so far."""

    def node(self) -> Any | None:
        """The view's node once it is ``settle`` s old (opening one if none is open), else None."""
        self._asked = True
        if self._open is None:
            self._open = _open_participant(VIEW_NODE, self._domain_id, self._env)
            self._opened_at = self._clock()
            self.opened += 1
        return self._open[1] if self._clock() - self._opened_at >= self._settle else None

    def present(self) -> set[tuple[str, str]]:
        """``(name, namespace)`` of every node in the view's graph (empty while none is open)."""
        return set(self._open[1].get_node_names_and_namespaces()) if self._open is not None else set()

    def tick(self) -> None:
        """End of one check: close the view if nothing asked for it since the last tick, replace it
        (close; the next ``node()`` opens a new one) when it is ``lifetime`` s old."""
        if self._open is not None and (not self._asked or self._clock() - self._opened_at >= self._lifetime):
            self.close()
        self._asked = False

    def close(self) -> None:
        if self._open is not None:
            _close_participant(*self._open)
            self._open = None
