"""The random-Fourier-feature hypothesis space (ird_core.hypothesis.rff): its kernel
is the RBF kernel up to a Monte-Carlo error that shrinks with D, it is seeded, training and test
cells go through the same map, the proxy and the literal plan are untouched, and a test cell far
from every training observation keeps the prior's spread while a training-like cell's shrinks."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from ird_core import planning, posterior
from ird_core.experiments import cli, trials
from ird_core.hypothesis import rff as kh
from ird_core.worlds import lavaland


def _points(seed: int, n: int = 40, p: int = 5) -> np.ndarray:
    return np.random.default_rng(seed).normal(size=(n, p))


def test_the_features_kernel_approximates_the_rbf_kernel_with_an_error_shrinking_in_d() -> None:
    x = _points(0)
    exact = kh.rbf_kernel(x, x, 2.0)
    errors = []
    for num in (25, 400, 6400):
        # the mean over independent maps of the RMS error, so the trend is not one draw's luck
        rms = [np.sqrt(np.mean((z @ z.T - exact) ** 2)) for z in
               (kh.fourier_map(5, num, 2.0, seed)(x) for seed in range(5))]
        errors.append(float(np.mean(rms)))
    assert errors[0] > errors[1] > errors[2]
    # O(1 / sqrt D): 16x the features, about a quarter of the error (within a factor 2)
    for coarse, fine in zip(errors, errors[1:]):
        assert 0.125 < fine / coarse < 0.5
    assert errors[2] < 0.02
    z = kh.fourier_map(5, 6400, 2.0, 1)(x)
    np.testing.assert_allclose(np.sum(z**2, axis=1), 1.0, atol=0.05)  # k(x, x) = 1: the prior's variance


def test_the_map_is_seeded() -> None:
    x = _points(1)
    a, b = kh.fourier_map(5, 30, 1.5, 7), kh.fourier_map(5, 30, 1.5, 7)
    np.testing.assert_array_equal(a(x), b(x))
    assert not np.allclose(a(x), kh.fourier_map(5, 30, 1.5, 8)(x))
    inst = lavaland.make_instance("latent_raw", 3, size=6, horizon=6, obs_dim=6)
    np.testing.assert_array_equal(kh.with_rff_hypothesis(inst, 20).test_features,
                                  kh.with_rff_hypothesis(inst, 20).test_features)


def test_shapes_and_validation_name_the_field() -> None:
    z = kh.fourier_map(4, 12, 1.0, 0)
    assert z(np.zeros((3, 5, 4))).shape == (3, 5, 12) and z.num_features == 12 and z.input_dim == 4
    with pytest.raises(ValueError, match="x:"):
        z(np.zeros((3, 5)))
    with pytest.raises(ValueError, match="num_features"):
        kh.fourier_map(4, 0, 1.0, 0)
    with pytest.raises(ValueError, match="input_dim"):
        kh.fourier_map(0, 3, 1.0, 0)
    with pytest.raises(ValueError, match="length_scale"):
        kh.fourier_map(4, 3, 0.0, 0)
    with pytest.raises(ValueError, match="offset"):
        kh.FourierMap(np.zeros((3, 2)), np.zeros(2), 1.0)
    with pytest.raises(ValueError, match="omega"):
        kh.FourierMap(np.zeros(3), np.zeros(3), 1.0)
    with pytest.raises(ValueError, match="train_features"):
        kh.median_length_scale(np.ones((1, 4)))
    with pytest.raises(ValueError, match="train_features"):
        kh.median_length_scale(np.ones((5, 4)))
    with pytest.raises(ValueError, match="factor"):
        kh.median_length_scale(_points(0), factor=-1.0)
    inst = lavaland.make_instance("latent_raw", 3, size=6, horizon=6, obs_dim=6)
    with pytest.raises(ValueError, match="num_features"):
        kh.with_rff_hypothesis(inst, 0)
    with pytest.raises(ValueError, match="feature_names"):
        kh.with_rff_hypothesis(kh.with_rff_hypothesis(inst, 8), 8)
    with pytest.raises(ValueError, match="hypothesis"):
        kh.hypothesis_instance(inst, "quadratic")
    with pytest.raises(ValueError, match="hypothesis"):
        trials.TrialSpec("latent_raw", 0, hypothesis="quadratic")
    with pytest.raises(ValueError, match="rff_features"):
        trials.TrialSpec("latent_raw", 0, hypothesis="rff", rff_features=0)


def test_the_median_rule_reads_the_training_observations_only() -> None:
    x = _points(2, n=30)
    gaps = np.linalg.norm(x[:, None] - x[None], axis=-1)[np.triu_indices(30, k=1)]
    assert kh.median_length_scale(x, factor=1.0) == pytest.approx(np.median(gaps))
    assert kh.median_length_scale(x, factor=2.0) == pytest.approx(2.0 * np.median(gaps))
    inst = lavaland.make_instance("latent_raw", 3, size=6, horizon=6, obs_dim=6)
    moved = dataclasses.replace(inst, test_features=inst.test_features + 100.0)  # the test map moves far away
    np.testing.assert_array_equal(kh.with_rff_hypothesis(moved, 16).train_features,
                                  kh.with_rff_hypothesis(inst, 16).train_features)


@pytest.mark.parametrize("condition", ["latent_raw", "latent_classifier"])
def test_training_and_test_columns_come_from_the_same_map_and_the_proxy_is_untouched(condition: str) -> None:
    inst = lavaland.make_instance(condition, 5, size=6, horizon=6, obs_dim=6)
    extra = lavaland.TrainingWorld(inst.train_labels, inst.train_features[::-1], inst.proxy_train_features[::-1],
                                   inst.train_start, inst.train_horizon, inst.proxy_weights)
    inst = dataclasses.replace(inst, extra_training_worlds=(extra,))
    rff = kh.with_rff_hypothesis(inst, 24)
    scale = kh.median_length_scale([inst.train_features, extra.features])
    z = kh.fourier_map(inst.num_features, 24, scale, np.random.SeedSequence([inst.seed, kh.RFF_STREAM]))
    np.testing.assert_array_equal(rff.train_features, z(inst.train_features))
    np.testing.assert_array_equal(rff.test_features, z(inst.test_features))
    np.testing.assert_array_equal(rff.extra_training_worlds[0].features, z(extra.features))
    assert rff.feature_names == tuple(f"rff_{i:03d}" for i in range(24))
    assert rff.proxy_feature_names == inst.proxy_feature_names
    np.testing.assert_array_equal(rff.proxy_weights, inst.proxy_weights)
    np.testing.assert_array_equal(rff.proxy_test_features, inst.proxy_test_features)
    # the proxy's behaviour is planned on its own features and counted in the new ones
    counts = posterior.proxy_feature_expectations(rff)
    assert counts.shape == (24,)
    literal = planning.plan_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights[None], "literal")
    again = planning.plan_path(lavaland.test_mdp(rff, proxy=True), rff.proxy_weights[None], "literal")
    assert literal.cells == again.cells


def test_the_indicator_conditions_keep_their_features() -> None:
    inst = lavaland.make_instance("side_effects", 5, size=6, horizon=6)
    assert kh.hypothesis_instance(inst, "rff") is inst
    raw = lavaland.make_instance("latent_raw", 5, size=6, horizon=6, obs_dim=6)
    assert kh.hypothesis_instance(raw, "linear") is raw


def test_a_far_cell_keeps_the_prior_spread_and_a_training_like_cell_shrinks() -> None:
    """latent_raw on a small map: one test cell is moved far from every training observation. The
    spread of its reward relative to the training-features baseline (what the planner compares)
    stays near the prior's; a test cell with a training cell's observation is pinned down."""
    sigma, num = 2.0, 64
    inst = lavaland.make_instance("latent_raw", 11, size=6, horizon=8, obs_dim=6)
    test = np.array(inst.test_features)
    centre = inst.train_features.reshape(-1, 6).mean(axis=0)
    test[0, 0] = centre + 30.0 * kh.median_length_scale(inst.train_features)  # far along every axis
    test[0, 1] = inst.train_features[inst.train_start]  # the start cell the proxy's behaviour visits
    rff = kh.with_rff_hypothesis(dataclasses.replace(inst, test_features=test), num)
    spec = trials.TrialSpec("latent_raw", 11, size=6, horizon=8, obs_dim=6, num_samples=256, prior_sigma=sigma,
                            num_chains=4, warmup=100, thin=2, max_leapfrog=16, factorial=False,
                            z_methods=("maxent_z",), sample_z_sampler=None, maxent_z_sampler=None)
    post = trials.trial_posterior(spec, rff, "maxent_z")
    reference = posterior.proxy_feature_expectations(rff) / (rff.train_horizon + 1)
    relative = rff.test_features[0, :2] - reference  # (2, D): far cell, training-like cell
    posterior_sd = (post.samples @ relative.T).std(axis=0)
    prior_sd = sigma * np.linalg.norm(relative, axis=1)
    ratio = posterior_sd / prior_sd
    assert ratio[0] > 0.8, f"the far cell's spread shrank to {ratio[0]:.2f} of the prior's"
    assert ratio[1] < 0.5 * ratio[0], f"the training-like cell kept {ratio[1]:.2f} of the prior's spread"


def test_the_flags_reach_the_spec_and_the_report_settings(tmp_path) -> None:
    args = cli.build_parser().parse_args(["--hypothesis", "rff", "--rff-features", "32", "--quick"])
    settings = cli.trial_settings(args)
    assert settings["hypothesis"] == "rff" and settings["rff_features"] == 32
    spec = trials.TrialSpec("latent_raw", 0, **settings)
    assert trials.trial_instance(spec).num_features == 32
    plain = cli.trial_settings(cli.build_parser().parse_args(["--quick"]))
    assert "hypothesis" not in plain  # the paper's space unless asked: old run.json files stay comparable


def test_a_trial_in_the_rff_space_keeps_the_literal_and_oracle_rows() -> None:
    tiny = dict(size=5, horizon=5, obs_dim=4, num_samples=16, num_chains=2, warmup=10, thin=1, max_leapfrog=4,
                num_proxy_samples=20, factorial_samples=16, factorial=False, sample_z_sampler=None,
                maxent_z_sampler=None)
    plain = trials.run_trial(trials.TrialSpec(condition="latent_classifier", seed=4, **tiny))
    rff = trials.run_trial(trials.TrialSpec(condition="latent_classifier", seed=4, hypothesis="rff",
                                            rff_features=12, **tiny))
    assert [r.cells for r in plain if r.planner in ("literal", "oracle")] == \
        [r.cells for r in rff if r.planner in ("literal", "oracle")]
    assert {r.planner for r in rff} == {r.planner for r in plain}
