"""Helper process for test_message_roundtrip.py: echoes every ird_msgs topic case and
serves every ird_msgs service with _roundtrip_cases.respond. Prints READY when set up.

Run as a script (its directory is then on sys.path): python tests/ros/_echo_node.py
"""

from __future__ import annotations

import rclpy
from _roundtrip_cases import QOS, READY, SERVICES, TOPIC_CASES, respond
from rclpy.executors import ExternalShutdownException


def main() -> None:
    rclpy.init()
    node = rclpy.create_node("ird_roundtrip_echo")
    for name, (msg_type, _) in TOPIC_CASES.items():
        pub = node.create_publisher(msg_type, f"/roundtrip/{name}/out", QOS)
        node.create_subscription(msg_type, f"/roundtrip/{name}/in", pub.publish, QOS)
    for name, srv_type in SERVICES.items():
        node.create_service(srv_type, f"/roundtrip/{name}", lambda request, _response: respond(request))
    print(READY, flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
