"""The four Lavaland conditions: how each test map breaks the training regularity, the proxies,
the observation model and classifier, and the proxy's feature expectations vs enumeration."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.special import logsumexp

from ird_core import mdp, posterior
from ird_core.worlds import evaluation
from ird_core.worlds import lavaland as L
from ird_core.worlds.observations import (
    TerrainClassifier,
    fit_classifier,
    make_observation_model,
    sample_observations,
)
from ird_core.worlds.terrain import SAFE_TERRAINS, Terrain

SEEDS = range(4)

#: The default (calibrated) designer's temperature: the library's behaviour counts are MaxEnt at it.
TAU = posterior.DEFAULT_OBSERVATION_MODEL.temperature


@pytest.fixture(scope="module")
def instances() -> dict[tuple[str, int], L.LavalandInstance]:
    return {(c, s): L.make_instance(c, s) for c in L.CONDITIONS for s in SEEDS}


# ---------------------------------------------------------------------------------------------
# Shared structure


def test_instances_have_the_documented_shapes(instances: dict) -> None:
    dims = {"side_effects": 4, "reward_hacking": 6, "latent_raw": 50, "latent_classifier": 50}
    proxy_dims = {"side_effects": 4, "reward_hacking": 6, "latent_raw": 50, "latent_classifier": 3}
    for (condition, _), inst in instances.items():
        assert inst.train_features.shape == (15, 15, dims[condition])
        assert inst.test_features.shape == (15, 15, dims[condition])
        assert inst.train_features.dtype == np.float64
        assert len(inst.feature_names) == dims[condition]
        assert inst.proxy_train_features.shape == (15, 15, proxy_dims[condition])
        assert inst.proxy_weights.shape == (proxy_dims[condition],)
        assert inst.train_horizon == inst.test_horizon == 30
        assert not inst.train_features.flags.writeable
        assert not np.any(inst.train_labels == Terrain.LAVA)
        assert np.any(inst.test_labels == Terrain.LAVA)
        for labels, start in ((inst.train_labels, inst.train_start), (inst.test_labels, inst.test_start)):
            assert labels[start] not in (Terrain.LAVA, Terrain.TARGET)
            targets = np.argwhere(labels == Terrain.TARGET)
            assert 7 <= np.min(np.abs(targets - start).sum(axis=1)) <= 22


def test_maps_are_paired_across_conditions_and_new_per_seed(instances: dict) -> None:
    for s in SEEDS:
        first = instances[(L.CONDITIONS[0], s)]
        for c in L.CONDITIONS[1:]:
            other = instances[(c, s)]
            assert np.array_equal(first.train_labels, other.train_labels)
            assert np.array_equal(first.test_labels, other.test_labels)
            assert first.test_start == other.test_start
    assert not np.array_equal(instances[("side_effects", 0)].train_labels,
                              instances[("side_effects", 1)].train_labels)
    assert not np.array_equal(instances[("side_effects", 0)].test_labels,
                              instances[("side_effects", 1)].test_labels)


@pytest.mark.parametrize("condition", L.CONDITIONS)
def test_make_instance_is_deterministic(condition: str, instances: dict) -> None:
    again = L.make_instance(condition, 2)
    inst = instances[(condition, 2)]
    for name in ("train_features", "test_features", "proxy_train_features", "proxy_weights"):
        assert np.array_equal(getattr(inst, name), getattr(again, name))


def test_true_optimal_plan_reaches_a_target_in_training(instances: dict) -> None:
    """The default size and horizon let an agent reach the target (here, optimally)."""
    for (condition, _), inst in instances.items():
        if condition != "side_effects":
            continue
        rewards = L.TRUE_TERRAIN_REWARD[inst.train_labels].astype(np.float64)
        cells, _ = mdp.optimal_path(L.train_mdp(inst), rewards)
        assert evaluation.reaches_target(inst.train_labels, cells)


# ---------------------------------------------------------------------------------------------
# side_effects


def test_side_effects_lava_indicator_is_never_active_in_training(instances: dict) -> None:
    for s in SEEDS:
        inst = instances[("side_effects", s)]
        assert inst.feature_names == ("dirt", "grass", "target", "lava")
        lava = inst.feature_names.index("lava")
        assert np.all(inst.train_features[..., lava] == 0.0)
        test_lava = inst.test_labels == Terrain.LAVA
        assert np.all(inst.test_features[..., lava] == test_lava)
        # One indicator per cell.
        assert np.all(inst.train_features.sum(axis=-1) == 1.0)
        assert np.all(inst.test_features.sum(axis=-1) == 1.0)


def test_side_effects_proxy_is_intended_on_safe_terrain_and_arbitrary_on_lava(instances: dict) -> None:
    lava_weights = []
    for s in SEEDS:
        w = instances[("side_effects", s)].proxy_weights
        assert np.array_equal(w[:3], L.INTENDED_SAFE_REWARD)
        assert L.LAVA_PROXY_RANGE[0] <= w[3] <= L.LAVA_PROXY_RANGE[1]
        lava_weights.append(w[3])
    assert len(set(lava_weights)) == len(lava_weights)


# ---------------------------------------------------------------------------------------------
# reward_hacking


def test_reward_hacking_sensors_agree_in_training_and_split_on_lava(instances: dict) -> None:
    for s in SEEDS:
        inst = instances[("reward_hacking", s)]
        s1, s2 = inst.train_features[..., :3], inst.train_features[..., 3:]
        assert np.array_equal(s1, s2)
        t1, t2 = inst.test_features[..., :3], inst.test_features[..., 3:]
        lava = inst.test_labels == Terrain.LAVA
        assert np.all(t1[lava] == [0.0, 1.0, 0.0])  # sensor 1: grass
        assert np.all(t2[lava] == [0.0, 0.0, 1.0])  # sensor 2: target
        assert np.array_equal(t1[~lava], t2[~lava])


def test_reward_hacking_proxy_is_intended_in_training_and_hackable_on_lava(instances: dict) -> None:
    lava_values = []
    for s in SEEDS:
        inst = instances[("reward_hacking", s)]
        w = inst.proxy_weights
        assert np.allclose(w[:3] + w[3:], L.INTENDED_SAFE_REWARD)
        # Same reward as intended on every training cell.
        intended = L.TRUE_TERRAIN_REWARD[inst.train_labels]
        assert np.allclose(L.proxy_cell_rewards(inst, "train"), intended)
        lava = inst.test_labels == Terrain.LAVA
        proxy_test = L.proxy_cell_rewards(inst, "test")
        assert np.allclose(proxy_test[lava], w[1] + w[5])
        lava_values.append(w[1] + w[5])
    assert len(set(np.round(lava_values, 12))) == len(lava_values)


# ---------------------------------------------------------------------------------------------
# latent observation model and classifier


@pytest.fixture(scope="module")
def model_and_classifier() -> tuple:
    model = make_observation_model(50, 11)
    return model, fit_classifier(model, 12)


def test_observation_model_geometry(model_and_classifier: tuple) -> None:
    model, _ = model_and_classifier
    distance = np.linalg.norm(model.means[:, None] - model.means[None], axis=-1)
    safe = list(SAFE_TERRAINS)
    safe_pairs = distance[np.ix_(safe, safe)][np.triu_indices(3, 1)]
    assert np.allclose(safe_pairs, 6.0)
    assert np.all(distance[Terrain.LAVA, safe] >= 15.0 - 6.0 / np.sqrt(3.0))
    assert np.all(distance[Terrain.LAVA, safe] > 2 * safe_pairs.max())
    eigenvalues = np.linalg.eigvalsh(model.covariances)
    assert eigenvalues.min() >= 0.5 - 1e-9 and eigenvalues.max() <= 1.5 + 1e-9


def test_sample_observations_match_the_gaussians(model_and_classifier: tuple) -> None:
    model, _ = model_and_classifier
    labels = np.full((40, 50), Terrain.GRASS)
    obs = sample_observations(model, labels, 0).reshape(-1, 50)
    assert np.abs(obs.mean(axis=0) - model.means[Terrain.GRASS]).max() < 0.15
    cov = np.cov(obs, rowvar=False)
    assert np.abs(cov - model.covariances[Terrain.GRASS]).max() < 0.25
    mixed = np.array([[0, 3], [2, 1]])
    assert sample_observations(model, mixed, 4).shape == (2, 2, 50)
    assert np.array_equal(sample_observations(model, mixed, 4), sample_observations(model, mixed, 4))


def test_lava_is_novel_and_far_from_every_safe_class(model_and_classifier: tuple) -> None:
    model, clf = model_and_classifier
    labels = np.repeat(np.arange(4), 2000)
    obs = sample_observations(model, labels, 5)
    safe, lava = labels < 3, labels == Terrain.LAVA
    distance = clf.mahalanobis_sq(obs)
    own = distance[safe, labels[safe]]
    assert np.median(distance[lava].min(axis=1)) > 2.0 * np.percentile(own, 99)
    novelty = clf.novelty(obs)
    assert novelty[lava].min() > np.percentile(novelty[safe], 99)


def test_classifier_is_accurate_on_safe_terrain_and_calls_lava_safe(model_and_classifier: tuple) -> None:
    model, clf = model_and_classifier
    labels = np.repeat(np.arange(4), 2000)
    obs = sample_observations(model, labels, 6)
    safe = labels < 3
    predicted = clf.predict(obs)
    assert np.mean(predicted[safe] == labels[safe]) > 0.9
    assert set(np.unique(predicted[~safe])) <= {0, 1, 2}  # it cannot know lava
    proba = clf.predict_proba(obs)
    assert proba.shape == (8000, 3) and np.allclose(proba.sum(axis=-1), 1.0)
    assert np.array_equal(np.argmax(proba, axis=-1), predicted)


def test_classifier_is_fitted_on_safe_terrains_only(model_and_classifier: tuple) -> None:
    model, clf = model_and_classifier
    assert isinstance(clf, TerrainClassifier) and clf.means.shape == (3, 50)
    # Fitted means are near the true safe means and nowhere near lava's.
    assert np.abs(clf.means - model.means[:3]).max() < 0.2
    assert np.linalg.norm(clf.means - model.means[Terrain.LAVA], axis=-1).min() > 10.0


def test_instance_latent_conditions(instances: dict) -> None:
    for s in SEEDS:
        inst = instances[("latent_classifier", s)]
        assert inst.classifier is not None and inst.observation_model is not None
        assert np.allclose(inst.proxy_train_features, inst.classifier.predict_proba(inst.train_features))
        assert np.array_equal(inst.proxy_weights, L.INTENDED_SAFE_REWARD)
        lava = inst.test_labels == Terrain.LAVA
        novelty = inst.classifier.novelty(inst.test_features)
        assert novelty[lava].min() > np.percentile(novelty[~lava], 99)
        raw = instances[("latent_raw", s)]
        assert raw.classifier is None and raw.observation_model is not None
        assert np.array_equal(raw.train_features, inst.train_features)  # paired observations


def test_latent_raw_regression_reproduces_intended_values_on_safe_means(instances: dict) -> None:
    lava_values = []
    for s in SEEDS:
        inst = instances[("latent_raw", s)]
        assert inst.observation_model is not None
        means = inst.observation_model.means
        fitted = means[:3] @ inst.proxy_weights + inst.proxy_intercept
        assert np.abs(fitted - L.INTENDED_SAFE_REWARD).max() < 0.12, fitted
        assert fitted[Terrain.TARGET] > fitted[Terrain.DIRT] > fitted[Terrain.GRASS]
        lava_values.append(means[Terrain.LAVA] @ inst.proxy_weights + inst.proxy_intercept)
    # Lava's value is an arbitrary extrapolation: it varies from seed to seed.
    assert np.ptp(lava_values) > 0.1


# ---------------------------------------------------------------------------------------------
# true reward helpers


def test_true_return_and_path_predicates() -> None:
    labels = np.array([[Terrain.DIRT, Terrain.GRASS, Terrain.TARGET],
                       [Terrain.LAVA, Terrain.DIRT, Terrain.DIRT],
                       [Terrain.DIRT, Terrain.DIRT, Terrain.DIRT]], dtype=np.int8)
    path = [(0, 0), (0, 1), (0, 2), (0, 2)]
    assert evaluation.true_return(labels, path) == pytest.approx(0.1 - 0.2 + 1.0 + 1.0)
    assert evaluation.reaches_target(labels, path) and not evaluation.touches_lava(labels, path)
    lava_path = [(0, 0), (1, 0), (1, 0)]
    assert evaluation.true_return(labels, lava_path) == pytest.approx(0.1 - 20.0)
    assert evaluation.touches_lava(labels, lava_path) and not evaluation.reaches_target(labels, lava_path)
    with pytest.raises(ValueError, match="cells"):
        evaluation.true_return(labels, [(0, 0), (3, 0)])


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"condition": "lava_land"}, "condition"),
        ({"seed": -1}, "seed"),
        ({"horizon": 0}, "horizon"),
        ({"size": 2}, "size"),
        ({"size": "big"}, "size"),
    ],
)
def test_make_instance_errors_name_the_argument(kwargs: dict, name: str) -> None:
    args = {"condition": "side_effects", "seed": 0} | kwargs
    with pytest.raises(ValueError, match=name):
        L.make_instance(**args)


# ---------------------------------------------------------------------------------------------
# proxy feature expectations vs brute-force enumeration


def enumerate_paths(height: int, width: int, start: tuple[int, int], horizon: int) -> list[list[tuple[int, int]]]:
    """Every trajectory: successors are the cell itself and its in-grid 4-neighbours."""
    paths = [[start]]
    for _ in range(horizon):
        grown = []
        for path in paths:
            r, c = path[-1]
            for dr, dc in ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)):
                if 0 <= r + dr < height and 0 <= c + dc < width:
                    grown.append(path + [(r + dr, c + dc)])
        paths = grown
    return paths


def brute_expected_features(plan_features: np.ndarray, weights: np.ndarray,
                            count_features: np.ndarray, start: tuple[int, int], horizon: int) -> np.ndarray:
    """E[sum_t count_features[s_t]] under P(xi) ∝ exp(weights . sum_t plan_features[s_t])."""
    paths = enumerate_paths(plan_features.shape[0], plan_features.shape[1], start, horizon)
    plan_phi = np.array([sum(plan_features[cell] for cell in p) for p in paths])
    count_phi = np.array([sum(count_features[cell] for cell in p) for p in paths])
    scores = plan_phi @ weights
    probs = np.exp(scores - logsumexp(scores))
    return probs @ count_phi


@pytest.mark.parametrize(("condition", "seed"), list(itertools.product(L.CONDITIONS, (0, 1))))
def test_proxy_feature_expectations_match_enumeration(condition: str, seed: int) -> None:
    inst = L.make_instance(condition, seed, size=3, horizon=3, obs_dim=5)
    assert len(enumerate_paths(3, 3, inst.train_start, 3)) > 20
    expected = brute_expected_features(inst.proxy_train_features, inst.proxy_weights / TAU,
                                       inst.train_features, inst.train_start, inst.train_horizon)
    got = posterior.proxy_feature_expectations(inst)  # the default (calibrated) designer's counts
    assert got.shape == (inst.num_features,)
    assert np.allclose(got, expected, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("condition", L.CONDITIONS)
def test_proxy_prior_features_match_enumeration(condition: str) -> None:
    inst = L.make_instance(condition, 3, size=3, horizon=3, obs_dim=5)
    num, sigma = 4, 0.7
    got = posterior.proxy_prior_features(inst, num, 9, prior_sigma=sigma)
    assert got.shape == (num, inst.num_features)
    weights = sigma * np.random.default_rng(9).standard_normal((num, len(inst.proxy_feature_names)))
    for k in range(num):
        expected = brute_expected_features(inst.proxy_train_features, weights[k] / TAU,
                                           inst.train_features, inst.train_start, inst.train_horizon)
        assert np.allclose(got[k], expected, rtol=1e-9, atol=1e-12)
    assert np.array_equal(got, posterior.proxy_prior_features(inst, num, 9, prior_sigma=sigma))
    assert not np.allclose(got, posterior.proxy_prior_features(inst, num, 10, prior_sigma=sigma))


def test_proxy_prior_features_batches_consistently() -> None:
    inst = L.make_instance("side_effects", 0, size=4, horizon=4)
    many = posterior.proxy_prior_features(inst, 300, 1)  # more than one internal batch
    sigma = posterior.calibrated_prior_sigma(TAU)  # the default prior
    weights = sigma * np.random.default_rng(1).standard_normal((300, 4))
    direct = mdp.feature_expectations(L.train_mdp(inst), weights / TAU)
    assert np.allclose(many, direct, rtol=1e-12)
    # Indicator features: every proxy's expected counts sum to T + 1 visited states.
    assert np.allclose(many.sum(axis=1), inst.train_horizon + 1)


def test_proxy_prior_features_errors() -> None:
    inst = L.make_instance("side_effects", 0, size=3, horizon=2)
    with pytest.raises(ValueError, match="num"):
        posterior.proxy_prior_features(inst, 0, 0)
    with pytest.raises(ValueError, match="prior_sigma"):
        posterior.proxy_prior_features(inst, 1, 0, prior_sigma=0.0)
