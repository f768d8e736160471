"""Fast tests of ird_core.experiments and scripts/run_experiments.py (tiny maps, few samples)."""

from __future__ import annotations

import csv
import importlib.util
import math
from pathlib import Path

import pytest

from ird_core import experiments as ex

ROOT = Path(__file__).resolve().parents[1]

TINY = dict(size=5, horizon=5, obs_dim=4, num_samples=16, num_chains=2, warmup=10, thin=1, max_leapfrog=4,
            num_proxy_samples=20, traj_samples=4, traj_time_limit=5.0)
TINY_ARGS = ["--size", "5", "--horizon", "5", "--obs-dim", "4", "--num-samples", "16", "--num-chains", "2",
             "--warmup", "10", "--thin", "1", "--max-leapfrog", "4", "--num-proxy-samples", "20",
             "--traj-samples", "4", "--traj-time-limit", "5"]


def _script():
    spec = importlib.util.spec_from_file_location("run_experiments", ROOT / "scripts" / "run_experiments.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


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
    assert len(a) == 1 + 2 * (1 + len(ex.GRANULARITIES) * len(ex.BASELINES))
    for r in a:
        assert len(r.cells) == TINY["horizon"] + 1
    # the main IRD plan is the factorial's per_step/training_features plan of the same posterior
    by = {r.planner: r for r in a}
    for z in ex.Z_METHODS:
        assert by[f"ird_{z}"].cells == by[f"{z}/per_step/training_features"].cells


@pytest.mark.timeout(300)
def test_one_vs_two_workers_identical():
    mod = _script()
    specs = ex.make_specs(["side_effects", "latent_classifier"], 2, 7, **TINY)
    one = mod.run_local(specs, 1)
    two = mod.run_local(specs, 2)
    assert _key(one) == _key(two)


@pytest.mark.timeout(300)
def test_results_csv_columns_and_rows(tmp_path):
    mod = _script()
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
    per_condition = 3 + 2 * len(ex.GRANULARITIES) * len(ex.BASELINES)
    assert len(rows) == 2 * per_condition
    assert all(r["trials"] == "2" for r in rows)
    for name in ("trials.csv", "results.md", "figure4_lava.png", "factorial_sample_z.png", "run.json"):
        assert (out / name).is_file()
    with (out / "trials.csv").open() as fh:
        assert len(list(csv.DictReader(fh))) == 2 * 2 * per_condition


@pytest.mark.timeout(300)
def test_dask_local_cluster_matches_local_pool():
    import distributed  # pinned in requirements.txt: a missing package fails, never skips
    mod = _script()
    specs = ex.make_specs(["reward_hacking"], 2, 11, **TINY)
    local = mod.run_local(specs, 1)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        remote = mod.run_dask(specs, client)
    assert _key(local) == _key(remote)
