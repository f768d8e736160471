"""The live view: the graph's state for Foxglove or Lichtblick (docs/live_view.md), ROS-free.

- :mod:`ird_ros.viz.scene`: what is shown, as plain data (numpy only): terrain and risk grids,
  plan lines, Rob's trail, the posterior per terrain and the designer's question as JSON dicts;
- :mod:`ird_ros.viz.foxglove_view`: :class:`LiveView`, the Foxglove WebSocket server
  (foxglove-sdk) that publishes them on the channels of :data:`CHANNELS`.

The rclpy shell that feeds them is :mod:`ird_ros.nodes.viz`.
"""

from __future__ import annotations

from ird_ros.viz.foxglove_view import (
    CHANNELS,
    DEFAULT_ALLOWED_ORIGINS,
    DEFAULT_PORT,
    GRID_CHANNELS,
    JSON_CHANNELS,
    POSES_CHANNELS,
    SCENE_CHANNELS,
    LiveView,
    bind_warning,
    grid_message,
    line_primitive,
    port_in_use_message,
)
from ird_ros.viz.scene import (
    GridLayer,
    Line,
    RobTrail,
    no_posterior,
    no_query,
    plan_kind,
    plan_line,
    posterior_by_terrain,
    query_state,
    risk_layer,
    rob_status_state,
    terrain_layer,
)

__all__ = [
    "CHANNELS",
    "DEFAULT_PORT",
    "GRID_CHANNELS",
    "JSON_CHANNELS",
    "POSES_CHANNELS",
    "SCENE_CHANNELS",
    "LiveView",
    "DEFAULT_ALLOWED_ORIGINS",
    "bind_warning",
    "port_in_use_message",
    "grid_message",
    "line_primitive",
    "GridLayer",
    "Line",
    "RobTrail",
    "no_posterior",
    "no_query",
    "rob_status_state",
    "plan_kind",
    "plan_line",
    "posterior_by_terrain",
    "query_state",
    "risk_layer",
    "terrain_layer",
]
