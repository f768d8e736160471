"""The designer-in-the-loop experiment (ird_core.experiments.active, its command line active_cli) on tiny maps:
outputs and columns, paired determinism, the oracle as a ceiling, the paired statistics."""

from __future__ import annotations

import csv
import math
from typing import Iterable

import pytest

from ird_core import experiments
from ird_core.experiments import active, active_cli, active_endpoints, active_report

TINY = dict(size=5, horizon=5, obs_dim=4, num_samples=16, num_chains=2, warmup=10, thin=1, max_leapfrog=4, warm_warmup=5,
            chains="fixed")
TINY_ARGS = ["--size", "5", "--horizon", "5", "--obs-dim", "4", "--num-samples", "16", "--num-chains", "2",
             "--warmup", "10", "--thin", "1", "--max-leapfrog", "4", "--warm-warmup", "5", "--chains", "fixed"]


def _key(results):
    return [(r.condition, r.seed, r.strategy, r.num_queries, r.asked, r.touched_lava, r.reached_target,
             r.reached_gold, r.true_return, None if math.isnan(r.information_gain) else r.information_gain,
             r.answers_correct, r.cells) for r in results]


@pytest.fixture(scope="module")
def gold_trials() -> list[list[active.ActiveResult]]:
    return [active.run_trial(active.ActiveSpec("pot_of_gold", seed, **TINY)) for seed in (0, 1, 2)]


@pytest.mark.timeout(300)
def test_trial_is_deterministic_paired_and_complete(gold_trials) -> None:
    again = active.run_trial(active.ActiveSpec("pot_of_gold", 1, **TINY))
    assert _key(again) == _key(gold_trials[1])
    for results in gold_trials:
        plans = [(r.strategy, r.num_queries) for r in results]
        assert plans == [("literal", 0), ("oracle", 0)] + [
            (s, k) for s in active.EXPERIMENT_STRATEGIES for k in active.QUERY_COUNTS]
        by = {(r.strategy, r.num_queries): r for r in results}
        # Paired: zero queries is the same posterior and plan for both strategies.
        assert by["info_gain", 0].cells == by["random", 0].cells
        for r in results:
            assert len(r.cells) == TINY["horizon"] + 1
            assert 0 <= r.asked <= r.num_queries and r.answers_correct <= r.asked
            assert math.isnan(r.information_gain) == (r.asked == 0)
        for s in active.EXPERIMENT_STRATEGIES:
            asked = [by[s, k].asked for k in active.QUERY_COUNTS]
            assert asked == sorted(asked)
            # "changed" says whether the answers moved the plan away from the 0-query plan.
            for k in active.QUERY_COUNTS:
                assert by[s, k].changed == (by[s, k].cells != by[s, 0].cells)


@pytest.mark.timeout(300)
def test_oracle_is_the_ceiling_of_every_plan(gold_trials) -> None:
    for results in gold_trials:
        oracle = next(r for r in results if r.strategy == "oracle")
        assert all(oracle.true_return >= r.true_return - 1e-12 for r in results)
        assert not oracle.touched_lava


def test_paired_difference_and_gap_closed_on_hand_made_results() -> None:
    def result(seed: int, strategy: str, count: int, value: float) -> active.ActiveResult:
        return active.ActiveResult("side_effects", seed, strategy, count, count, False, True, False, value,
                                   math.nan, 0, math.nan, ((0, 0),))

    results = [result(0, "info_gain", 1, 3.0), result(1, "info_gain", 1, 5.0), result(2, "info_gain", 1, 4.0),
               result(0, "random", 1, 1.0), result(1, "random", 1, 4.0), result(2, "random", 1, 4.0),
               result(0, "literal", 0, 0.0), result(1, "literal", 0, 2.0),
               result(0, "oracle", 0, 10.0), result(1, "oracle", 0, 12.0)]
    mean, lo, hi, n = active.paired_difference(results, "side_effects", ("info_gain", 1), ("random", 1))
    assert n == 3 and mean == pytest.approx(1.0)
    assert (mean, lo, hi) == pytest.approx(experiments.t_interval([2.0, 1.0, 0.0]))
    summaries = active.aggregate(results)
    # literal mean 1, oracle mean 11, info_gain after 1 query mean 4: 30% of the gap.
    assert active.gap_closed(summaries, "side_effects", "info_gain", 1) == pytest.approx(0.3)
    assert math.isnan(active.gap_closed(summaries, "side_effects", "info_gain", 3))
    cell = next(s for s in summaries if s.strategy == "random")
    assert cell.trials == 3 and cell.target_fraction == 1.0 and cell.mean_return == pytest.approx(3.0)
    assert (cell.target_ci_low, cell.target_ci_high) == experiments.wilson_interval(3, 3)


def test_spec_errors() -> None:
    with pytest.raises(ValueError, match="condition"):
        active.ActiveSpec("lava_lamp", 0)
    with pytest.raises(ValueError, match="query_counts"):
        active.ActiveSpec("side_effects", 0, query_counts=(2, 1))
    with pytest.raises(ValueError, match="strategies"):
        active.ActiveSpec("side_effects", 0, strategies=("ask_everything",))
    with pytest.raises(ValueError, match="designer_beta"):
        active.ActiveSpec("side_effects", 0, designer_beta=-1.0)


@pytest.mark.parametrize("field, value", [
    ("seed", -1), ("size", 2), ("horizon", 0), ("obs_dim", 2), ("num_samples", 0), ("beta", -1.0),
    ("temperature", 0.0), ("temperature", float("nan")), ("method", "laplace_z"), ("num_chains", 0), ("thin", 0),
    ("warm_warmup", -1),
])
def test_a_spec_names_a_field_no_trial_can_use(field: str, value: object) -> None:
    """Refused when the spec is made, in the parent, not when a worker first runs the trial."""
    with pytest.raises(ValueError, match=field):
        active.ActiveSpec("latent_raw", **{"seed": 0, field: value})
    with pytest.raises(ValueError, match="max_leapfrog"):
        active.ActiveSpec("latent_raw", 0, chains="fixed", max_leapfrog=0)


@pytest.mark.parametrize("argv, message", [
    (["--seed", "-5"], "bad argument: seed must be a non-negative int, got -5"),
    (["--size", "2"], "bad argument: size must be at least 3x3, got 2x2"),
    (["--temperature", "0"], "bad argument: temperature: expected a finite number in [0.001, 1000], got 0.0"),
    (["--warm-warmup", "-3"], "bad argument: warm_warmup: expected an integer >= 0, got -3"),
])
def test_the_command_line_refuses_a_bad_setting_before_any_trial(tmp_path, capsys, argv, message) -> None:
    out = tmp_path / "active"
    assert active_cli.main(["--trials", "1", "--workers", "1", "--out", str(out), *argv]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_an_out_that_cannot_be_a_folder_is_refused_before_any_trial(tmp_path, capsys) -> None:
    blocker = tmp_path / "active"
    blocker.write_text("a file where the report's folder would go")
    assert active_cli.main(["--trials", "1", "--workers", "1", "--out", str(blocker / "sub")]) == 2
    err = capsys.readouterr().err
    assert f"--out: cannot make the folder {blocker / 'sub'}:" in err and "trials (" not in err, err
    assert blocker.read_text() == "a file where the report's folder would go"

@pytest.mark.timeout(600)
def test_script_outputs_columns_rows_and_worker_independence(tmp_path, gold_trials) -> None:
    mod = active_cli
    out = tmp_path / "active"
    code = mod.main(["--trials", "2", "--workers", "2", "--out", str(out), "--conditions", "pot_of_gold", *TINY_ARGS])
    assert code == 0
    with (out / "active.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    required = {"condition", "strategy", "num_queries", "trials", "lava_fraction", "target_fraction",
                "gold_fraction", "mean_return", "return_ci_low", "return_ci_high", "lava_ci_low", "gold_ci_high"}
    assert required <= set(rows[0])
    keys = [(r["condition"], r["strategy"], r["num_queries"]) for r in rows]
    assert len(keys) == len(set(keys)) == 2 + len(active.EXPERIMENT_STRATEGIES) * len(active.QUERY_COUNTS)
    assert {r["num_queries"] for r in rows if r["strategy"] in ("literal", "oracle")} == {"0"}
    assert {r["strategy"] for r in rows} == {"literal", "oracle", *active.EXPERIMENT_STRATEGIES}
    assert all(r["trials"] == "2" for r in rows)
    for name in ("active_trials.csv", "active.md", "active_pot_of_gold.png", "run.json"):
        assert (out / name).is_file()
    # The script's trials (2 workers) are the library's trials (seeds 0 and 1, in process).
    with (out / "active_trials.csv").open() as fh:
        trials = list(csv.DictReader(fh))
    direct = [r for rs in gold_trials[:2] for r in rs]
    assert len(trials) == len(direct)
    for row, r in zip(trials, direct):
        assert (row["seed"], row["strategy"], row["num_queries"]) == (str(r.seed), r.strategy, str(r.num_queries))
        assert float(row["true_return"]) == pytest.approx(r.true_return, abs=1e-5)
        assert row["cells"] == " ".join(f"{a},{b}" for a, b in r.cells)
    text = (out / "active.md").read_text()
    assert "## pot_of_gold" in text and all(s in text for s in active.EXPERIMENT_STRATEGIES)
    assert "## Goal check" in text and "regret after 1" in text
    # The report rewritten from its own files (nothing run) is the same report (the csv's returns
    # are printed to 6 significant digits, so its numbers agree to that precision).
    text_before, rows_before = text, rows
    assert active_cli.main(["--report-only", "--out", str(out)]) == 0
    assert (out / "active.md").read_text() == text_before
    with (out / "active.csv").open() as fh:
        rows_after = list(csv.DictReader(fh))
    assert [r.keys() for r in rows_after] == [r.keys() for r in rows_before]
    for a, b in zip(rows_after, rows_before):
        for key in a:
            try:
                assert float(a[key]) == pytest.approx(float(b[key]), rel=1e-5, abs=1e-9, nan_ok=True), key
            except ValueError:
                assert a[key] == b[key]
    back = active_report.read_results_csv(out / "active_trials.csv")
    assert [(r.seed, r.strategy, r.num_queries, r.cells, r.changed) for r in back] == \
        [(r.seed, r.strategy, r.num_queries, r.cells, r.changed) for r in direct]


def test_endpoints_on_hand_made_results() -> None:
    def result(seed: int, strategy: str, count: int, value: float) -> active.ActiveResult:
        return active.ActiveResult("side_effects", seed, strategy, count, count, False, True, False, value,
                                   math.nan, 0, math.nan, ((0, 0),))

    results = [result(0, "oracle", 0, 10.0), result(1, "oracle", 0, 12.0), result(2, "oracle", 0, 11.0),
               result(0, "evoi", 1, 9.0), result(1, "evoi", 1, 12.0), result(2, "evoi", 1, 8.0),
               result(0, "random", 1, 7.0), result(1, "random", 1, 11.0), result(2, "random", 1, 8.0)]
    mean, lo, hi, n = active_endpoints.regret(results, "side_effects", "evoi", 1)
    assert n == 3 and (mean, lo, hi) == pytest.approx(experiments.t_interval([1.0, 0.0, 3.0]))
    mean, lo, hi, n = active_endpoints.versus(results, "side_effects", "evoi", "random", 1)
    assert (mean, lo, hi) == pytest.approx(experiments.t_interval([2.0, 1.0, 0.0]))
    check = active_endpoints.goal_check(results, active.aggregate(results), ["side_effects"])
    assert check[0].startswith("- Missed") and "1.00" in check[1]


@pytest.mark.timeout(600)
def _assert_same_rows(merged, single) -> None:
    """``active.csv`` of ``merged`` is ``single``'s, row for row (numbers to float precision)."""
    def rows(path):
        with (path / "active.csv").open() as fh:
            return list(csv.DictReader(fh))

    for a, b in zip(rows(merged), rows(single), strict=True):
        for key in a:
            try:
                assert float(a[key]) == pytest.approx(float(b[key]), rel=1e-5, abs=1e-9, nan_ok=True), key
            except ValueError:
                assert a[key] == b[key]


def test_chunks_merge_into_the_report_of_one_run(tmp_path) -> None:
    single, merged = tmp_path / "single", tmp_path / "merged"
    common = ["--workers", "1", "--conditions", "side_effects", *TINY_ARGS]
    assert active_cli.main(["--trials", "2", "--out", str(single), *common]) == 0
    chunks = [tmp_path / "a", tmp_path / "b"]
    assert active_cli.main(["--trials", "1", "--seed", "0", "--out", str(chunks[0]), *common]) == 0
    assert active_cli.main(["--trials", "1", "--seed", "1", "--out", str(chunks[1]), *common]) == 0
    assert active_cli.main(["--report-only", "--out", str(merged), "--merge", *map(str, chunks)]) == 0
    _assert_same_rows(merged, single)
    text = (merged / "active.md").read_text()
    assert "seed=0..1 in 2 chunks" in text and "trials=2" in text
    # Chunks that share a seed are refused.
    assert active_cli.main(["--report-only", "--out", str(merged), "--merge", str(chunks[0]), str(chunks[0])]) == 2


def test_chunks_of_other_conditions_merge_into_the_report_of_one_run(tmp_path) -> None:
    """One condition per chunk (e.g. a slow condition on its own machine) merges into the report
    of one run over both conditions, conditions in the chunks' order."""
    single, merged = tmp_path / "single", tmp_path / "merged"
    common = ["--trials", "1", "--workers", "1", *TINY_ARGS]
    assert active_cli.main(["--out", str(single), "--conditions", "side_effects", "pot_of_gold", *common]) == 0
    chunks = [tmp_path / "side", tmp_path / "gold"]
    for chunk, condition in zip(chunks, ("side_effects", "pot_of_gold")):
        assert active_cli.main(["--out", str(chunk), "--conditions", condition, *common]) == 0
    assert active_cli.main(["--report-only", "--out", str(merged), "--merge", *map(str, chunks)]) == 0
    _assert_same_rows(merged, single)
    assert "trials=1, seed=0..0 in 2 chunks" in (merged / "active.md").read_text()


def test_the_chains_follow_the_weight_space_size_unless_the_spec_sets_them() -> None:
    """The designer-loop posteriors use the experiments' MaxEnt-Z recipe per size: 16-step chains
    up to d = 10, 64-step ones (100 warm-up iterations, 32-step warm-up trajectories) in the
    latent conditions' d = 50, where 16 steps leave the calibrated posterior unconverged."""
    from ird_core.experiments.active import ActiveSpec
    spec = ActiveSpec("latent_raw", 0)
    assert spec.chain_settings(4) == dict(warmup=50, max_leapfrog=16, warmup_max_leapfrog=None)
    assert spec.chain_settings(50) == dict(warmup=100, max_leapfrog=64, warmup_max_leapfrog=32)
    explicit = ActiveSpec("latent_raw", 0, warmup=30, max_leapfrog=8, chains="fixed")
    assert explicit.chain_settings(50) == dict(warmup=30, max_leapfrog=8, warmup_max_leapfrog=32)


def test_the_converged_chains_are_the_main_experiments_recipe_for_the_method() -> None:
    """``chains="converged"``: the cold posterior and every re-sample use the main experiment's
    recipe for the spec's method and weight-space size (kernel, chains, run until converged),
    re-samples with the warm warm-up; ``"fixed"`` keeps the small fixed-length chains."""
    from ird_core.experiments.active import ActiveSpec
    from ird_core.experiments.trials import TrialSpec

    for method, dim in (("sample_z", 4), ("sample_z", 50), ("maxent_z", 50)):
        spec = ActiveSpec("side_effects", 3, method=method, chains="converged", warm_warmup=25)
        recipe = TrialSpec("side_effects", 3).sampler(method).for_dim(dim).options()
        assert recipe["until_converged"] is not None
        assert spec.sampler_options(dim, warm=False) == recipe
        assert spec.sampler_options(dim, warm=True) == dict(recipe, warmup=25)
    assert ActiveSpec("side_effects", 0, method="sample_z", chains="converged").sampler_options(4, False)["kernel"] \
        == "independence_elliptical"
    assert ActiveSpec("side_effects", 0).chains == "converged"
    fixed = ActiveSpec("side_effects", 0, method="sample_z", chains="fixed")
    assert fixed.sampler_options(4, warm=False) == dict(num_chains=4, thin=4, max_leapfrog=16, warmup_max_leapfrog=None,
                                                        warmup=50)
    assert fixed.sampler_options(4, warm=True)["warmup"] is None  # the library's warm warm-up
    with pytest.raises(ValueError, match="chains"):
        ActiveSpec("side_effects", 0, chains="long")
    with pytest.raises(ValueError, match="warmup, max_leapfrog"):
        ActiveSpec("side_effects", 0, warmup=30)


@pytest.mark.slow
def test_a_converged_trial_runs_its_posteriors_until_they_converge() -> None:
    """Sample-Z with the fixed-length MaxEnt-Z chains leaves this small trial's cold posterior
    and most re-samples unconverged; with its own recipe, run until converged, every one passes
    R-hat <= 1.1."""
    small = dict(size=5, horizon=5, obs_dim=4, num_samples=16)
    fixed = active.run_trial(active.ActiveSpec("side_effects", 0, method="sample_z", chains="fixed", **small))
    converged = active.run_trial(active.ActiveSpec("side_effects", 0, method="sample_z", **small))
    def r_hats(results: "Iterable[active.ActiveResult]") -> list[float]:
        return [r.r_hat_max for r in results if r.strategy not in ("literal", "oracle")]

    assert min(r_hats(r for r in fixed if r.num_queries == 0)) > 1.1  # the cold posterior
    assert sum(r > 1.1 for r in r_hats(fixed)) > len(r_hats(fixed)) // 2  # and most re-samples
    assert r_hats(converged) and max(r_hats(converged)) <= 1.1
    assert [(r.strategy, r.num_queries) for r in converged] == [(r.strategy, r.num_queries) for r in fixed]


def test_rob_plans_on_rescaled_samples_as_in_the_main_experiment(monkeypatch: pytest.MonkeyPatch) -> None:
    """The IRD plan before any question is the main experiment's planner on the cold posterior's
    samples rescaled over the training map (``sample_scale="training_spread"``, the default);
    ``"none"`` plans them as they are."""
    from ird_core import planning, posterior
    from ird_core.planning.sample_scale import normalise_samples
    from ird_core.worlds import lavaland

    drawn: list = []
    sample = posterior.sample_joint_posterior

    def recorded(*args, **kwargs):
        drawn.append(sample(*args, **kwargs))
        return drawn[-1]

    monkeypatch.setattr(active.posterior, "sample_joint_posterior", recorded)
    plans = []
    for scale in ("training_spread", "none"):
        drawn.clear()
        spec = active.ActiveSpec("latent_raw", 7, sample_scale=scale, query_counts=(0,), strategies=("random",), **TINY)
        zero = next(r for r in active.run_trial(spec) if r.strategy == "random")
        plans.append(zero.cells)
        inst = lavaland.make_instance("latent_raw", 7, size=spec.size, horizon=spec.horizon, obs_dim=spec.obs_dim)
        samples = normalise_samples(drawn[0].samples, inst.train_features) if scale != "none" else drawn[0].samples
        reference = posterior.proxy_feature_expectations(inst) / (inst.train_horizon + 1)
        expected = planning.plan_path(lavaland.test_mdp(inst), samples, "per_step", "training_features", reference)
        assert zero.cells == expected.cells
    assert plans[0] != plans[1]  # on this seed the scale decides the plan
    with pytest.raises(ValueError, match="sample_scale"):
        active.ActiveSpec("side_effects", 0, sample_scale="unit")
