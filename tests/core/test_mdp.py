"""The grid MDP engine against brute-force enumeration of every trajectory."""

from __future__ import annotations

import sys
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ird_core import mdp as M
from ird_core.mdp import linear_passes, passes
from ird_core.mdp.enumeration import (
    all_trajectories,
    brute_feature_expectations,
    brute_log_partition,
    brute_visitation,
    trajectory_features,
)

SHAPES = [(1, 1), (1, 3), (3, 1), (2, 2), (2, 4), (3, 3), (4, 2)]


def random_mdp(rng: np.random.Generator, height: int, width: int, d: int, horizon: int) -> M.GridMDP:
    features = rng.normal(size=(height, width, d))
    start = (int(rng.integers(height)), int(rng.integers(width)))
    return M.GridMDP(features, start, horizon)


def rel_close(a: np.ndarray, b: np.ndarray, rtol: float = 1e-9) -> bool:
    return bool(np.all(np.abs(a - b) <= rtol * np.maximum(1.0, np.abs(b))))


@pytest.mark.parametrize("seed", range(12))
def test_log_partition_and_expectations_match_enumeration(seed: int) -> None:
    rng = np.random.default_rng(seed)
    height, width = SHAPES[seed % len(SHAPES)]
    horizon = 1 + seed % 5
    mdp = random_mdp(rng, height, width, d=3, horizon=horizon)
    # Includes weights so large that exp(w . phi) overflows float64 in a naive implementation.
    weights = np.concatenate([rng.normal(size=(4, 3)), 300.0 * rng.normal(size=(2, 3)),
                              np.zeros((1, 3))])
    assert rel_close(M.log_partition(mdp, weights), brute_log_partition(mdp, weights))
    assert rel_close(M.feature_expectations(mdp, weights), brute_feature_expectations(mdp, weights))
    assert rel_close(M.expected_visitation(mdp, weights), brute_visitation(mdp, weights))
    log_z, phi = M.log_partition_and_feature_expectations(mdp, weights)
    assert rel_close(log_z, brute_log_partition(mdp, weights))
    assert rel_close(phi, brute_feature_expectations(mdp, weights))


@settings(max_examples=60, deadline=None)
@given(height=st.integers(1, 3), width=st.integers(1, 4), horizon=st.integers(1, 4),
       scale=st.sampled_from([0.1, 1.0, 30.0, 1e3]), seed=st.integers(0, 2**31 - 1))
def test_property_matches_enumeration(height: int, width: int, horizon: int, scale: float, seed: int) -> None:
    rng = np.random.default_rng(seed)
    mdp = random_mdp(rng, height, width, d=2, horizon=horizon)
    weights = scale * rng.normal(size=(3, 2))
    assert rel_close(M.log_partition(mdp, weights), brute_log_partition(mdp, weights))
    assert rel_close(M.feature_expectations(mdp, weights), brute_feature_expectations(mdp, weights), 1e-8)


def test_zero_weights_count_trajectories() -> None:
    # With w = 0 every trajectory has weight 1: log Z is the log of their number.
    mdp = M.GridMDP(np.ones((3, 3, 1)), (1, 1), 3)
    n = len(all_trajectories(mdp))
    assert np.isclose(M.log_partition(mdp, np.zeros((1, 1)))[0], np.log(n))
    # Hand count for the centre of a 3x3 grid after one move: stay + 4 neighbours.
    assert len(all_trajectories(M.GridMDP(np.ones((3, 3, 1)), (1, 1), 1))) == 5
    assert len(all_trajectories(M.GridMDP(np.ones((3, 3, 1)), (0, 0), 1))) == 3


def test_visitation_sums_to_horizon_plus_one() -> None:
    rng = np.random.default_rng(0)
    mdp = random_mdp(rng, 6, 7, d=4, horizon=9)
    visits = M.expected_visitation(mdp, 5 * rng.normal(size=(8, 4)))
    assert np.allclose(visits.sum(axis=(1, 2)), mdp.horizon + 1)
    assert np.all(visits >= 0)


def test_feature_expectations_is_gradient_of_log_partition() -> None:
    rng = np.random.default_rng(1)
    mdp = random_mdp(rng, 5, 4, d=3, horizon=6)
    w = rng.normal(size=(1, 3))
    eps = 1e-6
    numeric = np.array([(M.log_partition(mdp, w + eps * e) - M.log_partition(mdp, w - eps * e))[0] / (2 * eps)
                        for e in np.eye(3)[:, None, :]])
    assert np.allclose(M.feature_expectations(mdp, w)[0], numeric, rtol=1e-6, atol=1e-6)


def test_batch_equals_one_at_a_time() -> None:
    rng = np.random.default_rng(2)
    mdp = random_mdp(rng, 4, 5, d=3, horizon=5)
    weights = rng.normal(size=(6, 3))
    batched = M.feature_expectations(mdp, weights)
    single = np.concatenate([M.feature_expectations(mdp, w[None]) for w in weights])
    assert np.allclose(batched, single, rtol=1e-12, atol=1e-12)


def exact_reference(mdp: M.GridMDP, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """log Z and visits from the log-space passes alone (the fast path's fallback)."""
    log_visits, log_z = passes._log_visitation_exact(mdp, M.cell_rewards(mdp, weights))
    return log_z, np.exp(log_visits)


@pytest.mark.parametrize("height, width, horizon", [(15, 15, 30), (6, 11, 40), (1, 9, 12), (5, 5, 600)])
def test_linear_space_passes_match_log_space_on_large_grids(height: int, width: int, horizon: int) -> None:
    # Grids too large to enumerate: the fast path against the exact log-space passes. The
    # T = 600 case would overflow (5^600) without the rescalings of the backward values.
    rng = np.random.default_rng(height * 100 + horizon)
    mdp = random_mdp(rng, height, width, d=5, horizon=horizon)
    weights = rng.normal(size=(9, 5)) * np.array([0.0, 0.1, 0.3, 1.0, 1.0, 1.0, 1.0, 2.0, 2.0])[:, None]
    suspect = linear_passes.linear_backward(mdp, M.cell_rewards(mdp, weights)).suspect
    assert not suspect.any(), "ordinary rewards must not need the exact fallback"
    log_z, visits = exact_reference(mdp, weights)
    assert rel_close(M.log_partition(mdp, weights), log_z, 1e-12)
    assert np.allclose(M.expected_visitation(mdp, weights), visits, rtol=1e-10, atol=1e-12)


def test_mixed_batch_falls_back_per_element_and_matches_one_at_a_time() -> None:
    # Huge weights (reward spreads of thousands of nats) sit next to ordinary ones in the flat
    # layout: the flagged elements are recomputed exactly and nothing leaks into the others.
    rng = np.random.default_rng(7)
    mdp = random_mdp(rng, 7, 6, d=3, horizon=15)
    weights = rng.normal(size=(8, 3)) * np.array([1.0, 500.0, 1.0, 1.0, 2000.0, 0.0, 1.0, 300.0])[:, None]
    suspect = linear_passes.linear_backward(mdp, M.cell_rewards(mdp, weights)).suspect
    assert suspect[[1, 4]].all() and not suspect[[0, 2, 3, 5, 6]].any()
    log_z, visits = exact_reference(mdp, weights)
    batched_z, batched_phi = M.log_partition_and_feature_expectations(mdp, weights)
    assert rel_close(batched_z, log_z, 1e-12)
    assert np.allclose(M.expected_visitation(mdp, weights), visits, rtol=1e-10, atol=1e-12)
    single = np.concatenate([M.feature_expectations(mdp, w[None]) for w in weights])
    assert np.allclose(batched_phi, single, rtol=1e-12, atol=1e-12)


def test_flagged_elements_of_many_chunks_are_recomputed_together_bit_for_bit(monkeypatch) -> None:
    # The exact fallback runs on the flagged elements of every fast-path chunk at once, in
    # batches bounded by _EXACT_CHUNK_BYTES: however they are split, each flagged element's
    # numbers are those of its exact passes alone, and the others are the fast path's.
    rng = np.random.default_rng(11)
    mdp = random_mdp(rng, 6, 7, d=3, horizon=20)
    # Chunks of two weights (a NaN of a flagged element may leak to its chunk neighbour, so the
    # huge weights are paired): chunks 2 and 4 are flagged, 1, 3 and 5 are not.
    scales = np.array([1.0, 0.3, 400.0, 900.0, 1.0, 0.5, 1500.0, 700.0, 1.0, 2.0])
    weights = rng.normal(size=(len(scales), 3)) * scales[:, None]
    rewards = M.cell_rewards(mdp, weights)
    flagged = [2, 3, 6, 7]
    alone = [passes._log_visitation_exact(mdp, rewards[[i]]) for i in flagged]
    per_weight = 2 * 8 * (mdp.horizon + 1) * (mdp.height + 1) * (mdp.width + 1)
    exact_per_weight = 8 * (mdp.horizon + 1) * mdp.height * mdp.width
    calls: list[int] = []
    original = passes._log_visitation_exact

    def counting(mdp_: M.GridMDP, rewards_: np.ndarray):
        calls.append(len(rewards_))
        return original(mdp_, rewards_)

    monkeypatch.setattr(passes, "_log_visitation_exact", counting)
    monkeypatch.setattr(passes, "_CHUNK_BYTES", 2 * per_weight)
    results = []
    for exact_budget, expected_calls in ((10**9, [4]), (exact_per_weight, [1, 1, 1, 1]), (3 * exact_per_weight, [2, 2])):
        monkeypatch.setattr(passes, "_EXACT_CHUNK_BYTES", exact_budget)
        calls.clear()
        visits, log_z = passes._visitation_and_log_partition(mdp, weights)
        assert calls == expected_calls
        for i, (log_visits, z) in zip(flagged, alone):
            assert log_z[i] == z[0] and np.array_equal(visits[i], np.exp(log_visits[0]))
        results.append((visits, log_z))
    for visits, log_z in results[1:]:
        assert np.array_equal(visits, results[0][0]) and np.array_equal(log_z, results[0][1])
    assert np.allclose(results[0][0].sum(axis=(1, 2)), mdp.horizon + 1)


def test_reused_work_arrays_carry_nothing_between_calls() -> None:
    # The passes reuse per-thread work arrays: a batch whose flagged elements leave NaN and inf
    # behind, then ordinary batches of the same shape, must give what fresh arrays give.
    rng = np.random.default_rng(11)
    mdp = random_mdp(rng, 7, 6, d=3, horizon=15)
    wild = rng.normal(size=(8, 3)) * np.array([1.0, 500.0, 1.0, 1.0, 2000.0, 0.0, 1.0, 300.0])[:, None]
    calm = rng.normal(size=(8, 3))
    linear_passes._SCRATCH.__dict__.clear()
    fresh = M.log_partition_and_feature_expectations(mdp, calm), M.log_partition(mdp, calm)
    for _ in range(2):
        M.log_partition_and_feature_expectations(mdp, wild)
        M.log_partition(mdp, wild)
        again = M.log_partition_and_feature_expectations(mdp, calm), M.log_partition(mdp, calm)
        assert np.array_equal(again[0][0], fresh[0][0]) and np.array_equal(again[0][1], fresh[0][1])
        assert np.array_equal(again[1], fresh[1])


def test_threads_get_their_own_work_arrays() -> None:
    # ROS executors may call the passes from several threads at once.
    rng = np.random.default_rng(12)
    mdp = random_mdp(rng, 9, 8, d=4, horizon=20)
    batches = [rng.normal(size=(6, 4)) for _ in range(8)]
    serial = [M.feature_expectations(mdp, w) for w in batches]
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads between numpy calls, inside the passes
    try:
        with ThreadPoolExecutor(max_workers=4) as pool:
            for _ in range(5):
                threaded = list(pool.map(lambda w: M.feature_expectations(mdp, w), batches))
                assert all(np.array_equal(a, b) for a, b in zip(serial, threaded))
    finally:
        sys.setswitchinterval(interval)


@pytest.mark.parametrize("seed", range(10))
def test_optimal_path_matches_enumeration(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    height, width = SHAPES[seed % len(SHAPES)]
    mdp = random_mdp(rng, height, width, d=1, horizon=1 + seed % 5)
    rewards = rng.normal(size=(height, width))
    cells, value = M.optimal_path(mdp, rewards)
    trajectories = all_trajectories(mdp)
    best = rewards.ravel()[trajectories].sum(axis=1).max()
    assert abs(value - best) <= 1e-9 * max(1.0, abs(best))
    M.validate_path(mdp, cells)
    assert np.isclose(sum(rewards[r, c] for r, c in cells), value)


def test_optimal_path_stays_when_indifferent_and_avoids_forbidden_cells() -> None:
    mdp = M.GridMDP(np.zeros((3, 3, 1)), (1, 1), 4)
    cells, value = M.optimal_path(mdp, np.zeros((3, 3)))
    assert cells == [(1, 1)] * 5 and value == 0.0
    rewards = np.zeros((3, 3))
    rewards[1, 1] = -np.inf  # forbidden cell: must leave at once, then never return
    rewards[2, 2] = 1.0
    cells, value = M.optimal_path(mdp, rewards)
    assert value == -np.inf or cells[1:].count((1, 1)) == 0


def test_path_features_and_return() -> None:
    features = np.arange(2 * 3 * 2, dtype=float).reshape(2, 3, 2)
    mdp = M.GridMDP(features, (0, 0), 2)
    cells = [(0, 0), (0, 1), (1, 1)]
    assert np.array_equal(M.path_features(mdp, cells), features[0, 0] + features[0, 1] + features[1, 1])
    assert np.allclose(M.path_return(mdp, cells, np.array([[1.0, 0.0]])), [0 + 2 + 8])
    trajectories = all_trajectories(mdp)
    phi = trajectory_features(mdp, trajectories)
    assert any(np.array_equal(p, M.path_features(mdp, cells)) for p in phi)


@pytest.mark.parametrize("kwargs, field", [
    (dict(features=np.zeros((3, 3)), start=(0, 0), horizon=2), "features"),
    (dict(features=np.full((2, 2, 1), np.nan), start=(0, 0), horizon=2), "features"),
    (dict(features=np.zeros((2, 2, 1)), start=(2, 0), horizon=2), "start"),
    (dict(features=np.zeros((2, 2, 1)), start=(0, -1), horizon=2), "start"),
    (dict(features=np.zeros((2, 2, 1)), start=(0, 0), horizon=0), "horizon"),
    (dict(features=np.zeros((2, 2, 1)), start=(0, 0), horizon=1.5), "horizon"),
])
def test_bad_input_names_the_argument(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        M.GridMDP(**kwargs)


def test_bad_weights_and_paths_name_the_argument() -> None:
    mdp = M.GridMDP(np.zeros((2, 2, 3)), (0, 0), 2)
    with pytest.raises(ValueError, match="weights"):
        M.log_partition(mdp, np.zeros(3))
    with pytest.raises(ValueError, match="weights"):
        M.feature_expectations(mdp, np.full((1, 3), np.nan))
    with pytest.raises(ValueError, match="cells"):
        M.validate_path(mdp, [(0, 0), (1, 1), (1, 1)])
    with pytest.raises(ValueError, match="cells"):
        M.validate_path(mdp, [(0, 1), (1, 1), (1, 1)])
