"""The rob node over real DDS: executes published plans on the world's ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest
from nav_msgs.msg import Odometry
from nav_msgs.msg import Path as PathMsg

from ird_core.worlds import evaluation, lavaland
from ird_core.worlds.terrain import Terrain
from ird_msgs.msg import PlanInfo, RobStatus
from ird_ros import conversions as conv
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess
from ird_ros.testing import running_nodes as running
from ird_ros.waits import spin_until, wait_for_publishers, wait_for_subscribers

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
H, W, T = 8, 8, 10
SEED = 5
RESOLUTION, ORIGIN = 0.5, (0.0, 0.0)


@pytest.fixture(scope="module")
def graph(ros_domain: DomainLease) -> Iterator[list[NodeProcess]]:
    world_args = ["-m", "ird_ros.nodes.world", "--ros-args", "--params-file", PARAMS, "-p", "condition:=side_effects",
                  "-p", f"seed:={SEED}", "-p", f"height:={H}", "-p", f"width:={W}", "-p", f"horizon:={T}",
                  "-p", f"resolution:={RESOLUTION}"]
    rob_args = ["-m", "ird_ros.nodes.rob", "--ros-args", "--params-file", PARAMS, "-p", "rate_hz:=40.0"]
    with running(ros_domain, ("world", world_args), ("rob", rob_args)) as procs:
        yield procs


class Probe:
    def __init__(self, node: Any, graph: list[NodeProcess]) -> None:
        self.node = node
        self.graph = graph
        self.statuses: list[RobStatus] = []
        self.odoms: list[Odometry] = []
        self.status_sub = node.create_subscription(RobStatus, names.TOPIC_ROB_STATUS, self.statuses.append,
                                                   names.stream_qos(depth=100))
        self.odom_sub = node.create_subscription(Odometry, names.TOPIC_ODOM, self.odoms.append,
                                                 names.stream_qos(depth=100))
        self.plan_pub = node.create_publisher(PathMsg, names.TOPIC_PLAN, names.latched_qos())
        self.info_pub = node.create_publisher(PlanInfo, names.TOPIC_PLAN_INFO, names.latched_qos())
        # Volatile topics: make sure Rob's publishers are matched before anything is executed.
        wait_for_publishers(node, self.status_sub, processes=graph)
        wait_for_publishers(node, self.odom_sub, processes=graph)
        wait_for_subscribers(node, self.plan_pub, processes=graph)
        wait_for_subscribers(node, self.info_pub, processes=graph)

    def publish(self, cells: list[tuple[int, int]], label: str, info_first: bool = True) -> Any:
        stamp = self.node.get_clock().now().to_msg()
        path = conv.cells_to_path(cells, resolution=RESOLUTION, origin=ORIGIN, stamp=stamp)
        info = PlanInfo(label=label, mode="literal", baseline="none", objective=0.0,
                        rows=[r for r, _ in cells], cols=[c for _, c in cells])
        info.header = conv.make_header(stamp)
        if info_first:
            self.info_pub.publish(info)
        self.plan_pub.publish(path)
        if not info_first:
            self.info_pub.publish(info)
        return stamp

    def run(self, stamp: Any, timeout: float = 20.0) -> list[RobStatus]:
        mine = lambda: [s for s in self.statuses if s.plan_stamp == stamp]  # noqa: E731
        spin_until(self.node, lambda: any(s.done for s in mine()), timeout=timeout,
                   what="Rob's final status", processes=self.graph)
        return mine()


@pytest.fixture(scope="module")
def probe(ros_ctx: Any, graph: list[NodeProcess]) -> Iterator[Probe]:
    import rclpy

    node = rclpy.create_node("rob_probe", context=ros_ctx)
    yield Probe(node, graph)
    node.destroy_node()


@pytest.fixture(scope="module")
def instance() -> lavaland.LavalandInstance:
    return lavaland.make_instance("side_effects", SEED, size=(H, W), horizon=T)


def path_through(labels: np.ndarray, start: tuple[int, int], goals: list[int]) -> list[tuple[int, int]]:
    """A legal path from ``start`` that visits a cell of each terrain in ``goals`` in turn."""
    cells = [start]
    for terrain in goals:
        rows, cols = np.nonzero(labels == terrain)
        r, c = int(rows[0]), int(cols[0])
        while cells[-1] != (r, c):
            cr, cc = cells[-1]
            cells.append((cr + int(np.sign(r - cr)), cc) if cr != r else (cr, cc + int(np.sign(c - cc))))
    return cells + [cells[-1]]  # and stay one step


@pytest.mark.parametrize("goals,info_first", [([Terrain.LAVA, Terrain.TARGET], True), ([Terrain.GRASS], False)])
def test_executes_plan_and_evaluates_it(goals: list[int], info_first: bool, probe: Probe,
                                        instance: lavaland.LavalandInstance) -> None:
    labels = instance.test_labels
    cells = path_through(labels, instance.test_start, goals)
    stamp = probe.publish(cells, label=f"walk_{len(goals)}", info_first=info_first)
    statuses = probe.run(stamp)
    assert [(s.row, s.col) for s in statuses] == cells
    assert [s.step for s in statuses] == list(range(len(cells)))
    assert [s.done for s in statuses] == [False] * (len(cells) - 1) + [True]
    final = statuses[-1]
    assert final.horizon == len(cells) - 1
    assert final.touched_lava == evaluation.touches_lava(labels, cells)
    assert final.reached_target == evaluation.reaches_target(labels, cells)
    assert final.true_return == pytest.approx(evaluation.true_return(labels, cells), abs=1e-12)
    assert final.terrain == ("dirt", "grass", "target", "lava")[labels[cells[-1]]]
    assert final.plan_label == f"walk_{len(goals)}"
    if goals[0] == Terrain.LAVA:
        assert final.touched_lava and final.reached_target and final.true_return < 0
    # Odometry at the cell centres, in the same order.
    xy = [conv.cell_center(r, c, RESOLUTION, ORIGIN) for r, c in cells]
    spin_until(probe.node, lambda: len(probe.odoms) >= len(probe.statuses), timeout=10.0, what="odometry",
               processes=probe.graph)
    odom_xy = [(o.pose.pose.position.x, o.pose.pose.position.y) for o in probe.odoms]
    assert any(odom_xy[i:i + len(xy)] == xy for i in range(len(odom_xy) - len(xy) + 1))


def test_new_plan_replaces_the_current_one(probe: Probe, instance: lavaland.LavalandInstance) -> None:
    labels = instance.test_labels
    long_cells = [instance.test_start] * 200  # 5 s at 40 Hz
    first = probe.publish(long_cells, label="long")
    spin_until(probe.node, lambda: any(s.plan_stamp == first and s.step >= 3 for s in probe.statuses),
               timeout=20.0, what="the long plan under way", processes=probe.graph)
    short = path_through(labels, instance.test_start, [Terrain.TARGET])
    second = probe.publish(short, label="short")
    statuses = probe.run(second)
    assert [s.step for s in statuses] == list(range(len(short)))  # restarted at its first cell
    assert statuses[-1].reached_target and statuses[-1].plan_label == "short"
    old = [s for s in probe.statuses if s.plan_stamp == first]
    assert not any(s.done for s in old) and max(s.step for s in old) < 199
