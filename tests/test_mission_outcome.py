"""What a mission says about each goal (issue 43): a goal that "succeeded" may have left Rob at his
start; the line says what he did (ird_ros.apps.mission, ird_ros.bags.missions.drive_outcome)."""

from __future__ import annotations

import numpy as np

from ird_ros.apps.mission import goal_outcome, result_line, summary_line
from ird_ros.client.navigation import NavigationResult, NavigationStatus


def _result(cells: list[tuple[int, int]], *, lava: bool = False, target: bool = False,
            status: NavigationStatus = NavigationStatus.SUCCEEDED) -> NavigationResult:
    return NavigationResult(status, "", "", np.array(cells, dtype=np.int64).reshape(-1, 2), lava, target, 0.0, 1.0)


def test_a_goal_whose_rob_never_left_the_start_says_so() -> None:
    stayed = _result([(2, 2)] * 5)
    assert goal_outcome(stayed) == "stayed put"
    assert result_line(0, "ird", stayed).startswith("[mission] seed 0 ird: SUCCEEDED: stayed put (lava False")
    assert goal_outcome(_result([(0, 0), (0, 1)], target=True)) == "reached the target"
    assert goal_outcome(_result([(0, 0), (0, 1)], lava=True)) == "touched lava"
    assert goal_outcome(_result([(0, 0)], status=NavigationStatus.CANCELED)) == "canceled"


def test_the_summary_counts_what_rob_did_instead_of_every_goal_succeeded() -> None:
    line = summary_line(1, ["touched lava", "stayed put"], 0)
    assert line == "[mission] 1 seed(s): every goal ran to its end: 1 touched lava, 1 stayed put"
    assert "succeeded" not in line
    assert summary_line(2, ["stayed put", "canceled"], 1) == "[mission] 2 seed(s): 1 failed; 1 stayed put, 1 canceled"
