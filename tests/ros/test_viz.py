"""The live view in a running graph: a plain Foxglove WebSocket client watches a mission.

The launcher starts world, perception, inference, planner, rob and viz (a 6x6 latent_raw world,
T = 8) in a private domain, the viz node on a free port (``port: 0``; ``/viz/status`` says which).
A client speaking the protocol itself (tests/_foxglove_ws.py: subprotocol ``foxglove.sdk.v1``,
protobuf decoded with the advertised FileDescriptorSet) subscribes to every channel while an
``IrdClient`` runs the mission (infer, the literal and the IRD plan, Rob drives both, a question
to the designer), and each channel's real messages are checked against what the graph did.

``IRD_LIVE_VIEW_PICTURE=docs/live_view.png`` also draws the decoded messages into that PNG
(the picture of docs/live_view.md).
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from ird_core.worlds import lavaland
from ird_ros import conversions as conv

REPO = Path(__file__).resolve().parents[2]
SIZE, HORIZON, OBS_DIM, SEED = 6, 8, 6, 4
NODES = ["world", "perception", "inference", "planner", "rob", "viz"]


def _rows(grid: dict[str, Any]) -> int:
    return len(grid["data"]) // grid["row_stride"]


def _field(grid: dict[str, Any], name: str) -> np.ndarray:
    """One packed field of a decoded foxglove.Grid as an (H, W) array."""
    kinds = {1: "u1", 2: "i1", 3: "<u2", 4: "<i2", 5: "<u4", 6: "<i4", 7: "<f4", 8: "<f8"}
    f = next(f for f in grid["fields"] if f["name"] == name)
    dtype = np.dtype({"names": [name], "formats": [kinds[f["type"]]], "offsets": [f["offset"]],
                      "itemsize": grid["cell_stride"]})
    return np.frombuffer(grid["data"], dtype=dtype)[name].reshape(_rows(grid), grid["column_count"])


def _entities(client: Any, topic: str) -> dict[str, dict[str, Any]]:
    """The latest entity of each id over every SceneUpdate received on ``topic``."""
    out: dict[str, dict[str, Any]] = {}
    for update in client.messages.get(topic, []):
        for entity in update["entities"]:
            out[entity["id"]] = entity
    return out


@pytest.fixture(scope="module")
def watched(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    from _foxglove_ws import FoxgloveClient
    from _mission import drive_ird_plan

    from ird_core import posterior
    from ird_ros.client import IrdClient, infer_request, plan_request, query_request
    from ird_ros.graph import names
    from ird_ros.launch import GraphLauncher

    tmp = tmp_path_factory.mktemp("viz")
    params = yaml.safe_load((REPO / "msgs_config/params/graph.yaml").read_text())
    params["world"]["ros__parameters"].update(condition="latent_raw", seed=SEED, height=SIZE, width=SIZE,
                                              horizon=HORIZON, obs_dim=OBS_DIM)
    params["rob"]["ros__parameters"]["rate_hz"] = 50.0
    params["viz"]["ros__parameters"]["port"] = 0  # any free port; /viz/status names it
    params_file = tmp / "graph.yaml"
    params_file.write_text(yaml.safe_dump(params))
    out: dict[str, Any] = {}
    with GraphLauncher(nodes=NODES, params=params_file, private_domain=True, output="quiet",
                       log_dir=tmp / "logs") as graph:
        graph.wait_ready(timeout=120)  # viz is ready once /viz/status is out: its server listens
        with IrdClient(graph.domain_id, node_name="viz_test_client") as ird:
            status = json.loads(ird.latest(names.TOPIC_VIZ_STATUS, timeout=30).data)
            assert status["host"] == "127.0.0.1" and status["port"] > 0
            client = FoxgloveClient(status["url"])
            try:
                client.wait_for(lambda c: c.server_info is not None and len(c.channels) == len(status["channels"]),
                                30, "serverInfo and the advertised channels")
                out["status"], out["subprotocol"] = status, client.subprotocol
                ird.watch_rob(timeout=60)
                proxy = ird.proxy(timeout=60)
                start = (proxy.test_start_row, proxy.test_start_col)
                train = ird.latest(names.TOPIC_TRAIN_FEATURES, timeout=60)
                request = infer_request(train, (proxy.start_row, proxy.start_col), proxy.horizon, proxy.weights,
                                        beta=5.0, method="maxent_z", num_samples=40, seed=11)
                result = ird.infer(request, timeout=300)
                assert result.ok, result.message
                samples = result.unwrap().samples
                ird.risk_map(timeout=60)
                literal = ird.plan(plan_request(start, proxy.test_horizon, "literal", "none", label="literal"),
                                   timeout=120)
                assert literal.ok, literal.message
                ird.wait_for_rob(literal.unwrap(), timeout=60)
                inst = lavaland.make_instance("latent_raw", SEED, size=SIZE, horizon=HORIZON, obs_dim=OBS_DIM)
                reference = posterior.proxy_feature_expectations(inst) / (inst.train_horizon + 1)
                drive = drive_ird_plan(ird, proxy, samples, reference)
                query = ird.propose_query(query_request(start, horizon=proxy.test_horizon), timeout=300)
                assert query.ok, query.message
                out.update(inst=inst, proxy=proxy, samples=samples, literal=list(literal.unwrap().cells),
                           ird=drive["plan_cells"], final=drive["final"], query=query.unwrap(),
                           terrain=conv.terrain_grid_from_msg(ird.latest(names.TOPIC_TERRAIN, timeout=30)),
                           risk=ird.risk_map(timeout=30))
                last = out["ird"][-1]
                centre = conv.cell_center(*last)

                def seen_everything(c: Any) -> bool:
                    plans = _entities(c, "/viz/plans")
                    rob = _entities(c, "/viz/rob").get("rob")
                    query_msgs = c.messages.get("/viz/query", [])
                    post = c.messages.get("/viz/posterior", [])
                    return (all(t in c.messages for t in status["channels"].values())
                            and {"plan/literal", "plan/ird"} <= set(plans)
                            and rob is not None
                            and rob["cubes"][0]["pose"]["position"]["x"] == pytest.approx(centre[0])
                            and rob["cubes"][0]["pose"]["position"]["y"] == pytest.approx(centre[1])
                            and any(m["query_id"] == out["query"].query_id for m in query_msgs)
                            and any(m["num_samples"] == 40 for m in post))

                client.wait_for(seen_everything, 60, "a message of every channel showing the mission")
            finally:
                client.close()
            out["client"] = client
    if os.environ.get("IRD_LIVE_VIEW_PICTURE"):
        _draw(out, Path(os.environ["IRD_LIVE_VIEW_PICTURE"]))
    return out


def test_the_client_speaks_foxglove_sdk_v1_and_every_channel_is_advertised(watched: dict[str, Any]) -> None:
    from ird_ros.viz import CHANNELS

    client = watched["client"]
    assert watched["subprotocol"] == "foxglove.sdk.v1"
    assert client.server_info["op"] == "serverInfo"
    topics = client.topics()
    assert set(topics) == set(CHANNELS.values()) == set(watched["status"]["channels"].values())
    assert topics["/viz/terrain"]["schemaName"] == "foxglove.Grid" and topics["/viz/terrain"]["encoding"] == "protobuf"
    assert topics["/viz/plans"]["schemaName"] == "foxglove.SceneUpdate"
    assert topics["/viz/rob_trail"]["schemaName"] == "foxglove.PosesInFrame"
    assert topics["/viz/posterior"]["encoding"] == "json" and topics["/viz/query"]["encoding"] == "json"


def test_terrain_grids_are_the_maps(watched: dict[str, Any]) -> None:
    client, terrain = watched["client"], watched["terrain"]
    for topic in ("/viz/terrain", "/viz/perceived"):
        grid = client.messages[topic][-1]
        assert (grid["column_count"], _rows(grid)) == (SIZE, SIZE)
        assert grid["frame_id"] == "map" and grid["cell_size"] == {"x": terrain.resolution, "y": terrain.resolution}
        assert {f["name"] for f in grid["fields"]} >= {"red", "green", "blue", "alpha"}
    truth = client.messages["/viz/terrain"][-1]
    assert np.array_equal(_field(truth, "class"), terrain.classes)
    assert np.array_equal(_field(truth, "class"), watched["inst"].test_labels)


def test_risk_grid_is_the_planners_risk_map(watched: dict[str, Any]) -> None:
    grid = watched["client"].messages["/viz/risk_map"][-1]
    assert (grid["column_count"], _rows(grid)) == (SIZE, SIZE)
    risk = watched["risk"]
    shown = _field(grid, "risk")
    assert np.array_equal(np.isnan(shown), risk < 0)
    assert np.array_equal(shown[risk >= 0], risk[risk >= 0].astype(np.float32))


def test_plans_are_lines_with_one_point_per_cell(watched: dict[str, Any]) -> None:
    plans = _entities(watched["client"], "/viz/plans")
    for label in ("literal", "ird"):
        line = plans[f"plan/{label}"]["lines"][0]
        cells = watched[label]
        assert len(line["points"]) == len(cells) == HORIZON + 1
        xy = [(p["x"], p["y"]) for p in line["points"]]
        assert xy == [pytest.approx(conv.cell_center(r, c)) for r, c in cells]
    colours = {label: plans[f"plan/{label}"]["lines"][0]["color"] for label in ("literal", "ird")}
    assert colours["literal"] != colours["ird"]


def test_rob_pose_and_trail_follow_odom(watched: dict[str, Any]) -> None:
    client = watched["client"]
    last = watched["ird"][-1]
    trail = client.messages["/viz/rob_trail"][-1]
    assert trail["frame_id"] == "map"
    # The literal drive's trail was cleared when Rob jumped back to the start of the IRD plan.
    xy = [(p["position"]["x"], p["position"]["y"]) for p in trail["poses"]]
    assert xy == [pytest.approx(conv.cell_center(r, c)) for r, c in watched["ird"]]
    assert xy[-1] == pytest.approx(conv.cell_center(*last))
    line = _entities(client, "/viz/rob")["rob/trail"]["lines"][0]
    assert len(line["points"]) == len(trail["poses"])


def test_posterior_json_names_the_terrains(watched: dict[str, Any]) -> None:
    post = [m for m in watched["client"].messages["/viz/posterior"] if m["num_samples"] == 40][-1]
    labels, names_ = watched["inst"].test_labels, watched["terrain"].class_names
    present = {names_[k] for k in np.unique(labels)}
    assert set(post["terrains"]) == present and "lava" in present
    assert post["feature_source"] == "/world/test_features"
    features = watched["inst"].test_features.astype(np.float32).astype(np.float64)
    lava = names_.index("lava")
    rewards = watched["samples"] @ features[labels == lava].mean(axis=0)
    assert post["terrains"]["lava"]["mean"] == pytest.approx(rewards.mean())
    assert post["terrains"]["lava"]["sd"] == pytest.approx(rewards.std())
    assert len(post["features"]) == OBS_DIM


def test_query_json_is_the_open_question(watched: dict[str, Any]) -> None:
    query = watched["query"]
    shown = [m for m in watched["client"].messages["/viz/query"] if m["query_id"] == query.query_id][-1]
    assert shown["event"] == "proposed" and shown["open"] is True
    assert shown["options"] == [o.tolist() for o in query.options]


def _draw(out: dict[str, Any], path: Path) -> None:
    """The decoded channels as one picture: terrain grid, risk grid, plans and trail, posterior."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    client = out["client"]
    terrain, risk = client.messages["/viz/terrain"][-1], client.messages["/viz/risk_map"][-1]
    rgba = np.stack([_field(terrain, c) for c in ("red", "green", "blue", "alpha")], axis=-1)
    plans = _entities(client, "/viz/plans")
    post = [m for m in client.messages["/viz/posterior"] if m["num_samples"] == 40][-1]
    query = client.messages["/viz/query"][-1]
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.4))
    extent = (0, terrain["column_count"], 0, _rows(terrain))
    axes[0].imshow(rgba, origin="lower", extent=extent)
    for shift, entity in enumerate([*plans.values(), _entities(client, "/viz/rob")["rob/trail"]]):
        line = entity["lines"][0]
        c = line["color"]
        pts = np.array([(p["x"], p["y"]) for p in line["points"]]) + 0.08 * (shift - 1)  # overlapping lines apart
        label = next(kv["value"] for kv in entity["metadata"] if kv["key"] == "label")
        axes[0].plot(pts[:, 0], pts[:, 1], color=(c["r"], c["g"], c["b"]), lw=3 if "plan" in entity["id"] else 1.5,
                     label=label, alpha=0.9)
    rob = _entities(client, "/viz/rob")["rob"]["cubes"][0]["pose"]["position"]
    axes[0].plot(rob["x"], rob["y"], "s", color="#00c8ff", markeredgecolor="black", markersize=12, label="Rob")
    axes[0].legend(fontsize=7, loc="lower left")
    axes[0].set_title("/viz/terrain (Grid), /viz/plans + /viz/rob (SceneUpdate)", fontsize=9)
    im = axes[1].imshow(_field(risk, "risk"), origin="lower", extent=extent, cmap="Reds", vmin=0, vmax=100)
    for option in query["options"]:
        o = np.array(option) + 0.5
        axes[1].plot(o[:, 1], o[:, 0], lw=2, alpha=0.8)
    fig.colorbar(im, ax=axes[1], fraction=0.046)
    axes[1].set_title(f"/viz/risk_map (Grid) + /viz/query: question {query['query_id']} "
                      f"({'open' if query['open'] else query['event']})", fontsize=9)
    names_ = list(post["terrains"])
    axes[2].bar(names_, [post["terrains"][n]["mean"] for n in names_],
                yerr=[post["terrains"][n]["sd"] for n in names_], color="#7a8fb8", capsize=4)
    axes[2].axhline(0, color="0.5", lw=0.8)
    axes[2].set_title("/viz/posterior (JSON): reward per terrain, mean +- sd", fontsize=9)
    fig.suptitle("The live view's channels as a plain Foxglove WebSocket client decoded them "
                 f"(latent_raw seed {SEED}, {SIZE}x{SIZE}, T = {HORIZON})", fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)
