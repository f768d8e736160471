"""Experiments on a world file: ``ird-experiments --world FILE`` (ird_core.experiments.cli) and ``TrialSpec.world``."""

from __future__ import annotations

import csv
import warnings
from pathlib import Path

import numpy as np
import pytest

from ird_core import experiments as ex
from ird_core import posterior
from ird_core.experiments import cli
from ird_core.worlds import evaluation, lavaland, world_file

ROOT = Path(__file__).resolve().parents[1]
SMALL = dict(num_samples=16, num_chains=2, warmup=20, thin=1, max_leapfrog=8, num_proxy_samples=20,
             z_methods=("maxent_z",), factorial=False, sample_z_sampler=None, maxent_z_sampler=None)


def test_run_experiments_world_figure1(tmp_path: Path) -> None:
    """Figure 1's world is fixed: the literal plan is the same in every trial and crosses the
    lava on the shortcut; the IRD plans (sampler seeds 0 and 1) never touch lava."""
    args = ["--world", str(ROOT / "worlds" / "figure1.yaml"), "--trials", "2", "--workers", "1", "--out",
            str(tmp_path), "--no-factorial", "--z-methods", "maxent_z", "--num-samples", "16", "--num-chains", "2",
            "--warmup", "20", "--thin", "1"]
    assert cli.main(args) == 0
    with (tmp_path / "trials.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert {r["condition"] for r in rows} == {lavaland.FILE_CONDITION}
    assert sorted((r["seed"], r["planner"]) for r in rows) == [
        ("0", "ird_maxent_z"), ("0", "literal"), ("0", "oracle"), ("1", "ird_maxent_z"), ("1", "literal"),
        ("1", "oracle")]
    literal = [r for r in rows if r["planner"] == "literal"]
    assert literal[0]["cells"] == literal[1]["cells"] and all(r["touched_lava"] == "1" for r in literal)
    assert all(r["touched_lava"] == "0" for r in rows if r["planner"] != "literal")
    inst = world_file.load_world(ROOT / "worlds" / "figure1.yaml")
    cells = [tuple(int(v) for v in c.split(",")) for c in literal[0]["cells"].split()]
    expected = evaluation.true_return(inst.test_labels, cells, inst.true_terrain_reward)
    assert float(literal[0]["true_return"]) == pytest.approx(expected, rel=1e-5)  # the csv keeps 6 digits


def test_bad_world_file_exits_2_naming_the_key(tmp_path: Path, capsys) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("terrains: [{name: dirt, colour: [1, 2, 3]}]\n")
    assert cli.main(["--world", str(bad), "--trials", "1", "--out", str(tmp_path / "out")]) == 2
    assert f"{bad}: training_worlds: missing required key" in capsys.readouterr().err


def test_trial_posterior_is_the_joint_posterior_of_every_training_world() -> None:
    """Two training worlds: the trial's IRD plan is the plan of the joint posterior (docs/spec.md section 7)
    seeded from the trial seed, not of the first world's posterior alone."""
    path = ROOT / "worlds" / "two_training_worlds.yaml"
    spec = ex.TrialSpec(condition=lavaland.FILE_CONDITION, seed=5, world=str(path), **SMALL)
    (literal, oracle, ird) = ex.run_trial(spec)
    assert oracle.planner == "oracle" and oracle.true_return >= max(literal.true_return, ird.true_return)
    inst = world_file.load_world(path)
    assert len(inst.extra_training_worlds) == 1
    seed = int(np.random.SeedSequence([5, ex.Z_METHODS.index("maxent_z") + 1]).generate_state(1)[0]) % 2**31
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        joint = posterior.sample_joint_posterior(
            posterior.proxy_observations(inst), spec.beta, "maxent_z", spec.num_samples, seed, spec.prior_sigma,
            num_chains=2, warmup=20, thin=1, max_leapfrog=8)
    assert ird.r_hat_max == joint.r_hat_max
    reference = posterior.proxy_feature_expectations(inst) / (inst.train_horizon + 1)
    from ird_core import planning

    expected = planning.plan_path(lavaland.test_mdp(inst), joint.samples, "per_step", "training_features", reference)
    assert ird.cells == tuple(expected.cells)
    assert literal.condition == ird.condition == lavaland.FILE_CONDITION


def test_world_without_true_rewards_has_no_oracle_row(tmp_path: Path) -> None:
    """Without true rewards there is no ceiling: no oracle row, NaN returns and NaN gap shares."""
    import shutil

    source = ROOT / "worlds" / "figure1.yaml"
    for png in ROOT.joinpath("worlds").glob("figure1_*.png"):
        shutil.copy(png, tmp_path / png.name)
    text = "\n".join(line for line in source.read_text().splitlines() if "true_reward" not in line)
    (tmp_path / "figure1.yaml").write_text(text)
    assert world_file.load_world(tmp_path / "figure1.yaml").true_terrain_reward is None
    spec = ex.TrialSpec(condition=lavaland.FILE_CONDITION, seed=0, world=str(tmp_path / "figure1.yaml"), **SMALL)
    results = ex.run_trial(spec)
    assert [r.planner for r in results] == ["literal", "ird_maxent_z"]
    assert all(np.isnan(s.gap_closed) and np.isnan(s.mean_true_return) for s in ex.aggregate(results))
