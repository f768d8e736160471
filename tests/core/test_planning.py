"""Planners, baselines and the risk map against brute-force enumeration of every trajectory.

The references here never call the code under test: baselines are recomputed from their
definitions (``log_z`` from ``brute_log_partition``) and every optimum is a maximum over
``all_trajectories``.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ird_core import planning as P
from ird_core.mdp import GridMDP, successor_table, validate_path
from ird_core.mdp.enumeration import all_trajectories, brute_log_partition, trajectory_features
from ird_core.planning import trajectory_milp
from ird_core.planning import trajectory_solver as TS

SHAPES = [(1, 1), (1, 2), (2, 1), (1, 3), (3, 1), (2, 2), (2, 3), (3, 2), (3, 3), (2, 4)]
TRAJECTORY_SOLVERS = (None, "label-bb", "milp-highs")


# --------------------------------------------------------------------------- references


def random_case(seed: int, *, integer: bool | None = None) -> tuple[GridMDP, np.ndarray, np.ndarray]:
    """A tiny random MDP, K = 1..5 weights and a reference feature vector.

    Odd seeds use small-integer features and weights, which make exact ties between different
    paths common (the hard case for tie handling and label merging).
    """
    rng = np.random.default_rng(seed)
    height, width = SHAPES[seed % len(SHAPES)]
    horizon = int(rng.integers(1, 5 if height * width > 6 else 6))
    d, k = int(rng.integers(2, 4)), int(rng.integers(1, 6))
    integer = bool(seed % 2) if integer is None else integer
    if integer:
        features = rng.integers(-2, 3, size=(height, width, d)).astype(float)
        weights = rng.integers(-2, 3, size=(k, d)).astype(float)
    else:
        features = rng.normal(size=(height, width, d))
        weights = rng.normal(size=(k, d))
    start = (int(rng.integers(height)), int(rng.integers(width)))
    return GridMDP(features, start, horizon), weights, rng.normal(size=d)


def reference_baselines(mdp: GridMDP, weights: np.ndarray, baseline: str, reference: np.ndarray) -> np.ndarray:
    """The baselines straight from their definitions (section 4)."""
    if baseline == "none":
        return np.zeros(len(weights))
    if baseline == "initial_state":
        return weights @ mdp.features[mdp.start]
    if baseline == "training_features":
        return weights @ reference
    return brute_log_partition(mdp, weights) / (mdp.horizon + 1)


def brute_values(mdp: GridMDP, weights: np.ndarray, mode: str, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every trajectory (state indices) and its objective under ``mode``; ``(N, T+1)``, ``(N,)``."""
    trajectories = all_trajectories(mdp)
    if mode == "per_step":
        flat = mdp.features.reshape(mdp.num_states, -1)
        cell = (flat @ weights.T - b).min(axis=1)  # (S,)
        return trajectories, cell[trajectories].sum(axis=1)
    phi = trajectory_features(mdp, trajectories)
    return trajectories, (phi @ weights.T - (mdp.horizon + 1) * b).min(axis=1)


def value_of(mdp: GridMDP, weights: np.ndarray, mode: str, b: np.ndarray, cells) -> float:
    """A path's objective, computed like ``brute_values`` (independent of the module)."""
    path = validate_path(mdp, cells)
    visited = mdp.features[path[:, 0], path[:, 1]]
    if mode == "per_step":
        return float((visited @ weights.T - b).min(axis=1).sum())
    return float((weights @ visited.sum(axis=0) - (mdp.horizon + 1) * b).min())


def close(a: float, b: float, tol: float = 1e-9) -> bool:
    return abs(a - b) <= tol * max(1.0, abs(b))


def check_optimal(mdp, weights, mode, baseline, reference, plan: P.Plan) -> None:
    """``plan`` is a legal path achieving the brute-force optimum, and reports it."""
    b = reference_baselines(mdp, weights, baseline, reference)
    _, values = brute_values(mdp, weights, mode, b)
    optimum = float(values.max())
    assert len(plan.cells) == mdp.horizon + 1 and plan.cells[0] == mdp.start
    achieved = value_of(mdp, weights, mode, b, plan.cells)
    assert close(plan.objective, optimum), (plan, optimum)
    assert close(achieved, optimum), (plan, achieved, optimum)
    assert plan.bound >= plan.objective
    assert (plan.mode, plan.baseline) == (mode, baseline)


# --------------------------------------------------------------------------- brute force


@pytest.mark.parametrize("seed", range(48))
def test_every_mode_and_baseline_matches_brute_force(seed: int) -> None:
    mdp, weights, reference = random_case(seed)
    for baseline in P.BASELINES:
        for mode in ("literal", "per_step"):
            for row in ((weights[:1],) if mode == "literal" else (weights,)):
                plan = P.plan_path(mdp, row, mode, baseline, reference)
                assert plan.solver == "dp"
                check_optimal(mdp, row, mode, baseline, reference, plan)
        for solver in TRAJECTORY_SOLVERS:
            plan = P.plan_path(mdp, weights, "trajectory", baseline, reference, solver=solver)
            assert plan.solver in P.SOLVERS["trajectory"]
            if solver is not None:
                assert plan.solver == solver
            check_optimal(mdp, weights, "trajectory", baseline, reference, plan)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), integer=st.booleans(), duplicates=st.integers(0, 3))
def test_property_trajectory_matches_brute_force(seed: int, integer: bool, duplicates: int) -> None:
    mdp, weights, reference = random_case(seed, integer=integer)
    weights = np.concatenate([weights, *[weights[:1]] * duplicates])  # repeated samples change nothing
    for solver in TRAJECTORY_SOLVERS:
        plan = P.plan_path(mdp, weights, "trajectory", "training_features", reference, solver=solver)
        check_optimal(mdp, weights, "trajectory", "training_features", reference, plan)


def test_milp_is_exact_where_highs_presolve_was_wrong() -> None:
    """A hypothesis example (seed 135, integer) on which HiGHS 1.12 with presolve returned a
    1.40 path as optimal; the optimum, by brute force, is 3.22."""
    mdp, weights, reference = random_case(135, integer=True)
    plan = P.plan_path(mdp, weights, "trajectory", "training_features", reference, solver="milp-highs")
    check_optimal(mdp, weights, "trajectory", "training_features", reference, plan)


@pytest.mark.parametrize("seed", range(12))
def test_dominated_samples_are_dropped_without_changing_the_plan(seed: int) -> None:
    # A constant feature lets a sample's reward drop by 1 on every cell: the lowered copy
    # dominates (is below) the original, which can then never be the minimum.
    mdp, weights, _ = random_case(seed, integer=False)
    features = np.concatenate([mdp.features, np.ones(mdp.features.shape[:2] + (1,))], axis=2)
    mdp = mdp.with_features(features)
    weights = np.concatenate([weights, np.zeros((len(weights), 1))], axis=1)
    lowered = weights[:1] - np.eye(1, weights.shape[1], weights.shape[1] - 1)
    both = np.concatenate([weights, lowered])
    q = (features.reshape(mdp.num_states, -1) @ both.T).T
    kept = TS._reduce_samples(q)
    assert 0 not in kept and len(both) - 1 in kept
    for solver in TRAJECTORY_SOLVERS:
        plan = P.plan_path(mdp, both, "trajectory", solver=solver)
        check_optimal(mdp, both, "trajectory", "none", None, plan)
        assert close(plan.objective, P.plan_path(mdp, both[1:], "trajectory", solver=solver).objective)


@pytest.mark.parametrize("seed", range(24))
def test_milp_on_the_reachable_graph_matches_brute_force(seed: int) -> None:
    # The MILP formulation itself, on the graph pruned by reachability only (plan_path also
    # prunes it by bounds, which on tiny grids can leave little for HiGHS to do).
    mdp, weights, reference = random_case(seed)
    b = reference_baselines(mdp, weights, "initial_state", reference)
    q = (mdp.features.reshape(mdp.num_states, -1) @ weights.T - b).T  # (K, S)
    reachable = TS._start_distance(mdp)[None, :] <= np.arange(mdp.horizon + 1)[:, None]
    model = trajectory_milp.build_trajectory_milp(mdp, q, reachable)
    assert model.num_edges == sum(  # every reachable (t, s) keeps all its in-grid moves
        int((successor_table(mdp.height, mdp.width)[s] >= 0).sum())
        for t in range(mdp.horizon) for s in np.flatnonzero(reachable[t]))
    cells, bound = trajectory_milp.solve_trajectory_milp(mdp, model, np.inf)
    _, values = brute_values(mdp, weights, "trajectory", b)
    assert close(value_of(mdp, weights, "trajectory", b, cells), float(values.max()))
    assert bound >= float(values.max()) - 1e-6


@pytest.mark.parametrize("seed", range(24))
def test_exhaustive_label_search_matches_brute_force(seed: int) -> None:
    # No incumbent to prune with: only the bounds, dominance and merging act, and must keep
    # the optimum.
    mdp, weights, _ = random_case(seed)
    q = (mdp.features.reshape(mdp.num_states, -1) @ weights.T).T
    multipliers = np.full((1, len(q)), 1.0 / len(q))
    states = TS._label_search(mdp, q, multipliers, -np.inf, 0.0)
    _, values = brute_values(mdp, weights, "trajectory", np.zeros(len(q)))
    assert close(float(q[:, states].sum(axis=1).min()), float(values.max()))


# --------------------------------------------------------------------------- behaviour


def test_per_step_initial_state_stays_when_every_move_is_worse_for_some_sample() -> None:
    # Sample 1 values feature 0, sample 2 feature 1. The start is great for sample 2; every
    # other cell gains a little for sample 1 but loses a lot for sample 2, so relative to the
    # start every move is worse under some sample. Without a baseline the per-cell minimum
    # (1 vs 0) lures Rob away.
    features = np.tile([1.0, 1.0], (3, 3, 1))
    features[1, 1] = [0.0, 10.0]
    mdp = GridMDP(features, (1, 1), 4)
    weights = np.eye(2)
    plan = P.plan_path(mdp, weights, "per_step", "initial_state")
    assert plan.cells == ((1, 1),) * 5
    assert plan.objective == 0.0
    assert P.plan_path(mdp, weights, "per_step", "none").cells[1] != (1, 1)
    trajectory = P.plan_path(mdp, weights, "trajectory", "initial_state")
    assert trajectory.cells == ((1, 1),) * 5 and trajectory.objective == 0.0


@pytest.mark.parametrize("seed", range(16))
def test_literal_equals_per_step_and_trajectory_with_one_sample(seed: int) -> None:
    mdp, weights, reference = random_case(seed)
    w = weights[:1]
    for baseline in P.BASELINES:
        plans = {mode: P.plan_path(mdp, w, mode, baseline, reference) for mode in P.MODES}
        for mode, plan in plans.items():
            assert close(plan.objective, plans["literal"].objective)
            for other in P.MODES:  # each path achieves the common optimum under every mode
                assert close(P.path_objective(mdp, plan.cells, w, other, baseline, reference),
                             plans["literal"].objective)


def dyadic_case(seed: int) -> tuple[GridMDP, np.ndarray, np.ndarray, np.ndarray]:
    """Features, weights and a shift in multiples of 1/8: every sum is exact in float64, so a
    shift changes values by exactly the same constant and ties break identically."""
    rng = np.random.default_rng(seed)
    height, width = SHAPES[seed % len(SHAPES)]
    d, k = 3, int(rng.integers(2, 5))
    features = rng.integers(-16, 17, size=(height, width, d)) / 8.0
    weights = rng.integers(-16, 17, size=(k, d)) / 8.0
    shift = rng.integers(-16, 17, size=d) / 8.0
    start = (int(rng.integers(height)), int(rng.integers(width)))
    return GridMDP(features, start, int(rng.integers(1, 5))), weights, shift, rng.integers(-8, 9, size=d) / 8.0


@pytest.mark.parametrize("seed", range(20))
def test_literal_path_is_invariant_to_a_feature_shift(seed: int) -> None:
    mdp, weights, shift, reference = dyadic_case(seed)
    shifted = mdp.with_features(mdp.features + shift)
    w = weights[:1]
    for baseline in P.BASELINES:
        # The training map shifts too, so its per-state average moves by the same vector.
        before = P.plan_path(mdp, w, "literal", baseline, reference)
        after = P.plan_path(shifted, w, "literal", baseline, reference + shift)
        assert after.cells == before.cells
        expected = before.objective + (mdp.horizon + 1) * float(w[0] @ shift) * (baseline == "none")
        assert close(after.objective, expected)


@pytest.mark.parametrize("seed", range(20))
def test_baselines_that_move_with_the_shift_make_risk_averse_plans_invariant(seed: int) -> None:
    # q_i = w_i . (F + c) - b_i' equals w_i . F - b_i whenever b_i' = b_i + w_i . c: true for
    # initial_state (F[s_0] + c), for log_z (every return moves by (T+1) w_i . c) and for
    # training_features with the equally shifted training average.
    mdp, weights, shift, reference = dyadic_case(seed)
    shifted = mdp.with_features(mdp.features + shift)
    for baseline in ("initial_state", "training_features", "log_z"):
        b = reference_baselines(mdp, weights, baseline, reference)
        b_shifted = reference_baselines(shifted, weights, baseline, reference + shift)
        assert np.allclose(b_shifted, b + weights @ shift, rtol=1e-12, atol=1e-12)
        for mode in ("per_step", "trajectory"):
            before = P.plan_path(mdp, weights, mode, baseline, reference)
            after = P.plan_path(shifted, weights, mode, baseline, reference + shift)
            assert close(after.objective, before.objective)
            # The shifted plan is optimal for the unshifted problem as well.
            assert close(value_of(mdp, weights, mode, b, after.cells), before.objective)
            if baseline != "log_z":  # exact arithmetic: identical rewards, identical plan
                assert after.cells == before.cells


def test_no_baseline_is_not_shift_invariant_for_several_samples() -> None:
    # Start (0, 0) with features (0, 0); the other cell (1, -0.5). Samples value one feature
    # each. Per-cell minimum: start 0, other -0.5, so Rob stays. Shift by (0, 1): start
    # (0, 1) -> min 0, other (1, 0.5) -> min 0.5, so Rob moves.
    features = np.array([[[0.0, 0.0], [1.0, -0.5]]])
    mdp = GridMDP(features, (0, 0), 2)
    shifted = mdp.with_features(features + np.array([0.0, 1.0]))
    for mode in ("per_step", "trajectory"):
        assert P.plan_path(mdp, np.eye(2), mode, "none").cells == ((0, 0),) * 3
        assert P.plan_path(shifted, np.eye(2), mode, "none").cells != ((0, 0),) * 3


@pytest.mark.parametrize("seed", range(24))
def test_min_of_sums_dominates_sum_of_mins(seed: int) -> None:
    mdp, weights, reference = random_case(seed)
    for baseline in P.BASELINES:
        per_step = P.plan_path(mdp, weights, "per_step", baseline, reference)
        trajectory = P.plan_path(mdp, weights, "trajectory", baseline, reference)
        for cells in (per_step.cells, trajectory.cells):  # on every path
            assert (P.path_objective(mdp, cells, weights, "trajectory", baseline, reference)
                    >= P.path_objective(mdp, cells, weights, "per_step", baseline, reference) - 1e-9)
        assert trajectory.objective >= P.path_objective(
            mdp, per_step.cells, weights, "trajectory", baseline, reference) - 1e-9
        assert per_step.objective >= P.path_objective(
            mdp, trajectory.cells, weights, "per_step", baseline, reference) - 1e-9


@pytest.mark.parametrize("seed", range(8))
def test_reward_baselines_match_their_definitions(seed: int) -> None:
    mdp, weights, reference = random_case(seed)
    for baseline in P.BASELINES:
        got = P.reward_baselines(mdp, weights, baseline, reference)
        assert got.shape == (len(weights),)
        assert np.allclose(got, reference_baselines(mdp, weights, baseline, reference), rtol=1e-9, atol=1e-12)


def test_plan_is_frozen_and_typed() -> None:
    mdp, weights, _ = random_case(8)
    plan = P.plan_path(mdp, weights, "trajectory")
    with pytest.raises(dataclasses.FrozenInstanceError):
        plan.objective = 0.0  # type: ignore[misc]
    assert all(type(v) is int for cell in plan.cells for v in cell)
    assert type(plan.objective) is float


def hard_case() -> tuple[GridMDP, np.ndarray]:
    """15x15, T = 30, 50 widely spread samples: proving optimality takes minutes."""
    rng = np.random.default_rng(0)
    features = rng.normal(size=(15, 15, 50))
    weights = rng.normal(size=50) / np.sqrt(50) + rng.normal(size=(50, 50)) / np.sqrt(50)
    return GridMDP(features, (7, 7), 30), weights


@pytest.mark.parametrize("solver", TRAJECTORY_SOLVERS)
def test_time_limit_raises_with_the_best_plan_so_far(solver) -> None:
    mdp, weights = hard_case()
    with pytest.raises(P.PlanningTimeout) as info:
        P.plan_path(mdp, weights, "trajectory", solver=solver, time_limit=0.5)
    plan = info.value.plan
    validate_path(mdp, plan.cells)
    assert plan.objective == P.path_objective(mdp, plan.cells, weights, "trajectory")
    assert plan.bound > plan.objective  # a genuine, reported gap
    assert "time_limit" in str(info.value)


# --------------------------------------------------------------------------- risk map


def test_risk_map_is_zero_when_samples_agree() -> None:
    rng = np.random.default_rng(0)
    features = rng.normal(size=(4, 5, 3))
    w = rng.normal(size=(1, 3))
    for weights in (w, np.repeat(w, 7, axis=0)):
        for statistic in P.STATISTICS:
            cost = P.risk_map(features, weights, statistic)
            assert cost.dtype == np.int8 and cost.shape == (4, 5)
            assert np.all(cost == 0)
            assert np.all(P.reward_spread(features, weights, statistic) == 0.0)


def test_risk_map_is_monotone_in_disagreement() -> None:
    # Feature 1 is the uncertain one: the samples disagree about it, agree about feature 0.
    features = np.zeros((1, 4, 2))
    features[0, :, 0] = [5.0, 5.0, 5.0, 5.0]
    features[0, :, 1] = [0.0, 0.5, 1.0, 2.0]
    weights = np.array([[1.0, -1.0], [1.0, 0.0], [1.0, 2.0]])
    for statistic in P.STATISTICS:
        cost = P.risk_map(features, weights, statistic)[0]
        assert cost[0] == 0 and cost[-1] == 100
        assert np.all(np.diff(cost.astype(int)) > 0)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), statistic=st.sampled_from(P.STATISTICS))
def test_property_risk_map_orders_cells_by_spread(seed: int, statistic: str) -> None:
    rng = np.random.default_rng(seed)
    features = rng.normal(size=(int(rng.integers(1, 6)), int(rng.integers(1, 6)), 3))
    weights = rng.normal(size=(int(rng.integers(1, 8)), 3))
    spread = P.reward_spread(features, weights, statistic)
    rewards = np.einsum("hwd,kd->khw", features, weights)
    expected = rewards.std(axis=0) if statistic == "std" else rewards.max(axis=0) - rewards.min(axis=0)
    assert np.allclose(spread, expected, atol=1e-12 * max(1.0, float(np.abs(rewards).max())))
    cost = P.risk_map(features, weights, statistic)
    assert cost.dtype == np.int8 and cost.min() >= 0 and cost.max() <= 100
    order = np.argsort(spread, axis=None)
    assert np.all(np.diff(cost.ravel()[order].astype(int)) >= 0)  # more spread never costs less
    # A fixed reference scales linearly and saturates at 100.
    reference = float(np.median(spread)) or 1.0
    fixed = P.risk_map(features, weights, statistic, reference=reference)
    assert np.all(fixed[spread >= reference] == 100)
    assert np.array_equal(fixed, np.clip(np.ceil(100 * spread / reference), 0, 100).astype(np.int8))


# --------------------------------------------------------------------------- bad inputs


def test_bad_inputs_name_the_argument() -> None:
    mdp, weights, reference = random_case(4)
    d = mdp.num_features
    cases = [
        (lambda: P.plan_path(mdp, weights, "greedy"), "mode"),
        (lambda: P.plan_path(mdp, weights, "per_step", "mean"), "baseline"),
        (lambda: P.plan_path(mdp, np.ones((2, d)), "literal"), "weights"),
        (lambda: P.plan_path(mdp, np.ones(d), "per_step"), "weights"),
        (lambda: P.plan_path(mdp, np.ones((2, d + 1)), "per_step"), "weights"),
        (lambda: P.plan_path(mdp, np.full((2, d), np.nan), "trajectory"), "weights"),
        (lambda: P.plan_path(mdp, np.full((1, d), np.inf), "literal"), "weights"),
        (lambda: P.plan_path(mdp, np.ones((0, d)), "per_step"), "weights"),
        (lambda: P.plan_path(mdp, weights, "per_step", "training_features"), "reference_features"),
        (lambda: P.plan_path(mdp, weights, "per_step", "training_features", np.ones(d + 1)), "reference_features"),
        (lambda: P.plan_path(mdp, weights, "trajectory", "training_features", np.full(d, np.nan)),
         "reference_features"),
        (lambda: P.plan_path(mdp, weights, "per_step", solver="milp-highs"), "solver"),
        (lambda: P.plan_path(mdp, weights, "trajectory", solver="gurobi"), "solver"),
        (lambda: P.plan_path(mdp, weights, "trajectory", time_limit=0), "time_limit"),
        (lambda: P.plan_path(mdp, weights, "trajectory", time_limit=True), "time_limit"),
        (lambda: P.reward_baselines(mdp, weights, "average"), "baseline"),
        (lambda: P.path_objective(mdp, [(0, 0)], weights, "per_step"), "cells"),
        (lambda: P.path_objective(mdp, mdp.start, weights, "sum"), "mode"),
        (lambda: P.risk_map(np.ones((2, 2)), weights), "features"),
        (lambda: P.risk_map(np.full((2, 2, d), np.nan), weights), "features"),
        (lambda: P.risk_map(np.ones((2, 2, d)), np.ones((2, d + 1))), "weights"),
        (lambda: P.risk_map(np.ones((2, 2, d)), weights, "variance"), "statistic"),
        (lambda: P.risk_map(np.ones((2, 2, d)), weights, reference=-1.0), "reference"),
    ]
    for call, name in cases:
        with pytest.raises(ValueError, match=rf"^{name}:"):
            call()
