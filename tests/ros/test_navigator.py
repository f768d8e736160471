"""The NavigateIrd action (/ird/navigate) over real DDS: the whole default graph (with the navigator)
started by the launcher in a private domain, driven through ``IrdClient.navigate``.

A goal infers, plans and drives, with feedback in every stage, and its result judges the driven
cells like ird_core's evaluate_path on the ground truth; cancel stops Rob where he is; a second
goal while one runs is rejected; bad goals are rejected naming the field; "" uses the current
posterior; the goal's risk measure reaches /ird/plan; a question with no designer running aborts
saying so.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Iterator

import pytest
import yaml

from ird_core.worlds import evaluation, lavaland

REPO = Path(__file__).resolve().parents[2]
SIZE, HORIZON, OBS_DIM, SEED = 6, 8, 6, 4
#: The navigator's wait for an answer. It spans the designer's discovery of the question, its
#: call and the inference node's re-sampling (the answered record is published after it), so it
#: must not be a tight wall-clock budget: 3 s failed under a loaded CI run. The test without a
#: designer waits this long for its abort.
ANSWER_TIMEOUT = 30.0


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    from ird_ros.launch import GraphLauncher

    tmp = tmp_path_factory.mktemp("navigator")
    params = yaml.safe_load((REPO / "msgs_config/params/graph.yaml").read_text())
    params["world"]["ros__parameters"].update(condition="latent_raw", seed=SEED, height=SIZE, width=SIZE,
                                              horizon=HORIZON, obs_dim=OBS_DIM)
    # Slow enough to cancel mid-drive (T = 8 moves take 1.6 s), fast enough for the suite.
    params["rob"]["ros__parameters"]["rate_hz"] = 5.0
    params["navigator"]["ros__parameters"]["answer_timeout"] = ANSWER_TIMEOUT
    params_file = tmp / "graph.yaml"
    params_file.write_text(yaml.safe_dump(params))
    with GraphLauncher(params=params_file, private_domain=True, output="quiet", log_dir=tmp / "logs") as launched:
        launched.wait_ready(timeout=120)
        yield launched


@pytest.fixture(scope="module")
def ird(graph: Any) -> Iterator[Any]:
    from ird_ros.client import IrdClient

    with IrdClient(graph.domain_id, node_name="navigator_test") as client:
        client.watch_rob(timeout=60)
        yield client


@pytest.fixture(scope="module")
def inst() -> Any:
    return lavaland.make_instance("latent_raw", SEED, size=SIZE, horizon=HORIZON, obs_dim=OBS_DIM)


def _goal(**changes: Any) -> Any:
    from ird_ros.client import NavigationGoal

    fields: dict[str, Any] = dict(method="maxent_z", beta=5.0, num_samples=40, seed=11, label="nav_test")
    fields.update(changes)
    return NavigationGoal(**fields)


def _drive_statuses(ird: Any, since: int) -> list[Any]:
    """Rob's statuses of the first drive labelled nav_test among the statuses received after the
    first ``since``, up to its final one (``done``), which is waited for: /rob/status reaches this
    client independently of the action's result and may arrive after it (the navigator itself
    takes Rob's final status before it answers)."""
    from ird_ros.graph import names
    from ird_ros.stamps import stamp_key

    received = ird.received(names.TOPIC_ROB_STATUS)

    def drive() -> list[Any]:
        ours = [s for s in received[since:] if s.plan_label.startswith("nav_test")]
        key = stamp_key(ours[0].plan_stamp) if ours else None
        return [s for s in ours if stamp_key(s.plan_stamp) == key]

    ird.spin_until(lambda: any(s.done for s in drive()), timeout=60, what="Rob's final status of the drive")
    statuses = drive()
    return statuses[:next(i for i, s in enumerate(statuses) if s.done) + 1]


def _status_count(ird: Any) -> int:
    from ird_ros.graph import names

    return len(ird.received(names.TOPIC_ROB_STATUS))


def test_a_goal_infers_plans_drives_and_is_judged_on_the_ground_truth(ird: Any, inst: Any) -> None:
    from ird_ros.client import NavigationStatus

    feedback: list[Any] = []
    since = _status_count(ird)
    result = ird.navigate(_goal(), on_feedback=feedback.append, timeout=300)
    assert result.status is NavigationStatus.SUCCEEDED, result.message
    stages = {f.stage for f in feedback}
    assert {"inferring", "planning", "driving"} <= stages, stages
    # Progress only grows. The last feedback (1.0) may be lost: it travels apart from the result,
    # and rclpy drops a goal's feedback once its result is taken (ActionClient's
    # _remove_pending_result_request); the drive's end is checked on the result and Rob's status.
    driving = [f for f in feedback if f.stage == "driving" and f.pose_cell is not None]
    assert driving and all(a.progress <= b.progress for a, b in zip(driving, driving[1:]))
    assert all(0.0 <= f.progress <= 1.0 for f in feedback)
    summaries = [f.posterior_summary for f in feedback if f.posterior_summary]
    assert summaries and summaries[-1].startswith("maxent_z, 40 samples, R-hat")
    cells = result.cells
    assert cells.shape == (inst.test_horizon + 1, 2)
    assert tuple(cells[0]) == tuple(inst.test_start)
    path = [tuple(c) for c in cells]
    outcome = evaluation.evaluate_path(inst.test_labels, path)
    assert result.touched_lava == outcome.touched_lava
    assert result.reached_target == outcome.reached_target
    assert result.true_return == pytest.approx(outcome.true_return)
    assert math.isfinite(result.objective)
    final = _drive_statuses(ird, since)[-1]
    assert final.done and not final.stopped and (final.row, final.col) == path[-1]


def test_cancel_while_driving_stops_rob_where_he_is(ird: Any, inst: Any) -> None:
    from ird_ros.client import NavigationStatus

    feedback: list[Any] = []
    since = _status_count(ird)
    handle = ird.navigate_async(_goal(seed=12), on_feedback=feedback.append)
    ird.spin_until(lambda: any(f.stage == "driving" and f.pose_cell is not None for f in feedback) or handle.done(),
                   timeout=300, what="Rob driving the navigation plan")
    handle.cancel()
    result = handle.result(timeout=60)
    assert result.status is NavigationStatus.CANCELED, result.message
    cells = [tuple(c) for c in result.cells]
    assert 1 <= len(cells) < inst.test_horizon + 1
    assert cells[0] == tuple(inst.test_start)
    final = _drive_statuses(ird, since)[-1]
    assert final.stopped and final.done and final.step == len(cells) - 1
    assert (final.row, final.col) == cells[-1]
    assert result.touched_lava == evaluation.evaluate_path(inst.test_labels, cells).touched_lava


def test_a_second_goal_while_one_runs_is_rejected(ird: Any) -> None:
    from ird_ros.client import NavigationStatus

    feedback: list[Any] = []
    first = ird.navigate_async(_goal(seed=13), on_feedback=feedback.append)
    ird.spin_until(lambda: bool(feedback) or first.done(), timeout=120, what="the first goal's feedback")
    second = ird.navigate(_goal(seed=14), timeout=60)
    assert second.status is NavigationStatus.REJECTED
    assert "a goal is active" in second.message and second.field == ""
    assert first.result(timeout=300).status is NavigationStatus.SUCCEEDED


@pytest.mark.parametrize(("changes", "field"), [
    (dict(method="nope"), "method"),
    (dict(queries=-1), "queries"),
    (dict(risk_measure="worst"), "risk_measure"),
    (dict(risk_measure="cvar"), "risk_level"),  # cvar needs its alpha
    (dict(risk_measure="mean_sd", risk_level=1.0, mode="trajectory"), "risk_measure"),
    (dict(mode="zigzag"), "mode"),
])
def test_bad_goals_are_rejected_naming_the_field(ird: Any, changes: dict[str, Any], field: str) -> None:
    from ird_ros.client import NavigationStatus

    result = ird.navigate(_goal(**changes), timeout=60)
    assert result.status is NavigationStatus.REJECTED
    assert result.field == field and result.message.startswith(f"{field}: "), result.message
    assert result.cells.shape == (0, 2) and result.touched_lava is None


def test_the_current_posterior_is_used_after_an_inference(ird: Any, inst: Any) -> None:
    from ird_ros.client import NavigationStatus
    from ird_ros.graph import names
    from ird_ros.stamps import stamp_key

    current = ird.latest(names.TOPIC_POSTERIOR, timeout=60)  # latched: the one the navigator holds too
    posteriors = len(ird.received(names.TOPIC_POSTERIOR))
    feedback: list[Any] = []
    result = ird.navigate(_goal(method="", mode="trajectory", label="nav_test_current"),
                          on_feedback=feedback.append, timeout=300)
    assert result.status is NavigationStatus.SUCCEEDED, result.message
    assert tuple(result.cells[0]) == tuple(inst.test_start)
    assert [f.posterior_summary for f in feedback if f.posterior_summary][0].startswith("maxent_z, 40 samples")
    assert len(ird.received(names.TOPIC_POSTERIOR)) == posteriors  # no new inference
    assert stamp_key(ird.received(names.TOPIC_POSTERIOR)[-1].header.stamp) == stamp_key(current.header.stamp)


def test_the_goals_risk_measure_reaches_the_planner(ird: Any) -> None:
    """risk_measure / risk_level are /ird/plan's risk / risk_level: the plan Rob drives says so on
    /ird/plan_info, and "" leaves the planner's default (min, level 0)."""
    from ird_ros.client import NavigationStatus
    from ird_ros.graph import names

    ird.subscribe(names.TOPIC_PLAN_INFO)
    for label, changes, expected in (("nav_test_cvar", dict(risk_measure="cvar", risk_level=0.5), ("cvar", 0.5)),
                                     ("nav_test_default", dict(risk_measure=""), ("min", 0.0))):
        result = ird.navigate(_goal(method="", label=label, **changes), timeout=300)
        assert result.status is NavigationStatus.SUCCEEDED, result.message
        ird.spin_until(lambda lb=label: any(i.label == lb for i in ird.received(names.TOPIC_PLAN_INFO)),
                       timeout=30, what=f"/ird/plan_info of {label}")
        info = [i for i in ird.received(names.TOPIC_PLAN_INFO) if i.label == label][-1]
        assert (info.mode, info.risk, info.risk_level) == ("per_step", *expected)
        assert [tuple(c) for c in result.cells] == list(zip(info.rows, info.cols))


def test_a_question_without_a_designer_aborts_saying_so(ird: Any) -> None:
    from ird_ros.client import NavigationStatus

    feedback: list[Any] = []
    result = ird.navigate(_goal(method="", queries=1), on_feedback=feedback.append, timeout=120)
    assert result.status is NavigationStatus.ABORTED
    assert "designer" in result.message and "answer_timeout" in result.message, result.message
    assert "asking" in {f.stage for f in feedback}


def test_questions_answered_by_a_designer_come_before_the_drive(graph: Any, ird: Any, inst: Any) -> None:
    from ird_ros.client import NavigationStatus
    from ird_ros.graph import names
    from ird_ros.testing import spawn_node_process

    designer = spawn_node_process(["-m", "ird_ros.nodes.designer", "--ros-args", "--params-file",
                                   str(REPO / "msgs_config/params/graph.yaml"), "-p", "mode:=simulated"],
                                  domain=graph.domain_id, env=graph.env, name="designer",
                                  ready_text="designer ready", ready_timeout=60)
    try:
        ird.subscribe(names.TOPIC_QUERIES)
        feedback: list[Any] = []
        result = ird.navigate(_goal(seed=15, queries=2, label="nav_test_asked"), on_feedback=feedback.append,
                              timeout=300)
        assert result.status is NavigationStatus.SUCCEEDED, result.message
        stages = [f.stage for f in feedback]
        assert stages.index("asking") < stages.index("planning") < stages.index("driving"), stages
        assert any(f.posterior_summary.startswith("maxent_z, 40 samples") and "2 answers" in f.posterior_summary
                   for f in feedback if f.stage == "asking")
        def answered() -> set[int]:
            return {r.query_id for r in ird.received(names.TOPIC_QUERIES) if r.event == "answered"}

        ird.spin_until(lambda: len(answered()) >= 2, timeout=30, what="the designer's answers on /ird/queries")
        assert tuple(result.cells[0]) == tuple(inst.test_start) and len(result.cells) == inst.test_horizon + 1
    finally:
        designer.stop()


def test_cancel_while_inferring_ends_the_goal_before_rob_drives(ird: Any) -> None:
    from ird_ros.client import NavigationStatus

    feedback: list[Any] = []
    handle = ird.navigate_async(_goal(seed=16, label="nav_test_cancelled"), on_feedback=feedback.append)
    ird.spin_until(lambda: bool(feedback) or handle.done(), timeout=120, what="the goal's first feedback")
    assert feedback[0].stage == "inferring"
    handle.cancel()
    result = handle.result(timeout=60)
    assert result.status is NavigationStatus.CANCELED, result.message
    assert result.cells.shape == (0, 2) and result.touched_lava is None
    assert "driving" not in {f.stage for f in feedback}
