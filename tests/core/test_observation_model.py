"""The observation model's readings (optimal-path and MaxEnt counts, the designer's temperature,
Sample-Z's own term) against brute-force enumeration of every trajectory on tiny grids."""

from __future__ import annotations

import os

import numpy as np
import pytest
from scipy.special import logsumexp

from ird_core.posterior.calibration import CALIBRATED_TEMPERATURE
from ird_core import posterior
from ird_core.mdp import GridMDP, optimal_path
from ird_core.mdp.enumeration import all_trajectories, trajectory_features
from ird_core.mdp.optimal_paths import optimal_feature_counts, optimal_paths, optimal_returns
from ird_core.posterior import ObservationModel, make_joint_model, proxy_feature_counts


def tiny(seed: int, integer: bool = False) -> tuple[GridMDP, np.ndarray]:
    rng = np.random.default_rng(seed)
    h, w = (int(x) for x in rng.integers(1, 4, 2))
    d = int(rng.integers(2, 4))
    features = rng.integers(-2, 3, (h, w, d)).astype(float) if integer else rng.normal(size=(h, w, d))
    mdp = GridMDP(features, (int(rng.integers(h)), int(rng.integers(w))), int(rng.integers(1, 5)))
    weights = rng.integers(-2, 3, (6, d)).astype(float) if integer else rng.normal(size=(6, d))
    return mdp, weights


def brute_optimal_counts(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    phi = trajectory_features(mdp, all_trajectories(mdp))
    return phi[np.argmax(weights @ phi.T, axis=1)]


def brute_maxent_counts(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    phi = trajectory_features(mdp, all_trajectories(mdp))
    scores = weights @ phi.T
    p = np.exp(scores - logsumexp(scores, axis=1, keepdims=True))
    return p @ phi


@pytest.mark.parametrize("engine", ["numpy", "numba"])
@pytest.mark.parametrize("seed", range(40))
def test_optimal_paths_are_optimal_path_with_its_tie_breaking(seed: int, engine: str, monkeypatch) -> None:
    monkeypatch.setenv("IRD_ENGINE", engine)
    mdp, weights = tiny(seed, integer=seed % 2 == 1)  # integers: exact ties are common
    rewards = np.einsum("hwd,kd->khw", mdp.features, weights)
    paths = optimal_paths(mdp, rewards)
    for k in range(len(weights)):
        cells, _ = optimal_path(mdp, rewards[k])
        assert np.array_equal(paths[k], np.asarray(cells))


@pytest.mark.parametrize("seed", range(20))
def test_optimal_counts_reach_the_brute_force_optimum(seed: int) -> None:
    mdp, weights = tiny(seed)
    counts = optimal_feature_counts(mdp, weights)
    best = np.max(weights @ trajectory_features(mdp, all_trajectories(mdp)).T, axis=1)
    np.testing.assert_allclose(np.sum(weights * counts, axis=1), best, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(optimal_returns(mdp, weights), best, rtol=1e-12, atol=1e-12)


def test_optimal_counts_are_scale_free_and_deterministic() -> None:
    mdp, weights = tiny(3)
    counts = optimal_feature_counts(mdp, weights)
    np.testing.assert_array_equal(counts, optimal_feature_counts(mdp, 7.0 * weights))
    np.testing.assert_array_equal(counts, optimal_feature_counts(mdp, weights.copy()))


@pytest.mark.parametrize("temperature", [0.25, 1.0, 3.0])
def test_maxent_counts_at_a_temperature_are_the_brute_force_expectations(temperature: float) -> None:
    mdp, weights = tiny(5)
    model = ObservationModel("maxent", temperature)
    np.testing.assert_allclose(proxy_feature_counts(mdp, weights, model=model),
                               brute_maxent_counts(mdp, weights / temperature), rtol=1e-9, atol=1e-10)


def test_the_default_counts_are_the_calibrated_designers_maxent_counts() -> None:
    mdp, weights = tiny(6)
    calibrated = ObservationModel("maxent", CALIBRATED_TEMPERATURE)
    np.testing.assert_array_equal(proxy_feature_counts(mdp, weights), proxy_feature_counts(mdp, weights, model=calibrated))
    assert not np.allclose(proxy_feature_counts(mdp, weights),
                           proxy_feature_counts(mdp, weights, model=ObservationModel("maxent", 1.0)))


def brute_sample_z(w: np.ndarray, proxy: np.ndarray, samples: np.ndarray, mdp: GridMDP, beta: float,
                   model: ObservationModel) -> np.ndarray:
    """The Sample-Z log likelihood from its definition, every count by enumeration."""
    counts = brute_optimal_counts if model.optimal else (lambda m, x: brute_maxent_counts(m, x / model.temperature))
    phi_tilde = counts(mdp, proxy[None])[0]
    phi_i = counts(mdp, samples)
    out = []
    for wk in w:
        scores = [beta * wk @ f for f in phi_i]
        if model.own_term:
            scores.append(beta * wk @ counts(mdp, wk[None])[0])
        out.append(beta * wk @ phi_tilde - logsumexp(scores))
    return np.asarray(out) - 0.5 * np.sum(w**2, axis=1)


@pytest.mark.parametrize("model", [ObservationModel("optimal"), ObservationModel("maxent", 0.5),
                                   ObservationModel("optimal", own_term=False),
                                   ObservationModel("maxent", 1.0, own_term=False)], ids=str)
@pytest.mark.parametrize("seed", range(6))
def test_sample_z_log_density_differences_match_enumeration(model: ObservationModel, seed: int) -> None:
    mdp, w = tiny(seed + 100)
    rng = np.random.default_rng(seed)
    proxy, samples = rng.normal(size=w.shape[1]), rng.normal(size=(7, w.shape[1]))
    obs = posterior.ProxyObservation(proxy, mdp)
    built = make_joint_model([obs], 2.0, "sample_z", 1.0, samples, observation_model=model)
    got = built.log_density(w)
    want = brute_sample_z(w, proxy, samples, mdp, 2.0, model)
    np.testing.assert_allclose(got - got[0], want - want[0], rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("model", [ObservationModel("optimal"), ObservationModel("maxent", 0.5),
                                   ObservationModel("optimal", own_term=False)], ids=str)
def test_sample_z_gradient_matches_finite_differences_away_from_path_switches(model: ObservationModel) -> None:
    mdp, w = tiny(11)
    rng = np.random.default_rng(0)
    built = make_joint_model([posterior.ProxyObservation(rng.normal(size=w.shape[1]), mdp)], 2.0, "sample_z", 1.0,
                             rng.normal(size=(9, w.shape[1])), observation_model=model)
    _, grad = built.log_density_and_grad(w)
    eps = 1e-6
    for j in range(w.shape[1]):
        step = np.zeros_like(w)
        step[:, j] = eps
        if model.optimal:  # a difference quotient straddling a path switch is not the derivative
            same = np.all(optimal_feature_counts(mdp, w + step) == optimal_feature_counts(mdp, w - step), axis=1)
        else:
            same = np.ones(len(w), dtype=bool)
        numeric = (built.log_density(w + step) - built.log_density(w - step)) / (2 * eps)
        np.testing.assert_allclose(grad[same, j], numeric[same], rtol=1e-5, atol=1e-5)


def test_the_observation_model_refuses_bad_fields_by_name() -> None:
    with pytest.raises(ValueError, match="^counts:"):
        ObservationModel("soft")
    with pytest.raises(ValueError, match="^temperature:"):
        ObservationModel("maxent", 0.0)
    with pytest.raises(ValueError, match="^temperature:"):
        ObservationModel("maxent", float("nan"))
    with pytest.raises(ValueError, match="^own_term:"):
        ObservationModel("maxent", 1.0, "yes")  # type: ignore[arg-type]
    mdp, _ = tiny(1)
    with pytest.raises(ValueError, match="^observation_model:"):
        make_joint_model([posterior.ProxyObservation(np.zeros(mdp.num_features), mdp)], 1.0, "sample_z",
                         observation_model="optimal")  # type: ignore[arg-type]


def test_engine_choice_leaves_optimal_counts_unchanged(monkeypatch) -> None:
    rng = np.random.default_rng(1)
    mdp = GridMDP(rng.normal(size=(6, 7, 4)), (2, 3), 9)
    weights = rng.normal(size=(300, 4))  # more than one chunk
    monkeypatch.setenv("IRD_ENGINE", "numpy")
    a = optimal_feature_counts(mdp, weights)
    monkeypatch.setenv("IRD_ENGINE", "numba")
    b = optimal_feature_counts(mdp, weights)
    np.testing.assert_array_equal(a, b)
    assert os.environ["IRD_ENGINE"] == "numba"
