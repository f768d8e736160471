"""The navigator's ROS-free logic (ird_ros.jobs.navigation): goals validated naming the field, the
defaults filled in, Rob's drive followed per plan, driven cells judged like ird_core, and the client's
typed goal (ird_ros.client.navigation) refusing values the message cannot hold."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from ird_core.vocabulary import Baseline, PlanMode, ZMethod
from ird_core.worlds import evaluation, lavaland
from ird_core.worlds.terrain import Terrain
from ird_ros.jobs.navigation import (
    DEFAULT_LABEL,
    DriveTracker,
    GoalLimits,
    NavigationStatus,
    RiskMeasure,
    Stage,
    check_goal,
    judge,
    posterior_summary,
)

LIMITS = GoalLimits(max_queries=3, max_num_samples=500, default_beta=5.0, default_num_samples=40)


def goal(**changes: Any) -> dict[str, Any]:
    fields: dict[str, Any] = dict(method="maxent_z", beta=0.0, num_samples=0, seed=0, mode="per_step",
                                  baseline="training_features", risk_measure="min", risk_level=0.0, queries=0,
                                  label="")
    fields.update(changes)
    return fields


def test_a_good_goal_gets_the_defaults() -> None:
    checked = check_goal(**goal(), limits=LIMITS)
    assert checked.method is ZMethod.MAXENT_Z and not checked.uses_current_posterior
    assert (checked.beta, checked.num_samples) == (5.0, 40)
    assert checked.mode is PlanMode.PER_STEP and checked.baseline is Baseline.TRAINING_FEATURES
    assert checked.risk_measure is RiskMeasure.MIN and checked.label == DEFAULT_LABEL


def test_given_values_are_kept() -> None:
    checked = check_goal(**goal(method="sample_z", beta=2.5, num_samples=64, seed=9, mode="trajectory",
                                baseline="log_z", risk_measure="", queries=3, label="mine"), limits=LIMITS)
    assert (checked.method, checked.beta, checked.num_samples, checked.seed) == ("sample_z", 2.5, 64, 9)
    assert (checked.mode, checked.baseline, checked.queries, checked.label) == ("trajectory", "log_z", 3, "mine")
    assert checked.risk_measure is None  # "" = the planner's default measure
    cvar = check_goal(**goal(risk_measure="cvar", risk_level=0.25), limits=LIMITS)
    assert (cvar.risk_measure, cvar.risk_level) == (RiskMeasure.CVAR, 0.25)


def test_empty_method_uses_the_current_posterior() -> None:
    assert check_goal(**goal(method=""), limits=LIMITS).uses_current_posterior


@pytest.mark.parametrize(("changes", "field"), [
    (dict(method="nope"), "method"),
    (dict(method=None), "method"),
    (dict(beta=-1.0), "beta"),
    (dict(beta=math.nan), "beta"),
    (dict(beta=1e4), "beta"),
    (dict(num_samples=-1), "num_samples"),
    (dict(num_samples=501), "num_samples"),
    (dict(seed=-3), "seed"),
    (dict(mode="zigzag"), "mode"),
    (dict(baseline="nope"), "baseline"),
    (dict(risk_measure="worst"), "risk_measure"),
    (dict(risk_measure="cvar"), "risk_level"),
    (dict(risk_measure="cvar", risk_level=1.5), "risk_level"),
    (dict(risk_measure="mean_sd", risk_level=1.0, mode="trajectory"), "risk_measure"),
    (dict(risk_measure="", risk_level=101.0), "risk_level"),
    (dict(risk_level=0.5), "risk_level"),
    (dict(queries=-1), "queries"),
    (dict(queries=4), "queries"),
    (dict(queries=1.5), "queries"),
    (dict(label=3), "label"),
])
def test_bad_goals_are_refused_naming_the_field(changes: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError) as caught:
        check_goal(**goal(**changes), limits=LIMITS)
    assert str(caught.value).startswith(f"{field}: "), caught.value


@pytest.mark.parametrize("mode", ["per_step", "trajectory"])
@pytest.mark.parametrize("measure", ["min", "cvar", "mean_sd"])
@pytest.mark.parametrize("level", [0.0, 0.5, 1.0, 2.0])
def test_a_named_risk_is_refused_exactly_when_the_planner_refuses_it(mode: str, measure: str, level: float) -> None:
    from ird_core.planning.risk_measures import MIN_RISK
    from ird_ros.jobs.planning import request_risk

    try:
        request_risk(measure, level, MIN_RISK, mode)
        planner = None
    except ValueError as exc:
        planner = str(exc).split(":")[0]
    try:
        check_goal(**goal(mode=mode, risk_measure=measure, risk_level=level), limits=LIMITS)
        navigator = None
    except ValueError as exc:
        navigator = str(exc).split(":")[0]
    assert navigator == {"risk": "risk_measure"}.get(planner, planner)


def test_queries_refusal_names_the_limit() -> None:
    with pytest.raises(ValueError, match="max_queries=3"):
        check_goal(**goal(queries=4), limits=LIMITS)


def test_vocabularies() -> None:
    assert [str(s) for s in Stage] == ["inferring", "asking", "planning", "driving"]
    assert [str(s) for s in NavigationStatus] == ["succeeded", "canceled", "aborted", "rejected"]


def test_posterior_summary() -> None:
    assert posterior_summary("maxent_z", 64, 1.0213) == "maxent_z, 64 samples, R-hat 1.02"
    assert posterior_summary("sample_z", 8, 1.3, converged=False, answers=2) == \
        "sample_z, 8 samples, R-hat 1.30, 2 answers, not converged"


PLAN = ((0, 0), (0, 1), (1, 1), (2, 1))


def test_the_tracker_follows_one_plan_and_fills_missing_steps() -> None:
    tracker = DriveTracker("mine", PLAN)
    assert tracker.progress == 0.0 and tracker.cells == [] and not tracker.done
    assert not tracker.feed("other", 0, 5, 5, False)
    assert tracker.feed("mine", 0, 0, 0, False)
    assert tracker.feed("mine", 2, 1, 1, False)  # step 1's status was lost: the plan's cell stands in
    assert tracker.cells == [(0, 0), (0, 1), (1, 1)] and tracker.cell == (1, 1)
    assert tracker.progress == pytest.approx(2 / 3)
    assert tracker.feed("mine", 3, 2, 1, True, status="final")
    assert tracker.done and not tracker.stopped and tracker.final == "final" and tracker.progress == 1.0
    assert not tracker.feed("mine", 3, 2, 1, True)  # nothing after the final status


def test_a_stopped_drive_ends_where_rob_stood() -> None:
    tracker = DriveTracker("mine", PLAN)
    tracker.feed("mine", 0, 0, 0, False)
    tracker.feed("mine", 1, 0, 1, False)
    tracker.feed("mine", 1, 0, 1, True, stopped=True)
    assert tracker.done and tracker.stopped and tracker.cells == [(0, 0), (0, 1)]


def test_judge_equals_evaluate_path_on_the_ground_truth() -> None:
    inst = lavaland.make_instance("latent_raw", 4, size=6, horizon=8, obs_dim=6)
    names = [t.name.lower() for t in Terrain]
    rewards = {name: float(lavaland.TRUE_TERRAIN_REWARD[int(t)]) for name, t in zip(names, Terrain)}
    rng = np.random.default_rng(0)
    for _ in range(20):
        cells = [tuple(int(v) for v in rng.integers(0, 6, size=2)) for _ in range(5)]
        verdict = judge(cells, inst.test_labels.astype(np.uint8), names, rewards)
        outcome = evaluation.evaluate_path(inst.test_labels, cells)
        assert (verdict.touched_lava, verdict.reached_target) == (outcome.touched_lava, outcome.reached_target)
        assert verdict.true_return == pytest.approx(outcome.true_return)
    assert math.isnan(judge([(0, 0)], inst.test_labels.astype(np.uint8), names, {}).true_return)


def test_the_client_goal_refuses_what_the_message_cannot_hold() -> None:
    pytest.importorskip("ird_msgs.action")
    from ird_ros.client.navigation import NavigationGoal, NavigationResult

    msg = NavigationGoal(method="", seed=3, queries=-1, label="x").to_msg()
    assert (msg.method, msg.seed, msg.queries, msg.label, msg.mode) == ("", 3, -1, "x", "per_step")
    for bad, field in ((dict(seed=-1), "seed"), (dict(num_samples=2**40), "num_samples"), (dict(beta="x"), "beta"),
                       (dict(mode=None), "mode")):
        with pytest.raises(ValueError, match=f"^{field}: "):
            NavigationGoal(**bad).to_msg()
    rejected = NavigationResult.rejected("method: bad", "method")
    assert rejected.status is NavigationStatus.REJECTED and rejected.cells.shape == (0, 2)
    assert rejected.touched_lava is None and rejected.true_return is None


def test_rob_stops_where_he_is() -> None:
    from ird_ros.jobs.rob_logic import RobExecutor

    rob = RobExecutor()
    rob.set_terrain(np.zeros((3, 3), dtype=np.uint8), ["dirt"])
    rob.set_rewards(["dirt"], [0.5])
    assert rob.stop() is None  # idle: nothing to stop
    rob.set_plan(PLAN[:3], stamp="s", label="x")
    first, second = rob.tick(), rob.tick()
    assert first is not None and second is not None and not second.stopped
    stopped = rob.stop()
    assert stopped is not None and stopped.stopped and stopped.done
    assert (stopped.row, stopped.col, stopped.step, stopped.horizon) == (0, 1, 1, 2)
    assert stopped.true_return == second.true_return == pytest.approx(1.0)
    assert rob.tick() is None and not rob.active  # he stays
    rob.set_plan(PLAN[:3])
    at_start = rob.stop()  # before the first move: the start cell, step 0
    assert at_start is not None and (at_start.step, at_start.row, at_start.col) == (0, 0, 0) and at_start.stopped
