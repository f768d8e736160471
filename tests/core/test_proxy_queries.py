"""Active IRD's proxy-choice query (docs/spec.md section 7) against brute-force enumeration of every
trajectory of tiny grids: the evidence term, the candidates, the best pair, the simulated designer."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.special import logsumexp

from ird_core.designer import proxy_queries as PQ
from ird_core.designer import queries as Q
from ird_core.mdp import GridMDP, optimal_path, path_features, validate_path
from ird_core.mdp.enumeration import all_trajectories, trajectory_features
from ird_core.posterior import ChoiceObservation, ObservationModel, choice_log_likelihood, joint_log_posterior
from ird_core.vocabulary import QUERY_KINDS, QueryKind
from ird_core.worlds.lavaland import TRUE_TERRAIN_REWARD

MODELS = [ObservationModel("maxent"), ObservationModel("maxent", temperature=0.5), ObservationModel("optimal")]


def tiny(seed: int, d: int = 3, p: int | None = None, shape: tuple[int, int] = (2, 3),
         horizon: int = 2) -> tuple[GridMDP, GridMDP | None]:
    """A training MDP on d hypothesis features and, with ``p``, its proxy view on p other features."""
    rng = np.random.default_rng(seed)
    start = (int(rng.integers(shape[0])), int(rng.integers(shape[1])))
    train = GridMDP(rng.normal(size=shape + (d,)), start, horizon)
    return train, None if p is None else GridMDP(rng.normal(size=shape + (p,)), start, horizon)


def brute_counts(train: GridMDP, proxy_mdp: GridMDP | None, proxies: np.ndarray, model: ObservationModel) -> np.ndarray:
    """phi~(w~) by enumerating every trajectory: the MaxEnt expectation of the hypothesis counts, or
    the counts of the best trajectory."""
    planning = train if proxy_mdp is None else proxy_mdp
    trajectories = all_trajectories(planning)
    phi_plan = trajectory_features(planning, trajectories)  # (N, p)
    phi_hyp = trajectory_features(train, trajectories)  # (N, d)
    out = []
    for w in np.atleast_2d(proxies):
        scores = phi_plan @ w
        if model.optimal:
            out.append(phi_hyp[int(np.argmax(scores))])
        else:
            s = scores / model.temperature
            out.append(np.exp(s - logsumexp(s)) @ phi_hyp)
    return np.array(out)


def brute_log_likelihood(weights: np.ndarray, counts: np.ndarray, chosen: int, beta: float) -> np.ndarray:
    """log P(chosen | w) = beta w.phi_chosen - log sum_j exp(beta w.phi_j), by explicit loops."""
    out = []
    for w in weights:
        scores = [beta * float(np.dot(w, c)) for c in counts]
        top = max(scores)
        out.append(scores[chosen] - (top + math.log(sum(math.exp(s - top) for s in scores))))
    return np.array(out)


def direct_gain(counts: np.ndarray, samples: np.ndarray, beta: float) -> float:
    answers = []
    for w in samples:
        scores = np.array([beta * float(np.dot(w, c)) for c in counts])
        p = np.exp(scores - scores.max())
        answers.append(p / p.sum())
    answers = np.array(answers)
    entropy = lambda p: -sum(x * math.log(x) for x in p if x > 0)  # noqa: E731
    return entropy(answers.mean(axis=0)) - float(np.mean([entropy(a) for a in answers]))


# ------------------------------------------------------------------------------ the evidence term


@pytest.mark.parametrize("model", MODELS, ids=lambda m: f"{m.counts}-{m.temperature:g}")
@pytest.mark.parametrize("latent", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_evidence_term_equals_brute_force(seed: int, latent: bool, model: ObservationModel) -> None:
    train, proxy_mdp = tiny(seed, d=3, p=2 if latent else None, horizon=2 + seed % 2)
    rng = np.random.default_rng(100 + seed)
    p = 2 if latent else 3
    samples = rng.normal(size=(25, 3))
    q = 2 if model.optimal else 3  # few distinct optimal paths on a 2x3 grid
    query = PQ.propose_proxy_query(train, proxy_mdp, rng.normal(size=p), samples, 1.5, num_options=q,
                                   observation_model=model, seed=seed, perturbation_sigma=5.0)
    assert query.kind == "proxies" and query.num_options == q and query.proxies.shape == (q, p)
    expected = brute_counts(train, proxy_mdp, query.proxies, model)
    np.testing.assert_allclose(query.option_features, expected, rtol=0, atol=1e-10)
    weights = rng.normal(size=(40, 3)) * 2.0
    for chosen in range(q):
        for beta in (0.3, 2.0):
            choice = PQ.proxy_choice_observation(query, chosen, beta)
            assert isinstance(choice, ChoiceObservation)
            got = choice_log_likelihood(weights, choice.option_features, chosen, beta)
            np.testing.assert_allclose(got, brute_log_likelihood(weights, expected, chosen, beta), rtol=0, atol=1e-10)
    # The joint posterior adds exactly this term to the prior.
    choice = PQ.proxy_choice_observation(query, 1, 2.0)
    prior_only = joint_log_posterior(weights, [ChoiceObservation(np.zeros((2, 3)), 0, 0.0)], 1.0, "maxent_z")
    with_choice = joint_log_posterior(weights, [choice], 1.0, "maxent_z")
    np.testing.assert_allclose(with_choice - prior_only - math.log(2.0),  # the dummy term is -log 2
                               brute_log_likelihood(weights, expected, 1, 2.0), rtol=0, atol=1e-10)


@pytest.mark.parametrize("model", MODELS[::2], ids=lambda m: m.counts)
def test_plans_are_the_proxies_optimal_paths_and_optimal_counts_count_them(model: ObservationModel) -> None:
    train, proxy_mdp = tiny(4, d=3, p=2, shape=(3, 3), horizon=3)
    query = PQ.propose_proxy_query(train, proxy_mdp, np.array([1.0, -0.5]), np.zeros((5, 3)), 1.0, 2,
                                   observation_model=model, seed=2, num_perturbations=40, perturbation_sigma=3.0)
    for proxy, cells, f in zip(query.proxies, query.option_cells, query.option_features):
        validate_path(train, cells)
        assert cells.shape == (train.horizon + 1, 2) and not cells.flags.writeable
        expected, _ = optimal_path(proxy_mdp, np.einsum("hwp,p->hw", proxy_mdp.features, proxy))
        np.testing.assert_array_equal(cells, np.array(expected))
        if model.optimal:
            np.testing.assert_allclose(path_features(train, cells), f, rtol=0, atol=1e-12)


def test_behaviour_equivalent_rewards_are_indistinguishable() -> None:
    """Proposition-1-style invariances: adding the same vector to every cell's hypothesis
    features shifts every option's counts by (T + 1) c, so no weight's likelihood changes; under
    optimal counts a positive rescaling of an offered proxy changes nothing; a permutation of
    the options permutes the answer."""
    train, _ = tiny(7, d=3, horizon=3)
    rng = np.random.default_rng(7)
    samples, weights = rng.normal(size=(30, 3)), rng.normal(size=(20, 3))
    for model in MODELS:
        query = PQ.propose_proxy_query(train, None, rng.normal(size=3), samples, 1.0, 3, observation_model=model)
        shift = np.array([0.7, -1.3, 2.0])
        shifted = GridMDP(train.features + shift, train.start, train.horizon)
        counts = PQ.proxy_behaviour(shifted, train, query.proxies, model)  # planned on train, counted shifted
        np.testing.assert_allclose(counts, query.option_features + (train.horizon + 1) * shift, atol=1e-9)
        for chosen in range(3):
            np.testing.assert_allclose(choice_log_likelihood(weights, counts, chosen, 1.3),
                                       choice_log_likelihood(weights, query.option_features, chosen, 1.3), atol=1e-9)
        order = [2, 0, 1]
        np.testing.assert_allclose(choice_log_likelihood(weights, query.option_features[order], 0, 1.3),
                                   choice_log_likelihood(weights, query.option_features, 2, 1.3), atol=1e-12)
    optimal = ObservationModel("optimal")
    proxies = rng.normal(size=(4, 3))
    np.testing.assert_array_equal(PQ.proxy_behaviour(train, None, proxies * np.array([[0.2], [3.0], [1.0], [50.0]]),
                                                     optimal), PQ.proxy_behaviour(train, None, proxies, optimal))


# ------------------------------------------------------------------------------ candidates and proposal


def test_candidates_are_the_proxy_then_distinct_sample_behaviours() -> None:
    train, _ = tiny(3, d=3, shape=(2, 3), horizon=3)
    rng = np.random.default_rng(3)
    proxy = rng.normal(size=3)
    samples = np.concatenate([rng.normal(size=(20, 3)), proxy[None] * 2.0, rng.normal(size=(20, 3))])
    model = ObservationModel("optimal")
    proxies, counts = PQ.candidate_proxies(proxy, samples, train, observation_model=model)
    np.testing.assert_array_equal(proxies[0], proxy)  # the written proxy first
    brute = brute_counts(train, None, np.concatenate([proxy[None], samples]), model)
    distinct = {tuple(c.round(9)) for c in brute}
    assert len(proxies) == len(distinct) == len({tuple(c.round(9)) for c in counts})
    np.testing.assert_allclose(counts, brute_counts(train, None, proxies, model), atol=1e-10)
    assert not any(np.allclose(p, 2.0 * proxy) for p in proxies)  # same behaviour as the proxy: merged


def test_latent_candidates_are_seeded_perturbations_in_the_proxys_space() -> None:
    train, proxy_mdp = tiny(5, d=4, p=2, shape=(3, 3), horizon=3)
    proxy, samples = np.array([1.0, -1.0]), np.random.default_rng(5).normal(size=(30, 4))
    a = PQ.candidate_proxies(proxy, samples, train, proxy_mdp, seed=3)
    b = PQ.candidate_proxies(proxy, samples, train, proxy_mdp, seed=3)
    c = PQ.candidate_proxies(proxy, samples, train, proxy_mdp, seed=4)
    assert a[0].shape[1] == 2 and 2 <= len(a[0]) <= 31
    np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(a[1], b[1])
    assert not np.array_equal(a[0][1:], c[0][1:len(a[0])])
    np.testing.assert_array_equal(a[0][0], proxy)
    np.testing.assert_allclose(a[1], brute_counts(train, proxy_mdp, a[0], PQ.DEFAULT_OBSERVATION_MODEL), atol=1e-10)


@pytest.mark.parametrize("model", MODELS[::2], ids=lambda m: m.counts)
@pytest.mark.parametrize("seed", range(4))
def test_info_gain_picks_the_brute_force_best_pair(seed: int, model: ObservationModel) -> None:
    train, _ = tiny(20 + seed, d=3, shape=(2, 3), horizon=2 + seed % 2)
    rng = np.random.default_rng(seed)
    proxy, samples = rng.normal(size=3), rng.normal(size=(30, 3))
    for beta in (0.5, 3.0):
        query = PQ.propose_proxy_query(train, None, proxy, samples, beta, observation_model=model)
        candidates = {}
        for c in brute_counts(train, None, np.concatenate([proxy[None], samples]), model):
            candidates.setdefault(tuple(c.round(9)), c)
        assert query.num_candidates == len(candidates)
        best = max(direct_gain(np.stack(pair), samples, beta)
                   for pair in itertools.combinations(candidates.values(), 2))
        assert query.information_gain == pytest.approx(best, abs=1e-10)
        assert query.information_gain == pytest.approx(direct_gain(query.option_features, samples, beta), abs=1e-10)
        triple = PQ.propose_proxy_query(train, None, proxy, samples, beta, 3, observation_model=model)
        np.testing.assert_array_equal(triple.proxies[:2], query.proxies)  # greedy extends the best pair
        assert Q.information_gain(triple.option_features, samples, beta) == pytest.approx(triple.information_gain)


def test_seeded_determinism_and_the_random_strategy() -> None:
    train, proxy_mdp = tiny(9, d=3, p=2, shape=(3, 3), horizon=3)
    samples = np.random.default_rng(9).normal(size=(20, 3))
    args = (train, proxy_mdp, np.array([0.5, -1.0]), samples, 1.0, 3)
    for strategy in ("info_gain", "random"):
        a = PQ.propose_proxy_query(*args, strategy=strategy, seed=5)
        b = PQ.propose_proxy_query(*args, strategy=strategy, seed=5)
        assert a.strategy == strategy
        np.testing.assert_array_equal(a.proxies, b.proxies)
        np.testing.assert_array_equal(a.option_features, b.option_features)
        assert a.information_gain == b.information_gain
        assert len({tuple(f.round(9)) for f in a.option_features}) == 3  # distinct behaviours
    picks = {tuple(PQ.propose_proxy_query(*args, strategy="random", seed=s).proxies[:, 0].round(12))
             for s in range(6)}
    assert len(picks) > 1


def test_not_enough_candidates() -> None:
    train, _ = tiny(1)
    proxy = np.array([1.0, 0.0, 0.0])
    samples = np.repeat(proxy[None] * 3.0, 5, axis=0)  # every sample plans like the proxy
    with pytest.raises(Q.NotEnoughCandidates, match=r"^num_options:"):
        PQ.propose_proxy_query(train, None, proxy, samples, 1.0, observation_model=ObservationModel("optimal"))
    with pytest.raises(Q.NotEnoughCandidates, match=r"^num_options:"):
        PQ.propose_proxy_query(train, None, proxy, samples[:1], 1.0, num_options=3)


@pytest.mark.parametrize("kwargs, field", [
    (dict(proxy_weights=np.ones(2)), "proxy_weights"),
    (dict(proxy_weights=np.array([1.0, np.nan, 0.0])), "proxy_weights"),
    (dict(samples=np.ones((4, 2))), "samples"),
    (dict(samples=np.ones((40, 3))), "samples"),  # past max_candidates
    (dict(beta=-1.0), "beta"),
    (dict(num_options=1), "num_options"),
    (dict(strategy="best"), "strategy"),
    (dict(strategy="evoi"), "test_mdp"),
    (dict(strategy="max_regret"), "strategy"),
    (dict(seed=-1), "seed"),
    (dict(train_mdp="map"), "train_mdp"),
    (dict(proxy_mdp=GridMDP(np.zeros((3, 3, 3)), (0, 0), 2)), "proxy_mdp"),
    (dict(observation_model="maxent"), "observation_model"),
    (dict(max_candidates=1), "max_candidates"),
    (dict(perturbation_sigma=0.0), "perturbation_sigma"),
    (dict(num_perturbations=40), "num_perturbations"),
])
def test_bad_input_names_the_field(kwargs: dict, field: str) -> None:
    train, _ = tiny(2)
    args = dict(train_mdp=train, proxy_mdp=None, proxy_weights=np.ones(3), samples=np.random.default_rng(2).normal(
        size=(10, 3)), beta=1.0, max_candidates=20)
    args.update(kwargs)
    with pytest.raises(ValueError, match=rf"^{field}:"):
        PQ.propose_proxy_query(**args)
    with pytest.raises(ValueError, match=r"^query:"):
        PQ.proxy_choice_observation("query", 0, 1.0)  # type: ignore[arg-type]


def test_choice_arguments_name_the_field() -> None:
    train, _ = tiny(2)
    query = PQ.propose_proxy_query(train, None, np.ones(3), np.random.default_rng(2).normal(size=(10, 3)), 1.0)
    with pytest.raises(ValueError, match=r"^chosen:"):
        PQ.proxy_choice_observation(query, 2, 1.0)
    with pytest.raises(ValueError, match=r"^beta:"):
        PQ.proxy_choice_observation(query, 0, -1.0)


# ------------------------------------------------------------------------------ the simulated designer


def test_simulated_designer_picks_by_the_true_return_of_each_training_plan() -> None:
    train, _ = tiny(11, d=3, shape=(3, 3), horizon=3)
    labels = np.random.default_rng(11).integers(0, len(TRUE_TERRAIN_REWARD), size=(3, 3))
    query = PQ.propose_proxy_query(train, None, np.ones(3), np.random.default_rng(11).normal(size=(30, 3)), 1.0, 3)
    returns = PQ.proxy_option_returns(query, labels)
    np.testing.assert_allclose(returns, [TRUE_TERRAIN_REWARD[labels[c[:, 0], c[:, 1]]].sum()
                                         for c in query.option_cells])
    picks = [PQ.simulated_proxy_answer(query, labels, 1e3, np.random.default_rng(s)) for s in range(20)]
    assert all(returns[k] == returns.max() for k in picks)
    soft = [PQ.simulated_proxy_answer(query, labels, 0.0, np.random.default_rng(s)) for s in range(60)]
    assert len(set(soft)) == 3  # beta 0: uniform
    assert soft == [PQ.simulated_proxy_answer(query, labels, 0.0, np.random.default_rng(s)) for s in range(60)]


def test_the_kind_vocabulary() -> None:
    assert QUERY_KINDS == ("paths", "proxies") and QueryKind.PROXIES == PQ.ProxyQuery.kind
