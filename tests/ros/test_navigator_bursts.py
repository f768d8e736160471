"""Bursts on the NavigateIrd action (/ird/navigate): every goal and cancel request is answered.

A navigator runs alone (no world node: its goal waits for ``/world/proxy`` for ``service_timeout``,
so it stays active for the whole test). Two client nodes (each its own DDS participant, as two
programs would be) then send a burst of goals at once: every one must be answered (rejected: a
goal is active); then a burst of cancels of the active goal: every one must be answered, and the
goal ends canceled.

With rclpy's default action QoS (depth 10 on the goal, cancel and result services, both ends)
most of a burst was never answered (issue 43: 157 of 200 goals, 666 of 700 cancels): the
server's request readers kept the last 10 requests, and every client's response reader, which
receives the responses to every client, the last 10 responses. Server and client now use
``ird_ros.runtime.guard.action_qos()``.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any, Callable, Iterator

import pytest
from rclpy.executors import SingleThreadedExecutor

from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess, spawn_node_process

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
NUM_CLIENTS = 2
GOALS_PER_CLIENT = 25  # 50 goals at once, as in the issue
CANCELS_PER_CLIENT = 100  # 200 cancels at once
DEADLINE = 60.0  # seconds for a whole burst to be answered (rejections take milliseconds each)


@pytest.fixture(scope="module")
def navigator(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    args = ["-m", "ird_ros.nodes.navigator", "--ros-args", "--params-file", PARAMS,
            "-p", "service_timeout:=600.0"]
    with spawn_node_process(args, domain=ros_domain, name="navigator", ready_text="navigator ready") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()


def _spin_until(executor: SingleThreadedExecutor, condition: Callable[[], bool], what: str,
                timeout: float = DEADLINE) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout:g} s waiting for {what}")
        executor.spin_once(timeout_sec=0.05)


def test_bursts_of_goals_and_cancels_are_all_answered(ros_ctx: Any, navigator: NodeProcess) -> None:
    import rclpy

    from ird_msgs.action import NavigateIrd
    from ird_ros.client.navigation import make_action_client

    executor = SingleThreadedExecutor(context=ros_ctx)
    nodes = [rclpy.create_node(f"nav_burst_{i}", context=ros_ctx) for i in range(NUM_CLIENTS)]
    try:
        for node in nodes:
            executor.add_node(node)
        clients = [make_action_client(node) for node in nodes]
        _spin_until(executor, lambda: all(c.server_is_ready() for c in clients), "the action server")
        first = clients[0].send_goal_async(NavigateIrd.Goal(method="maxent_z", mode="per_step",
                                                            baseline="training_features"))
        _spin_until(executor, first.done, "the answer to the first goal")
        active = first.result()
        assert active.accepted

        goals = [c.send_goal_async(NavigateIrd.Goal(method="maxent_z", mode="per_step", seed=i))
                 for c in clients for i in range(GOALS_PER_CLIENT)]
        _spin_until(executor, lambda: all(f.done() for f in goals),
                    f"answers to {len(goals)} goals (answered: {sum(f.done() for f in goals)})")
        assert not any(f.result().accepted for f in goals)  # one goal at a time

        # Cancels of the active goal, from its own client and from the other one (any client may cancel).
        cancels = [c._cancel_goal_async(active) for c in clients for _ in range(CANCELS_PER_CLIENT)]
        _spin_until(executor, lambda: all(f.done() for f in cancels),
                    f"answers to {len(cancels)} cancels (answered: {sum(f.done() for f in cancels)})")
        accepted = [f for f in cancels if any(bytes(g.goal_id.uuid) == bytes(active.goal_id.uuid)
                                              for g in f.result().goals_canceling)]
        assert accepted  # at least the first cancel reached the goal while it was active
        result = active.get_result_async()
        _spin_until(executor, result.done, "the canceled goal's result")
        assert result.result().result.status == "canceled", result.result().result.message
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()
