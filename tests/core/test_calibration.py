"""The calibrated designer (ird_core.posterior.calibration): the prior's scale follows the modelled
designer's temperature, sigma = 1 / temperature, wherever a caller leaves prior_sigma out (the
library, the experiments' specs and flags), an explicit sigma wins, and every posterior records
the sigma it used."""

from __future__ import annotations

import argparse

import numpy as np
import pytest

from ird_core import posterior
from ird_core.experiments import TrialSpec
from ird_core.experiments.active import ActiveSpec
from ird_core.experiments.cli import build_parser, trial_settings
from ird_core.mdp import GridMDP
from ird_core.posterior import ObservationModel, ProxyObservation, calibrated_prior_sigma, make_joint_model


def tiny() -> tuple[GridMDP, np.ndarray]:
    rng = np.random.default_rng(0)
    return GridMDP(rng.normal(size=(3, 3, 2)), (0, 0), 3), np.array([1.0, -0.5])


@pytest.mark.parametrize("temperature, sigma", [(0.2, 5.0), (0.5, 2.0), (1.0, 1.0), (4.0, 0.25)])
def test_the_rule_is_one_over_the_temperature(temperature: float, sigma: float) -> None:
    assert calibrated_prior_sigma(temperature) == pytest.approx(sigma)


@pytest.mark.parametrize("bad", [0.0, -1.0, float("nan"), float("inf")])
def test_a_bad_temperature_is_refused_naming_it(bad: float) -> None:
    with pytest.raises(ValueError, match="^temperature"):
        calibrated_prior_sigma(bad)


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
    assert built.prior_sigma == pytest.approx(1.0 / temperature)
    explicit = make_joint_model([ProxyObservation(proxy, mdp)], 10.0, method, 1.0 / temperature, seed=1,
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
    assert calibrated.prior_sigma == 2.0


def test_sample_z_draws_its_prior_proxies_at_the_calibrated_sigma() -> None:
    mdp, proxy = tiny()
    model = ObservationModel(temperature=0.25)
    a = posterior.proxy_observation(mdp, proxy, num_proxy_samples=30, seed=4, observation_model=model)
    b = posterior.proxy_observation(mdp, proxy, num_proxy_samples=30, seed=4, prior_sigma=4.0, observation_model=model)
    c = posterior.proxy_observation(mdp, proxy, num_proxy_samples=30, seed=4, prior_sigma=1.0, observation_model=model)
    np.testing.assert_array_equal(a.proxy_sample_features, b.proxy_sample_features)
    assert not np.array_equal(a.proxy_sample_features, c.proxy_sample_features)


def test_experiment_specs_resolve_sigma_from_their_temperature() -> None:
    assert TrialSpec("side_effects", 0).prior_sigma == pytest.approx(1.0 / posterior.CALIBRATED_TEMPERATURE)
    assert TrialSpec("side_effects", 0, temperature=0.5).prior_sigma == pytest.approx(2.0)
    assert TrialSpec("side_effects", 0, temperature=0.5, prior_sigma=1.0).prior_sigma == 1.0
    assert ActiveSpec("side_effects", 0, temperature=0.25).prior_sigma == pytest.approx(4.0)
    assert ActiveSpec("side_effects", 0).obs_dim == 50


@pytest.mark.parametrize("argv, sigma", [([], 5.0), (["--temperature", "0.5"], 2.0),
                                         (["--temperature", "0.5", "--prior-sigma", "1"], 1.0),
                                         (["--prior-sigma", "3"], 3.0)])
def test_the_experiment_flags_record_the_sigma_they_use(argv: list[str], sigma: float) -> None:
    args: argparse.Namespace = build_parser().parse_args(argv)
    assert trial_settings(args)["prior_sigma"] == pytest.approx(sigma)
