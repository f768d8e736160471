"""Discovery with many participants in one domain (issue 30: a node dropped out of discovery
after bursts of clients).

With unicast discovery to 127.0.0.1 (``msgs_config/dds/fastdds_localhost.xml``) a participant
announces itself to the ports of participant ids ``0..maxInitialPeersRange-1``; one with a higher
id is found only by those it announces to. So two participants that both start after the range
is taken by live participants never find each other. This starts ``FILLERS`` participants (rclpy
contexts in this process: one participant each, a couple of seconds in all), then a node process,
then a client, and checks the client finds the node: with the former range of 32 it did not
(measured: not within 15 s), with the profile's range it does. The range itself is checked to
keep every announcement inside the domain's own ports.
"""

from __future__ import annotations

import contextlib
import re
import sys
from typing import Any

from ird_ros.graph.domains import DDS_PROFILE, DomainLease, ros_context
from ird_ros.testing import spawn_node_process
from ird_ros.waits import wait_for_node

FILLERS = 40  # more than the former range (32), well under the profile's
LATE_NODE = """
import rclpy
from rclpy.executors import ExternalShutdownException
rclpy.init()
node = rclpy.create_node("late_node")
print("late_node ready", flush=True)
try:
    rclpy.spin(node)
except (KeyboardInterrupt, ExternalShutdownException):
    pass
"""


def _peers_range() -> int:
    match = re.search(r"<maxInitialPeersRange>(\d+)</maxInitialPeersRange>", DDS_PROFILE.read_text())
    assert match is not None, f"{DDS_PROFILE} sets no maxInitialPeersRange"
    return int(match.group(1))


def test_the_peers_range_covers_bursts_and_stays_inside_the_domain_ports() -> None:
    peers = _peers_range()
    assert peers > FILLERS + 2
    # participant p of domain d: 7400 + 250 d + 10 + 2 p (metatraffic), + 11 + 2 p (user data);
    # the next domain's ports start 250 higher
    assert 11 + 2 * (peers - 1) < 250


def test_a_node_started_after_many_participants_is_found_by_a_later_client(ros_domain: DomainLease) -> None:
    import rclpy

    with contextlib.ExitStack() as stack:
        fillers: list[Any] = []
        for i in range(FILLERS):
            ctx = stack.enter_context(ros_context(ros_domain))
            fillers.append(rclpy.create_node(f"filler_{i}", context=ctx))
            stack.callback(fillers[-1].destroy_node)
        late = stack.enter_context(spawn_node_process(["-c", LATE_NODE], domain=ros_domain, name="late_node",
                                                      ready_text="late_node ready", python=sys.executable))
        client = rclpy.create_node("late_client", context=stack.enter_context(ros_context(ros_domain)))
        stack.callback(client.destroy_node)
        wait_for_node(client, "late_node", timeout=30.0, processes=[late])
        # and the first participants still find it too
        wait_for_node(fillers[0], "late_node", timeout=30.0, processes=[late])
