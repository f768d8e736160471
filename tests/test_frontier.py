"""The risk frontier and the controls of a Lavaland trial (ird_core.experiments.controls,
frontier_report): which rows a trial adds, that each row is the plan its name promises, and the
goal check's verdicts (tiny maps, few samples)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from ird_core import experiments as ex
from ird_core import planning, posterior
from ird_core.experiments import frontier_report
from ird_core.experiments.controls import FRONTIER_RISKS
from ird_core.experiments.report import RunRecord
from ird_core.experiments.summaries import aggregate
from ird_core.experiments.trials import trial_instance, trial_posterior
from ird_core.planning.novelty import novel_cells, novelty_avoiding_path
from ird_core.worlds import lavaland

TINY = dict(size=5, horizon=5, obs_dim=4, num_samples=16, num_chains=2, warmup=10, thin=1, max_leapfrog=4,
            num_proxy_samples=20, factorial_samples=16, traj_work_limit=2_000_000, sample_z_sampler=None,
            maxent_z_sampler=None, factorial=False)


@pytest.fixture(scope="module")
def trial() -> tuple[ex.TrialSpec, list[ex.TrialResult]]:
    spec = ex.TrialSpec("latent_raw", 2, frontier=True, controls=True, **TINY)
    return spec, ex.run_trial(spec)


def test_a_trial_with_frontier_and_controls_has_every_row_once(trial) -> None:
    spec, rows = trial
    names = [r.planner for r in rows]
    assert len(names) == len(set(names))
    labels = [risk.label() for risk in FRONTIER_RISKS]
    for post in ("sample_z", "maxent_z", "prior", "sample_z_optimal"):
        assert [n for n in names if n.startswith(post + "/")] == [f"{post}/{label}" for label in labels]
    for control in ("prior_only", "novelty", "sample_z_optimal", "sample_z_no_own"):
        assert names.count(control) == 1
    assert {r.experiment for r in rows} == {"main", "frontier", "controls"}


def test_frontier_rows_are_the_plans_their_names_promise(trial) -> None:
    spec, rows = trial
    by = {r.planner: r for r in rows}
    inst = trial_instance(spec)
    post = trial_posterior(spec, inst, "maxent_z")  # a trial is a pure function of its spec
    reference = posterior.proxy_feature_expectations(inst, spec.observation_model()) / (inst.train_horizon + 1)
    test = lavaland.test_mdp(inst)
    mean = planning.plan_path(test, post.samples.mean(axis=0)[None], "per_step", "training_features", reference)
    assert by["maxent_z/cvar1"].cells == mean.cells  # CVaR at 1 = the posterior mean reward (linear in w)
    assert by["maxent_z/min"].cells == by["ird_maxent_z"].cells  # the main planner is the min
    low = planning.plan_path(test, post.samples, "per_step", "training_features", reference, risk="cvar",
                             risk_level=1 / len(post.samples))
    assert by["maxent_z/min"].cells == low.cells


def test_the_novelty_control_is_the_literal_proxy_off_novel_cells(trial) -> None:
    spec, rows = trial
    inst = trial_instance(spec)
    novel = novel_cells([inst.train_features], inst.test_features)
    cells = novelty_avoiding_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights, novel)
    assert {r.planner: r for r in rows}["novelty"].cells == tuple(cells)
    assert not novel_cells([inst.train_features], inst.train_features).any()


def test_the_other_readings_posterior_differs_and_no_own_term_changes_the_posterior() -> None:
    spec = ex.TrialSpec("side_effects", 0, **TINY)
    inst = trial_instance(spec)
    a = trial_posterior(spec, inst, "sample_z", posterior.ObservationModel("maxent"))
    b = trial_posterior(spec, inst, "sample_z", posterior.ObservationModel("optimal"))
    c = trial_posterior(spec, inst, "sample_z", posterior.ObservationModel("optimal", own_term=False))
    assert not np.array_equal(a.samples, b.samples) and not np.array_equal(b.samples, c.samples)


def _summary(planner: str, lava: float, target: float, gap: float, experiment: str = "main"):
    rows = []
    for seed in range(10):
        ret = {"literal": 0.0, "oracle": 10.0}.get(planner, 10.0 * gap)
        rows.append(ex.TrialResult(experiment, "c", seed, planner, "" if planner in ("literal", "oracle") else "x",
                                   "per_step", "none", seed < 10 * lava, seed < 10 * target, ret, 0.0, "dp", False,
                                   0.0, math.nan, math.nan, ((0, 0),)))
    return rows


def test_the_goal_check_passes_only_when_every_bar_is_met() -> None:
    base = _summary("literal", 0.5, 1.0, math.nan) + _summary("oracle", 0.0, 1.0, math.nan)
    ok = aggregate(base + _summary("ird_a", 0.0, 0.8, 0.95))
    assert frontier_report.goal_check(ok)[0].endswith("PASS")
    for lava, target, gap, word in ((0.1, 0.9, 0.95, "lava"), (0.0, 0.7, 0.95, "target"), (0.0, 0.9, 0.5, "gap")):
        line = frontier_report.goal_check(aggregate(base + _summary("ird_a", lava, target, gap)))[0]
        assert "MISS" in line and word in line.split("MISS")[1]


def test_frontier_report_writes_the_table_and_a_picture_per_condition(trial, tmp_path) -> None:
    _, rows = trial
    run = RunRecord("test", 0.0, {}, "git 0123456789ab")
    paths = frontier_report.write_frontier(tmp_path, aggregate(rows), run)
    assert [p.name for p in paths] == ["frontier.md", "frontier_latent_raw.png"]
    text = (tmp_path / "frontier.md").read_text()
    assert "| latent_raw | maxent_z/cvar0.25 |" in text and "Goal check" in text
    assert "Code: git 0123456789ab\n" in text
