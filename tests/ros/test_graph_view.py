"""ird_ros.launch.graph_view: a node the readiness probe's graph reading keeps lacking is judged by
a fresh participant's reading (the upstream race it works around cannot be forced on demand, so
the probe's reading is made to lack /rob's services, as a dropped ros_discovery_info sample
leaves it, while rob itself serves them over real DDS)."""

from __future__ import annotations

import math
import time
from typing import Any

import pytest
from _standin_node import STANDIN_SPECS

from ird_ros.launch import GraphLauncher, LaunchError
from ird_ros.launch import graph_view, readiness


class _Blind:
    """The probe's node, except that its graph reading lists no service of /rob."""

    def __init__(self, node: Any) -> None:
        self._node = node

    def __getattr__(self, name: str) -> Any:
        return getattr(self._node, name)

    def get_service_names_and_types_by_node(self, name: str, namespace: str) -> list:
        found = self._node.get_service_names_and_types_by_node(name, namespace)
        return [] if name == "rob" else found


@pytest.fixture
def blind_probe(monkeypatch: pytest.MonkeyPatch) -> None:
    init = readiness.GraphProbe.__init__

    def blind_init(self: readiness.GraphProbe, *args: Any, **kwargs: Any) -> None:
        init(self, *args, **kwargs)
        self._node = _Blind(self._node)

    monkeypatch.setattr(readiness.GraphProbe, "__init__", blind_init)


def _until_the_probe_lacks_robs_services(graph: GraphLauncher) -> str:
    """What the launcher says it waits for, once the probe's own reading lists /rob and its
    publishers but (blind) none of its services: earlier, under load, it may lack /rob itself."""
    deadline = time.monotonic() + 60
    while True:
        with pytest.raises(LaunchError) as err:
            graph.wait_ready(timeout=1)
        text = str(err.value)
        if "rob (pid" in text and ": service /rob/stop not available\n" in text or time.monotonic() > deadline:
            return text


def test_a_node_the_probe_misreads_is_found_by_a_second_view(blind_probe: None, monkeypatch: pytest.MonkeyPatch) -> None:
    # No second view until the probe's reading lacks only what the blind probe hides, so that the
    # note names it (a second view asked earlier rightly names whatever the probe lacked then).
    monkeypatch.setattr(graph_view, "SECOND_VIEW_AFTER", math.inf)
    lines: list[str] = []
    with GraphLauncher(specs=STANDIN_SPECS, nodes=["world", "rob"], private_domain=True, output="quiet",
                       echo=lines.append) as graph:
        graph.wait_ready(timeout=60, nodes=["world"])
        text = _until_the_probe_lacks_robs_services(graph)
        assert ": service /rob/stop not available\n" in text, text
        monkeypatch.setattr(graph_view, "SECOND_VIEW_AFTER", 0.5)
        graph.wait_ready(timeout=60)
        rob = graph.pids()["rob"]
    notes = [line for line in lines if "a fresh participant's reading has it" in line and "rob (pid" in line]
    assert len(notes) == 1, lines  # once per process
    assert notes[0].startswith(f"[launcher] rob (pid {rob}): ") and "service /rob/stop not available" in notes[0]


def test_without_the_second_view_the_misread_node_never_gets_ready(blind_probe: None,
                                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(graph_view, "SECOND_VIEW_AFTER", math.inf)
    with GraphLauncher(specs=STANDIN_SPECS, nodes=["world", "rob"], private_domain=True, output="quiet") as graph:
        graph.wait_ready(timeout=60, nodes=["world"])
        text = _until_the_probe_lacks_robs_services(graph)
        assert graph.state("rob") == "starting"
    assert ": service /rob/stop not available\n" in text, text
    # the report shows what the node printed last: the stand-in got as far as serving
    assert "    last output: standin rob up" in text, text


class _TwoWorlds:
    """A graph reading with two nodes named /world, neither offering world's service or topics."""

    def get_node_names_and_namespaces(self) -> list[tuple[str, str]]:
        return [("launcher", "/"), ("world", "/"), ("world", "/")]

    def get_service_names_and_types_by_node(self, name: str, namespace: str) -> list:
        return []

    def get_publishers_info_by_topic(self, topic: str) -> list:
        return []


def test_a_second_node_of_the_same_name_is_named_in_what_is_missing(ros_domain: Any) -> None:
    """A node name twice in the graph (an older process's node in a reused domain, another graph)
    makes by-name queries read either node: the probe says so beside what is missing."""
    from ird_ros.graph import NODES_BY_NAME

    spec = NODES_BY_NAME["world"]
    probe = readiness.GraphProbe(ros_domain.domain_id, ros_domain.env())
    try:
        two = probe.missing(spec, 1, 0.0, {("world", "/")}, wait_topics=False, view=_TwoWorlds())
        assert f"service {spec.services[0]} not available" in two and two[-1] == "node /world 2 times in the graph"
        assert graph_view.graph_only(two)  # still decided by a graph reading (a fresh one may see one)
        one = _TwoWorlds()
        one.get_node_names_and_namespaces = lambda: [("world", "/")]  # type: ignore[method-assign]
        assert not [m for m in probe.missing(spec, 1, 0.0, {("world", "/")}, wait_topics=False, view=one)
                    if "times in the graph" in m]
    finally:
        probe.close()
