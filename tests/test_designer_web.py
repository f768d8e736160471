"""The designer's web server without ROS or a browser: state endpoint, live pushes, the checks
that keep bad or stale clicks from ever reaching the node's answer callback, and the caps that
keep hostile clients from breaking or tying up the server (oversized and deeply nested bodies,
slowloris connections, oversized WebSocket messages, exceptions in a handler); options named by
letters in every message, no sampler statistics in the thank-you line, the end state pushed
before the server stops, and a Gaussian-feature world's posterior shown per terrain."""

from __future__ import annotations

import asyncio
import concurrent.futures
import gc
import json
import logging
import socket
import threading
import time
import urllib.error
import urllib.request
from typing import Any, Iterator

import numpy as np
import pytest
import tornado.websocket

from ird_core.experiments.posterior_terrain import terrain_spreads
from ird_core.worlds import lavaland
from ird_ros.web import limits, terrain_view
from ird_ros.web.server import WEB_DIR, WebDesigner, is_loopback

WORLD = {"height": 3, "width": 4, "class_names": ["dirt", "grass", "target", "lava"],
         "classes": [[0, 0, 1, 2], [0, 3, 1, 0], [1, 1, 0, 0]], "start": [0, 0], "stamp": 1.0}


def record(query_id: int, chosen: int = -1, who: str = "") -> dict[str, Any]:
    return {"query_id": query_id, "event": "answered" if chosen >= 0 else "proposed", "strategy": "info_gain",
            "options": [[[0, 0], [0, 1], [0, 2]], [[0, 0], [1, 0], [2, 0]]],
            "feature_names": ["dirt", "grass", "target", "lava"],
            "option_features": [[2.0, 1.0, 0.0, 0.0], [2.0, 1.0, 0.0, 0.0]],
            "information_gain": 0.25, "chosen": chosen, "beta": 1.0 if chosen >= 0 else 0.0,
            "answered_by": who, "num_answers": 1 if chosen >= 0 else 0, "stamp": 2.0}


THANK_YOU = "Thank you: Option {letter} recorded for question #{query}; Rob's beliefs are updated."
# What the inference node's /ird/answer says on success (sampler statistics the page must not show).
NODE_SUCCESS = ("query 7: option 1 by web; 2 answers, acceptance 0.31, maxent_z, 400 samples, R-hat 1.012, "
                "ESS 812 (converged)")
SAMPLER_WORDS = ("R-hat", "ESS", "acceptance", "samples", "maxent", "option 1")


class FakeNode:
    """on_answer that records its calls; ``gate`` holds a call open until released."""

    def __init__(self) -> None:
        self.calls: list[tuple[int, int]] = []
        self.reply: tuple[bool, str] = (True, "posterior re-sampled")
        self.gate: threading.Event | None = None
        self.entered = threading.Event()

    def __call__(self, query_id: int, chosen: int) -> tuple[bool, str]:
        assert isinstance(query_id, int) and isinstance(chosen, int)
        self.calls.append((query_id, chosen))
        self.entered.set()
        if self.gate is not None:
            assert self.gate.wait(30.0)
        return self.reply


@pytest.fixture
def node() -> FakeNode:
    return FakeNode()


@pytest.fixture
def web(node: FakeNode) -> Iterator[WebDesigner]:
    server = WebDesigner("127.0.0.1", 0, node)
    server.start()
    server.show_world(WORLD)
    try:
        yield server
    finally:
        server.stop()


def request(web: WebDesigner, path: str, body: Any = None, *, raw: bytes | None = None,
            content_type: str = "application/json", host: str | None = None) -> tuple[int, Any]:
    data = raw if raw is not None else None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(web.url.rstrip("/") + path, data=data, method="POST" if data is not None else "GET")
    if data is not None:
        req.add_header("Content-Type", content_type)
    if host is not None:
        req.add_header("Host", host)
    try:
        with urllib.request.urlopen(req, timeout=30) as resp:
            payload = resp.read()
            status = resp.status
    except urllib.error.HTTPError as err:
        payload, status = err.read(), err.code
    try:
        return status, json.loads(payload)
    except ValueError:
        return status, payload.decode(errors="replace")


def answer(web: WebDesigner, query_id: Any, chosen: Any) -> tuple[int, dict[str, Any]]:
    return request(web, "/answer", {"query_id": query_id, "chosen": chosen})


def test_page_and_assets_are_served_locally(web: WebDesigner) -> None:
    status, page = request(web, "/")
    assert status == 200 and "<canvas" in page
    for asset in ("app.js", "style.css"):
        assert (WEB_DIR / asset).is_file()
        status, text = request(web, f"/static/{asset}")
        assert status == 200 and text == (WEB_DIR / asset).read_text()
    # Every asset comes from this server: no external URL in the page or its assets.
    for path in WEB_DIR.iterdir():
        assert "http://" not in path.read_text() and "https://" not in path.read_text(), path


def test_state_endpoint_follows_the_node(web: WebDesigner) -> None:
    status, state = request(web, "/state")
    assert status == 200
    assert state["world"] == WORLD and state["query"] is None and state["history"] == []
    web.show_query(record(7))
    state = request(web, "/state")[1]
    assert state["query"]["query_id"] == 7 and state["history"] == []
    web.show_answer(record(7, chosen=1, who="simulated"))
    state = request(web, "/state")[1]
    assert state["query"] is None and [r["query_id"] for r in state["history"]] == [7]
    # A re-shown proposal (respawned node) never reopens an answered query.
    web.show_query(record(7))
    assert request(web, "/state")[1]["query"] is None
    posterior = {"feature_names": ["dirt"], "mean": [0.1], "std": [0.2], "num_samples": 10, "num_answers": 1,
                 "method": "maxent_z", "converged": True, "r_hat_max": 1.0, "stamp": 3.0}
    risk = {"height": 3, "width": 4, "values": [[0, 1, 2, 3]] * 3, "stamp": 3.0}
    web.show_posterior(posterior, risk)
    state = request(web, "/state")[1]
    assert state["posterior"] == posterior and state["risk_map"] == risk
    assert state == web.state()


def test_accepted_answer_calls_the_node_once(web: WebDesigner, node: FakeNode) -> None:
    web.show_query(record(7))
    status, reply = answer(web, 7, 1)
    assert (status, reply) == (200, {"ok": True, "message": THANK_YOU.format(letter="B", query=7)})
    assert node.calls == [(7, 1)]
    # A second click on the answered query (before or after the node's record arrives).
    status, reply = answer(web, 7, 0)
    assert status == 409 and not reply["ok"] and "already answered" in reply["message"]
    web.show_answer(record(7, chosen=1, who="web"))
    status, reply = answer(web, 7, 1)
    assert status == 409 and "already answered" in reply["message"] and "by web" in reply["message"]
    assert node.calls == [(7, 1)]


def test_the_thank_you_names_the_option_by_its_letter_without_sampler_statistics(web: WebDesigner,
                                                                                node: FakeNode) -> None:
    web.show_query(record(7))
    node.reply = (True, NODE_SUCCESS)
    status, reply = answer(web, 7, 1)
    assert status == 200 and reply == {"ok": True, "message": THANK_YOU.format(letter="B", query=7)}
    for word in SAMPLER_WORDS:
        assert word not in reply["message"], word


def test_refusals_name_options_by_letters(web: WebDesigner, node: FakeNode) -> None:
    web.show_query(record(7))
    status, reply = answer(web, 7, 2)
    assert status == 400 and reply["message"] == "chosen: Option C is out of range: query 7 has 2 options (A..B)"
    assert answer(web, 7, 1)[0] == 200
    status, reply = answer(web, 7, 0)  # accepted from this page: named by the letter accepted
    assert status == 409 and "(Option B)" in reply["message"] and "option 1" not in reply["message"]
    web.show_query(record(8))
    web.show_answer(record(8, chosen=0, who="simulated"))
    status, reply = answer(web, 8, 1)
    assert status == 409 and "(Option A, by simulated)" in reply["message"]
    assert node.calls == [(7, 1)]


@pytest.mark.parametrize(
    ("query_id", "chosen", "status", "field", "words"),
    [
        (99, 0, 404, "query_id", "unknown query 99"),
        (7, 2, 400, "chosen", "out of range"),
        (7, -1, 400, "chosen", "out of range"),
        ("7", 0, 400, "query_id", "expected an integer"),
        (7, 1.0, 400, "chosen", "expected an integer"),
        (7, True, 400, "chosen", "expected an integer"),
        (None, 0, 400, "query_id", "expected an integer"),
    ],
)
def test_forged_or_malformed_clicks_are_refused(web: WebDesigner, node: FakeNode, query_id: Any, chosen: Any,
                                                status: int, field: str, words: str) -> None:
    web.show_query(record(7))
    before = web.state()
    got_status, reply = answer(web, query_id, chosen)
    assert got_status == status and reply["ok"] is False
    assert reply["message"].startswith(field + ":") and words in reply["message"]
    assert node.calls == [] and web.state() == before


def test_non_json_and_bad_bodies_are_refused(web: WebDesigner, node: FakeNode) -> None:
    web.show_query(record(7))
    # A plain form post (what another web site could make a browser send) is refused.
    status, reply = request(web, "/answer", raw=b"query_id=7&chosen=0", content_type="application/x-www-form-urlencoded")
    assert status == 415 and "application/json" in reply["message"]
    status, reply = request(web, "/answer", raw=b"{not json")
    assert status == 400 and reply["message"].startswith("body:")
    status, reply = request(web, "/answer", raw=b"[7, 0]")
    assert status == 400 and reply["message"].startswith("body:")
    assert node.calls == []


def test_double_click_while_the_first_is_in_flight(web: WebDesigner, node: FakeNode) -> None:
    web.show_query(record(7))
    node.gate = threading.Event()
    first: list[tuple[int, dict[str, Any]]] = []
    thread = threading.Thread(target=lambda: first.append(answer(web, 7, 0)))
    thread.start()
    assert node.entered.wait(30.0)
    assert request(web, "/state")[1]["pending"] == [7]
    status, reply = answer(web, 7, 1)
    assert status == 409 and "already being sent" in reply["message"]
    node.gate.set()
    thread.join(30.0)
    assert first == [(200, {"ok": True, "message": THANK_YOU.format(letter="A", query=7)})]
    assert node.calls == [(7, 0)]
    assert request(web, "/state")[1]["pending"] == []


def test_node_refusal_is_shown_and_the_query_stays_open(web: WebDesigner, node: FakeNode) -> None:
    web.show_query(record(7))
    node.reply = (False, "busy: re-sampling the posterior")
    status, reply = answer(web, 7, 0)
    assert status == 409 and reply == {"ok": False, "message": "busy: re-sampling the posterior"}
    state = request(web, "/state")[1]
    assert state["query"]["query_id"] == 7 and state["pending"] == []
    node.reply = (True, "ok")
    assert answer(web, 7, 0)[0] == 200
    assert node.calls == [(7, 0), (7, 0)]


def test_failing_callback_is_a_refusal(web: WebDesigner, node: FakeNode) -> None:
    def broken(query_id: int, chosen: int) -> tuple[bool, str]:
        raise RuntimeError("service gone")

    web.on_answer = broken
    web.show_query(record(7))
    status, reply = answer(web, 7, 0)
    assert status == 409 and reply["ok"] is False and "service gone" in reply["message"]
    assert request(web, "/state")[1]["query"]["query_id"] == 7


def test_new_world_makes_old_queries_stale(web: WebDesigner, node: FakeNode) -> None:
    web.show_query(record(7))
    web.show_world(dict(WORLD, stamp=5.0))
    status, reply = answer(web, 7, 0)
    assert status == 409 and "earlier world" in reply["message"]
    assert request(web, "/state")[1]["query"] is None and node.calls == []


def test_websocket_pushes_every_change(web: WebDesigner) -> None:
    async def scenario() -> list[dict[str, Any]]:
        conn = await tornado.websocket.websocket_connect(web.url.replace("http", "ws") + "ws")
        seen = [json.loads(await conn.read_message())]
        web.show_query(record(7))
        seen.append(json.loads(await conn.read_message()))
        web.show_answer(record(7, chosen=0, who="simulated"))
        seen.append(json.loads(await conn.read_message()))
        conn.close()
        return seen

    seen = asyncio.run(asyncio.wait_for(scenario(), 30.0))
    assert seen[0]["query"] is None
    assert seen[1]["query"]["query_id"] == 7
    assert seen[2]["query"] is None and seen[2]["history"][0]["answered_by"] == "simulated"
    assert seen[0]["version"] < seen[1]["version"] < seen[2]["version"]


def test_the_end_state_reaches_the_page_before_the_server_stops(node: FakeNode) -> None:
    server = WebDesigner("127.0.0.1", 0, node)
    server.start()
    server.show_world(WORLD)
    server.show_query(record(7))

    async def scenario() -> tuple[list[dict[str, Any]], Any]:
        conn = await tornado.websocket.websocket_connect(server.url.replace("http", "ws") + "ws")
        seen = [json.loads(await conn.read_message())]
        await asyncio.get_running_loop().run_in_executor(None, server.stop)
        while (message := await conn.read_message()) is not None:
            seen.append(json.loads(message))
        return seen, conn.close_code

    try:
        seen, code = asyncio.run(asyncio.wait_for(scenario(), 30.0))
    finally:
        server.stop()
    assert seen[0]["finished"] is None and seen[0]["query"]["query_id"] == 7
    assert seen[-1]["finished"] == "graph stopped" and seen[-1]["query"] is None and code == 1001


def test_a_finished_mission_closes_the_question(web: WebDesigner, node: FakeNode) -> None:
    web.show_query(record(7))
    web.finish("mission finished")
    state = request(web, "/state")[1]
    assert state["finished"] == "mission finished" and state["query"] is None
    status, reply = answer(web, 7, 0)
    assert status == 409 and reply["message"].startswith("finished: mission finished")
    assert node.calls == []


def test_a_gaussian_world_posterior_is_shown_per_terrain(web: WebDesigner) -> None:
    from ird_ros.conversions import PosteriorData
    from ird_ros.nodes.designer import posterior_dict

    inst = lavaland.make_instance("latent_raw", 4, size=8, horizon=10)
    assert inst.feature_names[0] == "obs_00"
    samples = np.random.default_rng(0).normal(size=(40, len(inst.feature_names)))
    post = PosteriorData(samples=samples, feature_names=tuple(inst.feature_names), proxy_weights=inst.proxy_weights,
                         method="maxent_z", beta=1.0, prior_sigma=1.0, acceptance_rate=0.5, r_hat_max=1.0,
                         ess_min=100.0, num_chains=4, seed=0, converged=True)
    # what the node knows: /world/proxy's condition, seed, horizon, test start and /world/terrain
    made = terrain_view.gaussian_instance("latent_raw", 4, inst.test_labels, inst.terrain_names, inst.train_horizon,
                                          inst.test_start, inst.feature_names)
    assert made is not None
    web.show_posterior(posterior_dict(post, 0, 3.0, instance=made), None)
    shown = request(web, "/state")[1]["posterior"]
    assert shown["feature_names"] == ["dirt", "grass", "target", "lava"] and shown["features"] == "terrains"
    spreads = terrain_spreads(samples, inst)
    assert shown["mean"] == pytest.approx([row["mean_reward"] for row in spreads.values()])
    assert shown["std"] == pytest.approx([row["sd_of_mean_reward"] for row in spreads.values()])
    assert not any(name.startswith("obs_") for name in shown["feature_names"])
    # what was published must match the instance made again: another seed's terrain does not
    other = lavaland.make_instance("latent_raw", 5, size=8, horizon=10)
    assert terrain_view.gaussian_instance("latent_raw", 4, other.test_labels, inst.terrain_names,
                                          inst.train_horizon, inst.test_start, inst.feature_names) is None
    assert terrain_view.gaussian_instance("side_effects", 4, inst.test_labels, inst.terrain_names,
                                          inst.train_horizon, inst.test_start, inst.feature_names) is None
    # and when it cannot be made again, the page is told the rows are observation dimensions
    said = posterior_dict(post, 0, 3.0, observations=True)
    assert said["feature_names"][0] == "obs_00" and said["features"] == "observations"
    assert "observation dimensions, not terrains" in said["feature_note"]


def test_foreign_host_header_is_refused_on_loopback(web: WebDesigner) -> None:
    status, _ = request(web, "/state", host="evil.example:80")
    assert status == 403
    assert request(web, "/state", host="localhost")[0] == 200


def test_binding_and_arguments(caplog: pytest.LogCaptureFixture) -> None:
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost") and is_loopback("127.3.0.1")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.0.2.1") and not is_loopback("example.org")
    with pytest.raises(ValueError, match="port"):
        WebDesigner("127.0.0.1", 70000, lambda q, c: (True, ""))
    with pytest.raises(ValueError, match="on_answer"):
        WebDesigner("127.0.0.1", 0, None)
    # Loopback: no warning, and the URL names the bound port.
    with caplog.at_level(logging.WARNING, logger="ird_ros.web.server"):
        with WebDesigner("127.0.0.1", 0, lambda q, c: (True, "")) as quiet:
            assert not quiet.url.endswith(":0/")
            assert request(quiet, "/state")[0] == 200
            quiet.stop()  # stop is idempotent: leaving the block stops again
            with pytest.raises(urllib.error.URLError):
                urllib.request.urlopen(quiet.url + "state", timeout=10)
    assert not caplog.records
    # Any other address is allowed but logged as a warning (no authentication on the page);
    # the warning comes with the configuration, so the test never binds a non-loopback address.
    with caplog.at_level(logging.WARNING, logger="ird_ros.web.server"):
        WebDesigner("0.0.0.0", 0, lambda q, c: (True, ""))
    assert any("not loopback" in r.getMessage() for r in caplog.records)


# ------------------------------------------------------------------------------ caps


def test_an_oversized_body_is_refused_with_413_naming_the_limit(web: WebDesigner, node: FakeNode) -> None:
    web.show_query(record(7))
    padding = "x" * (limits.MAX_BODY_BYTES + 1)
    status, reply = request(web, "/answer", raw=json.dumps({"query_id": 7, "chosen": 0, "pad": padding}).encode())
    assert status == 413 and reply["ok"] is False
    assert reply["message"].startswith("body:") and str(limits.MAX_BODY_BYTES) in reply["message"]
    assert limits.MAX_BODY_BYTES == 64 * 1024 and "the limit is 64 KiB" in reply["message"]
    # a body announced far beyond the limit: refused from the header alone, nothing of it read
    head = (b"POST /answer HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            b"Content-Length: %d\r\n\r\n" % (100 * limits.MAX_BODY_BYTES))
    answer_bytes = _closed_by_server(web, head)
    assert answer_bytes.startswith(b"HTTP/1.1 413 "), answer_bytes
    assert "64 KiB" in json.loads(answer_bytes.split(b"\r\n\r\n", 1)[1])["message"]
    assert node.calls == [] and answer(web, 7, 0)[0] == 200  # a body at the limit is fine, and the server serves


@pytest.mark.parametrize("body", [
    b"[" * 20000 + b"]" * 20000,  # would exhaust json.loads' recursion (was an HTTP 500)
    b'{"query_id": 7, "chosen": ' + b"[" * (limits.MAX_JSON_DEPTH + 1) + b"]" * (limits.MAX_JSON_DEPTH + 1) + b"}",
])
def test_deeply_nested_json_is_refused_with_400_naming_the_limit(web: WebDesigner, node: FakeNode,
                                                                  body: bytes) -> None:
    web.show_query(record(7))
    status, reply = request(web, "/answer", raw=body)
    assert status == 400 and reply["message"].startswith("body: JSON nested deeper than")
    assert f"the limit is {limits.MAX_JSON_DEPTH}" in reply["message"]
    assert node.calls == [] and request(web, "/state")[0] == 200


def test_json_depth_counts_brackets_outside_strings_only() -> None:
    assert limits.json_depth(b"7") == 0 and limits.json_depth(b"{}") == 1
    assert limits.json_depth(b'{"a": [[1], {"b": []}]}') == 4
    assert limits.json_depth(b'["[[[[", "\\", "\"[[["]') == 1
    assert limits.json_depth(b"[" * 100, stop_above=5) == 6
    at_limit = b"[" * limits.MAX_JSON_DEPTH + b"]" * limits.MAX_JSON_DEPTH
    limits.check_json_depth(at_limit)
    with pytest.raises(ValueError, match=f"limit is {limits.MAX_JSON_DEPTH}"):
        limits.check_json_depth(b"[" + at_limit + b"]")


@pytest.fixture
def impatient(node: FakeNode) -> Iterator[WebDesigner]:
    server = WebDesigner("127.0.0.1", 0, node, idle_timeout=1.0, body_timeout=1.0)
    server.start()
    try:
        yield server
    finally:
        server.stop()


def _closed_by_server(web: WebDesigner, first_bytes: bytes) -> bytes:
    """Send ``first_bytes`` and nothing more; return what the server sent until it closed the
    connection (recv b''). The socket timeout (30 s) only bounds a broken server."""
    with socket.create_connection(("127.0.0.1", int(web.url.rsplit(":", 1)[1].strip("/"))), timeout=30) as sock:
        sock.sendall(first_bytes)
        received = b""
        while chunk := sock.recv(4096):
            received += chunk
        return received


def test_slow_clients_are_disconnected_and_the_server_keeps_serving(impatient: WebDesigner) -> None:
    # slowloris: part of a header line, then nothing
    assert _closed_by_server(impatient, b"GET /state HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Slow: a") == b""
    # a body that never arrives in full
    head = (b"POST /answer HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Type: application/json\r\n"
            b"Content-Length: 100\r\n\r\n{")
    assert _closed_by_server(impatient, head) == b""
    assert request(impatient, "/state")[0] == 200


def test_a_failing_handler_is_a_json_500_and_the_server_keeps_serving(web: WebDesigner,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    def broken() -> str:
        raise RuntimeError("state went away")

    monkeypatch.setattr(web, "state_json", broken)
    status, reply = request(web, "/state")
    assert status == 500 and reply == {"ok": False, "message": "internal error: RuntimeError (the server keeps serving)"}
    monkeypatch.undo()
    assert request(web, "/state")[0] == 200
    status, reply = request(web, "/state", host="evil.example")
    assert status == 403 and reply == {"ok": False, "message": "Host not allowed"}


def test_an_oversized_websocket_message_closes_that_socket_only(web: WebDesigner) -> None:
    async def scenario() -> tuple[Any, Any]:
        url = web.url.replace("http", "ws") + "ws"
        conn = await tornado.websocket.websocket_connect(url)
        await conn.read_message()  # the state
        await conn.write_message("x" * (limits.MAX_WS_MESSAGE_BYTES + 1))
        closed = await conn.read_message()  # None: the server closed the socket
        other = await tornado.websocket.websocket_connect(url)
        state = await other.read_message()
        other.close()
        return closed, conn.close_code, state

    closed, code, state = asyncio.run(asyncio.wait_for(scenario(), 30.0))
    assert closed is None and code == 1009 and json.loads(state)["world"] == WORLD


TRAIN_WORLD = {"height": 4, "width": 5, "class_names": WORLD["class_names"],
               "classes": [[0, 0, 0, 1, 2], [0, 1, 1, 1, 0], [0, 0, 2, 1, 0], [1, 1, 0, 0, 0]], "start": [0, 0],
               "stamp": 1.0}


def proxies_record(query_id: int, chosen: int = -1) -> dict[str, Any]:
    """A proxy-choice query: two proxies' plans on the 4x5 TRAINING map (off the 3x4 test map)."""
    out = record(query_id, chosen, "web" if chosen >= 0 else "")
    out.update(kind="proxies", options=[[[0, 0], [0, 1], [0, 2], [0, 3], [0, 4]], [[0, 0], [1, 0], [2, 0], [3, 0],
                                                                                     [3, 1]]],
               option_proxies=[[0.1, -0.2, 1.0, -0.7], [0.1, -0.2, 1.0, 0.4]],
               proxy_feature_names=["dirt", "grass", "target", "lava"])
    return out


def test_a_proxies_record_is_shown_with_its_kind_weights_and_the_training_map(web: WebDesigner,
                                                                              node: FakeNode) -> None:
    from ird_ros.bags.rounds import event_from_msg, record_dict
    from ird_ros.nodes.designer import proxy_names

    web.show_train_world(TRAIN_WORLD)
    web.show_query(proxies_record(8))
    state = request(web, "/state")[1]
    query = state["query"]
    assert query["kind"] == "proxies" and query["proxy_feature_names"] == ["dirt", "grass", "target", "lava"]
    assert query["option_proxies"] == [[0.1, -0.2, 1.0, -0.7], [0.1, -0.2, 1.0, 0.4]]
    # The options lie on the training map the page is given, not on the (smaller) test map.
    assert state["train_world"] == TRAIN_WORLD and state["world"] == WORLD
    cells = [cell for option in query["options"] for cell in option]
    assert all(0 <= r < TRAIN_WORLD["height"] and 0 <= c < TRAIN_WORLD["width"] for r, c in cells)
    assert any(c >= WORLD["width"] or r >= WORLD["height"] for r, c in cells)
    # The page says each kind's question, draws a proxies question on the training map and shows
    # each option's weights beside its letter.
    app = (WEB_DIR / "app.js").read_text()
    for text in ("Which path do you prefer?", "Which reward would you have written for the training world?",
                 "state.train_world", "proxyWeights(query, k)", "Option ${letter(k)}"):
        assert text in app, text
    # Letters in refusals and the thank-you, answered by option index like a paths question.
    status, reply = answer(web, 8, 2)
    assert status == 400 and "Option C is out of range" in reply["message"] and "(A..B)" in reply["message"]
    status, reply = answer(web, 8, 1)
    assert status == 200 and reply["message"] == THANK_YOU.format(letter="B", query=8) and node.calls == [(8, 1)]
    web.show_answer(proxies_record(8, chosen=1))
    assert request(web, "/state")[1]["history"][0]["kind"] == "proxies"
    # A new world forgets the training map with the queries.
    web.show_world(dict(WORLD, stamp=5.0))
    assert request(web, "/state")[1]["train_world"] is None
    # The node's dict of a decoded record, and the proxy names it adds (w1.. when /world/proxy's do not fit).
    assert proxy_names(["dirt", "lava"], 2) == ["dirt", "lava"] and proxy_names(["dirt"], 2) == ["w1", "w2"]
    ns = _ns_record(kind="proxies", option_proxies=[0.5, -1.0, 2.0, 0.0])
    assert record_dict(event_from_msg(ns))["option_proxies"] == [[0.5, -1.0], [2.0, 0.0]]


def _ns_record(**kw: Any) -> Any:
    from types import SimpleNamespace as NS

    def path(cells: list[tuple[int, int]]) -> Any:
        return NS(poses=[NS(pose=NS(position=NS(x=c + 0.5, y=r + 0.5))) for r, c in cells])

    return NS(header=NS(stamp=NS(sec=1, nanosec=0)), query_id=1, event="proposed", strategy="random",
              options=[path([(0, 0), (0, 1)]), path([(0, 0), (1, 0)])], feature_names=["a"],
              option_features=[1.0, 2.0], information_gain=0.1, chosen=-1, beta=0.0, answered_by="",
              num_answers=0, **kw)


@pytest.mark.parametrize("condition", ["side_effects", "reward_hacking", "pot_of_gold", "latent_raw"])
def test_the_training_maps_terrain_is_recovered_from_its_features(condition: str) -> None:
    inst = lavaland.make_instance(condition, 6, size=9, horizon=10)
    made = None
    if condition in terrain_view.GAUSSIAN_CONDITIONS:  # what the node makes again from /world/proxy and /world/terrain
        made = terrain_view.gaussian_instance(condition, 6, inst.test_labels, inst.terrain_names, inst.train_horizon,
                                              inst.test_start, inst.feature_names)
        assert made is not None
    as_published = (inst.train_features.astype(np.float32), inst.test_features.astype(np.float32))
    got = terrain_view.training_classes(*as_published, inst.test_labels, made)
    # Every terrain of the training map is on the test map here, so every cell is known.
    assert set(np.unique(inst.train_labels)) <= set(np.unique(inst.test_labels))
    np.testing.assert_array_equal(got, inst.train_labels)


def test_unknowable_training_cells_are_unknown() -> None:
    inst = lavaland.make_instance("side_effects", 6, size=9, horizon=10)
    train, test = inst.train_features, inst.test_features
    # A terrain missing from the test map cannot be told: its training cells are unknown (255).
    no_grass = np.where(inst.test_labels == 1, 0, inst.test_labels)
    test_no_grass = np.where((inst.test_labels == 1)[..., None], test[inst.test_labels == 0][0], test)
    got = terrain_view.training_classes(train, test_no_grass, no_grass)
    assert np.all(got[inst.train_labels == 1] == terrain_view.UNKNOWN)
    assert np.array_equal(got[inst.train_labels != 1], inst.train_labels[inst.train_labels != 1])
    # Gaussian features without the instance: no terrain has one feature vector, nothing is known.
    latent = lavaland.make_instance("latent_raw", 6, size=9, horizon=10)
    assert np.all(terrain_view.training_classes(latent.train_features, latent.test_features,
                                                latent.test_labels) == terrain_view.UNKNOWN)
    # An instance whose training features are not the published ones is not used.
    other = lavaland.make_instance("latent_raw", 7, size=9, horizon=10)
    assert np.all(terrain_view.training_classes(latent.train_features, latent.test_features, latent.test_labels,
                                                other) == terrain_view.UNKNOWN)
    # A test map of other layers tells nothing.
    assert np.all(terrain_view.training_classes(train, test[..., :2], inst.test_labels) == terrain_view.UNKNOWN)


# ---------------------------------------------------------------------- sockets that never read (issue 43)

BIG_WORLD = {"height": 250, "width": 250, "class_names": WORLD["class_names"],
             "classes": [[(r * 7 + c) % 4 for c in range(250)] for r in range(250)], "start": [0, 0], "stamp": 1.0}


def _never_retrieved(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [r.getMessage() for r in caplog.records if "never retrieved" in r.getMessage()]


def _pending_bytes(web: WebDesigner) -> list[int]:
    """Bytes each open socket's stream still has to send (Tornado's write buffer)."""
    out = []
    for sock in list(web._sockets):
        conn = sock.ws_connection
        stream = None if conn is None else conn.stream
        out.append(0 if stream is None else len(stream._write_buffer))
    return out


def _on_loop(web: WebDesigner, fn: Any) -> Any:
    """Run ``fn()`` on the server's event loop and return its result (the loop has handled
    everything scheduled before)."""
    assert web._loop is not None
    done: concurrent.futures.Future = concurrent.futures.Future()
    web._loop.call_soon_threadsafe(lambda: done.set_result(fn()))
    return done.result(30.0)


def test_a_socket_that_never_reads_holds_one_state_and_its_close_logs_no_traceback(
        web: WebDesigner, caplog: pytest.LogCaptureFixture) -> None:
    """A page that stops reading must not make the server queue every state for it (memory), and
    its pending writes, failed by the close, must not each log an unretrieved-task traceback."""
    caplog.set_level(logging.ERROR)
    web.show_world(BIG_WORLD)
    size = len(web.state_json())
    pushes = 150  # about 28 MB in all: more than the kernel's socket buffers hold

    async def scenario() -> list[int]:
        url = web.url.replace("http", "ws") + "ws"
        conn = await tornado.websocket.websocket_connect(url)  # reads nothing from here on
        for i in range(pushes):
            web.show_posterior({"feature_names": ["a"], "mean": [float(i)], "std": [0.0]}, None)
        pending = await asyncio.get_running_loop().run_in_executor(None, _on_loop, web,
                                                                   lambda: _pending_bytes(web))
        conn.stream.socket.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        conn.stream.close()  # a reset: the server's pending writes fail
        return pending

    pending = asyncio.run(asyncio.wait_for(scenario(), 60.0))
    # the server notices the reset, drops the socket, and its loop moves on
    deadline = time.monotonic() + 30.0
    while _on_loop(web, lambda: len(web._sockets)) and time.monotonic() < deadline:
        request(web, "/state")
    assert _on_loop(web, lambda: len(web._sockets)) == 0
    _on_loop(web, gc.collect)
    gc.collect()
    assert _never_retrieved(caplog) == []
    assert request(web, "/state")[0] == 200
    # at most the state being sent and the newest one waited for it (not every state since)
    assert pending and max(pending) <= 2 * size + 1024, (pending, size)


def test_open_pages_are_capped_and_an_extra_one_is_refused_with_a_reason(node: FakeNode) -> None:
    server = WebDesigner("127.0.0.1", 0, node, max_sockets=3)
    server.start()
    server.show_world(WORLD)

    async def scenario() -> tuple[list[Any], Any, Any, Any]:
        url = server.url.replace("http", "ws") + "ws"
        conns = [await tornado.websocket.websocket_connect(url) for _ in range(3)]
        states = [json.loads(await c.read_message()) for c in conns]
        extra = await tornado.websocket.websocket_connect(url)
        refused = await extra.read_message()
        code, reason = extra.close_code, extra.close_reason
        conns[0].close()
        while _on_loop(server, lambda: len(server._sockets)) > 2:  # the server saw the close
            await asyncio.sleep(0.01)
        again = await tornado.websocket.websocket_connect(url)
        state = json.loads(await again.read_message())
        for c in [*conns[1:], again]:
            c.close()
        return states, refused, (code, reason), state

    try:
        states, refused, (code, reason), state = asyncio.run(asyncio.wait_for(scenario(), 30.0))
    finally:
        server.stop()
    assert all(s["world"] == WORLD for s in states) and state["world"] == WORLD
    assert refused is None and code == 1013 and "limit is 3" in reason, (code, reason)
    with pytest.raises(ValueError, match="max_sockets"):
        WebDesigner("127.0.0.1", 0, node, max_sockets=0)


def test_the_page_shows_how_the_mission_ended(web: WebDesigner) -> None:
    """Rob's final status and the navigator's goal outcome reach the page (GET /state and the
    socket), through the designer node's ``mission_dict``."""
    from types import SimpleNamespace

    from ird_ros.nodes.designer import mission_dict

    rob = SimpleNamespace(plan_label="ird_per_step", row=3, col=4, step=12, horizon=12, touched_lava=False,
                          reached_target=True, true_return=8.2, stopped=False,
                          header=SimpleNamespace(stamp=SimpleNamespace(sec=5, nanosec=0)))
    assert mission_dict(None, None) is None
    mission = mission_dict(rob, "succeeded")
    assert mission is not None
    assert mission["text"] == ("Rob finished plan ird_per_step (12 steps): no lava, reached a target, true return "
                               "8.20; the navigator's last goal succeeded.")
    stopped = mission_dict(SimpleNamespace(**{**vars(rob), "stopped": True, "step": 5}), "canceled")
    assert stopped is not None and stopped["text"].startswith("Rob stopped plan ird_per_step at step 5 of 12")
    assert request(web, "/state")[1]["mission"] is None
    web.show_mission(mission)
    state = request(web, "/state")[1]
    assert state["mission"]["text"] == mission["text"] and state["mission"]["rob"]["reached_target"] is True
    assert "mission" in (WEB_DIR / "app.js").read_text() and 'id="mission"' in (WEB_DIR / "index.html").read_text()


def test_the_designer_node_forwards_the_last_goal_outcome_and_robs_final_status() -> None:
    """``DesignerNode``'s handlers: only a terminal goal status and only Rob's final status count,
    each goal is shown once (the latched status array repeats old goals)."""
    from types import SimpleNamespace

    from action_msgs.msg import GoalStatus, GoalStatusArray

    from ird_msgs.msg import RobStatus
    from ird_ros.nodes.designer import DesignerNode

    shown: list[dict[str, Any]] = []
    fake = SimpleNamespace(rob_final=None, goal_outcome=None, _goal_seen=set(),
                           web=SimpleNamespace(show_mission=shown.append))
    fake._show_mission = lambda: DesignerNode._show_mission(fake)

    def status(uuid: int, code: int, sec: int) -> GoalStatus:
        s = GoalStatus(status=code)
        s.goal_info.goal_id.uuid = [uuid] * 16
        s.goal_info.stamp.sec = sec
        return s

    running = GoalStatusArray(status_list=[status(1, GoalStatus.STATUS_EXECUTING, 1)])
    DesignerNode._on_goal_status(fake, running)
    DesignerNode._on_rob_status(fake, RobStatus(done=False, step=3, horizon=12))
    assert shown == []
    DesignerNode._on_goal_status(fake, GoalStatusArray(status_list=[status(1, GoalStatus.STATUS_SUCCEEDED, 1),
                                                                    status(2, GoalStatus.STATUS_ABORTED, 2)]))
    assert fake.goal_outcome == "aborted" and len(shown) == 1
    DesignerNode._on_goal_status(fake, GoalStatusArray(status_list=[status(2, GoalStatus.STATUS_ABORTED, 2)]))
    assert len(shown) == 1  # seen already
    DesignerNode._on_rob_status(fake, RobStatus(done=True, plan_label="literal", step=12, horizon=12,
                                                touched_lava=True, true_return=-90.5))
    assert shown[-1]["text"] == ("Rob finished plan literal (12 steps): touched lava, no target, true return -90.50; "
                                 "the navigator's last goal aborted.")
