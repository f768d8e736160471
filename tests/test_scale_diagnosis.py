"""The scale diagnosis (ird_core.experiments.scale, scripts/diagnose_scale.py): its numbers are the
experiments' own, checked against brute force and against run_trial on tiny maps."""

from __future__ import annotations

import argparse
import csv
import dataclasses

import numpy as np
import pytest

from ird_core import planning, posterior
from ird_core.experiments import scale, scale_cli, trials
from ird_core.worlds import lavaland
from ird_core.worlds.terrain import Terrain

TINY = dict(size=5, horizon=5, obs_dim=4, num_samples=16, num_chains=2, warmup=10, thin=1, max_leapfrog=4,
            num_proxy_samples=20, factorial_samples=16, factorial=False, sample_z_sampler=None, maxent_z_sampler=None)


def test_lava_values_are_each_weights_value_of_the_lava_mean_minus_the_dirt_mean() -> None:
    rng = np.random.default_rng(0)
    labels = np.array([[0, 3, 1], [3, 0, 2]])
    features = rng.normal(size=(2, 3, 4))
    weights = rng.normal(size=(5, 4))
    lava = (features[0, 1] + features[1, 0]) / 2
    dirt = (features[0, 0] + features[1, 1]) / 2
    expected = [float(w @ lava - w @ dirt) for w in weights]
    np.testing.assert_allclose(scale.lava_values(features, labels, weights), expected, rtol=1e-12)


def test_a_map_without_lava_is_refused_naming_the_terrain() -> None:
    with pytest.raises(ValueError, match=f"terrain {int(Terrain.LAVA)}"):
        scale.lava_values(np.zeros((2, 2, 3)), np.zeros((2, 2), dtype=int), np.ones((1, 3)))


def test_target_signal_is_the_mean_rewards_target_minus_median_dirt_over_the_dirt_spread() -> None:
    rng = np.random.default_rng(1)
    labels = np.array([[0, 2, 1], [0, 0, 2], [1, 0, 3]])
    features = rng.normal(size=(3, 3, 4))
    weights = rng.normal(size=(6, 4))
    mean_reward = {(r, c): float(np.mean([w @ features[r, c] for w in weights])) for r in range(3) for c in range(3)}
    dirt = [mean_reward[cell] for cell in [(0, 0), (1, 0), (1, 1), (2, 1)]]
    target = (mean_reward[(0, 1)] + mean_reward[(1, 2)]) / 2
    expected = (target - np.median(dirt)) / np.std(dirt)
    assert scale.target_signal(features, labels, weights) == pytest.approx(expected, rel=1e-12)
    # one weight vector is the proxy's case; the sign follows the target
    assert scale.target_signal(features, labels, -weights[0]) == pytest.approx(
        -scale.target_signal(features, labels, weights[0]), rel=1e-12)


def test_target_signal_on_indicator_features_is_infinite_in_the_targets_direction() -> None:
    labels = np.array([[0, 0, 2]])
    features = np.eye(3)[labels]
    assert scale.target_signal(features, labels, np.array([0.1, -0.2, 1.0])) == np.inf
    assert scale.target_signal(features, labels, np.array([0.1, -0.2, -1.0])) == -np.inf
    assert np.isnan(scale.target_signal(features, labels, np.array([0.5, 0.0, 0.5])))
    # dirt cells one rounding step apart are still the same reward (a matrix product may do that)
    rounded = features.copy()
    rounded[0, 1, 0] = np.nextafter(1.0, 2.0)
    assert scale.target_signal(rounded, labels, np.array([0.1, -0.2, 1.0])) == np.inf


@pytest.mark.parametrize("terrain", [Terrain.TARGET, Terrain.DIRT])
def test_target_signal_without_a_target_or_dirt_cell_is_refused_naming_the_terrain(terrain: Terrain) -> None:
    labels = np.full((2, 2), int(Terrain.GRASS))
    labels[0, 0] = int(Terrain.TARGET if terrain == Terrain.DIRT else Terrain.DIRT)
    with pytest.raises(ValueError, match=f"terrain {int(terrain)}"):
        scale.target_signal(np.ones((2, 2, 3)), labels, np.ones((1, 3)))


@pytest.mark.parametrize("condition", ["side_effects", "latent_raw"])
@pytest.mark.parametrize("method", trials.Z_METHODS)
def test_the_diagnosis_describes_the_plan_the_experiments_score(condition: str, method: str) -> None:
    spec = trials.TrialSpec(condition=condition, seed=3, z_methods=(method,), **TINY)
    row = scale.diagnose(spec, method)
    main = next(r for r in trials.run_trial(spec) if r.planner == f"ird_{method}")
    labels = lavaland.make_instance(condition, 3, size=5, horizon=5, obs_dim=4).test_labels
    assert row.lava_steps == sum(labels[c] == Terrain.LAVA for c in main.cells)
    assert (row.lava_steps > 0) == main.touched_lava
    assert row.parked == (labels[main.cells[-1]] == Terrain.LAVA)
    assert 1 <= row.lava_cells <= row.lava_steps or row.lava_steps == row.lava_cells == 0
    assert row.r_hat_max == main.r_hat_max
    assert row.reached_target == main.reached_target
    assert 0.0 <= row.share_below <= 1.0 and row.lava_value_sd >= 0.0
    again = scale.diagnose(spec, method)  # seeded: the same numbers but the time
    assert dataclasses.replace(again, infer_seconds=0.0) == dataclasses.replace(row, infer_seconds=0.0)


def test_the_indicator_conditions_lava_value_is_the_lava_weight_minus_the_dirt_weight() -> None:
    spec = trials.TrialSpec(condition="side_effects", seed=1, z_methods=("maxent_z",), **TINY)
    row = scale.diagnose(spec, "maxent_z")
    inst = lavaland.make_instance("side_effects", 1, size=5, horizon=5)
    post = trials.trial_posterior(spec, inst, "maxent_z")
    names = list(inst.feature_names)
    values = post.samples[:, names.index("lava")] - post.samples[:, names.index("dirt")]
    assert row.lava_value_mean == pytest.approx(values.mean(), abs=1e-12)
    assert row.share_below == pytest.approx(np.mean(values < 0))
    proxy = inst.proxy_weights
    assert row.proxy_lava_value == pytest.approx(proxy[names.index("lava")] - proxy[names.index("dirt")], abs=1e-12)
    # indicator features: every dirt cell has one reward, so the target stands infinitely far off
    assert row.proxy_target_signal == np.inf  # the proxy puts the target (1) above dirt (0.1)
    assert abs(row.target_signal) == np.inf


def test_the_target_margin_is_positive_exactly_when_a_target_cell_is_the_best_safe_cell() -> None:
    spec = trials.TrialSpec(condition="side_effects", seed=1, z_methods=("maxent_z",), **TINY)
    row = scale.diagnose(spec, "maxent_z")
    inst = lavaland.make_instance("side_effects", 1, size=5, horizon=5)
    post = trials.trial_posterior(spec, inst, "maxent_z")
    test = lavaland.test_mdp(inst)
    reference = posterior.proxy_feature_expectations(inst, spec.observation_model()) / (inst.train_horizon + 1)
    reward = planning.per_step_reward(test, spec.planning_samples(inst, post.samples), trials.MAIN_BASELINE, reference)
    safe = {int(t): reward[inst.test_labels == int(t)] for t in (Terrain.DIRT, Terrain.GRASS, Terrain.TARGET)}
    best_other = max(values.max() for t, values in safe.items() if values.size and t != int(Terrain.TARGET))
    assert row.target_margin == pytest.approx(safe[int(Terrain.TARGET)].max() - best_other, abs=1e-12)


@pytest.mark.parametrize("text", ["32", "32:x", "2:10", "32:0", "a:b:c"])
def test_bad_sizes_are_refused_naming_the_flag(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match="--sizes"):
        scale_cli.parse_size(text)


@pytest.mark.parametrize("argv, message", [(["--seed", "-1"], "seed must be a non-negative int, got -1"),
                                           (["--betas", "-2"], "beta: expected a finite number >= 0, got -2.0")])
def test_the_command_line_refuses_a_bad_seed_or_beta_before_any_diagnosis(tmp_path, capsys, argv, message) -> None:
    out = tmp_path / "rows.csv"
    with pytest.raises(SystemExit) as stop:
        scale_cli.main(["--sizes", "5:5", "--seeds", "2", "--workers", "1", "--out", str(out), *argv])
    assert stop.value.code == 2 and message in capsys.readouterr().err
    assert not out.exists()


def test_an_out_that_cannot_be_written_is_refused_before_any_diagnosis(tmp_path, capsys) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    for out, message in ((tmp_path, f"--out: {tmp_path} is a folder, not a file"),
                         (blocker / "rows.csv", f"--out: {blocker} is not a folder")):
        with pytest.raises(SystemExit) as stop:
            scale_cli.main(["--sizes", "5:5", "--seeds", "1", "--workers", "1", "--out", str(out)])
        err = capsys.readouterr().err
        assert stop.value.code == 2 and message in err and "diagnoses," not in err, err
    assert blocker.read_text() == "kept"

def test_the_command_line_writes_one_row_per_diagnosis_and_a_table(tmp_path, capsys) -> None:
    out = tmp_path / "new" / "rows.csv"  # its folder is made
    assert scale_cli.main(["--sizes", "5:5", "--seeds", "2", "--betas", "50", "10", "--conditions", "side_effects",
                           "--workers", "1", "--out", str(out)]) == 0
    with out.open() as handle:
        rows = list(csv.DictReader(handle))
    assert [(r["beta"], r["seed"]) for r in rows] == [("50.0", "0"), ("50.0", "1"), ("10.0", "0"), ("10.0", "1")]
    table = capsys.readouterr().out
    assert "| side_effects | 5x5 | 5 | 50 | maxent_z | 2 |" in table
    assert "| side_effects | 5x5 | 5 | 10 | maxent_z | 2 |" in table
