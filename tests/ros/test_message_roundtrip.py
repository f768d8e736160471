"""Every ird_msgs message and service survives a trip through real DDS between two
separate processes (this test process and tests/ros/_echo_node.py) in a private domain.

Topics: the test publishes on /roundtrip/<case>/in, the echo process deserializes and
republishes on /roundtrip/<case>/out, the test compares what comes back with what it sent
(field equality and bit-identical field values; serialized CDR bytes can differ in
their uninitialised padding, so they are not compared). Services: the echo process answers with
_roundtrip_cases.respond(request); the request's field digest inside the answer proves the request
arrived intact, equality with the locally computed answer proves the response did.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterator

import numpy as np
import pytest
from _roundtrip_cases import (
    QOS,
    READY,
    SERVICE_REQUESTS,
    SERVICES,
    TOPIC_CASES,
    canonical,
    digest,
    infer_request,
    respond,
)

from ird_ros import conversions as conv
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess, spawn_node_process
from ird_ros.waits import call_service, spin_until, wait_for_publishers, wait_for_service, wait_for_subscribers

ECHO_SCRIPT = Path(__file__).with_name("_echo_node.py")


@pytest.fixture(scope="module")
def echo(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    with spawn_node_process([str(ECHO_SCRIPT)], domain=ros_domain, name="echo", ready_text=READY) as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()  # it shut down cleanly on SIGINT


@pytest.mark.parametrize("case", sorted(TOPIC_CASES))
def test_topic_roundtrip(case: str, ros_node: Any, echo: NodeProcess) -> None:
    msg_type, build = TOPIC_CASES[case]
    sent = build()
    received: list[Any] = []
    pub = ros_node.create_publisher(msg_type, f"/roundtrip/{case}/in", QOS)
    ros_node.create_subscription(msg_type, f"/roundtrip/{case}/out", received.append, QOS)
    wait_for_subscribers(ros_node, pub, processes=[echo])
    pub.publish(sent)
    spin_until(ros_node, lambda: bool(received), timeout=30.0, what=f"echo of {case}", processes=[echo])

    back = received[0]
    assert type(back) is msg_type
    assert back == sent
    assert canonical(back) == canonical(sent)  # bit-exact floats, not just ==


def test_large_feature_grid_values_exact(ros_node: Any, echo: NodeProcess) -> None:
    """The 100x100x50 grid comes back as the same float32 array (bit for bit)."""
    msg_type, build = TOPIC_CASES["feature_grid_100x100x50"]
    sent = build()
    received: list[Any] = []
    pub = ros_node.create_publisher(msg_type, "/roundtrip/feature_grid_100x100x50/in", QOS)
    sub = ros_node.create_subscription(msg_type, "/roundtrip/feature_grid_100x100x50/out", received.append, QOS)
    wait_for_subscribers(ros_node, pub, processes=[echo])
    wait_for_publishers(ros_node, sub, processes=[echo])
    pub.publish(sent)
    spin_until(ros_node, lambda: bool(received), timeout=30.0, what="echo of the large grid", processes=[echo])

    grid = conv.feature_grid_from_msg(received[0])
    expected = conv.feature_grid_from_msg(sent)
    assert grid.shape == (100, 100, 50)
    assert grid.features.dtype == np.float32
    assert np.array_equal(grid.features.view(np.uint32), expected.features.view(np.uint32))
    assert grid.layers == expected.layers
    assert (grid.resolution, grid.origin, grid.frame_id) == (0.5, (-3.25, 1.5), "map")


@pytest.mark.parametrize("service", sorted(SERVICES))
def test_service_roundtrip(service: str, ros_node: Any, echo: NodeProcess) -> None:
    srv_type = SERVICES[service]
    request = SERVICE_REQUESTS[service]()
    client = ros_node.create_client(srv_type, f"/roundtrip/{service}")
    wait_for_service(ros_node, client, processes=[echo])
    response = call_service(ros_node, client, request, processes=[echo])

    assert type(response) is srv_type.Response
    assert response.success
    assert digest(request) in response.message  # the request arrived byte for byte
    expected = respond(request)
    assert response == expected
    assert canonical(response) == canonical(expected)


def test_service_rejects_bad_request_naming_the_field(ros_node: Any, echo: NodeProcess) -> None:
    """The server validates with ird_ros.conversions: the answer names the bad field."""
    from ird_msgs.srv import InferReward

    client = ros_node.create_client(InferReward, "/roundtrip/infer_reward")
    wait_for_service(ros_node, client, processes=[echo])
    response = call_service(ros_node, client, infer_request(short_data=True), processes=[echo])
    assert not response.success
    assert response.message.startswith("training_map.data: expected 360 values (H=10 x W=12 x d=3), got 359")
    # ... and the server keeps serving.
    assert call_service(ros_node, client, infer_request(), processes=[echo]).success


def test_risk_and_observation_model_fields_travel(ros_node: Any, echo: NodeProcess) -> None:
    """The new fields cross DDS with their values: PlanPath's risk / risk_level both ways (the echo
    answers with the request's measure and twice its level), InferReward's proxy_counts /
    designer_temperature and the RewardPosterior that records them; PlanInfo's in the topic cases."""
    from ird_msgs.srv import InferReward, PlanPath

    plan_client = ros_node.create_client(PlanPath, "/roundtrip/plan_path")
    wait_for_service(ros_node, plan_client, processes=[echo])
    request = SERVICE_REQUESTS["plan_path"]()
    plan = call_service(ros_node, plan_client, request, processes=[echo])
    assert (request.risk, request.risk_level) == ("cvar", 0.1)
    assert (plan.risk, plan.risk_level) == ("cvar", 0.2)
    infer_client = ros_node.create_client(InferReward, "/roundtrip/infer_reward")
    wait_for_service(ros_node, infer_client, processes=[echo])
    inferred = call_service(ros_node, infer_client, infer_request(), processes=[echo])
    assert inferred.success, inferred.message
    posterior = conv.posterior_from_msg(inferred.posterior)
    assert (posterior.proxy_counts, posterior.designer_temperature) == ("optimal", 0.3)
    info = TOPIC_CASES["plan_info"][1]()
    assert (info.risk, info.risk_level) == ("cvar", 0.1)
