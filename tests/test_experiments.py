"""Fast tests of ird_core.experiments and its command line (ird_core.experiments.cli, ird_ros.apps.experiments;
tiny maps, few samples)."""

from __future__ import annotations

import csv
import gzip
import math
from pathlib import Path

import numpy as np
import pytest

from ird_core import experiments as ex
from ird_core.experiments import cli, report, trials
from ird_core.worlds.lavaland import FILE_CONDITION

ROOT = Path(__file__).resolve().parents[1]

TINY = dict(size=5, horizon=5, obs_dim=4, num_samples=16, num_chains=2, warmup=10, thin=1, max_leapfrog=4,
            num_proxy_samples=20, factorial_samples=16, traj_work_limit=2_000_000, sample_z_sampler=None,
            maxent_z_sampler=None)
TINY_ARGS = ["--size", "5", "--horizon", "5", "--obs-dim", "4", "--num-samples", "16", "--num-chains", "2",
             "--warmup", "10", "--thin", "1", "--max-leapfrog", "4", "--num-proxy-samples", "20",
             "--factorial-samples", "16", "--traj-work-limit", "2000000"]


def _key(results):
    """Comparable content of a result list (NaN-safe, timings excluded)."""
    return [(r.experiment, r.condition, r.seed, r.planner, r.touched_lava, r.reached_target, r.true_return,
             None if math.isnan(r.objective) else round(r.objective, 12), r.cells,
             None if math.isnan(r.r_hat_max) else r.r_hat_max) for r in results]


# --------------------------------------------------------------------------- statistics


def test_wilson_known_values():
    lo, hi = ex.wilson_interval(0, 10)
    assert lo == 0.0 and hi == pytest.approx(0.27753, abs=1e-4)
    lo, hi = ex.wilson_interval(5, 10)
    assert lo == pytest.approx(0.23659, abs=1e-4) and hi == pytest.approx(0.76341, abs=1e-4)
    lo, hi = ex.wilson_interval(10, 10)
    assert lo == pytest.approx(1 - 0.27753, abs=1e-4) and hi == 1.0
    assert all(math.isnan(v) for v in ex.wilson_interval(0, 0))
    with pytest.raises(ValueError):
        ex.wilson_interval(11, 10)


def test_t_interval_known_values():
    mean, lo, hi = ex.t_interval([1, 2, 3, 4, 5])
    # sd = sqrt(2.5), se = sd / sqrt(5), t_{0.975, 4} = 2.776445
    half = 2.776445105 * math.sqrt(2.5) / math.sqrt(5)
    assert mean == 3.0 and lo == pytest.approx(3 - half, abs=1e-6) and hi == pytest.approx(3 + half, abs=1e-6)
    assert ex.t_interval([2.0]) == (2.0, 2.0, 2.0)


def test_aggregate_counts():
    r = ex.TrialResult("main", "side_effects", 0, "literal", "", "literal", "none", True, False, -1.0, 0.0, "dp",
                       False, 0.0, math.nan, math.nan, ((0, 0),))
    s = ex.aggregate([r, ex.TrialResult(**{**r.__dict__, "seed": 1, "touched_lava": False, "true_return": 1.0})])
    assert len(s) == 1 and s[0].trials == 2 and s[0].lava_fraction == 0.5 and s[0].mean_true_return == 0.0


# --------------------------------------------------------------------------- trials


@pytest.mark.timeout(300)
def test_run_trial_deterministic_and_complete():
    spec = ex.TrialSpec("side_effects", 3, **TINY)
    a, b = ex.run_trial(spec), ex.run_trial(spec)
    assert _key(a) == _key(b)
    planners = [r.planner for r in a]
    assert planners[0] == "literal" and "ird_sample_z" in planners and "ird_maxent_z" in planners
    assert planners[1] == "oracle"
    assert len(a) == 2 + 2 * (1 + len(ex.GRANULARITIES) * len(ex.BASELINES))
    for r in a:
        assert len(r.cells) == TINY["horizon"] + 1
    # the main IRD plan is the factorial's per_step/training_features plan of the same posterior
    by = {r.planner: r for r in a}
    for z in ex.Z_METHODS:
        assert by[f"ird_{z}"].cells == by[f"{z}/per_step/training_features"].cells


@pytest.mark.timeout(300)
def test_one_vs_two_workers_identical():
    mod = cli
    specs = ex.make_specs(["side_effects", "latent_classifier"], 2, 7, **TINY)
    one = mod.run_local(specs, 1)
    two = mod.run_local(specs, 2)
    assert _key(one) == _key(two)


@pytest.mark.timeout(300)
def test_results_csv_columns_and_rows(tmp_path, capsys):
    mod = cli
    out = tmp_path / "exp"
    code = mod.main(["--trials", "2", "--workers", "1", "--out", str(out), "--conditions", "side_effects",
                     "reward_hacking", *TINY_ARGS])
    assert code == 0
    with (out / "results.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    required = {"experiment", "condition", "planner", "z_approx", "granularity", "baseline", "trials",
                "lava_fraction", "lava_ci_low", "lava_ci_high", "target_fraction", "mean_true_return"}
    assert required <= set(rows[0])
    cells = [(r["experiment"], r["condition"], r["planner"]) for r in rows]
    assert len(cells) == len(set(cells))
    per_condition = 4 + 2 * len(ex.GRANULARITIES) * len(ex.BASELINES)
    assert len(rows) == 2 * per_condition
    assert all(r["trials"] == "2" for r in rows)
    for name in ("trials.csv", "results.md", "figure4_lava.png", "figure4_return.png", "factorial_sample_z.png",
                 "run.json"):
        assert (out / name).is_file()
    with (out / "trials.csv").open() as fh:
        assert len(list(csv.DictReader(fh))) == 2 * 2 * per_condition
    # the gap share exists exactly for the IRD planners; literal and oracle rows are NaN
    assert {"gap_closed", "gap_ci_low", "gap_ci_high"} <= set(rows[0])
    for r in rows:
        if r["planner"] in ("literal", "oracle"):
            assert r["gap_closed"] == r["gap_ci_low"] == r["gap_ci_high"] == "nan"
    assert {r["planner"] for r in rows if r["experiment"] == "main"} == {"literal", "oracle", "ird_sample_z",
                                                                       "ird_maxent_z"}
    assert "| gap closed % [95% CI] |" in (out / "results.md").read_text()
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith("Wall time: ") and " s (" in last


@pytest.mark.timeout(300)
def test_dask_local_cluster_matches_local_pool():
    import distributed  # pinned in requirements.txt: a missing package fails, never skips
    mod = cli
    specs = ex.make_specs(["reward_hacking"], 2, 11, **TINY)
    local = mod.run_local(specs, 1)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        remote = mod.run_dask(specs, client)
    assert _key(local) == _key(remote)


# --------------------------------------------------------------------------- gap closed


def test_gap_share_known_values():
    assert ex.gap_share(0.0, 2.0, 1.0) == 0.5 and ex.gap_share(-3.0, 1.0, 2.0) == 1.25
    assert math.isnan(ex.gap_share(1.0, 1.0, 1.0))  # no gap
    assert math.isnan(ex.gap_share(2.0, 1.0, 1.5))


def test_gap_closed_endpoints_are_exact():
    literal, oracle = [0.0, -10.0, 1.0, 2.5], [3.0, 3.0, 3.9, 2.5]
    assert ex.gap_closed(literal, oracle, oracle) == (1.0, 1.0, 1.0)
    assert ex.gap_closed(literal, oracle, literal) == (0.0, 0.0, 0.0)


def test_gap_closed_two_trials_by_hand():
    """n = 2: a resample holds trial 0 twice (p = 1/4), both (1/2) or trial 1 twice (1/4), so the
    2.5% and 97.5% percentiles of 2000 resamples are the single-trial shares 0.5 and 1.0."""
    share, low, high = ex.gap_closed([0.0, 0.0], [2.0, 4.0], [1.0, 4.0])
    assert share == pytest.approx(5 / 6, abs=1e-15) and (low, high) == (0.5, 1.0)


def test_gap_closed_bootstrap_is_paired_deterministic_and_contains_the_share():
    rng = np.random.default_rng(3)
    literal = rng.normal(-2.0, 3.0, 40)
    oracle = literal + rng.uniform(0.0, 6.0, 40)
    planner = literal + 0.6 * (oracle - literal) + rng.normal(0.0, 0.5, 40)
    share, low, high = ex.gap_closed(literal, oracle, planner, seed=7, resamples=500)
    assert share == pytest.approx((planner.mean() - literal.mean()) / (oracle.mean() - literal.mean()), rel=1e-12)
    assert low < share < high
    assert ex.gap_closed(literal, oracle, planner, seed=7, resamples=500) == (share, low, high)
    # the same resampled trial indices for all three (paired), by a plain loop over resamples
    index = np.random.default_rng(7).integers(0, 40, size=(500, 40))
    boot = [(planner[i].mean() - literal[i].mean()) / (oracle[i].mean() - literal[i].mean()) for i in index]
    assert (low, high) == pytest.approx(tuple(np.percentile(boot, [2.5, 97.5])), rel=1e-12)


def test_gap_closed_edge_cases():
    assert ex.gap_closed([1.0], [3.0], [2.0]) == (0.5, 0.5, 0.5)  # n = 1: every resample is the trial
    assert all(math.isnan(v) for v in ex.gap_closed([], [], []))
    assert all(math.isnan(v) for v in ex.gap_closed([1.0, 2.0], [1.0, 2.0], [0.0, 5.0]))  # no gap
    with pytest.raises(ValueError, match="same length"):
        ex.gap_closed([1.0, 2.0], [3.0], [2.0, 2.0])


def test_aggregate_gap_pairs_trials_by_seed():
    def result(planner, seed, ret, z=""):
        return ex.TrialResult("main", "side_effects", seed, planner, z, "x", "none", False, True, ret, 0.0, "dp",
                              False, 0.0, math.nan, math.nan, ((0, 0),))

    rows = [result("literal", 0, 0.0), result("literal", 1, 0.0), result("oracle", 1, 4.0), result("oracle", 0, 2.0),
            result("ird_maxent_z", 1, 4.0, "maxent_z"), result("ird_maxent_z", 0, 1.0, "maxent_z")]
    by = {s.planner: s for s in ex.aggregate(rows)}
    assert (by["ird_maxent_z"].gap_closed, by["ird_maxent_z"].gap_ci_low, by["ird_maxent_z"].gap_ci_high) == \
        ex.gap_closed([0.0, 0.0], [2.0, 4.0], [1.0, 4.0])
    assert all(math.isnan(by[p].gap_closed) for p in ("literal", "oracle"))


# --------------------------------------------------------------------------- oracle and factorial


SMALL_MAP = dict(TINY, size=8, horizon=12, obs_dim=10, factorial_samples=4)


@pytest.mark.timeout(600)
def test_oracle_is_optimal_under_the_true_reward():
    """The oracle's true return bounds every planner's in every trial, equals its DP objective,
    and beats the literal plan somewhere (the gap is not empty on these seeds)."""
    strict = 0
    for condition in ("side_effects", "reward_hacking", "latent_raw", "latent_classifier"):
        for seed in (0, 1):
            results = ex.run_trial(ex.TrialSpec(condition, seed, **SMALL_MAP))
            oracle, = [r for r in results if r.planner == "oracle"]
            assert oracle.objective == pytest.approx(oracle.true_return, abs=1e-9)
            assert len(oracle.cells) == SMALL_MAP["horizon"] + 1
            for r in results:
                assert r.true_return <= oracle.true_return + 1e-9, (condition, seed, r.planner)
            strict += results[0].true_return < oracle.true_return - 1e-9
    assert strict > 0


@pytest.mark.timeout(600)
def test_factorial_granularities_share_the_first_samples():
    """Per-step and trajectory plans use the same first ``factorial_samples`` draws. On one
    sample set the per-step objective sum_t min_i q_i is at most min_i sum_t q_i on every path,
    so the trajectory optimum is at least the per-step optimum and at least the per-step path's
    trajectory objective; each plan's objective is its objective on exactly those samples."""
    from ird_core import planning, posterior
    from ird_core.worlds import lavaland

    spec = ex.TrialSpec("latent_raw", 2, **SMALL_MAP)
    inst = ex.trial_instance(spec)
    test = lavaland.test_mdp(inst)
    reference = posterior.proxy_feature_expectations(inst) / (inst.train_horizon + 1)
    by = {r.planner: r for r in ex.run_trial(spec)}
    for z in spec.z_methods:
        scaled = spec.planning_samples(inst, trials.trial_posterior(spec, inst, z).samples)  # as the planners see them
        samples = scaled[: spec.factorial_samples]
        assert by[f"ird_{z}"].cells == planning.plan_path(test, scaled, "per_step", ex.MAIN_BASELINE, reference).cells
        for base in ex.BASELINES:
            step, traj = by[f"{z}/per_step/{base}"], by[f"{z}/trajectory/{base}"]
            assert step.cells == planning.plan_path(test, samples, "per_step", base, reference).cells
            assert step.objective == pytest.approx(
                planning.path_objective(test, step.cells, samples, "per_step", base, reference), abs=1e-9)
            assert traj.objective == pytest.approx(
                planning.path_objective(test, traj.cells, samples, "trajectory" if not traj.fallback else "per_step",
                                        base, reference), abs=1e-9)
            if not traj.fallback:
                assert traj.objective >= step.objective - 1e-9
                assert traj.objective >= planning.path_objective(test, step.cells, samples, "trajectory", base,
                                                                 reference) - 1e-9


def test_factorial_samples_must_fit_the_posterior():
    with pytest.raises(ValueError, match="factorial_samples"):
        ex.TrialSpec("side_effects", 0, num_samples=8, factorial_samples=9)
    with pytest.raises(ValueError, match="z_methods"):
        ex.TrialSpec("side_effects", 0, z_methods=("laplace_z",))


@pytest.mark.parametrize("field, value", [
    ("seed", -1), ("size", 2), ("horizon", 0), ("obs_dim", 2), ("num_samples", 0), ("num_proxy_samples", 0),
    ("beta", float("nan")), ("beta", -1.0), ("num_chains", 0), ("thin", 0), ("max_leapfrog", 0), ("warmup", -1),
])
def test_a_spec_names_a_field_no_trial_can_use(field: str, value: object) -> None:
    """Refused when the spec is made, in the parent, not when a worker first runs the trial."""
    with pytest.raises(ValueError, match=field):
        ex.TrialSpec("latent_raw", **{"seed": 0, field: value})


def test_a_world_file_spec_checks_its_seed_not_the_lavaland_map(tmp_path: Path) -> None:
    ex.TrialSpec(FILE_CONDITION, 0, world=str(tmp_path / "w.yaml"), size=2, obs_dim=0)  # unused by a world file
    with pytest.raises(ValueError, match="seed"):
        ex.TrialSpec(FILE_CONDITION, -1, world=str(tmp_path / "w.yaml"))


@pytest.mark.parametrize("argv, message", [
    (["--seed", "-5"], "seed must be a non-negative int, got -5"),
    (["--size", "2"], "size must be at least 3x3, got 2x2"),
    (["--horizon", "0"], "horizon must be an integer >= 1, got 0"),
    (["--obs-dim", "0"], "obs_dim must be an integer >= 3, got 0"),
    (["--beta", "-1"], "beta: expected a finite number >= 0, got -1.0"),
    (["--num-chains", "0"], "num_chains must be >= 1, got 0"),
])
def test_the_command_line_refuses_a_bad_setting_before_any_trial(tmp_path: Path, capsys, argv: list[str],
                                                                 message: str) -> None:
    out = tmp_path / "out"
    assert cli.main(["--trials", "1", "--workers", "1", "--out", str(out), *argv]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_an_out_that_cannot_be_a_folder_is_refused_before_any_trial(tmp_path: Path, capsys) -> None:
    blocker = tmp_path / "results"
    blocker.write_text("a file where the report's folder would go")
    for out in (blocker, blocker / "sub"):
        assert cli.main(["--trials", "1", "--workers", "1", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert f"--out: cannot make the folder {out}:" in err and "trials (" not in err, err
    assert blocker.read_text() == "a file where the report's folder would go"


@pytest.mark.parametrize("workers", ["0", "-2", "two"])
def test_workers_must_be_a_positive_integer(tmp_path: Path, capsys, workers: str) -> None:
    with pytest.raises(SystemExit) as stop:
        cli.main(["--trials", "1", "--workers", workers, "--out", str(tmp_path / "out")])
    assert stop.value.code == 2
    assert f"argument --workers: expected an integer >= 1, got {workers!r}" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- settings


def test_defaults_are_paper_scale_and_quick_is_the_small_setting():
    mod = cli
    d = ex.TrialSpec("side_effects", 0)
    assert (d.size, d.horizon, d.obs_dim, d.z_methods, d.factorial) == (15, 30, 50, ex.Z_METHODS, True)

    def settings(*argv):
        args = mod.build_parser().parse_args(list(argv))
        mod.resolve_spec_flags(args)
        return mod.spec_settings(args)

    plain = settings()
    assert {k: plain[k] for k in ("size", "horizon", "obs_dim")} == {"size": 15, "horizon": 30, "obs_dim": 50}
    assert ex.TrialSpec("side_effects", 0, **plain) == d
    quick = settings("--quick")
    assert {k: quick[k] for k in ex.QUICK} == ex.QUICK
    assert (quick["size"], quick["horizon"], quick["obs_dim"], quick["factorial_samples"]) == (8, 12, 10, 10)
    mixed = settings("--quick", "--size", "9", "--num-chains", "2")
    assert (mixed["size"], mixed["num_chains"], mixed["horizon"]) == (9, 2, 12)


def test_per_method_sampler_settings():
    mod = cli
    args = mod.build_parser().parse_args(["--quick", "--z-sampler", "sample_z", "num_chains=8", "warmup=200"])
    mod.resolve_spec_flags(args)
    spec = ex.TrialSpec("side_effects", 0, **mod.spec_settings(args))
    assert spec.sampler("sample_z") == ex.SamplerSettings(num_chains=8, warmup=200, thin=4, max_leapfrog=16)
    assert spec.sampler("maxent_z") == ex.SamplerSettings(num_chains=4, warmup=50, thin=4, max_leapfrog=16)
    assert hash(spec) == hash(ex.TrialSpec("side_effects", 0, **mod.spec_settings(args)))
    # the trial's posterior of each method runs with that method's settings
    own = ex.TrialSpec("side_effects", 0, **dict(TINY, sample_z_sampler=ex.SamplerSettings(3, 12, 2, 4)))
    inst = ex.trial_instance(own)
    sz, mz = trials.trial_posterior(own, inst, "sample_z"), trials.trial_posterior(own, inst, "maxent_z")
    assert (sz.num_chains, sz.warmup, mz.num_chains, mz.warmup) == (3, 12, TINY["num_chains"], TINY["warmup"])
    long = mod.build_parser().parse_args(["--z-sampler", "sample_z", "warmup_max_leapfrog=64", "trajectory_length=3"])
    mod.resolve_spec_flags(long)
    recipe = mod.spec_settings(long)["sample_z_sampler"]
    assert (recipe.warmup_max_leapfrog, recipe.trajectory_length) == (64, 3.0)
    for item in ("trajectory_length=long", "trajectory_length=-1"):
        wrong = mod.build_parser().parse_args(["--z-sampler", "sample_z", item])
        mod.resolve_spec_flags(wrong)
        with pytest.raises(ValueError, match="trajectory_length"):
            mod.spec_settings(wrong)
    bad = mod.build_parser().parse_args(["--z-sampler", "sample_z", "chains=8"])
    mod.resolve_spec_flags(bad)
    with pytest.raises(ValueError, match="FIELD=INTEGER"):
        mod.spec_settings(bad)
    with pytest.raises(ValueError, match="num_chains"):
        ex.SamplerSettings(num_chains=0, warmup=1, thin=1, max_leapfrog=1)
    for bad_limit in (0, 2.5, True, None):
        with pytest.raises(ValueError, match="traj_work_limit"):
            ex.TrialSpec("side_effects", 0, traj_work_limit=bad_limit)
    with pytest.raises(ValueError, match="give_up_after"):
        ex.SamplerSettings(num_chains=2, warmup=1, thin=1, max_leapfrog=1, give_up_after=-1)
    # give_up_after reaches the sampler's stopping rule (0: never give up)
    assert ex.SamplerSettings(2, 1, 1, 1, max_iterations=9, give_up_after=5).run_until().give_up_after == 5
    assert ex.SamplerSettings(2, 1, 1, 1, max_iterations=9).run_until().give_up_after == 0


@pytest.mark.timeout(300)
def test_dask_scheduler_and_worker_processes_match_local_pool(tmp_path):
    """The documented local cluster: a ``dask scheduler`` and a ``dask worker`` process on
    127.0.0.1 reproduce the local pool's results exactly."""
    import os
    import socket
    import subprocess
    import sys

    import distributed

    mod = cli
    specs = ex.make_specs(["side_effects"], 2, 5, **TINY)
    local = mod.run_local(specs, 1)
    with socket.socket() as s:  # a free port; the scheduler binds it right away
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    address = f"tcp://127.0.0.1:{port}"
    dask = str(Path(sys.executable).with_name("dask"))
    env = dict(os.environ, PYTHONPATH=str(ROOT), OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    procs = []
    try:
        with (tmp_path / "scheduler.log").open("w") as log:
            procs.append(subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                                           "--no-dashboard"], cwd=tmp_path, env=env, stdout=log, stderr=log))
        with (tmp_path / "worker.log").open("w") as log:
            procs.append(subprocess.Popen([dask, "worker", address, "--nworkers", "2", "--nthreads", "1",
                                           "--no-dashboard"], cwd=tmp_path, env=env, stdout=log, stderr=log))
        with distributed.Client(address, timeout=120) as client:
            client.wait_for_workers(2, timeout=120)
            remote = mod.run_dask(specs, client)
    finally:
        for proc in reversed(procs):
            proc.terminate()
        for proc in reversed(procs):
            try:
                proc.wait(timeout=60)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
    assert _key(local) == _key(remote)


def test_sampler_settings_follow_the_weight_space_dimension():
    small = ex.SamplerSettings(3, 10, 1, 4, kernel="elliptical")
    settings = ex.SamplerSettings(2, 10, 1, 4, small_dim=4, small=small)
    assert (settings.for_dim(4), settings.for_dim(5), ex.SamplerSettings(2, 10, 1, 4).for_dim(1).kernel) == \
        (small, settings, "hmc")
    with pytest.raises(ValueError, match="kernel"):
        ex.SamplerSettings(2, 10, 1, 4, kernel="nuts")
    for small_dim, kernel, chains in ((4, "elliptical", 3), (3, "hmc", 2)):  # side_effects: d = 4
        spec = ex.TrialSpec("side_effects", 0, **dict(TINY, sample_z_sampler=ex.SamplerSettings(
            2, 10, 1, 4, small_dim=small_dim, small=small)))
        post = trials.trial_posterior(spec, ex.trial_instance(spec), "sample_z")
        assert (post.kernel, post.num_chains) == (kernel, chains)
    # the paper-scale defaults: Sample-Z's small weight spaces independence + slice, 50-d HMC; MaxEnt-Z HMC
    default = ex.TrialSpec("side_effects", 0)
    assert (default.sampler("sample_z").for_dim(4).kernel, default.sampler("sample_z").for_dim(50).kernel,
            default.sampler("maxent_z").for_dim(4).kernel) == ("independence_elliptical", "hmc", "hmc")


def test_trajectory_settings_reach_the_sampler(monkeypatch):
    seen = []

    def capture(*args, **kwargs):
        seen.append(kwargs)
        raise RuntimeError("captured")

    monkeypatch.setattr(trials.posterior, "sample_joint_posterior", capture)
    for settings, want in ((ex.SamplerSettings(4, 10, 1, 8), (None, None)),
                           (ex.SamplerSettings(4, 10, 1, 8, warmup_max_leapfrog=64, trajectory_length=3.0), (64, 3.0))):
        spec = ex.TrialSpec("side_effects", 0, **dict(TINY, sample_z_sampler=settings))
        with pytest.raises(RuntimeError, match="captured"):
            trials.trial_posterior(spec, ex.trial_instance(spec), "sample_z")
        assert (seen[-1]["warmup_max_leapfrog"], seen[-1]["trajectory_length"]) == want
    with pytest.raises(ValueError, match="trajectory_length"):
        ex.SamplerSettings(4, 10, 1, 8, trajectory_length=float("inf"))
    with pytest.raises(ValueError, match="warmup_max_leapfrog"):
        ex.SamplerSettings(4, 10, 1, 8, warmup_max_leapfrog=-1)


def test_ros_entry_point_is_the_core_command_line_plus_via_ros(tmp_path, capsys):
    """ird_ros.apps.experiments parses the core flags plus --via-ros and refuses --world with it."""
    from ird_ros.apps import experiments as app

    args = app.build_parser().parse_args(["--via-ros", "--quick"])
    assert args.via_ros and args.quick and args.trials is None
    assert "--via-ros" in app.build_parser().format_help() and "--via-ros" not in cli.build_parser().format_help()
    world = str(ROOT / "worlds" / "figure1.yaml")
    assert app.main(["--via-ros", "--world", world, "--out", str(tmp_path)]) == 2
    assert "--world: not supported with --via-ros" in capsys.readouterr().err
    # The graph's parameters decide the model: a model flag away from its default would be ignored.
    for flags, named in ((["--training-worlds", "3"], "--training-worlds"),
                         (["--novelty-feature"], "--novelty-feature"), (["--hypothesis", "rff"], "--hypothesis"),
                         (["--temperature", "0.5"], "--temperature"),
                         (["--risk", "cvar", "--risk-level", "0.1"], "--risk")):
        assert app.main(["--via-ros", *flags, "--out", str(tmp_path)]) == 2, flags
        assert f"{named}: not supported with --via-ros" in capsys.readouterr().err


@pytest.mark.timeout(600)
def test_chunks_merge_into_the_report_of_one_run(tmp_path, capsys):
    """Runs over other conditions and seeds, merged in any order, give one run's report (to the
    csv's 6 significant digits), its trials in that run's order; chunks that clash are refused."""
    common = ["--workers", "1", "--no-factorial", *TINY_ARGS]
    single = tmp_path / "single"
    assert cli.main(["--trials", "2", "--out", str(single), "--conditions", "side_effects", "reward_hacking",
                     *common]) == 0
    chunks = {name: tmp_path / name for name in ("hacking", "side0", "side1")}
    assert cli.main(["--trials", "2", "--out", str(chunks["hacking"]), "--conditions", "reward_hacking",
                     *common]) == 0
    for seed in (0, 1):
        assert cli.main(["--trials", "1", "--seed", str(seed), "--out", str(chunks[f"side{seed}"]),
                         "--conditions", "side_effects", *common]) == 0
    merged = tmp_path / "merged"
    order = [chunks["side1"], chunks["hacking"], chunks["side0"]]
    from ird_ros.apps import experiments as app  # scripts/run_experiments.py's program

    assert app.main(["--report-only", "--out", str(merged), "--merge", *map(str, order)]) == 0

    def rows(path, name):
        with (path / name).open() as fh:
            return list(csv.DictReader(fh))

    def same(a, b):
        for key in a:
            if key in ("infer_seconds", "mean_infer_seconds"):  # timings differ between runs
                continue
            try:
                assert float(a[key]) == pytest.approx(float(b[key]), rel=1e-5, abs=1e-9, nan_ok=True), key
            except ValueError:
                assert a[key] == b[key], key

    for name in ("results.csv", "trials.csv"):
        merged_rows, single_rows = rows(merged, name), rows(single, name)
        assert len(merged_rows) == len(single_rows) > 0
        for a, b in zip(merged_rows, single_rows, strict=True):
            same(a, b)
    text = (merged / "results.md").read_text()
    assert "seed=0..1 in 3 chunks" in text and "trials=2" in text and text.count(" && ") == 2
    single_text = (single / "results.md").read_text()
    table = single_text[single_text.index("## Figure 4"):]
    assert text[text.index("## Figure 4"):] == table
    # A report rewritten from its own files is the same report.
    assert cli.main(["--report-only", "--out", str(single)]) == 0
    assert (single / "results.md").read_text() == single_text
    back = report.read_trials_csv(single / "trials.csv")
    assert [(r.condition, r.seed, r.planner, r.cells) for r in back] == \
        [(r["condition"], int(r["seed"]), r["planner"], tuple(tuple(map(int, c.split(","))) for c in r["cells"].split()))
         for r in rows(single, "trials.csv")]
    # The committed copy is gzipped: read as it is, the same rows.
    (tmp_path / "trials.csv.gz").write_bytes(gzip.compress((single / "trials.csv").read_bytes()))
    assert repr(report.read_trials_csv(tmp_path / "trials.csv.gz")) == repr(back)  # repr: nan == nan
    # Clashes are refused with exit status 2 and a message naming the problem.
    capsys.readouterr()
    assert cli.main(["--report-only", "--out", str(merged), "--merge", str(chunks["side0"]),
                     str(chunks["side0"])]) == 2
    assert "--merge: the chunks share seeds" in capsys.readouterr().err
    other = tmp_path / "other_beta"
    assert cli.main(["--trials", "1", "--seed", "5", "--beta", "7", "--out", str(other), "--conditions",
                     "side_effects", *common]) == 0
    capsys.readouterr()
    assert cli.main(["--report-only", "--out", str(merged), "--merge", str(chunks["side0"]), str(other)]) == 2
    assert "--merge: the chunks' settings differ" in capsys.readouterr().err
    assert cli.main(["--report-only", "--out", str(merged), "--merge", str(tmp_path / "missing")]) == 2
    assert "cannot read" in capsys.readouterr().err
    blocker = tmp_path / "a_file"
    blocker.write_text("not a folder")
    assert cli.main(["--report-only", "--out", str(blocker / "report"), "--merge", str(chunks["side0"])]) == 2
    assert f"--out: cannot make the folder {blocker / 'report'}:" in capsys.readouterr().err
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "run.json").write_text((other / "run.json").read_text())
    (empty / "trials.csv").write_text((other / "trials.csv").read_text().splitlines()[0] + "\n")
    assert cli.main(["--report-only", "--out", str(empty)]) == 2
    assert "--report-only: no trials to report" in capsys.readouterr().err
    (empty / "trials.csv").write_text((other / "trials.csv").read_text().replace(",side_effects,5,", ",side_effects,x,"))
    assert cli.main(["--report-only", "--out", str(empty)]) == 2
    assert "trials.csv line 2" in capsys.readouterr().err
    assert app.main(["--report-only", "--via-ros", "--out", str(merged)]) == 2
    assert "--report-only: not with --via-ros" in capsys.readouterr().err
