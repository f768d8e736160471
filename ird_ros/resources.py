"""The files the stack reads at run time, found as package data through ``importlib.resources``.

``msgs_config/`` (top level of the repository) is the one source of truth: the DDS profile
(``dds/fastdds_localhost.xml``), the graph's parameter file (``params/graph.yaml``) and the
interface definitions (``ird_msgs/{msg,srv,action}``). Inside the package,
``ird_ros/msgs_config`` is a symbolic link to it in a checkout (and an editable install), and a
copy in a built wheel (``pyproject.toml``'s package data), so an installed ``ird-launch`` or
``ird-demo`` finds them from any working directory. The designer page's static files live in
``ird_ros/web/static``. Nothing here is ever written: outputs go to the working directory or
a path the user gives.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["CONFIG_DIR", "config_path", "dds_profile", "graph_params", "msg_root", "web_static_dir"]

CONFIG_DIR = "msgs_config"
"""The package-data folder of ``ird_ros`` that mirrors the repository's ``msgs_config/``."""


def _package_path(package: str, *parts: str) -> Path:
    # Installed wheels and checkouts are plain folders, so the Traversable is a real path (DDS
    # and rclpy need a file name, not a stream). Resolved: in a checkout the same file as
    # ``msgs_config/...`` (the name ``scripts/lib/ros_env.sh`` exports), not the link's.
    return Path(str(resources.files(package).joinpath(*parts))).resolve()


def config_path(*parts: str) -> Path:
    """``msgs_config/<parts>`` as shipped with ``ird_ros`` (e.g. ``config_path("params", "graph.yaml")``)."""
    return _package_path("ird_ros", CONFIG_DIR, *parts)


def dds_profile() -> Path:
    """The loopback-only Fast DDS profile (``ird_ros.graph.domains``)."""
    return config_path("dds", "fastdds_localhost.xml")


def graph_params() -> Path:
    """The graph's parameter file (``ird_ros.graph.PARAMS_FILE``, every node's defaults)."""
    return config_path("params", "graph.yaml")


def msg_root() -> Path:
    """The folder holding the interface packages' sources (``ird_msgs/msg/*.msg``, ...)."""
    return config_path()


def web_static_dir() -> Path:
    """The designer web page's static files (``index.html``, scripts, style)."""
    return _package_path("ird_ros.web", "static")
