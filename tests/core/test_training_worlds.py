"""More Lavaland training worlds (ird_core.worlds.training_worlds): the one-world instance is kept
(paired by seed), each extra world is drawn as the first one is and seeded apart from the
instance's own streams, the posterior conditions on the proxy in every world, and the
experiments' flag reaches the trial."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from ird_core import posterior
from ird_core.experiments import cli, trials
from ird_core.worlds import lavaland
from ird_core.worlds.terrain import TRAIN_MAP, Terrain
from ird_core.worlds.training_worlds import MAX_TRAINING_WORLDS, with_training_worlds

SMALL = dict(size=8, horizon=10, obs_dim=6)


@pytest.fixture(scope="module", params=["side_effects", "reward_hacking", "pot_of_gold", "latent_raw",
                                        "latent_classifier"])
def pair(request) -> tuple[lavaland.LavalandInstance, lavaland.LavalandInstance]:
    inst = lavaland.make_instance(request.param, 3, **SMALL)
    return inst, with_training_worlds(inst, 3)


def test_one_world_is_the_instance_itself() -> None:
    inst = lavaland.make_instance("latent_raw", 0, **SMALL)
    assert with_training_worlds(inst, 1) is inst


def test_the_first_world_test_map_and_proxy_are_the_one_world_instance(pair) -> None:
    inst, more = pair
    for name in ("train_labels", "test_labels", "train_features", "test_features", "proxy_train_features",
                 "proxy_test_features", "proxy_weights"):
        np.testing.assert_array_equal(getattr(more, name), getattr(inst, name), err_msg=name)
    assert (more.train_start, more.test_start, more.proxy_intercept) == \
        (inst.train_start, inst.test_start, inst.proxy_intercept)
    assert len(more.extra_training_worlds) == 2 and len(more.training_maps) == 3


def test_each_extra_world_is_drawn_like_the_first(pair) -> None:
    inst, more = pair
    reach = (3 * inst.train_horizon) // 4
    for world in more.extra_training_worlds:
        assert world.labels.shape == inst.train_labels.shape and world.horizon == inst.train_horizon
        assert np.count_nonzero(world.labels == Terrain.TARGET) == 1
        assert not np.isin(world.labels, (Terrain.LAVA, Terrain.GOLD)).any(), "training never shows lava or gold"
        assert world.labels[world.start] != Terrain.TARGET
        target = np.argwhere(world.labels == Terrain.TARGET)[0]
        assert abs(world.start[0] - target[0]) + abs(world.start[1] - target[1]) <= reach
        np.testing.assert_array_equal(world.proxy_weights, inst.proxy_weights)
        if inst.observation_model is None:
            np.testing.assert_array_equal(world.features, lavaland.indicator_features(inst.condition, world.labels))
            np.testing.assert_array_equal(world.proxy_features, world.features)
        elif inst.classifier is None:  # latent_raw: the proxy reads the observations themselves
            assert world.features.shape == inst.train_features.shape
            np.testing.assert_array_equal(world.proxy_features, world.features)
        else:
            np.testing.assert_array_equal(world.proxy_features, inst.classifier.predict_proba(world.features))
    first, second = more.extra_training_worlds
    assert not np.array_equal(first.labels, second.labels) or not np.array_equal(first.features, second.features)


def test_the_indicator_features_are_the_instances_own() -> None:
    for condition in ("side_effects", "reward_hacking", "pot_of_gold"):
        inst = lavaland.make_instance(condition, 5, **SMALL)
        np.testing.assert_array_equal(lavaland.indicator_features(condition, inst.train_labels), inst.train_features)
    with pytest.raises(ValueError, match="^condition"):
        lavaland.indicator_features("latent_raw", np.zeros((3, 3), dtype=np.int8))


def test_world_i_does_not_depend_on_how_many_follow_and_the_seed_decides() -> None:
    inst = lavaland.make_instance("latent_classifier", 7, **SMALL)
    two, four = with_training_worlds(inst, 2), with_training_worlds(inst, 4)
    again = with_training_worlds(lavaland.make_instance("latent_classifier", 7, **SMALL), 4)
    other = with_training_worlds(lavaland.make_instance("latent_classifier", 8, **SMALL), 2)
    for a, b in ((two.extra_training_worlds[0], four.extra_training_worlds[0]),
                 *zip(four.extra_training_worlds, again.extra_training_worlds)):
        np.testing.assert_array_equal(a.features, b.features)
        assert a.start == b.start
    assert not np.array_equal(two.extra_training_worlds[0].features, other.extra_training_worlds[0].features)


@pytest.mark.parametrize("count", [0, -1, MAX_TRAINING_WORLDS + 1, True, 2.0, "3", None])
def test_a_bad_count_is_refused_naming_the_field(count) -> None:
    inst = lavaland.make_instance("side_effects", 0, **SMALL)
    with pytest.raises(ValueError, match="^training_worlds"):
        with_training_worlds(inst, count)
    with pytest.raises(ValueError, match="^training_worlds"):
        trials.TrialSpec("side_effects", 0, training_worlds=count)


def test_an_instance_that_has_extra_worlds_is_refused() -> None:
    more = with_training_worlds(lavaland.make_instance("side_effects", 0, **SMALL), 2)
    with pytest.raises(ValueError, match="^training_worlds"):
        with_training_worlds(more, 2)
    with pytest.raises(ValueError, match="^training_worlds"):
        trials.TrialSpec("file", 0, world="worlds/lava_detour.yaml", training_worlds=2)


def test_the_posterior_conditions_on_the_proxy_in_every_world() -> None:
    """The joint MaxEnt-Z log density is the prior plus one likelihood term per world: the sum
    over the one-world views, each with the prior taken out once."""
    more = with_training_worlds(lavaland.make_instance("latent_raw", 1, **SMALL), 3)
    observations = posterior.proxy_observations(more)
    assert len(observations) == 3
    sigma = 2.0
    weights = np.random.default_rng(0).normal(size=(5, more.num_features))
    joint = posterior.make_joint_model(observations, 5.0, "maxent_z", sigma).log_density(weights)
    each = [posterior.make_joint_model([o], 5.0, "maxent_z", sigma).log_density(weights) for o in observations]
    prior = posterior.log_prior(weights, sigma)
    np.testing.assert_allclose(joint, sum(each) - 2 * prior, rtol=1e-12, atol=1e-9)


def test_the_flag_reaches_the_trial_and_the_report(tmp_path) -> None:
    args = cli.build_parser().parse_args(["--training-worlds", "3"])
    settings = cli.trial_settings(args)
    assert settings["training_worlds"] == 3
    spec = trials.TrialSpec("latent_raw", 2, **dict(settings, **SMALL))
    assert len(trials.trial_instance(spec).extra_training_worlds) == 2
    assert cli.main(["--training-worlds", "2", "--quick", "--trials", "1", "--conditions", "side_effects",
                     "--z-methods", "maxent_z", "--no-factorial", "--workers", "1", "--out", str(tmp_path)]) == 0
    assert json.loads((tmp_path / "run.json").read_text())["settings"]["training_worlds"] == 2
    assert cli.main(["--training-worlds", "0", "--quick", "--out", str(tmp_path / "bad")]) == 2


def test_a_one_world_trial_is_the_default_trial_bit_for_bit() -> None:
    tiny = dict(SMALL, num_samples=16, num_chains=2, warmup=10, thin=1, max_leapfrog=4, num_proxy_samples=20,
                factorial_samples=16, factorial=False, sample_z_sampler=None, maxent_z_sampler=None)
    plain = trials.run_trial(trials.TrialSpec("latent_raw", 4, **tiny))
    one = trials.run_trial(trials.TrialSpec("latent_raw", 4, training_worlds=1, **tiny))
    three = trials.run_trial(trials.TrialSpec("latent_raw", 4, training_worlds=3, **tiny))
    strip = lambda rows: [dataclasses.replace(r, infer_seconds=0.0) for r in rows]  # noqa: E731
    assert strip(plain) == strip(one)
    assert [r.cells for r in three if r.planner in ("literal", "oracle")] == \
        [r.cells for r in plain if r.planner in ("literal", "oracle")]


def test_the_extra_worlds_follow_the_training_map_distribution_given() -> None:
    """An instance made from another training distribution passes it on: two targets per map."""
    two = dataclasses.replace(TRAIN_MAP, num_targets=2)
    inst = lavaland.make_instance("side_effects", 2, train_map=two, **SMALL)
    more = with_training_worlds(inst, 3, train_map=two)
    assert [np.count_nonzero(w.labels == Terrain.TARGET) for w in more.extra_training_worlds] == [2, 2]
    assert np.count_nonzero(with_training_worlds(inst, 2).extra_training_worlds[0].labels == Terrain.TARGET) == 1
