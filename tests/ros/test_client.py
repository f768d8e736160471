"""ird_ros.client: how answers are classified (one place for "busy"), a query result's kind and
proxy weights, what a client reports when the graph is not in its domain, and the minimal
inference client (``ird-infer``) end to end."""

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


def _query_response(kind: str, proxies: list[float], proxy_names: list[str]) -> Any:
    """A ProposeQuery response with two options on a 3x3 map (resolution 1, origin 0)."""
    from nav_msgs.msg import Path
    from geometry_msgs.msg import PoseStamped

    from ird_msgs.srv import ProposeQuery

    def path(cells: list[tuple[int, int]]) -> Path:
        out = Path()
        for r, c in cells:
            pose = PoseStamped()
            pose.pose.position.x, pose.pose.position.y = c + 0.5, r + 0.5
            out.poses.append(pose)
        return out

    return ProposeQuery.Response(success=True, message="query 4: 2 options", query_id=4, kind=kind,
                                 options=[path([(0, 0), (0, 1)]), path([(0, 0), (1, 0)])],
                                 option_proxies=proxies, proxy_feature_names=proxy_names,
                                 feature_names=["a", "b"], option_features=[1.0, 0.0, 0.0, 1.0],
                                 information_gain=0.5)


def _decode_query(response: Any) -> Any:
    """What IrdClient.propose_query does with a response: its decoder, then decode_answer."""
    import numpy as np

    from ird_ros import conversions as conv
    from ird_ros.client.results import decode_answer

    grid = conv.feature_grid_to_msg(np.zeros((3, 3, 2), np.float32), ("a", "b"))
    return decode_answer(names.SRV_QUERY, response, lambda r: IrdClient._decode_query(r, grid))


def test_a_query_result_carries_its_kind_and_proxy_weights() -> None:
    import numpy as np

    from ird_ros.client import Query

    result = _decode_query(_query_response("proxies", [0.1, -0.2, 1.0, 0.5, 0.3, 0.0], ["dirt", "grass", "lava"]))
    query = result.unwrap()
    assert isinstance(query, Query) and query.kind == "proxies" and query.query_id == 4
    assert query.proxy_feature_names == ("dirt", "grass", "lava")
    np.testing.assert_array_equal(query.option_proxies, [[0.1, -0.2, 1.0], [0.5, 0.3, 0.0]])
    assert [o.tolist() for o in query.options] == [[[0, 0], [0, 1]], [[0, 0], [1, 0]]]
    # A paths query (and an older server's "" kind): "paths", no proxies.
    for kind in ("paths", ""):
        paths = _decode_query(_query_response(kind, [], [])).unwrap()
        assert paths.kind == "paths" and paths.option_proxies.shape == (2, 0) and paths.proxy_feature_names == ()
    with pytest.raises(ValueError, match="^option_proxies:"):
        _decode_query(_query_response("proxies", [0.1, 0.2, 0.3], ["dirt", "grass"]))


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


def test_call_inference_passes_the_observation_model(inference: NodeProcess,
                                                    capsys: pytest.CaptureFixture[str]) -> None:
    """--proxy-counts / --designer-temperature reach /ird/infer: the posterior records them; a
    temperature out of range is refused by the client before it asks (status 2, naming the option)
    and, sent anyway, by the node (``test_refusal_from_the_node_names_the_field``)."""
    assert call_inference.main(["--num-samples", "8", "--beta", "2", "--timeout", "60",
                                "--proxy-counts", "maxent", "--designer-temperature", "0.5"]) == 0
    assert "observation model: maxent proxy counts, designer temperature 0.5" in capsys.readouterr().out
    assert call_inference.main(["--num-samples", "8", "--beta", "2", "--timeout", "60",
                                "--proxy-counts", "optimal"]) == 0
    assert "observation model: optimal proxy counts\n" in capsys.readouterr().out
    with pytest.raises(SystemExit) as refused:
        call_inference.main(["--num-samples", "8", "--timeout", "60", "--designer-temperature", "-2"])
    assert refused.value.code == 2 and "argument --designer-temperature" in capsys.readouterr().err


@pytest.mark.parametrize("field, value", [("beta", -1.0), ("designer_temperature", -2.0)])
def test_refusal_from_the_node_names_the_field(inference: NodeProcess, ros_ctx: Any, field: str,
                                               value: float) -> None:
    request = call_inference.generated_request(0)
    request.beta, request.method, request.num_samples = 2.0, "maxent_z", 4
    setattr(request, field, value)
    with IrdClient(context=ros_ctx, node_name="refusal_client", processes=[inference]) as ird:
        result = ird.infer(request, timeout=60.0)
    assert result.status is CallStatus.REFUSED and result.field == field, result
    assert result.value is None and not result.response.success


# ------------------------------------------------------------------ a server that drops out


class _Future:
    def __init__(self) -> None:
        self.value: Any = None
        self.callbacks: list[Any] = []

    def done(self) -> bool:
        return self.value is not None

    def result(self) -> Any:
        return self.value

    def add_done_callback(self, callback: Any) -> None:
        self.callbacks.append(callback)

    def answer(self, message: str) -> None:
        from std_srvs.srv import Trigger

        self.value = Trigger.Response(success=True, message=message)
        for callback in self.callbacks:
            callback(self)


class _DroppingClient:
    """An rclpy client stand-in whose server can drop out (``ready``) and whose requests are kept."""

    def __init__(self) -> None:
        self.ready = True
        self.sent: list[_Future] = []
        self.removed: list[_Future] = []

    def service_is_ready(self) -> bool:
        return self.ready

    def call_async(self, _request: Any) -> _Future:
        self.sent.append(_Future())
        return self.sent[-1]

    def remove_pending_request(self, future: _Future) -> None:
        self.removed.append(future)


def _pending(resend: bool) -> tuple[Any, _DroppingClient, list[float], list[int]]:
    from ird_ros.client.pending import PendingCall

    client, now, fired = _DroppingClient(), [0.0], [0]
    pending = PendingCall(names.SRV_ROB_STOP, client, object(), None, resend=resend, lost_grace=5.0,
                          clock=lambda: now[0])
    pending.add_done_callback(lambda: fired.__setitem__(0, fired[0] + 1))
    return pending, client, now, fired


def test_a_request_whose_server_dropped_out_is_resent_and_the_first_answer_wins() -> None:
    pending, client, now, fired = _pending(resend=True)
    assert not pending.done() and len(client.sent) == 1
    client.ready = False
    now[0] = 21.0
    assert not pending.done() and pending.server_dropped and len(client.sent) == 1  # nothing sent while away
    client.ready = True
    now[0] = 25.0
    assert not pending.done() and len(client.sent) == 2 and pending.resends == 1 and pending.outage == 4.0
    now[0] = 1000.0
    assert not pending.done()  # a resent request waits for its answer (or the caller's timeout)
    client.sent[1].answer("stopped")
    assert pending.done() and pending.result().message == "stopped" and pending.result().response is not None
    assert client.removed == [client.sent[0]] and fired == [1]
    client.sent[0].answer("late")  # a late answer to the first copy changes nothing
    assert pending.result().message == "stopped" and fired == [1]


def test_a_timeout_note_says_whether_the_server_was_seen_back() -> None:
    pending, client, now, _ = _pending(resend=True)
    assert pending.drop_note() == ""
    client.ready = False
    now[0] = 21.0
    pending.poll()
    now[0] = 81.0
    note = pending.drop_note()
    assert "dropped out of the graph 1 time(s)" in note and "not seen the server back for 60.0 s" in note
    assert "a new IrdClient discovers it" in note
    client.ready = True
    pending.poll()
    assert "dropped out of the graph 1 time(s)" in pending.drop_note() and "not seen" not in pending.drop_note()


def test_a_request_that_is_not_resent_fails_after_the_grace_unless_answered() -> None:
    pending, client, now, fired = _pending(resend=False)
    client.ready = False
    now[0] = 20.0
    pending.poll()
    client.ready = True
    now[0] = 22.5
    pending.poll()
    now[0] = 27.4
    assert not pending.done() and len(client.sent) == 1  # within the grace: an answer may still come
    now[0] = 27.5
    assert pending.done() and fired == [1]
    result = pending.result()
    assert result.status is CallStatus.FAILED and result.response is None and not result.ok
    for words in (names.SRV_ROB_STOP, "dropped out of the graph for 2.5 s", "within 5 s", "may have been carried out"):
        assert words in result.message, result.message
    assert client.removed == [client.sent[0]]
    # answered within the grace instead: the answer, no failure
    pending, client, now, fired = _pending(resend=False)
    client.ready = False
    pending.poll()
    client.ready = True
    pending.poll()
    client.sent[0].answer("stopped after all")
    now[0] = 100.0
    assert pending.done() and pending.result().status is CallStatus.DONE and fired == [1]
    with pytest.raises(ValueError, match="lost_grace"):
        from ird_ros.client.pending import PendingCall

        PendingCall(names.SRV_ROB_STOP, client, object(), None, lost_grace=-1.0)
