"""A server waits seconds, not rmw_fastrtps's 100 ms, for a client's response reader
(the data_writer profile "service" of ``msgs_config/dds/fastdds_localhost.xml``).

A request can reach a server before the server has matched the client's response reader; the
server then waits up to its response writer's ``max_blocking_time`` for the match and drops the
answer after it (rclpy warns ``failed to send response (timeout)``). On a loaded machine 100 ms
lost answers. The test makes the match impossible (the client's response reader is in another
DDS partition) and measures the server's wait: from the moment its answer is ready to the
warning, at least the profile's value. With the profile's entry missing, or ignored by the
middleware, the wait is 0.1 s and the test fails.
"""

from __future__ import annotations

import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path

from ird_ros.graph.domains import DDS_PROFILE, DomainLease
from ird_ros.testing import spawn_node_process

NS = {"f": "http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles"}
SERVICE = "/answer_wait/trigger"

SERVER = f"""
import time, warnings
from std_srvs.srv import Trigger
from ird_ros.runtime.guard import GuardedNode
from ird_ros.runtime.node_main import exit_process, run_node


def show(message, category, filename, lineno, file=None, line=None):
    print(f"warning at {{time.monotonic():.3f}}: {{message}}", flush=True)


warnings.showwarning = show


class Server(GuardedNode):
    def __init__(self):
        super().__init__("answer_wait_server")
        self.create_service(Trigger, "{SERVICE}", self.on_trigger)

    def on_trigger(self, request, response):
        response.success = True
        print(f"answer ready at {{time.monotonic():.3f}}", flush=True)
        return response


exit_process(run_node(Server))
"""

# Requests until one gets through (a request sent before the request path matched is dropped);
# the client's response reader never matches, so no answer ever arrives.
CLIENT = f"""
import rclpy
from std_srvs.srv import Trigger

rclpy.init()
node = rclpy.create_node("answer_wait_client")
client = node.create_client(Trigger, "{SERVICE}")
print("client up", flush=True)
while True:
    client.call_async(Trigger.Request())
    rclpy.spin_once(node, timeout_sec=1.0)
"""


def _service_wait(profile: Path) -> float:
    """The "service" data_writer profile's max_blocking_time, in seconds."""
    root = ET.parse(profile).getroot()
    writer = root.find("f:profiles/f:data_writer[@profile_name='service']", NS)
    assert writer is not None, f"{profile}: no data_writer profile 'service'"
    wait = writer.find("f:qos/f:reliability/f:max_blocking_time", NS)
    assert wait is not None, f"{profile}: the 'service' profile sets no max_blocking_time"
    return float(wait.findtext("f:sec", "0", NS)) + float(wait.findtext("f:nanosec", "0", NS)) * 1e-9


def _unmatched_client_profile(tmp_path: Path) -> Path:
    """Our profile plus a "client" data_reader profile in a partition no server writes to."""
    ET.register_namespace("", NS["f"])
    tree = ET.parse(DDS_PROFILE)
    profiles = tree.getroot().find("f:profiles", NS)
    reader = ET.SubElement(profiles, f"{{{NS['f']}}}data_reader", profile_name="client")
    names = ET.SubElement(ET.SubElement(ET.SubElement(reader, f"{{{NS['f']}}}qos"), f"{{{NS['f']}}}partition"),
                          f"{{{NS['f']}}}names")
    ET.SubElement(names, f"{{{NS['f']}}}name").text = "nowhere"
    path = tmp_path / "unmatched_client.xml"
    tree.write(path, xml_declaration=True, encoding="UTF-8")
    return path


def test_a_server_waits_the_profiles_time_for_a_clients_response_reader(ros_domain: DomainLease,
                                                                       tmp_path: Path) -> None:
    configured = _service_wait(DDS_PROFILE)
    assert configured >= 1.0, f"{configured} s is not enough on a loaded machine"
    server = spawn_node_process(["-c", SERVER], domain=ros_domain, name="answer_wait_server",
                                ready_text="answer_wait_server ready", ready_timeout=60.0)
    with server:
        env = {**os.environ, "FASTRTPS_DEFAULT_PROFILES_FILE": str(_unmatched_client_profile(tmp_path))}
        client = spawn_node_process(["-c", CLIENT], domain=ros_domain, env=env, name="answer_wait_client",
                                    ready_text="client up", ready_timeout=60.0)
        with client:
            server.wait_for_output("failed to send response", timeout=60.0 + configured)
        output = server.output()
    ready = re.search(r"answer ready at ([\d.]+)", output)
    warned = re.search(r"warning at ([\d.]+): failed to send response", output)
    assert ready and warned, output
    waited = float(warned[1]) - float(ready[1])
    assert waited >= configured - 0.05, f"the server waited {waited:.3f} s, not {configured} s\n{output}"
