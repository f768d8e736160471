"""The rob node: executes the latest ``/plan`` one cell per tick and reports how it goes.

Run: ``python -m ird_ros.nodes.rob --ros-args --params-file msgs_config/params/graph.yaml``

Subscribes (latched) ``/plan``, ``/ird/plan_info``, ``/world/terrain`` (ground truth) and
``/world/proxy`` (true terrain rewards). Every ``1 / rate_hz`` seconds it moves to the next cell
of the current plan and publishes ``/odom`` (nav_msgs/Odometry at the cell centre, frame
``map``, child frame ``base_link``, zero twist) and ``/rob/status`` (RobStatus), both reliable
and volatile. The tick that reaches the last cell publishes the final status (``done: true``);
then Rob idles until the next plan. A new plan replaces the current one and Rob restarts at its
first cell (``step`` 0). The logic lives in :mod:`ird_ros.jobs.rob_logic`.

``/rob/stop`` (std_srvs/Trigger) stops the current plan where Rob is (the navigator's cancel):
Rob publishes his current cell once more with ``stopped: true`` and ``done: true`` and idles until
the next plan; the answer says where he stopped, or that he was idle (``success`` is true both ways).
Every callback runs in ``ird_ros.runtime.guard``'s guard: a malformed message is logged and dropped,
and an unexpected exception in ``/rob/stop`` is a ``success: false`` answer.

Because ``/plan`` is latched, a Rob started after the planner executes the current plan.
``plan_label`` comes from the ``/ird/plan_info`` whose stamp equals the plan's (the planner
publishes the info first; if it arrives later, the label is filled in then); ``plan_stamp``
is the executed ``/plan``'s header stamp.
"""

from __future__ import annotations

from collections import OrderedDict
from typing import Any

from nav_msgs.msg import Odometry, Path
from std_srvs.srv import Trigger

from ird_msgs.msg import PlanInfo, ProxyReward, RobStatus, TerrainGrid
from ird_ros import conversions as conv
from ird_ros.graph import names
from ird_ros.jobs.rob_logic import RobExecutor, RobStatusData
from ird_ros.runtime.node_main import exit_process, run_node
from ird_ros.runtime.lifecycle import ManagedNode
from ird_ros.runtime.node_params import Param
from ird_ros.stamps import stamp_key

__all__ = ["RobNode", "PARAMETERS", "main"]

PARAMETERS: dict[str, Param] = {
    "rate_hz": Param(5.0, "Cells Rob moves per second", min_value=0.01, max_value=1000.0, runtime=True),
    "child_frame_id": Param("base_link", "Odometry child frame", runtime=True),
}


class RobNode(ManagedNode):
    """Rob (managed): drives only while active (his tick timer runs then); ``rate_hz`` and
    ``child_frame_id`` may change at run time."""

    PARAMETERS = PARAMETERS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_ROB, **kwargs)

    def configure(self, p: dict[str, Any]) -> None:
        self.rate_hz, self.child_frame_id = p["rate_hz"], p["child_frame_id"]
        self.rob = RobExecutor()
        self._geometry: tuple[float, tuple[float, float]] | None = None
        self._labels: OrderedDict[tuple[int, int], str] = OrderedDict()  # plan_info stamp -> label
        self._pending_path: Path | None = None
        latched = names.latched_qos()
        stream = names.stream_qos()
        self._odom_pub = self.create_publisher(Odometry, names.TOPIC_ODOM, stream)
        self._status_pub = self.create_publisher(RobStatus, names.TOPIC_ROB_STATUS, stream)
        self.create_subscription(TerrainGrid, names.TOPIC_TERRAIN, self._on_terrain, latched)
        self.create_subscription(ProxyReward, names.TOPIC_PROXY, self._on_proxy, latched)
        self.create_subscription(PlanInfo, names.TOPIC_PLAN_INFO, self._on_info, latched)
        self.create_subscription(Path, names.TOPIC_PLAN, self._on_plan, latched)
        self.create_service(Trigger, names.SRV_ROB_STOP, self._on_stop)
        self._timer = self.create_timer(1.0 / self.rate_hz, self._tick)

    def apply_parameters(self, p: dict[str, Any], changed: set[str]) -> None:
        self.rate_hz, self.child_frame_id = p["rate_hz"], p["child_frame_id"]
        if "rate_hz" in changed:  # the next tick comes at the new rate
            self._timer.timer_period_ns = int(1e9 / self.rate_hz)

    # ------------------------------------------------------------------ inputs

    def _on_terrain(self, msg: TerrainGrid) -> None:
        try:
            terrain = conv.terrain_grid_from_msg(msg, field=names.TOPIC_TERRAIN)
        except ValueError as exc:
            self.get_logger().error(f"ignoring bad terrain: {exc}")
            return
        self.rob.set_terrain(terrain.classes, terrain.class_names)
        self._geometry = (terrain.resolution, terrain.origin)
        if self._pending_path is not None:
            path, self._pending_path = self._pending_path, None
            self._on_plan(path)

    def _on_proxy(self, msg: ProxyReward) -> None:
        try:
            self.rob.set_rewards(msg.terrain_names, msg.true_terrain_rewards)
        except ValueError as exc:
            self.get_logger().error(f"ignoring bad true rewards: {exc}")

    def _on_info(self, msg: PlanInfo) -> None:
        key = stamp_key(msg.header.stamp)
        self._labels[key] = msg.label
        while len(self._labels) > 64:
            self._labels.popitem(last=False)
        if self.rob.plan_stamp is not None and stamp_key(self.rob.plan_stamp) == key:
            self.rob.set_label(msg.label)

    def _on_plan(self, msg: Path) -> None:
        if self._geometry is None:  # cells need the map geometry: wait for the terrain
            self._pending_path = msg
            return
        resolution, origin = self._geometry
        shape = self.rob.shape
        try:
            cells = conv.path_to_cells(msg, resolution=resolution, origin=origin,
                                       height=shape[0] if shape else None, width=shape[1] if shape else None,
                                       field=names.TOPIC_PLAN)
            self.rob.set_plan(cells, stamp=msg.header.stamp, label=self._labels.get(stamp_key(msg.header.stamp), ""))
        except ValueError as exc:
            self.get_logger().error(f"ignoring plan: {exc}")
            return
        self.get_logger().info(f"executing a plan of {len(cells) - 1} moves "
                               f"({self._labels.get(stamp_key(msg.header.stamp), 'unlabelled')})")

    # ------------------------------------------------------------------ execution

    def _on_stop(self, _request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        try:
            status = self.rob.stop()
        except ValueError as exc:
            status = None
            self.get_logger().error(f"plan aborted: {exc}")
        response.success = True
        if status is None:
            response.message = "idle: no plan to stop"
        else:
            self._publish(status)
            response.message = (f"stopped at ({status.row}, {status.col}), step {status.step} of "
                                f"{status.horizon}")
            self.get_logger().info(f"plan stopped ({status.plan_label or 'unlabelled'}): {response.message}")
        return response

    def _tick(self) -> None:
        try:
            status = self.rob.tick()
        except ValueError as exc:
            self.get_logger().error(f"plan aborted: {exc}")
            return
        if status is None:
            return
        self._publish(status)
        if status.done:
            self.get_logger().info(
                f"plan done ({status.plan_label or 'unlabelled'}): return {status.true_return:.3f}, "
                f"lava {status.touched_lava}, target {status.reached_target}")

    def _publish(self, status: RobStatusData) -> None:
        """``/odom`` and ``/rob/status`` of one status report."""
        if self._geometry is None:
            return
        resolution, origin = self._geometry
        stamp = conv.now_stamp(self)
        x, y = conv.cell_center(status.row, status.col, resolution, origin)
        odom = Odometry()
        odom.header = conv.make_header(stamp)
        odom.child_frame_id = self.child_frame_id
        odom.pose.pose.position.x, odom.pose.pose.position.y = x, y
        odom.pose.pose.orientation.w = 1.0
        self._odom_pub.publish(odom)
        msg = RobStatus()
        msg.header = conv.make_header(stamp)
        msg.row, msg.col = status.row, status.col
        msg.terrain = status.terrain
        msg.step, msg.horizon = status.step, status.horizon
        msg.done = status.done
        msg.touched_lava, msg.reached_target = status.touched_lava, status.reached_target
        msg.true_return = float(status.true_return)
        msg.plan_label = status.plan_label
        if status.plan_stamp is not None:
            msg.plan_stamp = status.plan_stamp
        msg.stopped = status.stopped
        self._status_pub.publish(msg)


def main(args: list[str] | None = None) -> int:
    return run_node(RobNode, args)


if __name__ == "__main__":
    exit_process(main())
