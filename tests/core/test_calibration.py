"""The calibrated designer (ird_core.posterior.calibration): the prior's scale follows the modelled
designer's temperature and the training features, sigma = 1 / (temperature * rms feature norm)
(1 / temperature for one-hot terrains), wherever a caller leaves prior_sigma out (the library, the
experiments' specs and flags), an explicit sigma wins, and every posterior records the sigma it
used. The rule makes the posterior over rewards independent of the features' units."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from ird_core import posterior
from ird_core.experiments import TrialSpec
from ird_core.experiments.active import ActiveSpec
from ird_core.experiments.cli import build_parser, trial_settings
from ird_core.mdp import GridMDP
from ird_core.posterior import ObservationModel, ProxyObservation, calibrated_prior_sigma, feature_scale, make_joint_model
from ird_core.worlds import lavaland


def tiny() -> tuple[GridMDP, np.ndarray]:
    rng = np.random.default_rng(0)
    return GridMDP(rng.normal(size=(3, 3, 2)), (0, 0), 3), np.array([1.0, -0.5])


@pytest.mark.parametrize("temperature, sigma", [(0.2, 5.0), (0.5, 2.0), (1.0, 1.0), (4.0, 0.25)])
def test_the_rule_is_one_over_the_temperature_for_unit_features(temperature: float, sigma: float) -> None:
    assert calibrated_prior_sigma(temperature) == pytest.approx(sigma)
    assert calibrated_prior_sigma(temperature, 2.0) == pytest.approx(sigma / 2)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_a_bad_temperature_or_scale_is_refused_naming_it(bad: float) -> None:
    with pytest.raises(ValueError, match="^temperature"):
        calibrated_prior_sigma(bad)
    with pytest.raises(ValueError, match="^scale"):
        calibrated_prior_sigma(0.2, bad)


def test_the_feature_scale_is_the_rms_norm_over_every_cell_of_every_map() -> None:
    one_hot = np.eye(4)[np.random.default_rng(0).integers(0, 4, size=(5, 6))]  # (5, 6, 4)
    assert feature_scale(one_hot) == 1.0  # exactly: sigma = 1 / temperature for terrain indicators
    a, b = np.full((2, 2, 3), 1.0), np.full((1, 4, 3), 2.0)  # norms sqrt(3) (4 cells) and 2 sqrt(3) (4 cells)
    assert feature_scale([a, b]) == pytest.approx(np.sqrt((4 * 3 + 4 * 12) / 8))
    for bad in ([], [np.zeros((2, 2, 3))], [np.full((1, 1, 2), np.nan)]):
        with pytest.raises(ValueError, match="^features"):
            feature_scale(bad)


def test_the_indicator_conditions_keep_one_over_the_temperature_and_the_latent_ones_scale_down() -> None:
    side = lavaland.make_instance("side_effects", 0)
    assert feature_scale(side.train_features) == 1.0
    latent = lavaland.make_instance("latent_raw", 0)
    scale = feature_scale(latent.train_features)
    assert 6.0 < scale < 10.0  # 50-d Gaussian observations: about sqrt(50 + |mu|^2)
    model = make_joint_model([ProxyObservation(latent.proxy_weights, lavaland.train_mdp(latent))], 1.0, "maxent_z")
    assert model.prior_sigma == pytest.approx(1.0 / (posterior.CALIBRATED_TEMPERATURE * scale))


@pytest.mark.parametrize("method", ["maxent_z", "sample_z"])
def test_rescaled_features_give_the_same_posterior_over_rewards(method: str) -> None:
    """Features c phi with the calibrated prior: w / c has the same log density as w under phi (up to
    the prior's normalising constant, which the unnormalised density leaves out), so the posterior
    over cell rewards does not depend on the features' units."""
    mdp, proxy = tiny()
    c = 3.0
    scaled = GridMDP(c * np.asarray(mdp.features), mdp.start, mdp.horizon)
    samples = np.random.default_rng(5).normal(size=(40, 2))
    base = make_joint_model([ProxyObservation(proxy, mdp)], 10.0, method, None, samples, seed=1)
    other = make_joint_model([ProxyObservation(proxy / c, scaled)], 10.0, method, None, samples / c, seed=1)
    assert other.prior_sigma == pytest.approx(base.prior_sigma / c)
    w = np.random.default_rng(2).normal(size=(6, 2)) * base.prior_sigma
    np.testing.assert_allclose(other.log_density(w / c), base.log_density(w), rtol=1e-9, atol=1e-9)


def test_the_default_designer_is_the_calibrated_one() -> None:
    assert posterior.ObservationModel().temperature == posterior.CALIBRATED_TEMPERATURE
    assert posterior.DEFAULT_OBSERVATION_MODEL.temperature == posterior.CALIBRATED_TEMPERATURE
    assert posterior.MAXENT_OBSERVATION_MODEL.temperature == 1.0


@pytest.mark.parametrize("method", ["maxent_z", "sample_z"])
@pytest.mark.parametrize("temperature", [0.2, 0.5])
def test_a_model_without_sigma_takes_its_observation_models_calibrated_sigma(method: str, temperature: float) -> None:
    mdp, proxy = tiny()
    model = ObservationModel(temperature=temperature)
    built = make_joint_model([ProxyObservation(proxy, mdp)], 10.0, method, None, seed=1, num_proxy_samples=20,
                             observation_model=model)
    sigma = 1.0 / (temperature * feature_scale(mdp.features))
    assert built.prior_sigma == pytest.approx(sigma)
    explicit = make_joint_model([ProxyObservation(proxy, mdp)], 10.0, method, sigma, seed=1,
                                num_proxy_samples=20, observation_model=model)
    w = np.random.default_rng(2).normal(size=(5, 2))
    np.testing.assert_array_equal(built.log_density(w), explicit.log_density(w))


@pytest.mark.filterwarnings("ignore:sample_posterior:RuntimeWarning")
def test_an_explicit_sigma_wins_and_is_recorded() -> None:
    mdp, proxy = tiny()
    post = posterior.sample_posterior(proxy, mdp, 10.0, "maxent_z", 8, 0, 3.0, num_chains=2, warmup=10, thin=1)
    assert post.prior_sigma == 3.0
    calibrated = posterior.sample_posterior(proxy, mdp, 10.0, "maxent_z", 8, 0, num_chains=2, warmup=10, thin=1,
                                            observation_model=ObservationModel(temperature=0.5))
    assert calibrated.prior_sigma == pytest.approx(2.0 / feature_scale(mdp.features))


def test_sample_z_draws_its_prior_proxies_at_the_calibrated_sigma() -> None:
    mdp, proxy = tiny()
    model = ObservationModel(temperature=0.25)
    a = posterior.proxy_observation(mdp, proxy, num_proxy_samples=30, seed=4, observation_model=model)
    sigma = 4.0 / feature_scale(mdp.features)
    b = posterior.proxy_observation(mdp, proxy, num_proxy_samples=30, seed=4, prior_sigma=sigma, observation_model=model)
    c = posterior.proxy_observation(mdp, proxy, num_proxy_samples=30, seed=4, prior_sigma=1.0, observation_model=model)
    np.testing.assert_array_equal(a.proxy_sample_features, b.proxy_sample_features)
    assert not np.array_equal(a.proxy_sample_features, c.proxy_sample_features)


def test_experiment_specs_resolve_sigma_per_instance_from_their_temperature() -> None:
    side = lavaland.make_instance("side_effects", 0)
    latent = lavaland.make_instance("latent_raw", 0)
    assert TrialSpec("side_effects", 0).prior_sigma is None  # calibrated, per instance
    assert TrialSpec("side_effects", 0).prior_sigma_for(side) == pytest.approx(1.0 / posterior.CALIBRATED_TEMPERATURE)
    assert TrialSpec("side_effects", 0, temperature=0.5).prior_sigma_for(side) == pytest.approx(2.0)
    assert TrialSpec("latent_raw", 0, temperature=0.5).prior_sigma_for(latent) == \
        pytest.approx(2.0 / feature_scale(latent.train_features))
    assert TrialSpec("side_effects", 0, temperature=0.5, prior_sigma=1.0).prior_sigma_for(latent) == 1.0
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(ValueError, match="prior_sigma"):
            TrialSpec("side_effects", 0, prior_sigma=bad)
    assert ActiveSpec("side_effects", 0, temperature=0.25).prior_sigma is None
    assert ActiveSpec("side_effects", 0).obs_dim == 50


@pytest.mark.parametrize("argv, sigma", [([], None), (["--temperature", "0.5"], None),
                                         (["--temperature", "0.5", "--prior-sigma", "1"], 1.0),
                                         (["--prior-sigma", "3"], 3.0)])
def test_the_experiment_flags_record_the_sigma_they_use(argv: list[str], sigma: "float | None") -> None:
    """None is recorded as None: the calibrated rule, resolved per instance (run.json says so)."""
    args: argparse.Namespace = build_parser().parse_args(argv)
    assert trial_settings(args)["prior_sigma"] == sigma
