"""Queries to the designer (docs/spec.md section 7): information gain, proposal, simulated designer."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy import stats

from ird_core.designer import queries as Q
from ird_core.mdp import GridMDP, optimal_path, path_features, validate_path


def grid(seed: int, d: int = 3, shape: tuple[int, int] = (3, 3), horizon: int = 3) -> GridMDP:
    rng = np.random.default_rng(seed)
    return GridMDP(rng.normal(size=shape + (d,)), (int(rng.integers(shape[0])), int(rng.integers(shape[1]))),
                   horizon)


def direct_information_gain(options: np.ndarray, samples: np.ndarray, beta: float) -> float:
    """Mutual information by explicit loops over samples and answers."""
    q = len(options)
    answers = []
    for w in samples:
        scores = [beta * float(np.dot(w, f)) for f in options]
        top = max(scores)
        z = sum(math.exp(s - top) for s in scores)
        answers.append([math.exp(s - top) / z for s in scores])
    mean = [sum(p[j] for p in answers) / len(answers) for j in range(q)]
    entropy = lambda p: -sum(x * math.log(x) for x in p if x > 0)  # noqa: E731
    return entropy(mean) - sum(entropy(p) for p in answers) / len(answers)


# ------------------------------------------------------------------------------ information gain


@pytest.mark.parametrize("seed", range(5))
def test_information_gain_matches_direct_enumeration(seed: int) -> None:
    rng = np.random.default_rng(seed)
    q, d = 2 + seed % 3, 4
    options, samples = rng.normal(size=(q, d)), rng.normal(size=(9, d))
    for beta in (0.0, 0.3, 2.0, 50.0):
        assert Q.information_gain(options, samples, beta) == pytest.approx(
            direct_information_gain(options, samples, beta), abs=1e-12)


def test_information_gain_is_batched_over_queries() -> None:
    rng = np.random.default_rng(1)
    batch, samples = rng.normal(size=(6, 3, 4)), rng.normal(size=(11, 4))
    got = Q.information_gain(batch, samples, 1.3)
    assert got.shape == (6,)
    np.testing.assert_allclose(got, [Q.information_gain(f, samples, 1.3) for f in batch], rtol=0, atol=1e-14)


def test_information_gain_is_zero_when_the_samples_agree() -> None:
    rng = np.random.default_rng(2)
    options = rng.normal(size=(3, 4))
    assert Q.information_gain(options, np.repeat(rng.normal(size=(1, 4)), 20, axis=0), 1.7) == pytest.approx(
        0.0, abs=1e-14)
    # Different samples that rank the options identically, deterministic answers (large beta).
    options = np.array([[3.0, 0.0], [2.0, 0.0], [0.0, 0.0]])
    samples = np.column_stack([rng.uniform(1.0, 2.0, size=30), rng.normal(size=30)])
    assert Q.information_gain(options, samples, 200.0) == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("q", [2, 3, 4])
def test_information_gain_is_log_q_for_an_even_deterministic_split(q: int) -> None:
    options = np.eye(q)
    samples = np.repeat(np.eye(q), 5, axis=0) * np.random.default_rng(q).uniform(1.0, 2.0, size=(5 * q, 1))
    assert Q.information_gain(options, samples, 100.0) == pytest.approx(math.log(q), abs=1e-12)
    assert Q.information_gain(options, samples, 1.0) < math.log(q) - 0.1  # soft answers carry less


def test_information_gain_arguments() -> None:
    with pytest.raises(ValueError, match="option_features"):
        Q.information_gain(np.ones((1, 3)), np.ones((4, 3)), 1.0)
    with pytest.raises(ValueError, match="samples"):
        Q.information_gain(np.ones((2, 3)), np.ones((4, 2)), 1.0)
    with pytest.raises(ValueError, match="beta"):
        Q.information_gain(np.ones((2, 3)), np.ones((4, 3)), -1.0)


# ------------------------------------------------------------------------------ candidates


@pytest.mark.parametrize("chunked", [False, True])
@pytest.mark.parametrize("seed", range(4))
def test_literal_paths_are_the_optimal_paths_of_each_sample(seed: int, chunked: bool,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    if chunked:  # a value table of one sample per chunk
        monkeypatch.setattr(Q, "_PATH_TABLE_ELEMENTS", 1)
    mdp = grid(seed, shape=[(3, 3), (2, 4), (4, 3), (1, 5)][seed], horizon=3 + seed)
    samples = np.random.default_rng(seed).normal(size=(40, 3))
    samples[:5, :] = 0.0  # all-tie rewards: "stay" first, as optimal_path
    states = Q.literal_paths(mdp, samples)
    for w, path in zip(samples, states):
        cells, _ = optimal_path(mdp, np.einsum("hwd,d->hw", mdp.features, w))
        np.testing.assert_array_equal(np.stack(np.divmod(path, mdp.width), axis=1), np.array(cells))


def test_candidates_are_the_distinct_literal_plans() -> None:
    mdp = grid(5, shape=(4, 4), horizon=4)
    samples = np.random.default_rng(5).normal(size=(60, 3))
    states, features, counts = Q.candidate_paths(mdp, samples)
    plans = {}
    for w in samples:
        cells, _ = optimal_path(mdp, np.einsum("hwd,d->hw", mdp.features, w))
        plans.setdefault(tuple(path_features(mdp, cells).round(9)), []).append(cells)
    assert len(states) == len(plans) and counts.sum() == len(samples)
    assert np.all(np.diff(counts) <= 0)
    for path, f, count in zip(states, features, counts):
        key = tuple(f.round(9))
        assert len(plans[key]) == count
        np.testing.assert_allclose(path_features(mdp, np.stack(np.divmod(path, mdp.width), axis=1)), f)


# ------------------------------------------------------------------------------ proposal


def brute_best_pair(mdp: GridMDP, samples: np.ndarray, beta: float) -> float:
    """The best information gain over every pair of distinct candidate paths (explicit loops)."""
    plans = {}
    for w in samples:
        cells, _ = optimal_path(mdp, np.einsum("hwd,d->hw", mdp.features, w))
        f = path_features(mdp, cells)
        plans.setdefault(tuple(f.round(9)), f)
    candidates = list(plans.values())
    return max(direct_information_gain(np.stack([a, b]), samples, beta)
               for a, b in itertools.combinations(candidates, 2))


@pytest.mark.parametrize("screen", [False, True])
@pytest.mark.parametrize("seed", range(4))
def test_info_gain_query_is_the_best_pair(seed: int, screen: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    if screen:  # force the float32 screening path of the pair search
        monkeypatch.setattr(Q, "_SCREEN_ELEMENTS", 0)
    mdp = grid(10 + seed, d=4, shape=(4, 4), horizon=5)
    samples = np.random.default_rng(seed).normal(size=(50, 4))
    for beta in (0.5, 3.0):
        query = Q.propose_query(mdp, samples, beta)
        assert query.strategy == "info_gain" and query.num_options == 2 and query.num_candidates >= 2
        assert query.information_gain == pytest.approx(brute_best_pair(mdp, samples, beta), abs=1e-12)
        assert query.information_gain == pytest.approx(
            Q.information_gain(query.option_features, samples, beta), abs=1e-15)
        for cells, f in zip(query.option_cells, query.option_features):
            validate_path(mdp, cells)
            np.testing.assert_allclose(path_features(mdp, cells), f)
        assert not np.allclose(query.option_features[0], query.option_features[1])


def test_greedy_query_with_more_options_is_at_least_the_best_pair() -> None:
    mdp = grid(20, d=4, shape=(4, 4), horizon=5)
    samples = np.random.default_rng(20).normal(size=(80, 4))
    pair = Q.propose_query(mdp, samples, 1.0, num_options=2)
    triple = Q.propose_query(mdp, samples, 1.0, num_options=3)
    assert triple.num_options == 3 and len({tuple(f) for f in triple.option_features}) == 3
    np.testing.assert_array_equal(triple.option_features[:2], pair.option_features)
    assert triple.information_gain >= pair.information_gain - 1e-15
    # The third option is the best addition to the pair.
    _, features, _ = Q.candidate_paths(mdp, samples)
    best_third = max(Q.information_gain(np.vstack([pair.option_features, f[None]]), samples, 1.0)
                     for f in features if not any(np.array_equal(f, g) for g in pair.option_features))
    assert triple.information_gain == pytest.approx(best_third, abs=1e-14)


def test_random_query_is_seeded_and_uniform_over_distinct_candidates() -> None:
    mdp = grid(30, d=4, shape=(4, 4), horizon=5)
    samples = np.random.default_rng(30).normal(size=(50, 4))
    _, features, _ = Q.candidate_paths(mdp, samples)
    n = len(features)
    a = Q.propose_query(mdp, samples, 1.0, strategy="random", seed=3)
    b = Q.propose_query(mdp, samples, 1.0, strategy="random", seed=3)
    np.testing.assert_array_equal(a.option_features, b.option_features)
    assert a.strategy == "random"
    assert a.information_gain == pytest.approx(Q.information_gain(a.option_features, samples, 1.0), abs=1e-15)
    seen = np.zeros(n)
    for seed in range(400):
        query = Q.propose_query(mdp, samples, 1.0, strategy="random", seed=seed)
        index = [int(np.flatnonzero((features == f).all(axis=1))[0]) for f in query.option_features]
        assert index[0] != index[1]
        seen[index] += 1
    # Each candidate is in a uniform pair with probability 2 / n: 800 picks, chi-square at 0.1%.
    assert stats.chisquare(seen).pvalue > 1e-3


def test_too_few_candidates_is_a_clear_error() -> None:
    mdp = grid(40)
    with pytest.raises(Q.NotEnoughCandidates, match="num_options"):
        Q.propose_query(mdp, np.ones((10, 3)), 1.0)
    assert issubclass(Q.NotEnoughCandidates, ValueError)


@pytest.mark.parametrize("kwargs, field", [
    ({"strategy": "best"}, "strategy"),
    ({"num_options": 1}, "num_options"),
    ({"seed": -1}, "seed"),
    ({"beta": float("nan")}, "beta"),
    ({"samples": np.ones((5, 2))}, "samples"),
    ({"query_mdp": "map"}, "query_mdp"),
])
def test_bad_query_arguments_name_the_field(kwargs: dict, field: str) -> None:
    args = {"query_mdp": grid(41), "samples": np.random.default_rng(0).normal(size=(20, 3)), "beta": 1.0} | kwargs
    with pytest.raises(ValueError, match=field):
        Q.propose_query(**args)


def test_strategies_are_listed_once() -> None:
    assert Q.STRATEGIES == ("evoi", "max_regret", "info_gain", "random")


# ------------------------------------------------------------------------------ simulated designer


@pytest.mark.parametrize("returns, beta", [([1.0, 0.0], 1.0), ([2.0, 1.5, -1.0], 0.8), ([0.0, 0.0, 0.0, 1.0], 2.0)])
def test_simulated_answers_follow_the_boltzmann_probabilities(returns: list, beta: float) -> None:
    want = np.exp(beta * np.array(returns))
    want /= want.sum()
    np.testing.assert_allclose(Q.answer_probabilities(np.array(returns), beta), want, rtol=1e-14)
    rng = np.random.default_rng(7)  # seeded: the test is deterministic; 0.1% significance
    n = 20000
    counts = np.bincount([Q.simulated_answer(np.array(returns), beta, rng) for _ in range(n)], minlength=len(want))
    assert stats.chisquare(counts, n * want).pvalue > 1e-3


def test_simulated_designer_is_seeded() -> None:
    returns = np.array([0.3, 0.2, 0.1])
    a = [Q.SimulatedDesigner(1.0, 5).answer(returns) for _ in range(1)]
    first, second = Q.SimulatedDesigner(1.0, 5), Q.SimulatedDesigner(1.0, 5)
    assert [first.answer(returns) for _ in range(50)] == [second.answer(returns) for _ in range(50)]
    assert a[0] in range(3)
    # A very rational designer always picks the best option; beta 0 picks uniformly.
    assert all(Q.SimulatedDesigner(1e4, s).answer(returns) == 0 for s in range(20))
    with pytest.raises(ValueError, match="beta"):
        Q.SimulatedDesigner(-1.0, 0)
