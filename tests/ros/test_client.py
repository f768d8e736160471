"""ird_ros.client: how answers are classified (one place for "busy"), what a client reports when
the graph is not in its domain, and the minimal inference client (``ird-infer``) end to end."""

from __future__ import annotations

from typing import Any, Iterator

import pytest
from _inference_node import small_inference_node

from ird_ros.apps import call_inference
from ird_ros.client import (
    CallFailed,
    CallResult,
    CallStatus,
    ClientTimeout,
    GraphNotFound,
    IrdClient,
    classify_answer,
)
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease, lease_domain
from ird_ros.runtime.offload import BUSY_PREFIX
from ird_ros.testing import NodeProcess


@pytest.mark.parametrize("success,message,status,field", [
    (True, "maxent_z: 12 samples", CallStatus.DONE, None),
    (False, f"{BUSY_PREFIX}: 8 requests are pending (max_pending=8); this one would be queue position 9",
     CallStatus.BUSY, None),
    (False, "busy: re-sampling the posterior with an answer; ask again when it is published", CallStatus.BUSY, None),
    (False, "weights: a value of magnitude 1e+308", CallStatus.REFUSED, "weights"),
    (False, "map.data: 6000000 values exceed max_map_values=5000000", CallStatus.REFUSED, "map.data"),
    (False, "training_worlds[0].horizon: must be in [1, 200]", CallStatus.REFUSED, "training_worlds[0].horizon"),
    (False, "/world/proxy.condition: unknown condition 'x'", CallStatus.REFUSED, "/world/proxy.condition"),
    (False, "internal error: the worker process died (boom)", CallStatus.FAILED, None),
    (False, "planning failed: PlanningTimeout: no plan", CallStatus.FAILED, None),
    (False, "the answer was not taken: the evidence was replaced", CallStatus.FAILED, None),
])
def test_answers_are_classified(success: bool, message: str, status: CallStatus, field: str | None) -> None:
    assert classify_answer(success, message) == (status, field)


def test_unwrap_raises_unless_done() -> None:
    done = CallResult("/ird/plan", CallStatus.DONE, "ok", value=3)
    assert done.ok and done.unwrap() == 3
    refused = CallResult("/ird/plan", CallStatus.REFUSED, "weights: bad", field="weights")
    with pytest.raises(CallFailed, match="/ird/plan refused: weights: bad") as info:
        refused.unwrap()
    assert info.value.status is CallStatus.REFUSED and not refused.ok


@pytest.fixture
def empty_domain() -> Iterator[DomainLease]:
    with lease_domain() as lease:
        yield lease


def test_a_missing_graph_names_the_domain_and_how_to_change_it(empty_domain: DomainLease) -> None:
    with IrdClient(empty_domain.domain_id, node_name="lonely_client") as ird:
        assert ird.domain_id == empty_domain.domain_id
        with pytest.raises(GraphNotFound) as info:
            ird.wait_ready(1.0, services=(names.SRV_INFER,))
        message = str(info.value)
        assert isinstance(info.value, TimeoutError) and isinstance(info.value, ClientTimeout)
        assert names.SRV_INFER in message and f"ROS_DOMAIN_ID={empty_domain.domain_id}" in message
        assert "export ROS_DOMAIN_ID=" in message
        with pytest.raises(GraphNotFound, match=names.TOPIC_PROXY):
            ird.proxy(timeout=0.5)
        with pytest.raises(RuntimeError, match="watch_rob"):
            ird.wait_for_rob(None, timeout=0.1)  # type: ignore[arg-type]


def test_call_inference_without_a_graph_exits_1(empty_domain: DomainLease, monkeypatch: pytest.MonkeyPatch,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("ROS_DOMAIN_ID", str(empty_domain.domain_id))
    assert call_inference.main(["--timeout", "1"]) == 1
    err = capsys.readouterr().err
    assert f"ROS_DOMAIN_ID={empty_domain.domain_id}" in err and "export ROS_DOMAIN_ID=" in err


@pytest.fixture(scope="module")
def inference(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    with small_inference_node(ros_domain) as proc:
        yield proc


def test_call_inference_prints_the_posterior(inference: NodeProcess, capsys: pytest.CaptureFixture[str]) -> None:
    """The module's domain (ROS_DOMAIN_ID of the ros_domain fixture) holds the inference node."""
    assert call_inference.main(["--num-samples", "8", "--beta", "2", "--timeout", "60"]) == 0
    out = capsys.readouterr().out
    assert "maxent_z, beta=2" in out and "8 samples from 4 chains" in out
    for feature in ("dirt", "grass", "target"):
        assert any(line.startswith(feature) for line in out.splitlines()), out
    assert "acceptance" in out and "R-hat max" in out


def test_refusal_from_the_node_names_the_field(inference: NodeProcess, ros_ctx: Any) -> None:
    request = call_inference.generated_request(0)
    request.beta, request.method, request.num_samples = -1.0, "maxent_z", 4
    with IrdClient(context=ros_ctx, node_name="refusal_client", processes=[inference]) as ird:
        result = ird.infer(request, timeout=60.0)
    assert result.status is CallStatus.REFUSED and result.field == "beta", result
    assert result.value is None and not result.response.success
