"""msgs_config/params/graph.yaml: one section per node plus the launcher's, every parameter
commented, and every parameter one the node declares, with its type and (unless a listed
override) its default; the launcher's section repeats ``ird_ros.launch.LAUNCHER_DEFAULTS``."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import yaml

from ird_ros.launch import LAUNCHER_DEFAULTS, LAUNCHER_SECTION, plan_launch

GRAPH = Path(__file__).resolve().parents[1] / "msgs_config" / "params" / "graph.yaml"
NODES = {"world", "perception", "inference", "planner", "rob", "designer", "recorder", "viz", "navigator"}


def test_every_node_has_a_parameter_section() -> None:
    data = yaml.safe_load(GRAPH.read_text())
    assert NODES <= set(data), f"missing sections: {sorted(NODES - set(data))}"
    for node, section in data.items():
        assert set(section) == {"ros__parameters"}, node
        assert section["ros__parameters"], f"{node} has no parameters"


def test_every_parameter_is_commented() -> None:
    lines = GRAPH.read_text().splitlines()
    for i, line in enumerate(lines):
        stripped = line.strip()
        # parameter keys sit at indentation 4 under "node:\n  ros__parameters:"
        if line.startswith("    ") and not line.startswith("     ") and stripped and not stripped.startswith(("#", "-")):
            j = i - 1
            while j >= 0 and lines[j].startswith("    ") and not lines[j].strip().startswith("#") \
                    and not lines[j].strip().endswith(":"):
                j -= 1  # a group of related keys shares one comment (e.g. start_row/start_col)
            assert j >= 0 and lines[j].strip().startswith("#"), f"graph.yaml line {i + 1} has no comment: {stripped}"


# Deliberate differences between graph.yaml and the nodes' defaults: the recorder's defaults
# (record every topic, no output folder: refused) suit a bare `python -m ird_ros.nodes.recorder -p ...`,
# the graph records its own topics into a fresh runs/ folder.
OVERRIDES = {("recorder", "topics"), ("recorder", "output_dir")}


def _parameter_tables() -> dict[str, dict[str, Any]]:
    """{node name: its module's PARAMETERS}: what each node declares (ird_ros.runtime.node_params.declare_all)."""
    from ird_ros import graph
    from ird_ros.nodes import recorder

    modules = {spec.name: spec.module for spec in graph.NODES} | {recorder.NODE_NAME: "ird_ros.nodes.recorder"}
    assert set(modules) == NODES
    return {name: importlib.import_module(module).PARAMETERS for name, module in modules.items()}


def _ros_type(value: Any) -> type:
    """The Python type that stands for the ROS parameter type (string arrays: list or tuple)."""
    return list if isinstance(value, (list, tuple)) else type(value)


def test_graph_yaml_sets_declared_parameters_with_their_types_and_defaults() -> None:
    from ird_ros.runtime.node_params import Param

    data = yaml.safe_load(GRAPH.read_text())
    assert set(data) == NODES | {LAUNCHER_SECTION}
    tables = _parameter_tables()
    for node, section in data.items():
        if node == LAUNCHER_SECTION:
            continue  # not a node: test_launcher_section_repeats_the_launcher_defaults
        table = tables[node]
        assert table and all(isinstance(p, Param) for p in table.values()), node
        for key, value in section["ros__parameters"].items():
            assert key in table, f"graph.yaml sets {node}.{key}, which the node does not declare"
            default = table[key].default
            assert _ros_type(value) is _ros_type(default), (node, key, value, default)
            if isinstance(value, list):
                assert all(isinstance(v, str) for v in value), (node, key)
            same = (list(value) == list(default)) if isinstance(value, list) else value == default
            assert same != ((node, key) in OVERRIDES), (
                f"{node}.{key}: graph.yaml says {value!r}, the node's default is {default!r}"
                + (" (a listed override that no longer differs)" if same else ""))


def test_overrides_are_set_by_the_yaml() -> None:
    data = yaml.safe_load(GRAPH.read_text())
    for node, key in OVERRIDES:
        assert key in data[node]["ros__parameters"], (node, key)


def test_parameter_defaults_are_valid() -> None:
    """Every default lies in its own range and choices (the node would not start otherwise)."""
    for node, table in _parameter_tables().items():
        for key, p in table.items():
            if p.min_value is not None:
                assert p.default >= p.min_value, (node, key)
            if p.max_value is not None:
                assert p.default <= p.max_value, (node, key)
            if p.choices is not None:
                assert p.default in p.choices, (node, key)


def test_launcher_section_repeats_the_launcher_defaults() -> None:
    """Every launcher setting is in the file with its default's type and value, and a plan
    built from the file uses them."""
    section = yaml.safe_load(GRAPH.read_text())[LAUNCHER_SECTION]["ros__parameters"]
    assert set(section) == set(LAUNCHER_DEFAULTS)
    for key, default in LAUNCHER_DEFAULTS.items():
        value = section[key]
        assert _ros_type(value) is _ros_type(default), (key, value, default)
        assert (list(value) == list(default)) if isinstance(value, list) else value == default, key
    plan = plan_launch(params=GRAPH)
    assert plan.respawned == frozenset(section["respawn"])
    assert (plan.respawn_delay, plan.respawn_max_retries) == (section["respawn_delay"], section["respawn_max_retries"])
