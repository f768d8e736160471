"""Shared pytest set-up: every ROS test talks only inside a private ROS domain.

- The whole session runs with loopback-only DDS (``ird_ros.graph.domains.dds_env``), a private
  ROS_LOG_DIR, and (if ROS_DOMAIN_ID was not set by scripts/test.sh) a leased domain.
- ``ros_domain`` (module scope) leases a further domain of its own for each test module
  (see ird_ros.testing.lease_domain) and points ROS_DOMAIN_ID at it while the module runs,
  so modules never see each other's nodes.
- ``ros_ctx`` / ``ros_node`` give an rclpy context and a node in that domain.
- Tests under tests/ros/ are marked ``ros`` automatically (``-m "not ros"`` skips them).
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Any, Iterator

import pytest

from ird_ros.graph.domains import DomainLease, dds_env, lease_domain, ros_context

_SESSION: dict[str, Any] = {}


def pytest_configure(config: pytest.Config) -> None:
    dds_env(os.environ)  # loopback-only DDS, as every entry point (ird_ros.graph.domains)
    if not os.environ.get("ROS_LOG_DIR"):
        tmp = tempfile.TemporaryDirectory(prefix="ird_pytest_ros_log_")
        _SESSION["log_tmp"] = tmp
        os.environ["ROS_LOG_DIR"] = tmp.name
    if not os.environ.get("ROS_DOMAIN_ID"):
        lease = lease_domain(log_dir=os.environ["ROS_LOG_DIR"])
        _SESSION["lease"] = lease
        os.environ["ROS_DOMAIN_ID"] = str(lease.domain_id)


def pytest_unconfigure(config: pytest.Config) -> None:
    lease = _SESSION.pop("lease", None)
    if lease is not None:
        lease.release()
    tmp = _SESSION.pop("log_tmp", None)
    if tmp is not None:
        tmp.cleanup()


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    ros_dir = Path(__file__).parent / "ros"
    for item in items:
        if ros_dir in Path(str(item.fspath)).parents:
            item.add_marker(pytest.mark.ros)


@pytest.fixture(scope="module")
def ros_domain() -> Iterator[DomainLease]:
    """A ROS domain leased for this test module; ROS_DOMAIN_ID and ROS_LOG_DIR point at it."""
    with lease_domain() as lease, pytest.MonkeyPatch.context() as mp:
        mp.setenv("ROS_DOMAIN_ID", str(lease.domain_id))
        mp.setenv("ROS_LOG_DIR", str(lease.log_dir))
        yield lease


@pytest.fixture(scope="module")
def ros_ctx(ros_domain: DomainLease) -> Iterator[Any]:
    """An initialised rclpy context in the module's domain."""
    with ros_context(ros_domain) as ctx:
        yield ctx


@pytest.fixture
def ros_node(ros_ctx: Any, request: pytest.FixtureRequest) -> Iterator[Any]:
    """A fresh rclpy node in the module's domain, destroyed after the test."""
    import rclpy

    name = "test_" + "".join(c if c.isalnum() else "_" for c in request.node.name)[:60]
    node = rclpy.create_node(name, context=ros_ctx)
    try:
        yield node
    finally:
        node.destroy_node()
