"""ird_core.posterior.proxy_observation: the one builder of proxy observations reproduces the
Lavaland conveniences and the draws of ``proxy_prior_samples`` bit for bit."""

from __future__ import annotations

import numpy as np

from ird_core import posterior
from ird_core.worlds import lavaland


def test_builder_with_a_proxy_map_equals_the_lavaland_conveniences() -> None:
    inst = lavaland.make_instance("latent_classifier", 3, size=5, horizon=5, obs_dim=6)
    train, proxy = lavaland.train_mdp(inst), lavaland.train_mdp(inst, proxy=True)
    obs = posterior.proxy_observation(train, inst.proxy_weights, proxy_mdp=proxy, num_proxy_samples=12, seed=4,
                                      prior_sigma=0.5)
    assert np.array_equal(obs.proxy_features, posterior.proxy_feature_expectations(inst))
    assert np.array_equal(obs.proxy_sample_features, posterior.proxy_prior_features(inst, 12, 4, 0.5))
    samples = posterior.proxy_prior_samples(12, proxy.num_features, 0.5, 4)
    assert np.array_equal(obs.proxy_sample_features, posterior.proxy_feature_counts(proxy, samples, train.features))


def test_builder_without_a_proxy_map_matches_the_lazy_evidence() -> None:
    inst = lavaland.make_instance("side_effects", 3, size=5, horizon=5)
    train = lavaland.train_mdp(inst)
    built = posterior.proxy_observation(train, inst.proxy_weights, num_proxy_samples=10, seed=2, prior_sigma=0.7)
    lazy = posterior.ProxyObservation(inst.proxy_weights, train)
    a = posterior.make_joint_model([built], 2.0, "sample_z", 0.7, seed=2, num_proxy_samples=10)
    b = posterior.make_joint_model([lazy], 2.0, "sample_z", 0.7, seed=2, num_proxy_samples=10)
    assert np.array_equal(a.proxy_features, b.proxy_features)
    assert np.array_equal(a.sample_features, b.sample_features)
    assert posterior.proxy_observation(train, inst.proxy_weights).proxy_sample_features is None
