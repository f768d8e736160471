"""Stand-in for a graph node, for launcher and recorder tests (fast to start, no IRD maths).

Run as a script: ``python tests/ros/_standin_node.py --ros-args -r __node:=world [...]``.
It takes the role of the node it is named after in ``ird_ros.graph``: creates a publisher for
each topic of that node's ``publishes`` (type from ``names.TOPIC_TYPES``, QoS from
``names.qos_for``; a type that is not installed falls back to ``std_msgs/String``), serves its
``services`` with default responses, and publishes one default message on each latched topic
at start (so ``ready_topics`` become satisfied). It exits 0 on SIGINT/SIGTERM.

``STANDIN_SPECS`` is the graph's table of default nodes (``ird_ros.graph.NODES``) with every
node run as this stand-in.
"""

from __future__ import annotations

import importlib
import signal
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from ird_ros import graph
from ird_ros.graph import names

SCRIPT = str(Path(__file__).resolve())

STANDIN_SPECS = [replace(s, script=SCRIPT, ros_args=("-r", f"__node:={s.name}")) for s in graph.NODES if s.default]


def _load(typename: str) -> Any:
    pkg, kind, name = typename.split("/")
    return getattr(importlib.import_module(f"{pkg}.{kind}"), name)


def main() -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from std_msgs.msg import String

    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, lambda *_: (_ for _ in ()).throw(KeyboardInterrupt()))
    rclpy.init(args=sys.argv)
    node = rclpy.create_node("standin")
    spec = graph.NODES_BY_NAME[node.get_name()]
    keep: list[Any] = []
    for topic in spec.publishes:
        try:
            msg_type = _load(names.TOPIC_TYPES[topic])
        except (ImportError, AttributeError):
            msg_type = String
        pub = node.create_publisher(msg_type, topic, names.qos_for(topic))
        keep.append(pub)
        if names.TOPIC_QOS[topic] == names.LATCHED:
            pub.publish(msg_type())
    for service in spec.services:
        srv_type = _load(names.SERVICE_TYPES[service])
        keep.append(node.create_service(srv_type, service, lambda _req, resp: resp))
    print(f"standin {node.get_name()} up", flush=True)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
