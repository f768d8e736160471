"""The *novel* hypothesis feature (ird_core.hypothesis.novelty): zero in training,
the novelty rule on the test map at the training cells' rms feature norm (so the calibrated prior
gives a novel cell the reward spread 1 / temperature, and rescaled observations rescale it),
invisible to the proxy's behaviour, so its weight keeps its prior; the literal plan does not
change."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from ird_core import planning, posterior
from ird_core.experiments import cli, trials
from ird_core.hypothesis.novelty import NOVELTY_FEATURE, with_novelty_feature
from ird_core.planning.novelty import novel_cells
from ird_core.posterior import CALIBRATED_TEMPERATURE, feature_scale
from ird_core.worlds import lavaland
from ird_core.worlds.terrain import Terrain


@pytest.fixture(scope="module", params=["side_effects", "latent_raw", "latent_classifier"])
def pair(request) -> tuple[lavaland.LavalandInstance, lavaland.LavalandInstance]:
    inst = lavaland.make_instance(request.param, 2, size=7, horizon=8, obs_dim=6)
    return inst, with_novelty_feature(inst)


def test_the_feature_is_zero_in_training_and_the_novelty_rule_on_the_test_map(pair) -> None:
    inst, novel = pair
    assert novel.feature_names == (*inst.feature_names, NOVELTY_FEATURE)
    np.testing.assert_array_equal(novel.train_features[..., :-1], inst.train_features)
    np.testing.assert_array_equal(novel.test_features[..., :-1], inst.test_features)
    assert not novel.train_features[..., -1].any()
    expected = novel_cells(inst.train_features, inst.test_features) * feature_scale(inst.train_features)
    np.testing.assert_array_equal(novel.test_features[..., -1], expected)
    if inst.observation_model is not None:  # latent: lava's observations lie far from the safe terrains'
        lava = inst.test_labels == Terrain.LAVA
        assert novel.test_features[..., -1][lava].all(), "lava is unlike every training cell"


def test_a_novel_cell_gets_the_calibrated_reward_spread_of_a_training_cell(pair) -> None:
    """sigma = 1 / (temperature * rms norm) times the value (the rms norm) is 1 / temperature: the
    novel weight gives a novel cell the prior reward spread the rule gives a training cell. With
    terrain indicators no test cell is novel (every two terrains are equally far apart)."""
    inst, novel = pair
    values = novel.test_features[..., -1]
    if inst.observation_model is None:
        assert not values.any()
        return
    assert values.any(), "the latent test map has novel cells (lava at least)"
    sigma = trials.TrialSpec(condition="latent_raw", seed=0).prior_sigma_for(novel)
    np.testing.assert_allclose(sigma * values[values > 0], 1.0 / CALIBRATED_TEMPERATURE, rtol=1e-12)


def test_rescaled_observations_rescale_the_feature_and_keep_the_same_cells(pair) -> None:
    inst, novel = pair
    c = 3.5
    scaled = with_novelty_feature(dataclasses.replace(inst, train_features=c * inst.train_features,
                                                      test_features=c * inst.test_features))
    np.testing.assert_allclose(scaled.test_features[..., -1], c * novel.test_features[..., -1], rtol=1e-12)
    spec = trials.TrialSpec(condition="latent_raw", seed=0)
    assert spec.prior_sigma_for(scaled) == pytest.approx(spec.prior_sigma_for(novel) / c, rel=1e-12)


def test_the_proxy_is_untouched_and_its_behaviour_has_no_novel_count(pair) -> None:
    inst, novel = pair
    assert novel.proxy_feature_names == inst.proxy_feature_names
    np.testing.assert_array_equal(novel.proxy_weights, inst.proxy_weights)
    before = posterior.proxy_feature_expectations(inst)
    after = posterior.proxy_feature_expectations(novel)
    np.testing.assert_allclose(after[:-1], before, rtol=1e-12, atol=1e-12)
    assert after[-1] == 0.0
    literal = planning.plan_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights[None], "literal")
    again = planning.plan_path(lavaland.test_mdp(novel, proxy=True), novel.proxy_weights[None], "literal")
    assert literal.cells == again.cells


@pytest.mark.parametrize("method", ["maxent_z", "sample_z"])
def test_the_novel_weight_moves_the_log_posterior_only_through_the_prior(pair, method: str) -> None:
    _, novel = pair
    observations = posterior.proxy_observations(novel, 50 if method == "sample_z" else None, seed=1)
    model = posterior.make_joint_model(observations, 50.0, method, 1.0)
    rng = np.random.default_rng(0)
    weights = rng.normal(size=(6, novel.num_features))
    shifted = weights.copy()
    shifted[:, -1] += rng.normal(scale=2.0, size=6)
    prior_gap = -0.5 * (shifted[:, -1] ** 2 - weights[:, -1] ** 2)
    np.testing.assert_allclose(model.log_density(shifted) - model.log_density(weights), prior_gap,
                               rtol=1e-9, atol=1e-9)


def test_the_value_one_keeps_the_bare_novelty_rule_and_a_bad_value_is_refused_naming_it(pair) -> None:
    inst, _ = pair
    ones = with_novelty_feature(inst, "one")
    np.testing.assert_array_equal(ones.test_features[..., -1], novel_cells(inst.train_features, inst.test_features))
    with pytest.raises(ValueError, match="^value"):
        with_novelty_feature(inst, "two")
    with pytest.raises(ValueError, match="^novelty_value"):
        trials.TrialSpec("latent_raw", 0, novelty_value="two")


def test_the_flags_reach_the_spec_and_the_report_states_the_value(tmp_path) -> None:
    settings = cli.trial_settings(cli.build_parser().parse_args(["--novelty-feature", "--novelty-value", "one"]))
    spec = trials.TrialSpec("latent_raw", 2, size=7, horizon=8, obs_dim=6, **{
        k: v for k, v in settings.items() if k not in ("size", "horizon", "obs_dim")})
    assert spec.novelty_feature and spec.novelty_value == "one"
    assert set(np.unique(trials.trial_instance(spec).test_features[..., -1])) == {0.0, 1.0}
    assert cli.main(["--novelty-feature", "--quick", "--trials", "1", "--conditions", "latent_raw",
                     "--z-methods", "maxent_z", "--no-factorial", "--workers", "1", "--out", str(tmp_path)]) == 0
    assert json.loads((tmp_path / "run.json").read_text())["settings"]["novelty_value"] == "feature_scale"


def test_a_second_novel_feature_is_refused_naming_the_field(pair) -> None:
    _, novel = pair
    with pytest.raises(ValueError, match="feature_names"):
        with_novelty_feature(novel)


def test_extra_training_worlds_get_a_zero_column() -> None:
    inst = lavaland.make_instance("side_effects", 1, size=6, horizon=6)
    extra = lavaland.TrainingWorld(inst.train_labels, inst.train_features, inst.proxy_train_features,
                                   inst.train_start, inst.train_horizon, inst.proxy_weights)
    novel = with_novelty_feature(dataclasses.replace(inst, extra_training_worlds=(extra,)))
    world = novel.extra_training_worlds[0]
    assert world.features.shape[-1] == novel.num_features and not world.features[..., -1].any()


def test_a_trial_with_the_feature_keeps_the_literal_row_and_plans_in_d_plus_one() -> None:
    tiny = dict(size=5, horizon=5, obs_dim=4, num_samples=16, num_chains=2, warmup=10, thin=1, max_leapfrog=4,
                num_proxy_samples=20, factorial_samples=16, factorial=False, sample_z_sampler=None,
                maxent_z_sampler=None)
    plain = trials.run_trial(trials.TrialSpec(condition="latent_raw", seed=4, **tiny))
    novel = trials.run_trial(trials.TrialSpec(condition="latent_raw", seed=4, novelty_feature=True, **tiny))
    assert [r.cells for r in plain if r.planner in ("literal", "oracle")] == \
        [r.cells for r in novel if r.planner in ("literal", "oracle")]
    spec = trials.TrialSpec(condition="latent_raw", seed=4, novelty_feature=True, **tiny)
    assert trials.trial_instance(spec).num_features == 5
