"""ird_ros.apps.analyze_bag (scripts/analyze_bag.py) and ird_ros.bags.analysis on a bag written here with rosbags (no ROS).

The bag holds the project's own types (ird_msgs from msgs_config, nav_msgs) as the recorder
would write them: ground-truth terrain, a posterior, and three missions (/plan, /odom,
/rob/status), two labelled ``literal`` (one through lava) and one ``ird_per_step``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import matplotlib.colors as mcolors
import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys.base import Nodetype

from ird_core import style
from ird_ros.apps import analyze_bag as analyze_bag_app
from ird_ros.bags import plots
from ird_ros.bags.analysis import analyze, extract_missions
from ird_ros.bags.missions import terrain_from_msg
from ird_ros.bags.storage import make_typestore, read_messages, summarize

T0 = 1_700_000_000_000_000_000  # ns
SEC = 1_000_000_000
RES = 0.5  # m per cell
ORIGIN = (-1.0, 2.0)
CLASS_NAMES = ["dirt", "grass", "target", "lava"]
DIRT, GRASS, TARGET, LAVA = range(4)
TRUE_REWARD = {DIRT: 0.1, GRASS: -0.2, TARGET: 1.0, LAVA: -10.0}
LAVA_RGB = style.hex_rgb(style.terrain_color("lava"))

_NUMPY = {"float32": np.float32, "float64": np.float64, "uint8": np.uint8, "int8": np.int8, "uint32": np.uint32,
          "int32": np.int32, "uint16": np.uint16, "int16": np.int16, "uint64": np.uint64, "int64": np.int64}


def make(store: Any, typename: str, **values: Any) -> Any:
    """A rosbags message of ``typename`` with default (zero / empty) fields, overridden by ``values``."""
    cls = store.types[typename]
    _consts, fields = store.fielddefs[typename]
    kwargs = {}
    for name, (kind, rest) in fields:
        if name in values:
            kwargs[name] = values[name]
        elif kind == Nodetype.NAME:
            kwargs[name] = make(store, rest)
        elif kind == Nodetype.BASE:
            typ = rest[0]
            kwargs[name] = "" if typ == "string" else (False if typ == "bool" else 0)
        elif kind == Nodetype.ARRAY:
            (sub_kind, sub), length = rest
            if sub_kind == Nodetype.BASE and sub[0] in _NUMPY:
                kwargs[name] = np.zeros(length, dtype=_NUMPY[sub[0]])
            else:
                kwargs[name] = [make(store, sub) for _ in range(length)]
        else:  # sequence
            (sub_kind, sub), _bound = rest
            kwargs[name] = np.zeros(0, dtype=_NUMPY[sub[0]]) if sub_kind == Nodetype.BASE and sub[0] in _NUMPY else []
    return cls(**kwargs)


def centre(row: int, col: int) -> tuple[float, float]:
    return ORIGIN[0] + (col + 0.5) * RES, ORIGIN[1] + (row + 0.5) * RES


def terrain_classes() -> np.ndarray:
    classes = np.full((5, 6), DIRT, dtype=np.uint8)
    classes[3:, :2] = GRASS
    classes[1, 2] = LAVA
    classes[2, 0] = TARGET
    return classes


class BagBuilder:
    def __init__(self, path: Path):
        self.store = make_typestore()
        self.writer = Writer(path, version=9, storage_plugin=StoragePlugin.MCAP)
        self.writer.open()
        self.conns: dict[str, Any] = {}
        self.counts: dict[str, int] = {}

    def write(self, topic: str, typename: str, t_ns: int, msg: Any) -> None:
        if topic not in self.conns:
            self.conns[topic] = self.writer.add_connection(topic, typename, typestore=self.store)
            self.counts[topic] = 0
        self.writer.write(self.conns[topic], t_ns, bytes(self.store.serialize_cdr(msg, typename)))
        self.counts[topic] += 1

    def header(self, t_ns: int) -> Any:
        stamp = make(self.store, "builtin_interfaces/msg/Time", sec=t_ns // SEC, nanosec=t_ns % SEC)
        return make(self.store, "std_msgs/msg/Header", stamp=stamp, frame_id="map")

    def info(self, h: int, w: int) -> Any:
        s = self.store
        origin = make(s, "geometry_msgs/msg/Pose",
                      position=make(s, "geometry_msgs/msg/Point", x=ORIGIN[0], y=ORIGIN[1], z=0.0),
                      orientation=make(s, "geometry_msgs/msg/Quaternion", w=1.0))
        return make(s, "nav_msgs/msg/MapMetaData", resolution=RES, width=w, height=h, origin=origin)

    def pose(self, t_ns: int, x: float, y: float) -> Any:
        s = self.store
        return make(s, "geometry_msgs/msg/PoseStamped", header=self.header(t_ns),
                    pose=make(s, "geometry_msgs/msg/Pose",
                              position=make(s, "geometry_msgs/msg/Point", x=x, y=y, z=0.0),
                              orientation=make(s, "geometry_msgs/msg/Quaternion", w=1.0)))

    def plan_info(self, t_ns: int, stamp_ns: int, label: str, mode: str, cells: list[tuple[int, int]]) -> None:
        info = make(self.store, "ird_msgs/msg/PlanInfo", header=self.header(stamp_ns), label=label, mode=mode,
                    baseline="log_z", objective=float(len(cells)) / 4,
                    rows=np.array([r for r, _ in cells], np.uint32), cols=np.array([c for _, c in cells], np.uint32))
        self.write("/ird/plan_info", "ird_msgs/msg/PlanInfo", t_ns, info)

    def mission(self, t_ns: int, label: str, cells: list[tuple[int, int]], classes: np.ndarray,
                status_label: bool = True) -> dict[str, Any]:
        """Plan (+ plan info with the same stamp) at t, then per step an /odom and a /rob/status
        0.1 s apart; returns the expectation. A decoy plan info with another stamp is logged
        between the real one and the plan, so only stamp matching finds the right one."""
        s = self.store
        mode = "literal" if label == "literal" else "per_step"
        self.plan_info(t_ns - 2_000_000, t_ns, label, mode, cells)
        self.plan_info(t_ns - 1_000_000, t_ns - 7, "decoy", "trajectory", cells[:2])
        path = make(s, "nav_msgs/msg/Path", header=self.header(t_ns), poses=[self.pose(t_ns, *centre(*c)) for c in cells])
        self.write("/plan", "nav_msgs/msg/Path", t_ns, path)
        ret, lava, target = 0.0, False, False
        for step, (r, c) in enumerate(cells):
            t = t_ns + (step + 1) * SEC // 10
            x, y = centre(r, c)
            odom = make(s, "nav_msgs/msg/Odometry", header=self.header(t), child_frame_id="base_link",
                        pose=make(s, "geometry_msgs/msg/PoseWithCovariance", pose=self.pose(t, x, y).pose))
            self.write("/odom", "nav_msgs/msg/Odometry", t, odom)
            cls = int(classes[r, c])
            ret += TRUE_REWARD[cls]
            lava |= cls == LAVA
            target |= cls == TARGET
            status = make(s, "ird_msgs/msg/RobStatus", header=self.header(t), row=r, col=c, terrain=CLASS_NAMES[cls],
                          step=step, horizon=len(cells) - 1, done=step == len(cells) - 1, touched_lava=lava,
                          reached_target=target, true_return=ret, plan_label=label if status_label else "")
            self.write("/rob/status", "ird_msgs/msg/RobStatus", t, status)
        moves = sum(1 for a, b in zip(cells, cells[1:]) if a != b)
        return {"label": label, "plan_moves": len(cells) - 1, "length_m": moves * RES, "touched_lava": lava,
                "reached_target": target, "true_return": ret, "steps": len(cells) - 1, "mode": mode,
                "objective": len(cells) / 4, "cells": cells}

    def close(self) -> None:
        self.writer.close()


MISSIONS = [
    ("literal", [(0, 0), (0, 1), (1, 1), (1, 2), (2, 2)]),          # through lava
    ("ird_per_step", [(0, 0), (1, 0), (2, 0), (2, 0), (2, 0)]),     # to the target, then stays
    ("literal", [(0, 0), (0, 1), (0, 2), (0, 3), (1, 3)]),          # dirt only
]


@pytest.fixture(scope="module")
def bag(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, Any]]:
    path = tmp_path_factory.mktemp("analyze") / "run_bag"
    b = BagBuilder(path)
    s = b.store
    classes = terrain_classes()
    h, w = classes.shape
    terrain = make(s, "ird_msgs/msg/TerrainGrid", header=b.header(T0), info=b.info(h, w), class_names=CLASS_NAMES,
                   classes=classes.ravel().copy(), probabilities=np.zeros(0, np.float32), novelty=np.zeros(0, np.float32))
    b.write("/world/terrain", "ird_msgs/msg/TerrainGrid", T0, terrain)
    feats = np.eye(4, dtype=np.float32)[classes]  # (H, W, 4) indicators
    grid = make(s, "ird_msgs/msg/FeatureGrid", header=b.header(T0), info=b.info(h, w), layers=CLASS_NAMES,
                data=feats.ravel().copy())
    b.write("/world/train_features", "ird_msgs/msg/FeatureGrid", T0 + 1000, grid)
    b.write("/world/test_features", "ird_msgs/msg/FeatureGrid", T0 + 1000, grid)
    rng = np.random.default_rng(0)
    samples = rng.normal(size=(20, 4))
    post = make(s, "ird_msgs/msg/RewardPosterior", header=b.header(T0), feature_names=CLASS_NAMES, method="maxent_z",
                beta=10.0, prior_sigma=1.0, proxy_weights=np.array([0.1, -0.2, 1.0, 0.3]), samples=samples.ravel().copy(),
                num_samples=20, num_chains=4, seed=1, acceptance_rate=0.5, r_hat_max=1.01, ess_min=80.0, converged=True)
    b.write("/ird/posterior", "ird_msgs/msg/RewardPosterior", T0 + SEC // 2, post)
    # the last mission's statuses carry no label: it comes from its /ird/plan_info
    expected = [b.mission(T0 + (k + 1) * SEC, label, cells, classes, status_label=k < len(MISSIONS) - 1)
                for k, (label, cells) in enumerate(MISSIONS)]
    counts = dict(b.counts)
    b.close()
    return path, {"missions": expected, "counts": counts, "samples": samples, "classes": classes}


def test_summary_counts_times_and_rates(bag: tuple[Path, dict[str, Any]]) -> None:
    path, exp = bag
    topics = {t.topic: t for t in summarize(path)}
    assert {k: t.count for k, t in topics.items()} == exp["counts"]
    assert topics["/rob/status"].msgtype == "ird_msgs/msg/RobStatus"
    assert topics["/world/terrain"].msgtype == "ird_msgs/msg/TerrainGrid"
    status = topics["/rob/status"]
    assert topics["/ird/plan_info"].count == 2 * len(MISSIONS)
    # first status 0.1 s after the first plan at T0+1 s; last: 5th status of the 3rd mission
    assert status.first_ns == T0 + SEC + SEC // 10
    assert status.last_ns == T0 + 3 * SEC + 5 * SEC // 10
    assert status.rate_hz == pytest.approx((15 - 1) / 2.4)
    assert math.isnan(topics["/world/terrain"].rate_hz)  # one message: no rate


def test_messages_decode_to_the_values_written(bag: tuple[Path, dict[str, Any]]) -> None:
    path, exp = bag
    msgs = read_messages(path, ["/world/terrain", "/ird/posterior", "/world/train_features"])
    terrain = terrain_from_msg(msgs["/world/terrain"][0].msg)
    np.testing.assert_array_equal(terrain.classes, exp["classes"])
    assert terrain.class_names == tuple(CLASS_NAMES)
    assert terrain.cell_of(*centre(1, 2)) == (1, 2)
    post = msgs["/ird/posterior"][0].msg
    np.testing.assert_array_equal(np.asarray(post.samples).reshape(20, 4), exp["samples"])
    feats = np.asarray(msgs["/world/train_features"][0].msg.data).reshape(5, 6, 4)
    np.testing.assert_array_equal(feats.argmax(-1), exp["classes"])


def test_missions_are_segmented_and_scored(bag: tuple[Path, dict[str, Any]]) -> None:
    path, exp = bag
    missions = extract_missions(path)
    assert len(missions) == len(exp["missions"])
    for m, e in zip(missions, exp["missions"]):
        assert m.label == e["label"]
        assert m.plan_moves == e["plan_moves"]
        assert m.plan_length_m == pytest.approx(e["length_m"])
        assert m.executed_length_m == pytest.approx(e["length_m"])  # odometry follows the plan here
        assert m.touched_lava == e["touched_lava"]
        assert m.reached_target == e["reached_target"]
        assert m.true_return == pytest.approx(e["true_return"])
        assert m.steps == e["steps"] and m.done
        assert len(m.odom) == e["plan_moves"] + 1  # odometry window excludes the other missions
        assert (m.mode, m.baseline, m.objective) == (e["mode"], "log_z", e["objective"])  # from the matching plan info
        assert m.plan_cells == e["cells"]
    assert [m.touched_lava for m in missions] == [True, False, False]
    assert [m.reached_target for m in missions] == [False, True, False]
    assert missions[0].executed_cells == MISSIONS[0][1]


def test_segmentation_without_plans_splits_on_label_and_step_reset(tmp_path: Path) -> None:
    b = BagBuilder(tmp_path / "bag")
    classes = terrain_classes()
    for k, label in enumerate(["a", "a", "b"]):  # two runs of "a" back to back: the step reset splits them
        for step in range(3):
            t = T0 + k * SEC + step * SEC // 10
            msg = make(b.store, "ird_msgs/msg/RobStatus", header=b.header(t), step=step, horizon=2, done=step == 2,
                       true_return=float(step + 10 * k), plan_label=label, terrain=CLASS_NAMES[int(classes[0, 0])])
            b.write("/rob/status", "ird_msgs/msg/RobStatus", t, msg)
    b.close()
    missions = extract_missions(tmp_path / "bag")
    assert [m.label for m in missions] == ["a", "a", "b"]
    assert [m.true_return for m in missions] == [2.0, 12.0, 22.0]
    assert all(m.plan_moves == 0 for m in missions)


def test_analyze_writes_plots_and_label_statistics(bag: tuple[Path, dict[str, Any]], tmp_path: Path) -> None:
    import matplotlib.image as mpimg

    path, _exp = bag
    report = analyze(path, tmp_path / "plots")
    names = sorted(Path(p).name for p in report["plots"])
    assert names == ["posterior.png", "trajectories_0.png", "true_return.png"]
    for p in report["plots"]:
        assert Path(p).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(tmp_path / "plots" / "trajectories_0.png")[..., :3]
    # the terrain is drawn: some pixels have the lava colour
    lava = np.all(np.abs(img - np.array(LAVA_RGB)) < 0.02, axis=-1)
    assert lava.sum() > 50
    labels = report["labels"]
    assert labels["literal"] == pytest.approx({"runs": 2, "lava_fraction": 0.5, "target_fraction": 0.0,
                                               "mean_true_return": (0.1 * 3 - 10 + 0.1 + 0.5) / 2})
    assert labels["ird_per_step"]["target_fraction"] == 1.0
    json.dumps(report)  # JSON-able


def test_posterior_plot_is_per_terrain_of_the_test_map(bag: tuple[Path, dict[str, Any]]) -> None:
    """Indicator features: the reward of terrain t is the weight of its indicator; the plot has one
    box per terrain of the test map, in the terrain's colour."""
    path, exp = bag
    msgs = read_messages(path, ["/world/terrain", "/ird/posterior", "/world/test_features"])
    terrain = terrain_from_msg(msgs["/world/terrain"][0].msg)
    grid = msgs["/world/test_features"][0].msg
    layers, features = plots.feature_map(grid)
    rewards = plots.terrain_rewards(exp["samples"], features, terrain.classes, terrain.class_names)
    assert list(rewards) == CLASS_NAMES == list(layers)
    for t, name in enumerate(CLASS_NAMES):
        np.testing.assert_allclose(rewards[name], exp["samples"][:, t])
    ax = plots.posterior_figure(msgs["/ird/posterior"][0].msg, terrain, grid).axes[0]
    assert [t.get_text() for t in ax.get_xticklabels()] == CLASS_NAMES
    assert [mcolors.to_hex(p.get_facecolor()) for p in ax.patches] == [style.terrain_color(n) for n in CLASS_NAMES]


def test_cli_prints_summary_and_writes_json(bag: tuple[Path, dict[str, Any]], tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    path, exp = bag
    out = tmp_path / "out"
    code = analyze_bag_app.main([str(path), "--out", str(out), "--json", str(tmp_path / "new" / "r.json")])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    lines = captured.out.splitlines()
    status_line = next(line for line in lines if line.startswith("/rob/status"))
    assert status_line.split()[1:3] == ["ird_msgs/msg/RobStatus", "15"]
    assert any("ird_per_step" in line and "True" in line for line in lines)
    report = json.loads((tmp_path / "new" / "r.json").read_text())
    assert [m["touched_lava"] for m in report["missions"]] == [True, False, False]
    assert (out / "trajectories_0.png").is_file() and (out / "true_return.png").is_file()


def test_cli_refuses_an_out_or_json_it_cannot_write_before_reading_the_bag(
        bag: tuple[Path, dict[str, Any]], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path, _exp = bag
    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    for argv, message in ((["--out", str(blocker / "plots")], f"error: --out: {blocker} is not a folder"),
                          (["--json", str(tmp_path)], f"error: --json: {tmp_path} is a folder, not a file"),
                          (["--no-plots", "--json", str(blocker / "r.json")], f"error: --json: {blocker} is not a folder")):
        assert analyze_bag_app.main([str(path), *argv]) == 2
        captured = capsys.readouterr()
        assert captured.err == message + "\n" and captured.out == ""  # nothing analysed
    assert blocker.read_text() == "kept"

def test_cli_rejects_an_unfinished_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "broken").mkdir()
    (tmp_path / "broken" / "broken.mcap").write_bytes(b"\x89MCAP0\r\n")  # what a SIGKILLed writer leaves
    assert analyze_bag_app.main([str(tmp_path / "broken")]) == 1
    err = capsys.readouterr().err
    assert "metadata.yaml" in err and "ird-reindex-bag" in err


@pytest.mark.parametrize(("name", "said"), [("nowhere", "does not exist"), ("notes.txt", "is not a folder")])
def test_cli_names_what_is_not_a_bag(tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, said: str) -> None:
    (tmp_path / "notes.txt").write_text("not a bag")
    assert analyze_bag_app.main([str(tmp_path / name), "--no-plots"]) == 1
    assert capsys.readouterr().err == f"error: {tmp_path / name} {said}" + (
        " (BAG is the rosbag2 folder, or the .mcap file in it)\n" if name == "notes.txt" else "\n")


def test_a_bag_without_missions_says_so_and_draws_no_trajectories(tmp_path: Path,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """A launched graph that nobody drove: the world's maps, no /plan or /rob/status."""
    b = BagBuilder(tmp_path / "idle")
    classes = terrain_classes()
    h, w = classes.shape
    terrain = make(b.store, "ird_msgs/msg/TerrainGrid", header=b.header(T0), info=b.info(h, w),
                   class_names=CLASS_NAMES, classes=classes.ravel().copy(), probabilities=np.zeros(0, np.float32),
                   novelty=np.zeros(0, np.float32))
    b.write("/world/terrain", "ird_msgs/msg/TerrainGrid", T0, terrain)
    b.close()
    report = analyze(tmp_path / "idle", tmp_path / "plots")
    assert report["missions"] == [] and report["plots"] == []
    assert not list((tmp_path / "plots").glob("trajectories_*.png"))
    out = tmp_path / "cli_plots"
    assert analyze_bag_app.main([str(tmp_path / "idle"), "--out", str(out)]) == 0
    text = capsys.readouterr().out
    line = next(x for x in text.splitlines() if "no mission in this bag" in x)
    assert "/plan 0" in line and "/rob/status 0" in line
    assert "run the graph with --mission, or drive Rob with a client" in line
    assert "Plots:" not in text and not list(out.glob("trajectories_*.png"))


# ---------------------------------------------------------------------------- issue 43


def _one_question_bag(path: Path) -> Path:
    """A bag with the map and one answered question (what ``demo.sh --queries 1`` records)."""
    b = BagBuilder(path)
    s = b.store
    classes = terrain_classes()
    h, w = classes.shape
    b.write("/world/terrain", "ird_msgs/msg/TerrainGrid", T0,
            make(s, "ird_msgs/msg/TerrainGrid", header=b.header(T0), info=b.info(h, w), class_names=CLASS_NAMES,
                 classes=classes.ravel().copy(), probabilities=np.zeros(0, np.float32),
                 novelty=np.zeros(0, np.float32)))
    options = [[(0, 0), (1, 0), (2, 0)], [(0, 0), (0, 1), (1, 1)]]
    for k, (event, chosen) in enumerate((("proposed", -1), ("answered", 0))):
        t = T0 + (k + 1) * SEC
        paths = [make(s, "nav_msgs/msg/Path", header=b.header(t), poses=[b.pose(t, *centre(*c)) for c in o])
                 for o in options]
        b.write("/ird/queries", "ird_msgs/msg/QueryRecord", t,
                make(s, "ird_msgs/msg/QueryRecord", header=b.header(t), query_id=1, event=event, strategy="evoi",
                     options=paths, feature_names=["dirt", "lava"], option_features=np.array([1.0, 0.0, 2.0, 1.0]),
                     information_gain=0.5, chosen=chosen, beta=1.0 if chosen >= 0 else 0.0,
                     answered_by="simulated" if chosen >= 0 else "", num_answers=int(chosen >= 0)))
    b.close()
    return path


def test_one_question_is_drawn_on_a_single_panel(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``demo.sh --queries 1``: one round is a 1 x 1 grid of panels (it used to end in
    ``'Axes' object has no attribute 'flat'``, reported as an unreadable bag)."""
    bag_path = _one_question_bag(tmp_path / "one_question")
    out = tmp_path / "plots"
    assert analyze_bag_app.main([str(bag_path), "--out", str(out)]) == 0, capsys.readouterr().err
    assert (out / "query_rounds.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_plot_that_fails_is_reported_as_a_plotting_failure_not_an_unreadable_bag(
        bag: tuple[Path, dict[str, Any]], tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    from ird_ros.bags import analysis

    def broken(*_args: Any, **_kwargs: Any) -> Path:
        raise AttributeError("a plotting bug")

    monkeypatch.setattr(analysis, "plot_posterior", broken)
    path, _exp = bag
    out = tmp_path / "out"
    code = analyze_bag_app.main([str(path), "--out", str(out), "--json", str(tmp_path / "r.json")])
    captured = capsys.readouterr()
    assert code == 3, captured.err
    assert "cannot read" not in captured.err
    assert "plot(s) could not be drawn (the bag was read" in captured.err
    assert "posterior.png: AttributeError: a plotting bug" in captured.err
    assert "Missions:" in captured.out  # the report is printed
    assert (out / "true_return.png").is_file() and (out / "trajectories_0.png").is_file()  # the others drawn
    report = json.loads((tmp_path / "r.json").read_text())
    assert report["plot_errors"] == ["posterior.png: AttributeError: a plotting bug"]


def test_a_cancelled_drive_shows_as_cancelled_and_a_drive_that_stayed_put_says_so(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    b = BagBuilder(tmp_path / "drives")
    s = b.store

    def status(t: int, label: str, step: int, cell: tuple[int, int], *, done: bool = False,
               stopped: bool = False) -> None:
        b.write("/rob/status", "ird_msgs/msg/RobStatus", t,
                make(s, "ird_msgs/msg/RobStatus", header=b.header(t), row=cell[0], col=cell[1], terrain="dirt",
                     step=step, horizon=4, done=done, stopped=stopped, true_return=0.1 * step, plan_label=label))

    status(T0 + 1, "stays", 0, (0, 0))
    for k in range(1, 5):  # a plan of five times the start cell: "succeeded", never left
        status(T0 + 1 + k, "stays", k, (0, 0), done=k == 4)
    status(T0 + 10, "cancelled", 0, (0, 0))
    status(T0 + 11, "cancelled", 1, (0, 1))
    status(T0 + 12, "cancelled", 1, (0, 1), done=True, stopped=True)  # /rob/stop: done and stopped
    b.close()
    report = analyze(tmp_path / "drives")
    rows = {m["label"]: m for m in report["missions"]}
    assert (rows["stays"]["end"], rows["stays"]["outcome"]) == ("done", "stayed put")
    assert (rows["cancelled"]["end"], rows["cancelled"]["outcome"]) == ("cancelled", "moved 1 cell, reached no target")
    assert analyze_bag_app.main([str(tmp_path / "drives"), "--no-plots"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert any(" cancelled " in line and line.lstrip().split()[1] == "cancelled" for line in lines)
    assert any(line.rstrip().endswith("stayed put") for line in lines)
    [mcap] = (tmp_path / "drives").glob("*.mcap")  # the bag's file names the same bag
    assert analyze_bag_app.main([str(mcap), "--no-plots"]) == 0
    assert capsys.readouterr().out.splitlines() == lines


def test_drive_outcome_names_what_rob_did() -> None:
    from ird_ros.bags.missions import drive_outcome

    assert drive_outcome(touched_lava=False, reached_target=False, moves=0) == "stayed put"
    assert drive_outcome(touched_lava=True, reached_target=False, moves=3) == "touched lava"
    assert drive_outcome(touched_lava=True, reached_target=True, moves=3) == "touched lava, reached the target"
    assert drive_outcome(touched_lava=False, reached_target=True, moves=2) == "reached the target"
    assert drive_outcome(touched_lava=None, reached_target=None, moves=2) == "moved 2 cells, reached no target"
