"""msgs_config/params/graph.yaml: one section per node, every parameter commented."""

from __future__ import annotations

from pathlib import Path

import yaml

GRAPH = Path(__file__).resolve().parents[1] / "msgs_config" / "params" / "graph.yaml"
NODES = {"world", "perception", "inference", "planner", "rob", "recorder"}


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
