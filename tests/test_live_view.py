"""The live view without ROS (ird_ros.viz): grids, plan lines, Rob's trail, the posterior per terrain
and the designer's question as data, their Foxglove encoding (decoded back with the advertised
schema), and the server's state-on-subscribe over a real WebSocket."""

from __future__ import annotations

import math

import numpy as np
import pytest
from _foxglove_ws import SUBPROTOCOL, FoxgloveClient, decode, descriptor_pool
from foxglove.messages import Grid

from ird_core.vocabulary import QueryEvent, QueryStrategy
from ird_core.worlds.terrain import TERRAIN_COLORS, TERRAIN_NAMES
from ird_ros.bags.rounds import QueryRecordData
from ird_ros.viz import (
    CHANNELS,
    DEFAULT_PORT,
    LiveView,
    RobTrail,
    bind_warning,
    grid_message,
    plan_kind,
    plan_line,
    posterior_by_terrain,
    query_state,
    risk_layer,
    terrain_layer,
)
from ird_ros.viz.scene import IRD_COLOR, LINE_Z, LITERAL_COLOR, UNKNOWN_COLOR, hex_rgba

NAMES = ("dirt", "grass", "target", "lava")


def _rgb255(color: str) -> list[int]:
    return [round(v * 255) for v in hex_rgba(color)[:3]]


def test_terrain_layer_packs_classes_and_the_projects_terrain_colours() -> None:
    classes = np.array([[0, 1, 2], [3, 255, 0]])
    layer = terrain_layer(classes, NAMES, resolution=0.5, origin=(1.0, -2.0), stamp_ns=7)
    assert (layer.width, layer.height, layer.cell_stride, layer.row_stride) == (3, 2, 5, 15)
    assert [n for n, _ in layer.fields] == ["class", "red", "green", "blue", "alpha"]
    assert np.array_equal(layer.field_array("class"), classes)
    rgb = np.stack([layer.field_array(c) for c in ("red", "green", "blue")], axis=-1)
    for (r, c), k in np.ndenumerate(classes):
        expected = TERRAIN_COLORS[TERRAIN_NAMES.index(NAMES[k])] if k < len(NAMES) else UNKNOWN_COLOR
        assert rgb[r, c].tolist() == _rgb255(expected)
    assert (layer.field_array("alpha") == 255).all()
    assert layer.labels == NAMES and layer.origin == (1.0, -2.0)


def test_risk_layer_keeps_values_and_hides_unknown_cells() -> None:
    costs = np.array([[0, 50], [100, -1]], dtype=np.int8)
    layer = risk_layer(costs, resolution=1.0, origin=(0.0, 0.0), stamp_ns=1)
    risk = layer.field_array("risk")
    assert risk[0].tolist() == [0.0, 50.0] and risk[1, 0] == 100.0 and math.isnan(risk[1, 1])
    alpha = layer.field_array("alpha")
    assert alpha[1, 1] == 0 and alpha[0, 0] < alpha[0, 1] < alpha[1, 0]
    assert layer.field_array("green")[1, 0] == 0 and layer.field_array("green")[0, 0] == 255


def test_grid_message_decodes_with_the_advertised_schema() -> None:
    layer = terrain_layer(np.array([[0, 1], [3, 2], [1, 1]]), NAMES, resolution=0.5, origin=(1.0, 2.0),
                          stamp_ns=3_000_000_004)
    schema = Grid.get_schema()
    msg = decode(descriptor_pool(bytes(schema.data)), "." + schema.name, grid_message(layer).encode())
    assert msg["frame_id"] == "map" and msg["column_count"] == 2
    assert msg["row_stride"] == 10 and msg["cell_stride"] == 5 and len(msg["data"]) == 30
    assert msg["cell_size"] == {"x": 0.5, "y": 0.5}
    assert msg["pose"]["position"]["x"] == 1.0 and msg["pose"]["position"]["y"] == 2.0
    assert msg["timestamp"] == {"seconds": 3, "nanos": 4}
    assert [(f["name"], f["offset"]) for f in msg["fields"]] == [("class", 0), ("red", 1), ("green", 2),
                                                               ("blue", 3), ("alpha", 4)]
    assert msg["data"] == layer.data


def test_plan_lines_have_one_point_per_pose_and_the_kinds_colour() -> None:
    xy = np.array([[0.5, 0.5], [1.5, 0.5], [1.5, 1.5]])
    literal = plan_line("literal", "literal", xy, resolution=1.0, stamp_ns=1)
    ird = plan_line("ird", "per_step", xy, resolution=1.0, stamp_ns=2)
    assert literal.points.shape == (3, 3) and np.allclose(literal.points[:, :2], xy)
    assert np.allclose(literal.points[:, 2], LINE_Z)
    assert literal.color == hex_rgba(LITERAL_COLOR) and ird.color == hex_rgba(IRD_COLOR)
    assert literal.id == "plan/literal" and ird.id == "plan/ird"
    assert plan_kind("ird_per_step_log_z", "per_step") == "ird" and plan_kind("x", "literal") == "literal"


def test_rob_trail_keeps_the_last_poses() -> None:
    trail = RobTrail(3)
    for i in range(5):
        trail.add(i, 0.0, math.sin(0.25), math.cos(0.25), stamp_ns=i)
    assert [p[0] for p in trail.poses()] == [2.0, 3.0, 4.0]
    assert trail.poses()[-1][2] == pytest.approx(0.5) and trail.stamp_ns == 4
    assert trail.line(1.0).points.shape == (3, 3)
    trail.add(4.0, 1.0, 0.0, 1.0, stamp_ns=5, max_step=1.5)  # one cell: the same drive
    assert len(trail.poses()) == 3
    trail.add(0.0, 0.0, 0.0, 1.0, stamp_ns=6, max_step=1.5)  # a jump: a new plan's first cell
    assert trail.poses() == [(0.0, 0.0, 0.0)]
    with pytest.raises(ValueError):
        RobTrail(0)


def test_posterior_by_terrain_with_indicator_features_is_the_indicators_weight() -> None:
    classes = np.array([[0, 1], [3, 0]])
    features = np.eye(4)[classes]  # one indicator per terrain; target absent from the map
    samples = np.array([[0.1, -0.2, 1.0, -5.0], [0.3, 0.0, 1.0, -1.0]])
    out = posterior_by_terrain(samples, NAMES, classes=classes, class_names=NAMES, features=features,
                               source="/world/test_features", stamp_ns=2_000_000_000, method="maxent_z")
    assert set(out["terrains"]) == {"dirt", "grass", "lava"}
    assert out["terrains"]["lava"] == {"mean": pytest.approx(-3.0), "sd": pytest.approx(2.0), "cells": 1}
    assert out["terrains"]["dirt"]["mean"] == pytest.approx(0.2) and out["terrains"]["dirt"]["cells"] == 2
    assert out["features"]["lava"]["mean"] == pytest.approx(-3.0)
    assert out["num_samples"] == 2 and out["stamp"] == 2.0 and out["feature_source"] == "/world/test_features"


def test_posterior_by_terrain_with_observations_uses_the_terrains_mean_observation() -> None:
    rng = np.random.default_rng(0)
    classes = rng.integers(0, 4, size=(5, 5))
    features = rng.normal(size=(5, 5, 3))
    samples = rng.normal(size=(10, 3))
    out = posterior_by_terrain(samples, ("a", "b", "c"), classes=classes, class_names=NAMES, features=features,
                               source=None, stamp_ns=0)
    for t, name in enumerate(NAMES):
        rewards = samples @ features[classes == t].mean(axis=0)
        assert out["terrains"][name]["mean"] == pytest.approx(rewards.mean())
        assert out["terrains"][name]["sd"] == pytest.approx(rewards.std())
    only_features = posterior_by_terrain(samples, ("a", "b", "c"), classes=None, class_names=(), features=None,
                                         source=None, stamp_ns=0)
    assert only_features["terrains"] == {} and set(only_features["features"]) == {"a", "b", "c"}
    with pytest.raises(ValueError):
        posterior_by_terrain(samples, ("a", "b"), classes=None, class_names=(), features=None, source=None,
                             stamp_ns=0)


def _event(query_id: int, event: QueryEvent, chosen: int = -1) -> QueryRecordData:
    options = (np.array([[0, 0], [0, 1]]), np.array([[0, 0], [1, 0]]))
    return QueryRecordData(query_id, event, QueryStrategy.INFO_GAIN, options, ("a",), np.zeros((2, 1)), 0.3, chosen,
                           1.0 if chosen >= 0 else 0.0, "simulated" if chosen >= 0 else "", int(chosen >= 0),
                           query_id * 10 + (chosen >= 0))


def test_query_state_shows_the_open_question_then_its_answer() -> None:
    assert query_state([]) is None
    proposed = query_state([_event(1, QueryEvent.PROPOSED)])
    assert proposed is not None and proposed["open"] and proposed["query_id"] == 1
    assert proposed["event"] == "proposed" and proposed["options"] == [[[0, 0], [0, 1]], [[0, 0], [1, 0]]]
    answered = query_state([_event(1, QueryEvent.PROPOSED), _event(1, QueryEvent.ANSWERED, chosen=1)])
    assert answered is not None and not answered["open"] and answered["chosen"] == 1 and answered["open_ids"] == []


def test_bind_warning_only_off_loopback() -> None:
    assert DEFAULT_PORT != 8765
    assert bind_warning("127.0.0.1") is None and bind_warning("localhost") is None and bind_warning("::1") is None
    warning = bind_warning("0.0.0.0")
    assert warning is not None and "0.0.0.0" in warning


def test_a_late_client_gets_every_channels_current_state() -> None:
    """The server re-sends each channel's latest message to a subscriber that joins later."""
    view = LiveView("127.0.0.1", 0)
    try:
        assert view.port > 0 and view.url == f"ws://127.0.0.1:{view.port}"
        view.show_grid("terrain", terrain_layer(np.array([[0, 3]]), NAMES, resolution=1.0, origin=(0, 0), stamp_ns=1))
        view.show_json("posterior", {"terrains": {"lava": {"mean": -1.0}}})
        client = FoxgloveClient(view.url)
        try:
            assert client.subprotocol == SUBPROTOCOL
            client.wait_for(lambda c: "/viz/terrain" in c.messages and "/viz/posterior" in c.messages, 10,
                            "the state logged before the client came")
            assert client.server_info is not None and client.server_info["op"] == "serverInfo"
            assert set(client.topics()) == set(CHANNELS.values())
            grid = client.messages["/viz/terrain"][-1]
            assert grid["column_count"] == 1 + 1 and len(grid["data"]) == 2 * grid["cell_stride"]
            assert client.messages["/viz/posterior"][-1] == {"terrains": {"lava": {"mean": -1.0}}}
            view.show_json("query", {"query_id": 3})
            client.wait_for(lambda c: "/viz/query" in c.messages, 10, "a message logged while subscribed")
        finally:
            client.close()
    finally:
        view.stop()


# ---------------------------------------------------------------------------- issue 43: per-client state, origins


def _terrain(stamp_ns: int = 1) -> object:
    return terrain_layer(np.array([[0, 3]]), NAMES, resolution=1.0, origin=(0, 0), stamp_ns=stamp_ns)


def test_a_new_subscriber_gets_the_state_and_the_other_clients_get_nothing_again() -> None:
    """The latched state goes to the client that subscribed only: 200 clients used to cost every
    client 200 copies of every channel (1.34 GB)."""
    view = LiveView("127.0.0.1", 0)
    first = second = None
    try:
        view.show_grid("terrain", _terrain())
        view.show_json("posterior", {"terrains": {}})
        first = FoxgloveClient(view.url)
        first.wait_for(lambda c: "/viz/terrain" in c.messages and "/viz/posterior" in c.messages, 10, "first's state")
        second = FoxgloveClient(view.url)
        second.wait_for(lambda c: "/viz/terrain" in c.messages and "/viz/posterior" in c.messages, 10,
                        "second's state")
        view.show_json("query", {"query_id": 1})  # logged after second's subscriptions: a marker for first
        first.wait_for(lambda c: "/viz/query" in c.messages, 10, "the marker")
        assert len(first.messages["/viz/terrain"]) == 1 and len(first.messages["/viz/posterior"]) == 1, \
            {t: len(m) for t, m in first.messages.items()}
    finally:
        for client in (first, second):
            if client is not None:
                client.close()
        view.stop()


def _handshake(url: str, **headers: str) -> tuple[int, str]:
    """Status and body of a WebSocket handshake with these headers (101: accepted)."""
    import websocket

    try:
        ws = websocket.create_connection(url, subprotocols=[SUBPROTOCOL], timeout=10, **headers)
    except websocket.WebSocketBadStatusException as exc:
        body = exc.resp_body.decode() if isinstance(exc.resp_body, bytes) else str(exc.resp_body)
        return exc.status_code, body
    ws.close()
    return 101, ""


def test_the_live_view_refuses_foreign_origins_and_hosts_with_403() -> None:
    """A web page in a browser on the machine sends its own Origin (and a DNS-rebinding page its own
    Host): refused like the designer page does. Loopback origins, the desktop apps' and none pass."""
    import json as json_module

    view = LiveView("127.0.0.1", 0)
    try:
        status, body = _handshake(view.url, origin="https://evil.example")
        assert status == 403, (status, body)
        assert json_module.loads(body)["message"].startswith("Origin: 'https://evil.example' is not allowed")
        status, body = _handshake(view.url, host="evil.example:8766")
        assert status == 403 and json_module.loads(body)["message"].startswith("Host: "), (status, body)
        for origin in ("http://localhost:3000", "http://127.0.0.1:8080", "file://", "https://app.foxglove.dev"):
            assert _handshake(view.url, origin=origin)[0] == 101, origin
        assert _handshake(view.url)[0] == 101
        client = FoxgloveClient(view.url)  # still serving after the refusals
        try:
            client.wait_for(lambda c: len(c.channels) == len(CHANNELS), 10, "the channels")
        finally:
            client.close()
    finally:
        view.stop()


def test_allowed_origins_are_configurable() -> None:
    view = LiveView("127.0.0.1", 0, allowed_origins=["https://lichtblick.example"])
    try:
        assert _handshake(view.url, origin="https://lichtblick.example")[0] == 101
        assert _handshake(view.url, origin="https://app.foxglove.dev")[0] == 403
        assert _handshake(view.url, origin="http://[::1]:5173")[0] == 101  # loopback always
    finally:
        view.stop()


def test_a_port_in_use_is_an_oserror_and_the_message_names_viz_port() -> None:
    from ird_ros.viz import port_in_use_message

    view = LiveView("127.0.0.1", 0)
    try:
        with pytest.raises(OSError) as caught:
            LiveView("127.0.0.1", view.port)
        text = port_in_use_message("127.0.0.1", view.port, caught.value)
        assert text.startswith(f"port: cannot listen on 127.0.0.1:{view.port}") and "--viz-port" in text
    finally:
        view.stop()


def _decoded(message: object) -> dict:
    schema = type(message).get_schema()
    return decode(descriptor_pool(bytes(schema.data)), "." + schema.name, message.encode())


def test_a_stamp_before_the_epoch_is_shown_as_zero() -> None:
    """/odom or /world/terrain with stamp.sec = -1 used to raise OverflowError in the node."""
    view = LiveView("127.0.0.1", 0)
    try:
        view.show_grid("terrain", _terrain(stamp_ns=-1_000_000_000))
        assert _decoded(view.latest("terrain"))["timestamp"] == {"seconds": 0, "nanos": 0}
        trail = RobTrail(5)
        trail.add(0.5, 0.5, 0.0, 1.0, -5)
        view.show_rob(trail, 1.0)
        assert _decoded(view.latest("trail"))["timestamp"] == {"seconds": 0, "nanos": 0}
        big = _decoded(grid_message(_terrain(stamp_ns=2**40 * 1_000_000_000)))
        assert big["timestamp"]["seconds"] == 2**32 - 1
    finally:
        view.stop()
