"""Names of the IRD ROS graph (docs/spec.md section 6) and the QoS profiles of its topics.

Every node, test, launcher and recorder takes topic and service names from here.

QoS:

- ``latched_qos()``: reliable, transient local, keep last 1. Maps, the proxy, the posterior,
  the risk map, ``/plan`` and ``/ird/plan_info``: state that a late joiner must still get
  (a node started after the world still receives the maps; a bag recorder started late still
  records the current plan). Subscribers must use the same profile to get the history.
- ``stream_qos()``: reliable, volatile, keep last 10. ``/odom`` and ``/rob/status``: a stream
  of samples; what was published before a subscriber matched is gone (wait for the match).
- ``history_qos()``: reliable, transient local, keep last :data:`HISTORY_DEPTH` (100).
  ``/ird/queries``: every proposal and answer of the conversation with the designer, so a late
  joiner (the recorder, a respawned designer) gets the recent rounds, not only the last event.

The ROS-free part (the strings) imports nothing; the profiles import ``rclpy.qos`` when called.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "FRAME_ID",
    "NODE_WORLD",
    "NODE_PERCEPTION",
    "NODE_INFERENCE",
    "NODE_PLANNER",
    "NODE_ROB",
    "NODE_DESIGNER",
    "NODE_RECORDER",
    "NODE_VIZ",
    "NODE_NAVIGATOR",
    "NODE_LAUNCHER",
    "NODE_LAUNCHER_PING",
    "NODE_LAUNCHER_VIEW",
    "NODE_LAUNCHER_VIZ_STATUS",
    "LAUNCHER_NODES",
    "ACTION_NAVIGATE",
    "ACTION_TYPES",
    "SRV_ROB_STOP",
    "TOPIC_TRAIN_FEATURES",
    "TOPIC_TEST_FEATURES",
    "TOPIC_TRAIN_PROXY_FEATURES",
    "TOPIC_HYPOTHESIS_TRAIN_FEATURES",
    "TOPIC_HYPOTHESIS_TEST_FEATURES",
    "TOPIC_TERRAIN",
    "TOPIC_PROXY",
    "TOPIC_INFER_REQUEST",
    "TOPIC_TERRAIN_CLASSES",
    "TOPIC_TERRAIN_FEATURES",
    "TOPIC_POSTERIOR",
    "TOPIC_RISK_MAP",
    "TOPIC_PLAN",
    "TOPIC_PLAN_INFO",
    "TOPIC_ODOM",
    "TOPIC_ROB_STATUS",
    "TOPIC_QUERIES",
    "TOPIC_RECORDER_STATUS",
    "TOPIC_VIZ_STATUS",
    "SRV_GENERATE",
    "SRV_INFER",
    "SRV_QUERY",
    "SRV_ANSWER",
    "SRV_PLAN",
    "LATCHED",
    "STREAM",
    "HISTORY",
    "HISTORY_DEPTH",
    "TOPIC_TYPES",
    "TOPIC_QOS",
    "SERVICE_TYPES",
    "latched_qos",
    "stream_qos",
    "history_qos",
    "qos_for",
]

FRAME_ID = "map"

NODE_WORLD = "world"
NODE_PERCEPTION = "perception"
NODE_INFERENCE = "inference"
NODE_PLANNER = "planner"
NODE_ROB = "rob"
NODE_DESIGNER = "designer"
NODE_RECORDER = "recorder"
# the live view for Foxglove / Lichtblick (ird_ros.nodes.viz; off by default)
NODE_VIZ = "viz"
NODE_NAVIGATOR = "navigator"
# the launcher's own nodes, each in a participant of its own (ird_ros.launch): the readiness probe,
# the liveness pings, the probe's second view of the graph, the demo's live-view status line
NODE_LAUNCHER = "launcher"
NODE_LAUNCHER_PING = "launcher_ping"
NODE_LAUNCHER_VIEW = "launcher_view"
NODE_LAUNCHER_VIZ_STATUS = "launcher_viz_status"
LAUNCHER_NODES = (NODE_LAUNCHER, NODE_LAUNCHER_PING, NODE_LAUNCHER_VIEW, NODE_LAUNCHER_VIZ_STATUS)
"""Nodes a launched graph holds besides the launched ones: seeing one means the launched nodes run."""

# world
TOPIC_TRAIN_FEATURES = "/world/train_features"
TOPIC_TEST_FEATURES = "/world/test_features"
TOPIC_TRAIN_PROXY_FEATURES = "/world/train_proxy_features"
# IRD's hypothesis space when the world node's differs from the sensors' (ird_ros.nodes.world)
TOPIC_HYPOTHESIS_TRAIN_FEATURES = "/world/hypothesis/train_features"
TOPIC_HYPOTHESIS_TEST_FEATURES = "/world/hypothesis/test_features"
TOPIC_TERRAIN = "/world/terrain"
TOPIC_PROXY = "/world/proxy"
# The whole /ird/infer request the world poses (every training world; see ird_ros.nodes.world)
TOPIC_INFER_REQUEST = "/world/infer_request"
SRV_GENERATE = "/world/generate"
# perception
TOPIC_TERRAIN_CLASSES = "/terrain/classes"
TOPIC_TERRAIN_FEATURES = "/terrain/features"
# inference
TOPIC_POSTERIOR = "/ird/posterior"
SRV_INFER = "/ird/infer"
TOPIC_QUERIES = "/ird/queries"
SRV_QUERY = "/ird/query"
SRV_ANSWER = "/ird/answer"
# planner
TOPIC_RISK_MAP = "/ird/risk_map"
TOPIC_PLAN = "/plan"
TOPIC_PLAN_INFO = "/ird/plan_info"
SRV_PLAN = "/ird/plan"
# rob
TOPIC_ODOM = "/odom"
TOPIC_ROB_STATUS = "/rob/status"
# std_srvs/Trigger: stop the current plan where Rob is (RobStatus.stopped)
SRV_ROB_STOP = "/rob/stop"
# navigator: the NavigateIrd action (goal -> infer / ask / plan / drive -> result)
ACTION_NAVIGATE = "/ird/navigate"
# recorder: std_msgs/String, latched, JSON {"output_dir": ..., "counts": {topic: messages}}
TOPIC_RECORDER_STATUS = "/recorder/status"
# viz: std_msgs/String, latched, JSON {"url": "ws://host:port", "host", "port", "channels": {key: topic}};
# published once its Foxglove WebSocket server listens (the node's readiness)
TOPIC_VIZ_STATUS = "/viz/status"

LATCHED = "latched"
STREAM = "stream"
HISTORY = "history"
HISTORY_DEPTH = 100

TOPIC_TYPES: dict[str, str] = {
    TOPIC_TRAIN_FEATURES: "ird_msgs/msg/FeatureGrid",
    TOPIC_TEST_FEATURES: "ird_msgs/msg/FeatureGrid",
    TOPIC_TRAIN_PROXY_FEATURES: "ird_msgs/msg/FeatureGrid",
    TOPIC_HYPOTHESIS_TRAIN_FEATURES: "ird_msgs/msg/FeatureGrid",
    TOPIC_HYPOTHESIS_TEST_FEATURES: "ird_msgs/msg/FeatureGrid",
    TOPIC_TERRAIN: "ird_msgs/msg/TerrainGrid",
    TOPIC_PROXY: "ird_msgs/msg/ProxyReward",
    TOPIC_INFER_REQUEST: "ird_msgs/srv/InferReward_Request",
    TOPIC_TERRAIN_CLASSES: "ird_msgs/msg/TerrainGrid",
    TOPIC_TERRAIN_FEATURES: "ird_msgs/msg/FeatureGrid",
    TOPIC_POSTERIOR: "ird_msgs/msg/RewardPosterior",
    TOPIC_RISK_MAP: "nav_msgs/msg/OccupancyGrid",
    TOPIC_PLAN: "nav_msgs/msg/Path",
    TOPIC_PLAN_INFO: "ird_msgs/msg/PlanInfo",
    TOPIC_ODOM: "nav_msgs/msg/Odometry",
    TOPIC_ROB_STATUS: "ird_msgs/msg/RobStatus",
    TOPIC_QUERIES: "ird_msgs/msg/QueryRecord",
    TOPIC_VIZ_STATUS: "std_msgs/msg/String",
}
"""Message type of every topic of the graph (``package/msg/Name``)."""

TOPIC_QOS: dict[str, str] = {
    topic: (STREAM if topic in (TOPIC_ODOM, TOPIC_ROB_STATUS) else HISTORY if topic == TOPIC_QUERIES else LATCHED)
    for topic in TOPIC_TYPES
}
"""QoS kind of every topic: :data:`LATCHED`, :data:`STREAM` or :data:`HISTORY`."""

SERVICE_TYPES: dict[str, str] = {
    SRV_GENERATE: "ird_msgs/srv/GenerateWorld",
    SRV_INFER: "ird_msgs/srv/InferReward",
    SRV_PLAN: "ird_msgs/srv/PlanPath",
    SRV_QUERY: "ird_msgs/srv/ProposeQuery",
    SRV_ANSWER: "ird_msgs/srv/AnswerQuery",
    SRV_ROB_STOP: "std_srvs/srv/Trigger",
}

ACTION_TYPES: dict[str, str] = {
    ACTION_NAVIGATE: "ird_msgs/action/NavigateIrd",
}
"""Type of every action of the graph (``package/action/Name``)."""


def latched_qos() -> Any:
    """Reliable, transient local, keep last 1 (maps, proxy, posterior, plan)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=1,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


def stream_qos(depth: int = 10) -> Any:
    """Reliable, volatile, keep last ``depth`` (/odom, /rob/status)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.VOLATILE,
    )


def history_qos(depth: int = HISTORY_DEPTH) -> Any:
    """Reliable, transient local, keep last ``depth`` (/ird/queries: the rounds so far)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=depth,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )


def qos_for(topic: str) -> Any:
    """The QoS profile of a topic of the graph (``KeyError`` for an unknown topic)."""
    kind = TOPIC_QOS[topic]
    return latched_qos() if kind == LATCHED else history_qos() if kind == HISTORY else stream_qos()
