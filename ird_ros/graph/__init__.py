"""The graph as data: node, topic and service names, the node table, ROS domains."""

from __future__ import annotations

from ird_ros.graph.nodes import (
    DEFAULT_NODES,
    NODES,
    NODES_BY_NAME,
    PARAMS_FILE,
    RECORDER_SPEC,
    NodeSpec,
)

__all__ = [
    "NodeSpec",
    "NODES",
    "NODES_BY_NAME",
    "DEFAULT_NODES",
    "PARAMS_FILE",
    "RECORDER_SPEC",
]
