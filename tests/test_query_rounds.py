"""ird_ros.bags.rounds (no ROS): decoding /ird/queries records (their kind and proxy weights; an
older record without them is a paths query), pairing rounds, open queries, the true returns the
simulated designer judges by, and the report rows."""

from __future__ import annotations

import json
from types import SimpleNamespace as NS
from typing import Any

import numpy as np
import pytest

from ird_core.vocabulary import QueryKind
from ird_core.worlds import evaluation, lavaland
from ird_core.worlds.terrain import TERRAIN_NAMES
from ird_ros.bags import rounds as qr

RES, ORIGIN = 0.5, (-1.0, 2.0)


def _path(cells: list[tuple[int, int]]) -> Any:
    poses = [NS(pose=NS(position=NS(x=ORIGIN[0] + (c + 0.5) * RES, y=ORIGIN[1] + (r + 0.5) * RES)))
             for r, c in cells]
    return NS(poses=poses)


OPTIONS = [[(0, 0), (1, 0), (1, 1)], [(0, 0), (0, 1), (0, 2)]]


def record(query_id: int, event: str = "proposed", chosen: int = -1, sec: int = 10, **kw: Any) -> Any:
    fields = dict(header=NS(stamp=NS(sec=sec, nanosec=5)), query_id=query_id, event=event, strategy="info_gain",
                  options=[_path(o) for o in OPTIONS], feature_names=["a", "b"],
                  option_features=[1.0, 2.0, 3.0, 4.0], information_gain=0.25, chosen=chosen,
                  beta=1.5 if event == "answered" else 0.0, answered_by="web" if event == "answered" else "",
                  num_answers=1 if event == "answered" else 0)
    fields.update(kw)
    return NS(**fields)


def test_event_from_msg_decodes_cells_features_and_stamp() -> None:
    ev = qr.event_from_msg(record(3, "answered", chosen=1), resolution=RES, origin=ORIGIN)
    assert [o.tolist() for o in ev.options] == [[list(c) for c in o] for o in OPTIONS]
    assert ev.option_features.tolist() == [[1.0, 2.0], [3.0, 4.0]]
    assert (ev.query_id, ev.event, ev.chosen, ev.beta, ev.answered_by, ev.num_answers) == (3, "answered", 1, 1.5,
                                                                                          "web", 1)
    assert ev.stamp_ns == 10_000_000_005
    assert qr.event_from_msg(record(3, chosen=7), resolution=RES, origin=ORIGIN).chosen == -1  # proposals: -1


@pytest.mark.parametrize("kw, field", [
    (dict(event="asked"), "QueryRecord.event"),
    (dict(option_features=[1.0, 2.0, 3.0]), "QueryRecord.option_features"),
    (dict(option_features=[1.0, 2.0, 3.0, float("nan")]), "QueryRecord.option_features"),
    (dict(options=[_path(OPTIONS[0])], option_features=[1.0, 2.0]), "QueryRecord.options"),
    (dict(feature_names=[]), "QueryRecord.feature_names"),
    (dict(event="answered", chosen=2), "QueryRecord.chosen"),
])
def test_bad_records_name_the_field(kw: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field}:"):
        qr.event_from_msg(record(1, **kw), resolution=RES, origin=ORIGIN)


def test_a_proxies_record_decodes_its_kind_and_proxy_weights() -> None:
    weights = [0.1, -0.2, 1.0, 0.5, 0.3, 0.0]  # q = 2 proxies of p = 3 weights, row-major
    ev = qr.event_from_msg(record(4, kind="proxies", option_proxies=weights), resolution=RES, origin=ORIGIN)
    assert ev.kind == "proxies" and ev.kind is QueryKind.PROXIES
    assert ev.option_proxies.shape == (2, 3) and ev.option_proxies.tolist() == [[0.1, -0.2, 1.0], [0.5, 0.3, 0.0]]
    shown = qr.record_dict(ev)
    assert shown["kind"] == "proxies" and shown["option_proxies"] == [[0.1, -0.2, 1.0], [0.5, 0.3, 0.0]]
    json.dumps(shown)
    row = qr.round_summary(qr.rounds_from_events([ev])[0])
    assert row["kind"] == "proxies"
    # A paths record: kind "paths", no proxies ((q, 0)).
    paths = qr.event_from_msg(record(5, kind="paths", option_proxies=[]), resolution=RES, origin=ORIGIN)
    assert paths.kind == "paths" and paths.option_proxies.shape == (2, 0)
    assert qr.record_dict(paths)["option_proxies"] == [[], []]


def test_an_older_record_without_kind_or_proxies_is_a_paths_query() -> None:
    old = record(6)  # the stand-in has neither field, as a record decoded from an older bag
    assert not hasattr(old, "kind") and not hasattr(old, "option_proxies")
    ev = qr.event_from_msg(old, resolution=RES, origin=ORIGIN)
    assert ev.kind == "paths" and ev.option_proxies.shape == (2, 0)
    assert qr.event_from_msg(record(6, kind=""), resolution=RES, origin=ORIGIN).kind == "paths"
    assert qr.round_summary(qr.rounds_from_events([ev])[0])["kind"] == "paths"


@pytest.mark.parametrize("kw, field", [
    (dict(kind="rewards"), "QueryRecord.kind"),
    (dict(kind="proxies", option_proxies=[]), "QueryRecord.option_proxies"),
    (dict(kind="proxies", option_proxies=[1.0, 2.0, 3.0]), "QueryRecord.option_proxies"),
    (dict(kind="proxies", option_proxies=[1.0, float("inf")]), "QueryRecord.option_proxies"),
    (dict(kind="paths", option_proxies=[1.0, 2.0]), "QueryRecord.option_proxies"),
])
def test_bad_kinds_and_proxies_name_the_field(kw: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field}:"):
        qr.event_from_msg(record(1, **kw), resolution=RES, origin=ORIGIN)


def _events(*records: Any) -> list[qr.QueryRecordData]:
    return [qr.event_from_msg(r, resolution=RES, origin=ORIGIN) for r in records]


def test_rounds_pair_answers_with_proposals_and_open_queries_are_the_rest() -> None:
    events = _events(record(1), record(2), record(1, "answered", chosen=0, sec=11),
                     record(9, "answered", chosen=1),  # its proposal is not in the history: ignored
                     record(1, "answered", chosen=1, sec=12),  # a second answer to 1: ignored
                     record(3))
    rounds = qr.rounds_from_events(events)
    assert [(r.query_id, r.chosen) for r in rounds] == [(1, 0), (2, None), (3, None)]
    assert [e.query_id for e in qr.open_queries(events)] == [2, 3]
    # The inference node restarted (ids start again): a new proposal of id 1 is a new, open round.
    again = qr.rounds_from_events(events + _events(record(1, sec=20)))
    assert [(r.query_id, r.chosen) for r in again] == [(1, 0), (2, None), (3, None), (1, None)]
    assert [e.stamp_ns for e in qr.open_queries(events + _events(record(1, sec=20)))][-1] == 20_000_000_005


def test_round_summary_and_table() -> None:
    rounds = qr.rounds_from_events(_events(record(1), record(2), record(1, "answered", chosen=1, sec=12)))
    rows = [qr.round_summary(r, start_ns=10_000_000_000) for r in rounds]
    assert rows[0]["chosen"] == 1 and rows[0]["answered_by"] == "web" and rows[0]["horizon"] == 2
    assert rows[0]["answered_s"] == pytest.approx(2.000000005)
    assert rows[1]["chosen"] is None and rows[1]["answered_by"] is None
    table = qr.rounds_table(rows).splitlines()
    assert len(table) == 3 and table[0].split()[:3] == ["query", "strategy", "info"]
    assert table[1].split() == ["1", "info_gain", "0.2500", "2", "1", "web", "1"]
    assert table[2].split() == ["2", "info_gain", "0.2500", "2", "open"]
    json.dumps(rows)
    json.dumps(qr.record_dict(rounds[0].answer))


def test_option_returns_equal_lavaland_true_return_in_any_class_order() -> None:
    rng = np.random.default_rng(0)
    labels = rng.integers(0, len(TERRAIN_NAMES), size=(6, 7))
    options = [np.column_stack([rng.integers(0, 6, 9), rng.integers(0, 7, 9)]) for _ in range(5)]
    expected = [evaluation.true_return(labels, o) for o in options]
    rewards = lavaland.TRUE_TERRAIN_REWARD[: len(TERRAIN_NAMES)]
    got = qr.option_returns(labels, TERRAIN_NAMES, TERRAIN_NAMES, rewards, options)
    assert np.allclose(got, expected)
    # The reward table may list the terrains in another order than the grid's classes.
    perm = rng.permutation(len(TERRAIN_NAMES))
    got = qr.option_returns(labels, TERRAIN_NAMES, [TERRAIN_NAMES[i] for i in perm], rewards[perm], options)
    assert np.allclose(got, expected)


def test_option_returns_refuse_unknown_cells_and_off_map_paths() -> None:
    labels = np.zeros((3, 3), dtype=np.uint8)
    labels[1, 1] = 255
    names, rewards = ["dirt"], [0.1]
    assert qr.option_returns(labels, ["dirt"], names, rewards, [np.array([[0, 0], [0, 1]])]).tolist() == [0.2]
    with pytest.raises(ValueError, match=r"^options\[0\]: .*unknown"):
        qr.option_returns(labels, ["dirt"], names, rewards, [np.array([[0, 0], [1, 1]])])
    with pytest.raises(ValueError, match=r"^options\[1\]: .*off"):
        qr.option_returns(labels, ["dirt"], names, rewards, [np.array([[0, 0]]), np.array([[3, 0]])])
    with pytest.raises(ValueError, match="^terrain_rewards:"):
        qr.option_returns(labels, ["dirt"], ["dirt", "lava"], [0.1], [np.array([[0, 0]])])


def test_plot_query_rounds_draws_every_round(tmp_path: Any) -> None:
    from ird_ros.bags.missions import Terrain
    from ird_ros.bags.plots import plot_query_rounds

    rounds = qr.rounds_from_events(_events(record(1), record(2), record(1, "answered", chosen=1)))
    terrain = Terrain(classes=np.zeros((3, 4), np.uint8), class_names=("dirt",), resolution=RES, origin=ORIGIN)
    path = plot_query_rounds(rounds, terrain, tmp_path / "rounds.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_analyze_bag_reports_and_draws_the_rounds(tmp_path: Any) -> None:
    """A bag with /world/terrain and three /ird/queries records: analyze() and the CLI."""
    import subprocess
    import sys
    from pathlib import Path

    from test_analyze_bag import ORIGIN as B_ORIGIN
    from test_analyze_bag import RES as B_RES
    from test_analyze_bag import SEC, BagBuilder, make, terrain_classes

    from ird_ros.bags.analysis import analyze

    path = tmp_path / "bag"
    b = BagBuilder(path)
    s = b.store
    classes = terrain_classes()
    h, w = classes.shape
    b.write("/world/terrain", "ird_msgs/msg/TerrainGrid", SEC,
            make(s, "ird_msgs/msg/TerrainGrid", header=b.header(SEC), info=b.info(h, w),
                 class_names=["dirt", "grass", "target", "lava"], classes=classes.ravel().copy(),
                 probabilities=np.zeros(0, np.float32), novelty=np.zeros(0, np.float32)))

    def centre(r: int, c: int) -> tuple[float, float]:
        return B_ORIGIN[0] + (c + 0.5) * B_RES, B_ORIGIN[1] + (r + 0.5) * B_RES

    options = [[(0, 0), (1, 0), (2, 0)], [(0, 0), (0, 1), (1, 1)]]
    for k, (qid, event, chosen) in enumerate(((1, "proposed", -1), (1, "answered", 1), (2, "proposed", -1))):
        t = (2 + k) * SEC
        paths = [make(s, "nav_msgs/msg/Path", header=b.header(t), poses=[b.pose(t, *centre(*c)) for c in o])
                 for o in options]
        msg = make(s, "ird_msgs/msg/QueryRecord", header=b.header(t), query_id=qid, event=event, strategy="info_gain",
                   options=paths, feature_names=["dirt", "lava"], option_features=np.array([1.0, 0.0, 2.0, 1.0]),
                   information_gain=0.125 * qid, chosen=chosen, beta=1.0 if chosen >= 0 else 0.0,
                   answered_by="simulated" if chosen >= 0 else "", num_answers=int(chosen >= 0))
        b.write("/ird/queries", "ird_msgs/msg/QueryRecord", t, msg)
    b.close()

    report = analyze(path, tmp_path / "out")
    rows = report["query_rounds"]
    assert [(r["query_id"], r["chosen"], r["answered_by"], r["information_gain"]) for r in rows] == [
        (1, 1, "simulated", 0.125), (2, None, None, 0.25)]
    assert rows[0]["horizon"] == 2 and rows[0]["proposed_s"] == pytest.approx(1.0)
    assert str(tmp_path / "out" / "query_rounds.png") in report["plots"]
    script = Path(__file__).resolve().parents[1] / "scripts" / "analyze_bag.py"
    proc = subprocess.run([sys.executable, str(script), str(path), "--no-plots"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    i = lines.index("Questions to the designer:")
    assert lines[i + 2].split() == ["1", "info_gain", "0.1250", "2", "1", "simulated", "1"]
    assert lines[i + 3].split() == ["2", "info_gain", "0.2500", "2", "open"]
