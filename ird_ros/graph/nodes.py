"""The IRD ROS graph as data: which node runs from which module, what it publishes and serves.

The one node record of the project (docs/spec.md section 6): the launcher turns it into
processes and readiness checks (``ird_ros.launch.plan``), tests replace a node's ``script``
and ``ros_args`` to run stand-ins. Data only: no ROS import.

Readiness of a node (what a launcher waits for before it calls the node "up"). A managed node
(``is_managed``: every node of this table run from its module) is a lifecycle node the launcher
drives (``ird_ros.launch.lifecycle_driver``): it is ready when its ``activate`` transition
succeeded and a message was received on every topic in ``ready_topics`` (they are transient
local, so a subscriber with ``names.latched_qos()`` gets the latest one whenever it joins).
A stand-in (``script``) is ready, from the graph, when

- every service in ``services`` is discovered (``client.service_is_ready()``), and
- a message was received on every topic in ``ready_topics``, and
- if both are empty, the node's name is in the graph (``get_node_names_and_namespaces``).

``ready_topics`` only appear once the node's inputs exist: perception publishes after the
world did; the planner's risk map needs a posterior, so it is not a readiness topic.
``after`` lists the nodes whose output a node needs before it can become ready; the launcher
starts them first and activates them first.

Every node logs ``<name> ready`` when it becomes active (``ird_ros.runtime.lifecycle``): its
publishers, subscriptions and services exist and, for inference and planner, the worker process
has started and imported ``ird_core``; the world has published its first world. A node exits
with code 0 on SIGINT or SIGTERM.
"""

from __future__ import annotations

from dataclasses import dataclass

from ird_ros.graph import names

__all__ = ["NodeSpec", "is_managed", "NODES", "NODES_BY_NAME", "DEFAULT_NODES", "RECORDER_SPEC", "PARAMS_FILE"]

PARAMS_FILE = "msgs_config/params/graph.yaml"
"""The one parameter file of the graph, relative to the repository root. The parameters' defaults
live in each node module's ``PARAMETERS`` table (``ird_ros.runtime.node_params``); the file repeats them
for whoever edits it, and ``tests/test_graph_params.py`` keeps the two in step."""


@dataclass(frozen=True)
class NodeSpec:
    """One node of the graph: how to run it and when it counts as ready.

    Attributes:
        name: node name (``/name`` in the graph, key in graph.yaml).
        module: run as ``python -m <module> --ros-args --params-file <PARAMS_FILE>``.
        publishes: topics the node publishes (see ``names.TOPIC_TYPES`` / ``names.TOPIC_QOS``).
        subscribes: topics it reads.
        services: services it serves.
        ready_topics: latched topics on which a message must have arrived.
        after: nodes whose output this node needs to become ready (started before it).
        default: started when no node list is given (``GraphLauncher(nodes=None)``,
            ``scripts/launch_graph.py`` without ``--nodes``); the designer is off by default.
        script: if set, run as ``python <script>`` instead of ``python -m <module>`` (stand-ins).
        ros_args: appended after ``--ros-args --params-file FILE`` (e.g. ``-p key:=value``).
        managed: a lifecycle node (``ird_ros.runtime.lifecycle.ManagedNode``) the launcher
            configures and activates; ``script`` stand-ins never are (``is_managed``).
    """

    name: str
    module: str
    publishes: tuple[str, ...] = ()
    subscribes: tuple[str, ...] = ()
    services: tuple[str, ...] = ()
    ready_topics: tuple[str, ...] = ()
    after: tuple[str, ...] = ()
    default: bool = True
    script: str | None = None
    ros_args: tuple[str, ...] = ()
    managed: bool = True


def is_managed(spec: NodeSpec) -> bool:
    """Whether the launcher drives ``spec``'s lifecycle (configure, activate): a graph node run
    from its module (``ird_ros.runtime.lifecycle``); a stand-in script is an ordinary node."""
    return spec.managed and spec.script is None


NODES: tuple[NodeSpec, ...] = (
    NodeSpec(
        name=names.NODE_WORLD,
        module="ird_ros.nodes.world",
        publishes=(
            names.TOPIC_TRAIN_FEATURES,
            names.TOPIC_TEST_FEATURES,
            names.TOPIC_TRAIN_PROXY_FEATURES,
            names.TOPIC_HYPOTHESIS_TRAIN_FEATURES,
            names.TOPIC_HYPOTHESIS_TEST_FEATURES,
            names.TOPIC_TERRAIN,
            names.TOPIC_PROXY,
            names.TOPIC_INFER_REQUEST,
        ),
        subscribes=(),
        services=(names.SRV_GENERATE,),
        ready_topics=(names.TOPIC_PROXY,),
    ),
    NodeSpec(
        name=names.NODE_PERCEPTION,
        module="ird_ros.nodes.perception",
        publishes=(names.TOPIC_TERRAIN_CLASSES, names.TOPIC_TERRAIN_FEATURES),
        subscribes=(names.TOPIC_TEST_FEATURES, names.TOPIC_PROXY),
        services=(),
        ready_topics=(names.TOPIC_TERRAIN_CLASSES, names.TOPIC_TERRAIN_FEATURES),
        after=(names.NODE_WORLD,),
    ),
    NodeSpec(
        name=names.NODE_INFERENCE,
        module="ird_ros.nodes.inference",
        publishes=(names.TOPIC_POSTERIOR, names.TOPIC_QUERIES),
        subscribes=(names.TOPIC_HYPOTHESIS_TEST_FEATURES, names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN_FEATURES,
                    names.TOPIC_PROXY),
        services=(names.SRV_INFER, names.SRV_QUERY, names.SRV_ANSWER),
        ready_topics=(),
    ),
    NodeSpec(
        name=names.NODE_PLANNER,
        module="ird_ros.nodes.planner",
        publishes=(names.TOPIC_PLAN, names.TOPIC_PLAN_INFO, names.TOPIC_RISK_MAP),
        subscribes=(
            names.TOPIC_HYPOTHESIS_TEST_FEATURES,
            names.TOPIC_TEST_FEATURES,
            names.TOPIC_TERRAIN_FEATURES,
            names.TOPIC_HYPOTHESIS_TRAIN_FEATURES,
            names.TOPIC_TRAIN_FEATURES,
            names.TOPIC_TRAIN_PROXY_FEATURES,
            names.TOPIC_INFER_REQUEST,
            names.TOPIC_PROXY,
            names.TOPIC_POSTERIOR,
        ),
        services=(names.SRV_PLAN,),
        ready_topics=(),
    ),
    NodeSpec(
        name=names.NODE_ROB,
        module="ird_ros.nodes.rob",
        publishes=(names.TOPIC_ODOM, names.TOPIC_ROB_STATUS),
        subscribes=(names.TOPIC_PLAN, names.TOPIC_PLAN_INFO, names.TOPIC_TERRAIN, names.TOPIC_PROXY),
        services=(names.SRV_ROB_STOP,),
        ready_topics=(),
    ),
    NodeSpec(
        # Serves the NavigateIrd action names.ACTION_NAVIGATE (not a service: readiness is the node
        # in the graph; clients wait for the action server themselves). A client of /ird/infer,
        # /ird/query, /ird/plan and /rob/stop while a goal runs, and of planner/get_parameters and
        # inference/get_parameters before it (the goal's work limits); publishes nothing of its own.
        name=names.NODE_NAVIGATOR,
        module="ird_ros.nodes.navigator",
        publishes=(),
        subscribes=(names.TOPIC_INFER_REQUEST, names.TOPIC_PROXY, names.TOPIC_TERRAIN, names.TOPIC_POSTERIOR,
                    names.TOPIC_QUERIES, names.TOPIC_ROB_STATUS),
        services=(),
        ready_topics=(),
    ),
    NodeSpec(
        # Answers the robot's questions (/ird/queries -> /ird/answer): simulated, or a person on a
        # web page; a calling client (the demo) starts it with --nodes or nodes=[...].
        name=names.NODE_DESIGNER,
        module="ird_ros.nodes.designer",
        publishes=(),
        # /world/train_features and /world/test_features: the training map's terrain (proxies queries);
        # /rob/status and (web mode) the NavigateIrd action's status: how the mission ended, on the page
        subscribes=(names.TOPIC_QUERIES, names.TOPIC_TERRAIN, names.TOPIC_PROXY, names.TOPIC_TRAIN_FEATURES,
                    names.TOPIC_TEST_FEATURES, names.TOPIC_POSTERIOR, names.TOPIC_RISK_MAP, names.TOPIC_PLAN_INFO,
                    names.TOPIC_ROB_STATUS),
        services=(),
        ready_topics=(),
        default=False,
    ),
    NodeSpec(
        # The live view: serves the Foxglove WebSocket protocol (foxglove-sdk) on 127.0.0.1:8766 for
        # Foxglove or Lichtblick (docs/live_view.md); ready once its latched /viz/status (the URL)
        # is out, i.e. the server listens; started with --nodes or nodes=[...] (the demo's --viz).
        name=names.NODE_VIZ,
        module="ird_ros.nodes.viz",
        publishes=(names.TOPIC_VIZ_STATUS,),
        subscribes=(names.TOPIC_TERRAIN, names.TOPIC_TERRAIN_CLASSES, names.TOPIC_HYPOTHESIS_TEST_FEATURES,
                    names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN_FEATURES, names.TOPIC_POSTERIOR, names.TOPIC_RISK_MAP, names.TOPIC_PLAN,
                    names.TOPIC_PLAN_INFO, names.TOPIC_ODOM, names.TOPIC_QUERIES, names.TOPIC_ROB_STATUS),
        services=(),
        ready_topics=(names.TOPIC_VIZ_STATUS,),
        default=False,
    ),
)

NODES_BY_NAME: dict[str, NodeSpec] = {spec.name: spec for spec in NODES}
DEFAULT_NODES: tuple[str, ...] = tuple(spec.name for spec in NODES if spec.default)
"""The nodes started when no node list is given."""

RECORDER_SPEC = NodeSpec(name=names.NODE_RECORDER, module="ird_ros.nodes.recorder", default=False)
"""The bag recorder: started by the launcher only when it records (not in :data:`NODES`); it
subscribes to what the other nodes publish, and its readiness is its own (``ird_ros.launch.readiness``)."""
