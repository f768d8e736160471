"""The viz node: a live view of the graph for Foxglove or Lichtblick (docs/live_view.md).

Run: ``python -m ird_ros.nodes.viz --ros-args --params-file msgs_config/params/graph.yaml``; off by
default in the launcher (``scripts/launch_graph.py --nodes ...,viz``). It serves the Foxglove
WebSocket protocol (foxglove-sdk) on ``ws://host:port`` (127.0.0.1:8766 by default: not 8765,
the designer page's port; an address other than loopback logs a warning).

It subscribes with the graph's QoS (``names.qos_for``) to ``/world/terrain``, ``/terrain/classes``,
``/world/test_features``, ``/terrain/features``, ``/ird/posterior``, ``/ird/risk_map``, ``/plan``,
``/ird/plan_info``, ``/odom``, ``/rob/status`` and ``/ird/queries``, and publishes on the channels of
:data:`ird_ros.viz.CHANNELS`: the terrain (ground truth and perceived) and the risk map as
Grids, the plans (``/plan`` labelled by the ``/ird/plan_info`` with the same stamp) and Rob (pose
and trail) as SceneUpdates, the trail as PosesInFrame, the posterior per terrain, the
designer's open question and Rob's status (driving, done or stopped; what he reached) as JSON.
What is drawn is computed by the ROS-free :mod:`ird_ros.viz.scene`.
Once the server listens it publishes the latched ``/viz/status`` (std_msgs/String, JSON ``{"url",
"host", "port", "channels"}``): the launcher's readiness, and how a client learns the port.

Invariants: a new world (a ``/world/terrain`` with a later stamp) forgets the plans, the trail,
the posterior and the query records stamped before it (the posterior and query channels then say
"new world: no posterior yet" / "no question yet"), and a posterior stamped before the current
world is ignored; a plan is shown once both its path and its info arrived. Every callback runs in
``ird_ros.runtime.guard``'s guard (a ``GuardedNode``): a bad message is logged and ignored, never
fatal; a stamp before the epoch is shown as 0. A port that is taken (or an address that cannot
be bound) stops the node at start-up (``cannot start: port: ...``, exit code 2), naming
``--viz-port``. Browsers' pages are kept out by the gate (``ird_ros.viz.gate``): ``Host`` must be
loopback while bound to loopback, ``Origin`` loopback or one of ``allowed_origins``.
"""

from __future__ import annotations

import json
from collections import OrderedDict
from typing import Any

from nav_msgs.msg import OccupancyGrid, Odometry, Path
from std_msgs.msg import String

from ird_msgs.msg import FeatureGrid, PlanInfo, QueryRecord, RewardPosterior, RobStatus, TerrainGrid
from ird_ros import conversions as conv
from ird_ros.bags import rounds as qr
from ird_ros.graph import names
from ird_ros.runtime.node_main import StartupError, exit_process, run_node
from ird_ros.runtime.lifecycle import ManagedNode
from ird_ros.runtime.node_params import Param
from ird_ros.stamps import stamp_key, stamp_ns
from ird_ros.viz import (
    CHANNELS,
    DEFAULT_ALLOWED_ORIGINS,
    DEFAULT_PORT,
    LiveView,
    RobTrail,
    no_posterior,
    no_query,
    plan_line,
    port_in_use_message,
    posterior_by_terrain,
    query_state,
    risk_layer,
    rob_status_state,
    terrain_layer,
)

__all__ = ["VizNode", "PARAMETERS", "FEATURE_TOPICS", "main"]

PARAMETERS: dict[str, Param] = {
    "host": Param("127.0.0.1", "Live view address (loopback by default; anything else logs a warning)"),
    "port": Param(DEFAULT_PORT, "Live view port (0 = any free port; not 8765, the designer page's)",
                  min_value=0, max_value=65535),
    "trail_length": Param(200, "Poses of Rob's trail kept and shown", min_value=1, max_value=100000),
    "allowed_origins": Param(list(DEFAULT_ALLOWED_ORIGINS),
                             "Origin headers allowed besides loopback ones (web apps; \"*\" = any); a request "
                             "without Origin (desktop apps, scripts) is allowed"),
}

FEATURE_TOPICS: tuple[str, ...] = (names.TOPIC_HYPOTHESIS_TEST_FEATURES, names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN_FEATURES)
"""Where the posterior's features are looked up (the first map with its layers), for the reward per terrain."""

_PENDING = 16  # unmatched /plan or /ird/plan_info messages kept


class VizNode(ManagedNode):
    """The live view (managed): its Foxglove server listens from configure to cleanup and shows
    what arrives; ``/viz/status`` (the launcher's ready topic) is published at activate."""

    PARAMETERS = PARAMETERS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_VIZ, **kwargs)

    def configure(self, p: dict[str, Any]) -> None:
        origins = [str(o) for o in p["allowed_origins"] if str(o).strip()]
        try:
            self.view = LiveView(str(p["host"]), int(p["port"]), logger=self.get_logger(), allowed_origins=origins)
        except (OSError, RuntimeError) as exc:  # the port is taken, the address unknown (foxglove: RuntimeError)
            raise StartupError(port_in_use_message(str(p["host"]), int(p["port"]), exc)) from None
        self.trail = RobTrail(int(p["trail_length"]))
        self.terrain: conv.TerrainGridData | None = None
        self.terrain_ns = 0
        self.feature_maps: dict[str, conv.FeatureGridData] = {}
        self.posterior: RewardPosterior | None = None
        self._rob_plan: tuple[int, int] | None = None  # plan stamp of the drive /rob/status reports
        self._rob_start: tuple[int, int] | None = None  # Rob's first cell of that drive
        self._rob_moved = False
        self.records: list[QueryRecord] = []
        self._paths: OrderedDict[tuple[int, int], Path] = OrderedDict()
        self._infos: OrderedDict[tuple[int, int], PlanInfo] = OrderedDict()
        self._plans: dict[str, Any] = {}  # label -> scene.Line of the latest plan with that label
        sub = self.create_subscription
        sub(TerrainGrid, names.TOPIC_TERRAIN, self._on_terrain, names.qos_for(names.TOPIC_TERRAIN))
        sub(TerrainGrid, names.TOPIC_TERRAIN_CLASSES, self._on_classes, names.qos_for(names.TOPIC_TERRAIN_CLASSES))
        for topic in FEATURE_TOPICS:
            sub(FeatureGrid, topic, lambda msg, t=topic: self._on_features(t, msg), names.qos_for(topic))
        sub(RewardPosterior, names.TOPIC_POSTERIOR, self._on_posterior, names.qos_for(names.TOPIC_POSTERIOR))
        sub(OccupancyGrid, names.TOPIC_RISK_MAP, self._on_risk, names.qos_for(names.TOPIC_RISK_MAP))
        sub(Path, names.TOPIC_PLAN, self._on_path, names.qos_for(names.TOPIC_PLAN))
        sub(PlanInfo, names.TOPIC_PLAN_INFO, self._on_info, names.qos_for(names.TOPIC_PLAN_INFO))
        sub(Odometry, names.TOPIC_ODOM, self._on_odom, names.qos_for(names.TOPIC_ODOM))
        sub(RobStatus, names.TOPIC_ROB_STATUS, self._on_rob_status, names.qos_for(names.TOPIC_ROB_STATUS))
        sub(QueryRecord, names.TOPIC_QUERIES, self._on_record, names.qos_for(names.TOPIC_QUERIES))
        # Last: the status says the server listens (the launcher's readiness), so clients may connect.
        status_qos = names.qos_for(names.TOPIC_VIZ_STATUS)
        self._status_pub = self.create_publisher(String, names.TOPIC_VIZ_STATUS, status_qos)

    def activate(self) -> None:
        self._status_pub.publish(String(data=json.dumps(
            {"url": self.view.url, "host": self.view.host, "port": self.view.port, "channels": CHANNELS})))

    def release(self) -> None:
        if getattr(self, "view", None) is not None:
            self.view.stop()
            self.view = None

    @property
    def resolution(self) -> float:
        return 1.0 if self.terrain is None else self.terrain.resolution

    def _bad(self, what: str, exc: Exception) -> None:
        self.get_logger().error(f"ignoring a bad {what}: {exc}")

    # ------------------------------------------------------------------ maps

    def _on_terrain(self, msg: TerrainGrid) -> None:
        try:
            terrain = conv.terrain_grid_from_msg(msg, field=names.TOPIC_TERRAIN)
        except ValueError as exc:
            return self._bad("terrain", exc)
        self.terrain, self.terrain_ns = terrain, stamp_ns(msg.header.stamp)
        self.view.show_grid("terrain", terrain_layer(terrain.classes, terrain.class_names,
                                                     resolution=terrain.resolution, origin=terrain.origin,
                                                     stamp_ns=self.terrain_ns, frame_id=terrain.frame_id))
        stale = [label for label, line in self._plans.items() if line.stamp_ns < self.terrain_ns]
        for label in stale:
            del self._plans[label]
        if stale:
            self.view.show_plans(list(self._plans.values()))
        if self.trail.stamp_ns < self.terrain_ns:
            self.trail = RobTrail(self.trail.length)
        self.records = [r for r in self.records if stamp_ns(r.header.stamp) >= self.terrain_ns]
        if self.posterior is not None and stamp_ns(self.posterior.header.stamp) < self.terrain_ns:
            self.posterior = None  # the previous world's
            self.view.show_json("posterior", no_posterior(self.terrain_ns))
        self._show_posterior()
        if not self.records and self.view.latest("query") is not None:
            self.view.show_json("query", no_query(self.terrain_ns))
        self._show_query()

    def _on_classes(self, msg: TerrainGrid) -> None:
        try:
            perceived = conv.terrain_grid_from_msg(msg, field=names.TOPIC_TERRAIN_CLASSES)
        except ValueError as exc:
            return self._bad("perceived terrain", exc)
        self.view.show_grid("perceived", terrain_layer(perceived.classes, perceived.class_names,
                                                       resolution=perceived.resolution, origin=perceived.origin,
                                                       stamp_ns=stamp_ns(msg.header.stamp),
                                                       frame_id=perceived.frame_id))

    def _on_features(self, topic: str, msg: FeatureGrid) -> None:
        try:
            self.feature_maps[topic] = conv.feature_grid_from_msg(msg, field=topic)
        except ValueError as exc:
            return self._bad(f"{topic} map", exc)
        self._show_posterior()

    def _on_risk(self, msg: OccupancyGrid) -> None:
        try:
            costs = conv.occupancy_grid_from_msg(msg, field=names.TOPIC_RISK_MAP)
        except ValueError as exc:
            return self._bad("risk map", exc)
        origin = (msg.info.origin.position.x, msg.info.origin.position.y)
        self.view.show_grid("risk", risk_layer(costs, resolution=float(msg.info.resolution), origin=origin,
                                               stamp_ns=stamp_ns(msg.header.stamp),
                                               frame_id=msg.header.frame_id or conv.MAP_FRAME))

    # ------------------------------------------------------------------ posterior

    def _on_posterior(self, msg: RewardPosterior) -> None:
        if stamp_ns(msg.header.stamp) < self.terrain_ns:
            return  # computed before the current world: the previous world's
        self.posterior = msg
        self._show_posterior()

    def _show_posterior(self) -> None:
        if self.posterior is None:
            return
        try:
            post = conv.posterior_from_msg(self.posterior, field=names.TOPIC_POSTERIOR)
        except ValueError as exc:
            return self._bad("posterior", exc)
        found = conv.first_with_layers(self.feature_maps, FEATURE_TOPICS, post.feature_names)
        terrain = self.terrain
        usable = (found is not None and terrain is not None
                  and found[1].features.shape[:2] == terrain.classes.shape)
        source, features = (found[0], found[1].features) if usable and found is not None else (None, None)
        try:
            data = posterior_by_terrain(post.samples, post.feature_names,
                                        classes=None if terrain is None else terrain.classes,
                                        class_names=() if terrain is None else terrain.class_names,
                                        features=features, source=source,
                                        stamp_ns=stamp_ns(self.posterior.header.stamp),
                                        method=str(post.method), converged=post.converged)
        except ValueError as exc:
            return self._bad("posterior", exc)
        self.view.show_json("posterior", data)

    # ------------------------------------------------------------------ plans and Rob

    def _on_path(self, msg: Path) -> None:
        self._paths[stamp_key(msg.header.stamp)] = msg
        self._match()

    def _on_info(self, msg: PlanInfo) -> None:
        self._infos[stamp_key(msg.header.stamp)] = msg
        self._match()

    def _match(self) -> None:
        changed = False
        for key in [k for k in self._paths if k in self._infos]:
            path, info = self._paths.pop(key), self._infos.pop(key)
            ns = stamp_ns(path.header.stamp)
            if ns < self.terrain_ns or not path.poses:
                continue  # a forgotten world's plan, or nothing to draw
            xy = [(p.pose.position.x, p.pose.position.y) for p in path.poses]
            line = plan_line(str(info.label), str(info.mode), xy, resolution=self.resolution, stamp_ns=ns)
            self._plans[str(info.label)] = line
            changed = True
        for pending in (self._paths, self._infos):
            while len(pending) > _PENDING:
                pending.popitem(last=False)
        if changed:
            self.view.show_plans(list(self._plans.values()))

    def _on_odom(self, msg: Odometry) -> None:
        pose = msg.pose.pose
        # Rob moves one cell per tick: a longer jump starts a new trail (he began a new plan)
        self.trail.add(pose.position.x, pose.position.y, pose.orientation.z, pose.orientation.w,
                       stamp_ns(msg.header.stamp), max_step=1.5 * self.resolution)
        self.view.show_rob(self.trail, self.resolution, msg.header.frame_id or conv.MAP_FRAME)

    def _on_rob_status(self, msg: RobStatus) -> None:
        plan, cell = stamp_key(msg.plan_stamp), (int(msg.row), int(msg.col))
        if plan != self._rob_plan or self._rob_start is None or int(msg.step) == 0:
            self._rob_plan, self._rob_start, self._rob_moved = plan, cell, False  # a new drive
        self._rob_moved |= cell != self._rob_start
        self.view.show_json("rob_status", rob_status_state(
            stamp_ns=stamp_ns(msg.header.stamp), plan_label=str(msg.plan_label), row=msg.row, col=msg.col,
            terrain=str(msg.terrain), step=msg.step, horizon=msg.horizon, done=bool(msg.done),
            stopped=bool(msg.stopped), touched_lava=bool(msg.touched_lava), reached_target=bool(msg.reached_target),
            true_return=float(msg.true_return), moved=self._rob_moved))

    # ------------------------------------------------------------------ the designer's question

    def _on_record(self, msg: QueryRecord) -> None:
        self.records.append(msg)
        self._show_query()

    def _show_query(self) -> None:
        if self.terrain is None:
            return  # option poses become cells with the map's geometry
        events = []
        for msg in self.records:
            if stamp_ns(msg.header.stamp) < self.terrain_ns:
                continue
            try:
                events.append(qr.event_from_msg(msg, resolution=self.terrain.resolution, origin=self.terrain.origin,
                                                field=names.TOPIC_QUERIES))
            except ValueError as exc:
                self._bad("query record", exc)
        state = query_state(events)
        if state is not None:
            self.view.show_json("query", state)


def main(args: list[str] | None = None) -> int:
    return run_node(VizNode, args)


if __name__ == "__main__":
    exit_process(main())
