"""Samples in units of their training spread (ird_core.planning.sample_scale): each spans one unit
over the training maps, the per-step min becomes invariant to rescaling any one sample
(Proposition 1, per sample), an ordinary step costs at most one unit more than another training
cell, and the planner's DP is the brute-force optimum of the scaled objective."""

from __future__ import annotations

import re

import numpy as np
import pytest

from ird_core import planning
from ird_core.mdp import GridMDP
from ird_core.mdp.enumeration import all_trajectories
from ird_core.planning.sample_scale import MAX_SCALED_WEIGHT, RELATIVE_FLOOR, normalise_samples, training_spread, worst_step_by_terrain


def tiny(seed: int) -> tuple[np.ndarray, GridMDP, np.ndarray]:
    """A training map, a test map (the training cells plus one novel feature vector) and samples."""
    rng = np.random.default_rng(seed)
    h, w, d = int(rng.integers(2, 4)), int(rng.integers(2, 4)), int(rng.integers(2, 4))
    train = rng.normal(size=(h, w, d))
    test = train[rng.integers(h, size=h)][:, rng.integers(w, size=w)].copy()
    test[rng.integers(h), rng.integers(w)] = 3.0 * rng.normal(size=d)  # never seen in training
    mdp = GridMDP(test, (int(rng.integers(h)), int(rng.integers(w))), int(rng.integers(1, 4)))
    return train, mdp, rng.normal(size=(int(rng.integers(2, 6)), d))


@pytest.mark.parametrize("seed", range(20))
def test_every_scaled_sample_spans_one_unit_over_the_training_map(seed: int) -> None:
    train, _, weights = tiny(seed)
    scaled = normalise_samples(weights * 10.0 ** np.random.default_rng(seed).uniform(-2, 2, size=(len(weights), 1)),
                               train)
    np.testing.assert_allclose(training_spread(scaled, train), 1.0, rtol=1e-12)


@pytest.mark.parametrize("seed", range(20))
def test_rescaling_one_sample_changes_no_scaled_plan(seed: int) -> None:
    train, mdp, weights = tiny(seed)
    factors = 10.0 ** np.random.default_rng(seed + 100).uniform(-2, 2, size=(len(weights), 1))
    for mode in ("per_step", "trajectory"):
        a = planning.plan_path(mdp, normalise_samples(weights, train), mode, "initial_state")
        b = planning.plan_path(mdp, normalise_samples(factors * weights, train), mode, "initial_state")
        assert a.cells == b.cells
        assert a.objective == pytest.approx(b.objective, rel=1e-9, abs=1e-12)


def test_unscaled_plans_do_depend_on_one_samples_size() -> None:
    """The defect the scaling removes: a large sample's min dominates every cell."""
    train = np.array([[[1.0, 0.0], [0.0, 1.0]]])  # two terrains, A and B
    mdp = GridMDP(train, (0, 0), 2)
    weights = np.array([[1.0, -1.0], [-1.0, 1.0]])  # they disagree on which is better
    changed = []
    for factor in (0.5, 100.0):  # the second sample small: stay on A; large: its -factor on A drives Rob to B
        w = weights * np.array([[1.0], [factor]])
        changed.append((planning.plan_path(mdp, w, "per_step").cells,
                        planning.plan_path(mdp, normalise_samples(w, train), "per_step").cells))
    assert changed[0][1] == changed[1][1]
    assert changed[0][0] != changed[1][0]


@pytest.mark.parametrize("seed", range(20))
def test_a_training_step_costs_at_most_one_unit_more_than_another(seed: int) -> None:
    train, _, weights = tiny(seed)
    big = weights * 10.0 ** np.random.default_rng(seed).uniform(-2, 2, size=(len(weights), 1))
    mdp = GridMDP(train, (0, 0), 1)
    rewards = planning.per_step_reward(mdp, normalise_samples(big, train), "none")
    assert rewards.max() - rewards.min() <= 1.0 + 1e-12


@pytest.mark.parametrize("seed", range(20))
def test_the_scaled_per_step_plan_is_the_brute_force_optimum(seed: int) -> None:
    train, mdp, weights = tiny(seed)
    scaled = normalise_samples(weights, train)
    plan = planning.plan_path(mdp, scaled, "per_step", "initial_state")
    per_cell = planning.sample_cell_rewards(mdp, scaled, "initial_state").min(axis=0).ravel()
    best = per_cell[all_trajectories(mdp)].sum(axis=1).max()
    assert plan.objective == pytest.approx(best, rel=1e-12, abs=1e-12)


def test_a_sample_with_no_spread_is_divided_by_its_floor_and_a_zero_sample_is_unchanged() -> None:
    train = np.array([[[1.0, 0.0], [0.0, 1.0]]])  # feature norms 1
    weights = np.array([[2.0, 0.0], [1.0, 1.0], [0.0, 0.0]])  # the second values both terrains alike
    scaled = normalise_samples(weights, train)
    np.testing.assert_allclose(scaled[0], weights[0] / 2.0)
    np.testing.assert_allclose(scaled[1], weights[1] / (RELATIVE_FLOOR * np.sqrt(2.0)))
    np.testing.assert_array_equal(scaled[2], 0.0)


def test_several_training_maps_share_one_unit() -> None:
    a, b = np.array([[[1.0, 0.0]]]), np.array([[[0.0, 1.0]]])
    np.testing.assert_allclose(training_spread(np.array([[3.0, -1.0]]), [a, b]), [4.0])


@pytest.mark.parametrize("bad, field", [
    (np.zeros((2, 2)), "training_features[0]"),
    (np.full((2, 2, 3), np.nan), "training_features[0]"),
    ([], "training_features"),
])
def test_bad_training_maps_are_refused_naming_the_field(bad, field: str) -> None:
    with pytest.raises(ValueError, match="^" + re.escape(field)):
        normalise_samples(np.ones((2, 3)), bad)


def test_bad_weights_are_refused_naming_the_field() -> None:
    with pytest.raises(ValueError, match="^weights"):
        normalise_samples(np.ones(3), np.ones((1, 1, 3)))
    with pytest.raises(ValueError, match="^weights"):
        normalise_samples(np.array([[np.nan, 1.0, 1.0]]), np.ones((1, 1, 3)))


def test_worst_step_by_terrain_names_each_terrains_minimum() -> None:
    rewards = np.array([[0.0, -1.0], [-5.0, 2.0]])
    labels = np.array([[0, 0], [2, 0]])
    assert worst_step_by_terrain(rewards, labels, ["dirt", "grass", "lava"]) == {"dirt": -1.0, "lava": -5.0}
    with pytest.raises(ValueError, match="^labels"):
        worst_step_by_terrain(rewards, labels[:1], ["dirt"])


@pytest.mark.parametrize("seed", range(10))
def test_scaled_weights_stay_plannable_whatever_the_features_size(seed: int) -> None:
    rng = np.random.default_rng(seed)
    train = 1e-4 * rng.normal(size=(2, 2, 3))  # tiny features: the first floor alone would allow huge weights
    weights = np.concatenate([rng.normal(size=(3, 3)), [[1.0, 1.0, 1.0]]])
    train[..., :] = train[..., :1]  # every feature equal per cell: the last sample has no spread
    scaled = normalise_samples(weights, train)
    assert np.abs(scaled).max() <= MAX_SCALED_WEIGHT * (1 + 1e-12)
    planning.plan_path(GridMDP(train, (0, 0), 2), scaled, "per_step")


@pytest.mark.parametrize("seed", range(12))
def test_robs_plan_among_the_query_candidates_is_the_planners_scaled_plan(seed: int) -> None:
    """``PlanSettings(scale_features=...)``: the candidates' "plan" path (the one the questions
    are about) is the planner's per-step plan on the rescaled samples, whatever one sample's size;
    without it, Rob's plan is the unscaled one."""
    from ird_core.designer.candidates import PlanSettings, query_candidates

    train, mdp, weights = tiny(seed)
    factors = 10.0 ** np.random.default_rng(seed + 200).uniform(-2, 2, size=(len(weights), 1))
    for w in (weights, factors * weights):
        rob = query_candidates(mdp, w, PlanSettings(scale_features=train), alternatives=0)
        planner = planning.plan_path(mdp, normalise_samples(w, train), "per_step")
        assert [tuple(c) for c in rob.cells[list(rob.sources).index("plan")].tolist()] == [tuple(c) for c in planner.cells]
        plain = query_candidates(mdp, w, PlanSettings(), alternatives=0)
        assert [tuple(c) for c in plain.cells[0].tolist()] == [tuple(c) for c in planning.plan_path(mdp, w, "per_step").cells]
