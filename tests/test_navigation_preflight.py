"""The navigator's up-front checks (issue 43), without DDS: ``check_goal_work`` refuses a goal that
the planner or ``/ird/query`` would refuse only after the inference, naming ``num_samples`` and the
limit; ``DriveTracker.other_plan`` ends a drive that a newer plan replaced."""

from __future__ import annotations

import math

import pytest

from ird_core import planning
from ird_core.planning.risk_measures import MIN_RISK
from ird_ros.jobs.navigation import DownstreamLimits, DriveTracker, GoalLimits, check_goal, check_goal_work
from ird_ros.jobs.planning import request_risk
from ird_ros.jobs.work import query_work

SIZE = dict(horizon=8, height=6, width=6, num_features=6)


def _goal(**changes: object):  # noqa: ANN202 - CheckedGoal
    fields: dict = dict(method="maxent_z", beta=5.0, num_samples=40, seed=0, mode="per_step",
                        baseline="training_features", risk_measure="", risk_level=0.0, queries=0, label="")
    fields.update(changes)
    return check_goal(limits=GoalLimits(), **fields)


def test_num_samples_past_the_planners_work_is_refused_naming_the_limit_and_what_fits() -> None:
    limits = DownstreamLimits(max_plan_work=1_000_000)
    fits = 1_000_000 // (9 * 36)
    assert planning.plan_work(fits, 8, 6, 6) <= 1_000_000 < planning.plan_work(fits + 1, 8, 6, 6)
    check_goal_work(_goal(num_samples=fits), limits=limits, **SIZE)
    with pytest.raises(ValueError, match=rf"^num_samples: {fits + 1} samples .* max_plan_work=1e\+06 .* "
                                         rf"at most {fits} samples fit"):
        check_goal_work(_goal(num_samples=fits + 1), limits=limits, **SIZE)
    # The goal at the default limit on a 15x15 map, T = 30.
    with pytest.raises(ValueError, match=r"^num_samples: 100000 samples .* max_plan_work=5e\+07"):
        check_goal_work(_goal(num_samples=100000), limits=DownstreamLimits(max_plan_work=5e7),
                        horizon=30, height=15, width=15, num_features=50)


def test_samples_that_do_not_reach_the_planner_are_not_held_to_its_work() -> None:
    limits = DownstreamLimits(max_plan_work=10)
    check_goal_work(_goal(num_samples=1000, mode="literal", baseline="none"), limits=limits, **SIZE)
    check_goal_work(_goal(method=""), limits=limits, **SIZE)  # the current posterior: no inference to save
    check_goal_work(_goal(num_samples=100000), limits=DownstreamLimits(), **SIZE)  # limits unknown


def test_num_samples_past_the_query_work_is_refused_only_when_asking() -> None:
    limit = 5e9
    limits = DownstreamLimits(max_query_work=limit)
    check_goal_work(_goal(num_samples=3000), limits=limits, **SIZE)  # no questions
    with pytest.raises(ValueError, match=r"^num_samples: 3000 samples .* max_query_work=5e\+09: at most (\d+)") as err:
        check_goal_work(_goal(num_samples=3000, queries=1), limits=limits, **SIZE)
    fits = int(str(err.value).rsplit("at most ", 1)[1].split()[0])
    assert query_work(fits, 6, 6, 8, 6, 2) <= limit < query_work(fits + 1, 6, 6, 8, 6, 2)
    check_goal_work(_goal(num_samples=fits, queries=1), limits=limits, **SIZE)


def test_the_planners_default_risk_and_horizon_are_checked_up_front() -> None:
    mean_sd = request_risk("mean_sd", 1.0, MIN_RISK)
    with pytest.raises(ValueError, match=r"^risk_measure: mean_sd is a per_step risk measure"):
        check_goal_work(_goal(mode="trajectory"), limits=DownstreamLimits(default_risk=mean_sd), **SIZE)
    risk = check_goal_work(_goal(), limits=DownstreamLimits(default_risk=mean_sd), **SIZE)
    assert risk is not None and risk.measure == "mean_sd" and risk.level == 1.0
    with pytest.raises(ValueError, match=r"^horizon: the world's test horizon 8 exceeds the planner's max_horizon=5"):
        check_goal_work(_goal(), limits=DownstreamLimits(max_horizon=5), **SIZE)


def test_a_newer_plan_ends_the_drive_and_older_ones_change_nothing() -> None:
    tracker = DriveTracker((10, 0), ((0, 0), (0, 1), (1, 1)))
    assert not tracker.other_plan((9, 5), "older")  # a status of the plan before ours
    assert not tracker.other_plan((10, 0), "ours")
    assert tracker.feed((10, 0), 0, 0, 0, False) and tracker.feed((10, 0), 1, 0, 1, False)
    assert not tracker.over
    assert tracker.other_plan((10, 1), "someone_else")
    assert tracker.over and not tracker.done and tracker.replaced_by == ((10, 1), "someone_else")
    assert tracker.cells == [(0, 0), (0, 1)] and tracker.progress == pytest.approx(0.5)
    assert not tracker.other_plan((11, 0), "later")  # the first replacement is the one reported
    finished = DriveTracker((10, 0), ((0, 0),))
    finished.feed((10, 0), 0, 0, 0, True)
    assert not finished.other_plan((12, 0)) and finished.replaced_by is None and not math.isnan(finished.progress)
