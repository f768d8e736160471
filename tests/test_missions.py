"""Mission segmentation (ird_ros.bags.missions) and the cell geometry on hand-made messages: no bag, no ROS.

Messages are plain namespaces with the fields the analysis reads; every expectation is
written from the rules in the ``ird_ros.bags.missions`` docstring, never from the code under test.
"""

from __future__ import annotations

import math
import subprocess
import sys
from types import SimpleNamespace as NS
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ird_ros.bags import missions as M
from ird_ros.geometry import cell_center, grid_coordinates, point_cells
from ird_ros.graph import names

SEC = 1_000_000_000
T0 = 1_000 * SEC


def logged(t_ns: int, msg: Any) -> NS:
    return NS(timestamp=t_ns, msg=msg)


def header(t_ns: int) -> NS:
    return NS(stamp=NS(sec=t_ns // SEC, nanosec=t_ns % SEC))


def status(t_ns: int, label: str, step: int, horizon: int, *, cell: tuple[int, int] = (0, 0),
           ret: float = 0.0, lava: bool = False, target: bool = False) -> NS:
    return logged(t_ns, NS(plan_label=label, step=step, horizon=horizon, done=step == horizon, row=cell[0],
                           col=cell[1], true_return=ret, touched_lava=lava, reached_target=target, terrain="dirt"))


def plan(t_ns: int, cells: list[tuple[int, int]], stamp_ns: int | None = None) -> NS:
    poses = [NS(pose=NS(position=NS(x=c + 0.5, y=r + 0.5))) for r, c in cells]
    return logged(t_ns, NS(header=header(t_ns if stamp_ns is None else stamp_ns), poses=poses))


def info(t_ns: int, stamp_ns: int, label: str, mode: str, cells: list[tuple[int, int]]) -> NS:
    return logged(t_ns, NS(header=header(stamp_ns), label=label, mode=mode, baseline="none", objective=float(len(cells)),
                           rows=[r for r, _ in cells], cols=[c for _, c in cells]))


def odom(t_ns: int, x: float, y: float) -> NS:
    return logged(t_ns, NS(pose=NS(pose=NS(position=NS(x=x, y=y)))))


def run(label: str, start_ns: int, horizon: int, *, cells: list[tuple[int, int]] | None = None) -> list[NS]:
    """Statuses of one finished mission, 0.1 s apart, return = step."""
    cells = cells or [(0, 0)] * (horizon + 1)
    return [status(start_ns + k * SEC // 10, label, k, horizon, cell=cells[k], ret=float(k)) for k in range(horizon + 1)]


# --------------------------------------------------------------------------- segmentation


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(["a", "b", ""]), st.integers(0, 4)), min_size=1, max_size=6))
def test_segmentation_recovers_concatenated_missions(spec: list[tuple[str, int]]) -> None:
    # Finished missions logged back to back (same label or not) come out one for one.
    statuses = [s for k, (label, horizon) in enumerate(spec) for s in run(label, T0 + k * SEC, horizon)]
    missions = M.missions_from_messages({names.TOPIC_ROB_STATUS: statuses})
    assert [(m.label, m.steps, m.horizon, m.done) for m in missions] == [
        (label or f"mission_{k}", horizon, horizon, True) for k, (label, horizon) in enumerate(spec)]
    assert [m.true_return for m in missions] == [float(h) for _, h in spec]
    assert [m.start_ns for m in missions] == [T0 + k * SEC for k in range(len(spec))]
    assert [m.index for m in missions] == list(range(len(spec)))


def test_a_step_going_back_splits_an_unfinished_mission() -> None:
    # A replan under the same label restarts the steps before the first plan was done.
    statuses = run("a", T0, 4)[:3] + run("a", T0 + SEC, 4)
    missions = M.missions_from_messages({names.TOPIC_ROB_STATUS: statuses})
    assert [(m.steps, m.done) for m in missions] == [(2, False), (4, True)]


def test_a_repeated_step_stays_in_the_mission_and_the_last_report_wins() -> None:
    statuses = [status(T0, "a", 0, 2, cell=(0, 0)), status(T0 + 1, "a", 1, 2, cell=(0, 1)),
                status(T0 + 2, "a", 1, 2, cell=(1, 1)), status(T0 + 3, "a", 2, 2, cell=(1, 1))]
    (mission,) = M.missions_from_messages({names.TOPIC_ROB_STATUS: statuses})
    assert mission.executed_cells == [(0, 0), (1, 1), (1, 1)]
    assert mission.executed_moves == 1
    np.testing.assert_array_equal(mission.status_returns[:, 0], [T0, T0 + 1, T0 + 2, T0 + 3])


# --------------------------------------------------------------------------- plans and plan info


def test_each_mission_takes_the_latest_untaken_plan_before_it() -> None:
    superseded, first, second = [(0, 0), (0, 1)], [(0, 0), (1, 0), (1, 1)], [(2, 2), (2, 3)]
    plans = [plan(T0, superseded), plan(T0 + SEC // 2, first), plan(T0 + 3 * SEC, second)]
    statuses = run("a", T0 + SEC, 2) + run("b", T0 + 2 * SEC, 2) + run("c", T0 + 4 * SEC, 1)
    missions = M.missions_from_messages({names.TOPIC_PLAN: plans, names.TOPIC_ROB_STATUS: statuses})
    assert [m.plan_ns for m in missions] == [T0 + SEC // 2, None, T0 + 3 * SEC]
    assert [m.plan_moves for m in missions] == [2, 0, 1]
    np.testing.assert_array_equal(missions[0].plan_xy, [[0.5, 0.5], [0.5, 1.5], [1.5, 1.5]])
    # a mission's window starts at its plan when it has one
    assert [m.start_ns for m in missions] == [T0 + SEC // 2, T0 + 2 * SEC, T0 + 3 * SEC]


def test_plan_info_with_the_plan_stamp_wins_over_a_later_one() -> None:
    cells = [(0, 0), (0, 1)]
    plans = [plan(T0 + SEC, cells, stamp_ns=T0 + 7)]
    infos = [info(T0, T0 + 7, "proxy", "literal", cells), info(T0 + SEC - 1, T0 + 99, "decoy", "trajectory", cells[:1])]
    statuses = [status(T0 + 2 * SEC, "", 0, 1), status(T0 + 3 * SEC, "", 1, 1)]
    (mission,) = M.missions_from_messages({names.TOPIC_PLAN: plans, names.TOPIC_PLAN_INFO: infos,
                                           names.TOPIC_ROB_STATUS: statuses})
    assert (mission.label, mission.mode, mission.baseline, mission.objective) == ("proxy", "literal", "none", 2.0)
    assert mission.plan_cells == cells


def test_without_a_stamp_match_the_latest_plan_info_before_the_plan_is_used() -> None:
    cells = [(0, 0), (0, 1), (0, 2)]
    plans = [plan(T0 + SEC, cells, stamp_ns=T0 + 1)]
    infos = [info(T0, T0 + 2, "old", "literal", cells), info(T0 + SEC // 2, T0 + 3, "new", "per_step", cells),
             info(T0 + 2 * SEC, T0 + 4, "after", "trajectory", cells)]
    (mission,) = M.missions_from_messages({names.TOPIC_PLAN: plans, names.TOPIC_PLAN_INFO: infos,
                                           names.TOPIC_ROB_STATUS: run("rob", T0 + SEC, 2)})
    assert (mission.label, mission.mode) == ("rob", "per_step")  # the status label is kept


def test_a_bag_without_statuses_has_one_mission_per_plan() -> None:
    plans = [plan(T0, [(0, 0), (0, 1)]), plan(T0 + SEC, [(1, 1)])]
    infos = [info(T0, T0, "first", "literal", [(0, 0), (0, 1)])]
    missions = M.missions_from_messages({names.TOPIC_PLAN: plans, names.TOPIC_PLAN_INFO: infos})
    assert [(m.label, m.start_ns, m.end_ns, m.plan_moves) for m in missions] == [
        ("first", T0, T0, 1), ("first", T0 + SEC, T0 + SEC, 1)]  # the latest info before the second plan
    assert missions[1].plan_cells == [(0, 0), (0, 1)] and len(missions[1].plan_xy) == 1
    assert all(math.isnan(m.true_return) and not m.done for m in missions)
    assert M.missions_from_messages({}) == []


# --------------------------------------------------------------------------- odometry


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(0, 40 * SEC // 10), min_size=0, max_size=30))
def test_odometry_windows_partition_the_run(times: list[int]) -> None:
    # Missions at T0, T0 + 1 s and T0 + 2.5 s: an odometry sample belongs to the last mission
    # started at or before it, and samples before the first mission to none.
    starts = [T0, T0 + SEC, T0 + 5 * SEC // 2]
    statuses = [s for k, t in enumerate(starts) for s in run(str(k), t, 2)]
    stamps = sorted(T0 - SEC + t for t in times)
    odoms = [odom(t, float(t - T0), 0.0) for t in stamps]
    missions = M.missions_from_messages({names.TOPIC_ROB_STATUS: statuses, names.TOPIC_ODOM: odoms})
    for k, mission in enumerate(missions):
        stop = starts[k + 1] if k + 1 < len(starts) else math.inf
        assert mission.odom[:, 0].tolist() == [float(t) for t in stamps if starts[k] <= t < stop]
        np.testing.assert_array_equal(mission.odom[:, 1], mission.odom[:, 0] - T0)
    assert sum(len(m.odom) for m in missions) == sum(t >= T0 for t in stamps)


def test_lengths_of_the_plan_and_of_the_odometry() -> None:
    plans = [plan(T0, [(0, 0), (0, 1), (1, 1), (1, 1)])]
    odoms = [odom(T0 + k, x, y) for k, (x, y) in enumerate([(0.0, 0.0), (3.0, 4.0), (3.0, 4.0), (0.0, 4.0)])]
    (mission,) = M.missions_from_messages({names.TOPIC_PLAN: plans, names.TOPIC_ROB_STATUS: run("a", T0, 3),
                                           names.TOPIC_ODOM: odoms})
    assert mission.plan_length_m == pytest.approx(2.0)
    assert mission.executed_length_m == pytest.approx(8.0)
    (bare,) = M.missions_from_messages({names.TOPIC_ROB_STATUS: run("a", T0, 1)})
    assert math.isnan(bare.executed_length_m) and bare.plan_length_m == 0.0


# --------------------------------------------------------------------------- statistics


def test_label_statistics_are_per_label_fractions_and_means() -> None:
    def mission(label: str, lava: bool, target: bool, ret: float) -> M.Mission:
        return M.Mission(index=0, label=label, start_ns=0, end_ns=0, touched_lava=lava, reached_target=target,
                         true_return=ret)

    stats = M.label_statistics([mission("a", True, False, -10.0), mission("b", False, True, 1.0),
                                mission("a", False, True, 2.0), mission("a", False, False, math.nan),
                                mission("c", False, False, math.nan)])
    assert stats["a"] == pytest.approx({"runs": 3, "lava_fraction": 1 / 3, "target_fraction": 1 / 3,
                                        "mean_true_return": -4.0})
    assert stats["b"] == {"runs": 1, "lava_fraction": 0.0, "target_fraction": 1.0, "mean_true_return": 1.0}
    assert stats["c"]["runs"] == 1 and math.isnan(stats["c"]["mean_true_return"])
    assert M.label_statistics([]) == {}


def test_latest_before_falls_back_on_the_first_item() -> None:
    items = [logged(t, None) for t in (10, 20, 20, 30)]
    assert [M.latest_before(items, t) for t in (5, 10, 25, 20, 99)] == [0, 0, 2, 2, 3]
    assert M.latest_before([], 10) is None


# --------------------------------------------------------------------------- geometry


@settings(max_examples=60, deadline=None)
@given(st.integers(-50, 50), st.integers(-50, 50), st.sampled_from([0.05, 0.25, 0.5, 1.0, 3.0]),
       st.floats(-100, 100), st.floats(-100, 100), st.floats(0, 0.999), st.floats(0, 0.999))
def test_points_inside_a_cell_map_to_it(row: int, col: int, res: float, ox: float, oy: float,
                                        fx: float, fy: float) -> None:
    x, y = cell_center(row, col, res, (ox, oy))
    np.testing.assert_allclose(grid_coordinates([(x, y)], res, (ox, oy)), [[row + 0.5, col + 0.5]], atol=1e-9)
    assert point_cells([(x, y)], res, (ox, oy)).tolist() == [[row, col]]
    inside = (ox + (col + 0.01 + 0.98 * fx) * res, oy + (row + 0.01 + 0.98 * fy) * res)
    assert point_cells([inside], res, (ox, oy)).tolist() == [[row, col]]
    assert M.path_cells(np.array([inside, (x, y)]), res, (ox, oy)) == [(row, col), (row, col)]
    terrain = M.Terrain(np.zeros((1, 1), np.uint8), ("dirt",), res, (ox, oy))
    assert terrain.cell_of(*inside) == (row, col)


def test_cell_corners_belong_to_the_cell_above_and_right() -> None:
    corners = [(2.0, 3.0), (2.5, 3.0), (2.0, 3.5), (1.999, 2.999)]
    assert point_cells(corners, 0.5, (1.0, 2.0)).tolist() == [[2, 2], [2, 3], [3, 2], [1, 1]]
    assert point_cells(np.zeros((0, 2)), 1.0).shape == (0, 2)


def test_terrain_decodes_classes_row_major_and_rejects_a_short_array() -> None:
    msg = NS(info=NS(height=2, width=3, resolution=0.5, origin=NS(position=NS(x=-1.0, y=2.0))),
             classes=[0, 1, 2, 3, 255, 0], class_names=["dirt", "grass", "target", "lava"])
    terrain = M.terrain_from_msg(msg)
    np.testing.assert_array_equal(terrain.classes, [[0, 1, 2], [3, 255, 0]])
    assert terrain.extent == (-1.0, 0.5, 2.0, 3.0)
    msg.classes = msg.classes[:-1]
    with pytest.raises(ValueError, match="TerrainGrid.classes"):
        M.terrain_from_msg(msg)


def test_missions_import_neither_ros_nor_rosbags() -> None:
    code = ("import sys, ird_ros.bags.missions, ird_ros.geometry; "
            "bad = sorted(m for m in sys.modules if m.split('.')[0] in ('rclpy', 'rosbags', 'ird_msgs')); "
            "assert not bad, bad")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
