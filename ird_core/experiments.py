"""Lavaland experiments (IRD_SPEC.md section 5): literal vs IRD, Sample-Z vs MaxEnt-Z, and the
appendix factorial of min-granularity x reward baseline. Pure numpy/scipy, no ROS.

One trial (:func:`run_trial`) = one seeded Lavaland instance of one condition:

1. ``literal``: the proxy's optimal path on the proxy's test features (for latent_classifier the
   classifier outputs with the designer's weights), ``planning.plan_path(mode="literal")``.
2. For each Z-approximation (``sample_z``, ``maxent_z``): ONE posterior (seeded from the trial
   seed and the method), then from the same samples
   - the main-experiment IRD planner (Figure 4): :data:`MAIN_GRANULARITY` x
     :data:`MAIN_BASELINE` = ``per_step`` x ``training_features``. Why: it is the combination the
     paper's appendix recommends (the per-step min is the more robust granularity, the training
     features baseline the best baseline), it is solved exactly by dynamic programming on all
     ``K`` samples (no MILP, no subsample), so the main result does not depend on a solver
     time limit;
   - the factorial: ``per_step`` and ``trajectory`` x ``initial_state``, ``training_features``,
     ``log_z``. ``trajectory`` is the exact MILP/label search of ``ird_core.planning`` on the
     first ``traj_samples`` posterior samples (draw-major pooled, so spread over the chains),
     with a per-plan time limit; if the solver does not prove optimality in time, the trial
     falls back to the ``per_step`` plan of the same samples and baseline and is flagged
     (``fallback``), counted in the aggregated table.
3. Outcomes on the executed path (Rob executes plans exactly, so the executed path is the
   plan's cells): touched lava, reached a target, true return (``ird_core.lavaland``).

Seeding: trial ``i`` of a run with seed ``S`` uses instance seed ``S + i`` for every condition
(conditions are paired by seed, see ``lavaland``), the Sample-Z proxy prior features and the
posterior sampler get seeds derived with ``numpy.random.SeedSequence([trial_seed, k])`` (for
Lavaland the trial seed is the instance seed).
A trial is a pure function of its :class:`TrialSpec`, so results do not depend on the number
of workers or the order in which trials finish.

World files (``TrialSpec.world``, ``scripts/run_experiments.py --world FILE``): the trial runs
on the file's instance (:func:`ird_core.world_file.load_world`; its size, horizons and
observations are the file's) and the posterior is the joint one over every training world of
the file (``lavaland.proxy_observations``, IRD_SPEC 7). The world is fixed, so the trials of a
file differ only in the trial seed ``S + i``, which seeds the sampler and the Sample-Z proxies:
they measure how the outcome varies with the posterior's randomness, not with the map. The true
return uses the file's true rewards (NaN when the file gives none).

Aggregation (:func:`aggregate`): fractions with 95% Wilson score intervals, mean true return
with a 95% Student-t interval.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np
from scipy import stats

from ird_core import inference, lavaland, planning, world_file

__all__ = [
    "Z_METHODS",
    "GRANULARITIES",
    "BASELINES",
    "MAIN_GRANULARITY",
    "MAIN_BASELINE",
    "TrialSpec",
    "TrialResult",
    "CellSummary",
    "trial_seed",
    "trial_instance",
    "make_specs",
    "run_trial",
    "wilson_interval",
    "t_interval",
    "aggregate",
    "RESULT_COLUMNS",
    "TRIAL_COLUMNS",
]

Z_METHODS: tuple[str, ...] = ("sample_z", "maxent_z")
GRANULARITIES: tuple[str, ...] = ("per_step", "trajectory")
BASELINES: tuple[str, ...] = ("initial_state", "training_features", "log_z")
MAIN_GRANULARITY = "per_step"
MAIN_BASELINE = "training_features"


@dataclass(frozen=True)
class TrialSpec:
    """Everything one trial depends on (a trial is a pure function of this).

    Defaults are the experiment defaults of ``scripts/run_experiments.py`` (chosen to fit 100
    trials per cell of all four conditions into 15 minutes on 2 cores; see the README).
    """

    condition: str
    seed: int
    size: int = 8
    horizon: int = 12
    obs_dim: int = 10
    num_samples: int = 64
    beta: float = 50.0
    prior_sigma: float = 1.0
    num_chains: int = 4
    warmup: int = 50
    thin: int = 4
    max_leapfrog: int = 16
    num_proxy_samples: int = 100
    traj_samples: int = 10
    traj_time_limit: float = 2.0
    z_methods: tuple[str, ...] = Z_METHODS
    factorial: bool = True
    world: str = ""  # a world file: the trial's instance (size, horizon, obs_dim unused); "" = Lavaland


@dataclass(frozen=True)
class TrialResult:
    """One planner's outcome in one trial."""

    experiment: str  # "main" or "factorial"
    condition: str
    seed: int
    planner: str  # "literal", "ird_sample_z", ... or "sample_z/per_step/log_z"
    z_approx: str  # "" for literal
    granularity: str  # "literal", "per_step" or "trajectory"
    baseline: str  # "none" for literal
    touched_lava: bool
    reached_target: bool
    true_return: float
    objective: float
    solver: str
    fallback: bool
    infer_seconds: float
    r_hat_max: float
    acceptance_rate: float
    cells: tuple[tuple[int, int], ...]


def trial_seed(base_seed: int, index: int) -> int:
    """Instance seed of trial ``index``: ``base_seed + index`` (paired across conditions)."""
    return int(base_seed) + int(index)


def make_specs(conditions: Iterable[str], trials: int, seed: int, **settings) -> list[TrialSpec]:
    """Specs of ``trials`` trials per condition, ordered condition-major."""
    return [TrialSpec(condition=c, seed=trial_seed(seed, i), **settings)
            for c in conditions for i in range(trials)]


def _derived_seed(seed: int, *keys: int) -> int:
    return int(np.random.SeedSequence([int(seed), *keys]).generate_state(1)[0])


def _outcome(inst: lavaland.LavalandInstance, cells) -> tuple[bool, bool, float]:
    labels = inst.test_labels
    rewards = inst.true_terrain_reward
    return lavaland.touches_lava(labels, cells), lavaland.reaches_target(labels, cells), \
        (math.nan if rewards is None else lavaland.true_return(labels, cells, rewards))


def _posterior(spec: TrialSpec, inst: lavaland.LavalandInstance, method: str) -> inference.Posterior:
    """The joint posterior over the instance's training worlds (one for Lavaland)."""
    method_index = Z_METHODS.index(method) + 1
    sampler_seed = _derived_seed(spec.seed, method_index) % (2**31)
    observations = lavaland.proxy_observations(
        inst, spec.num_proxy_samples if method == "sample_z" else None, _derived_seed(spec.seed, 100),
        spec.prior_sigma)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # R-hat is recorded per trial instead
        return inference.sample_joint_posterior(
            observations, spec.beta, method, spec.num_samples, sampler_seed, spec.prior_sigma,
            num_chains=spec.num_chains, warmup=spec.warmup, thin=spec.thin, max_leapfrog=spec.max_leapfrog)


def trial_instance(spec: TrialSpec) -> lavaland.LavalandInstance:
    """The spec's instance: its world file's, else ``make_instance(condition, seed, ...)``."""
    if spec.world:
        return world_file.load_world(spec.world)
    return lavaland.make_instance(spec.condition, spec.seed, size=spec.size, horizon=spec.horizon,
                                  obs_dim=spec.obs_dim)


def run_trial(spec: TrialSpec) -> list[TrialResult]:
    """Run one trial: literal plan, and per Z-approximation one posterior and its IRD plans."""
    inst = trial_instance(spec)
    results: list[TrialResult] = []
    literal = planning.plan_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights[None], "literal")
    results.append(TrialResult("main", spec.condition, spec.seed, "literal", "", "literal", "none",
                               *_outcome(inst, literal.cells), literal.objective, literal.solver, False,
                               0.0, math.nan, math.nan, literal.cells))
    reference = lavaland.proxy_feature_expectations(inst) / (inst.train_horizon + 1)
    test = lavaland.test_mdp(inst)
    for method in spec.z_methods:
        t0 = time.perf_counter()
        post = _posterior(spec, inst, method)
        seconds = time.perf_counter() - t0
        diag = (seconds, post.r_hat_max, post.acceptance_rate)
        plans: dict[tuple[str, str], tuple[planning.Plan, bool]] = {}
        grans = GRANULARITIES if spec.factorial else (MAIN_GRANULARITY,)
        bases = BASELINES if spec.factorial else (MAIN_BASELINE,)
        for gran in grans:
            for base in bases:
                if gran == "per_step":
                    plans[gran, base] = (planning.plan_path(test, post.samples, "per_step", base, reference), False)
                    continue
                subset = post.samples[: spec.traj_samples]
                try:
                    plan = planning.plan_path(test, subset, "trajectory", base, reference,
                                              time_limit=spec.traj_time_limit)
                    plans[gran, base] = (plan, False)
                except RuntimeError:
                    plans[gran, base] = (planning.plan_path(test, subset, "per_step", base, reference), True)
        main, _ = plans[MAIN_GRANULARITY, MAIN_BASELINE]
        results.append(TrialResult("main", spec.condition, spec.seed, f"ird_{method}", method,
                                   MAIN_GRANULARITY, MAIN_BASELINE, *_outcome(inst, main.cells),
                                   main.objective, main.solver, False, *diag, main.cells))
        if spec.factorial:
            for (gran, base), (plan, fallback) in plans.items():
                results.append(TrialResult("factorial", spec.condition, spec.seed, f"{method}/{gran}/{base}",
                                           method, gran, base, *_outcome(inst, plan.cells), plan.objective,
                                           plan.solver, fallback, *diag, plan.cells))
    return results


# --------------------------------------------------------------------------- statistics


def wilson_interval(successes: int, n: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a binomial proportion; ``(nan, nan)`` for ``n = 0``."""
    if n <= 0:
        return math.nan, math.nan
    if not 0 <= successes <= n:
        raise ValueError(f"successes must be in 0..{n}, got {successes}")
    z = float(stats.norm.ppf(0.5 + confidence / 2))
    p = successes / n
    denom = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def t_interval(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float, float]:
    """``(mean, low, high)``: Student-t interval of the mean (``low = high = mean`` if n = 1)."""
    x = np.asarray(values, dtype=np.float64)
    if x.size == 0:
        return math.nan, math.nan, math.nan
    mean = float(x.mean())
    if x.size == 1:
        return mean, mean, mean
    half = float(stats.t.ppf(0.5 + confidence / 2, x.size - 1) * x.std(ddof=1) / math.sqrt(x.size))
    return mean, mean - half, mean + half


RESULT_COLUMNS: tuple[str, ...] = (
    "experiment", "condition", "planner", "z_approx", "granularity", "baseline", "trials",
    "lava_fraction", "lava_ci_low", "lava_ci_high", "target_fraction", "target_ci_low",
    "target_ci_high", "mean_true_return", "return_ci_low", "return_ci_high", "fallbacks",
    "mean_infer_seconds", "max_r_hat", "nonconverged")

TRIAL_COLUMNS: tuple[str, ...] = (
    "experiment", "condition", "seed", "planner", "z_approx", "granularity", "baseline",
    "touched_lava", "reached_target", "true_return", "objective", "solver", "fallback",
    "infer_seconds", "r_hat_max", "acceptance_rate", "cells")


@dataclass(frozen=True)
class CellSummary:
    experiment: str
    condition: str
    planner: str
    z_approx: str
    granularity: str
    baseline: str
    trials: int
    lava_fraction: float
    lava_ci_low: float
    lava_ci_high: float
    target_fraction: float
    target_ci_low: float
    target_ci_high: float
    mean_true_return: float
    return_ci_low: float
    return_ci_high: float
    fallbacks: int
    mean_infer_seconds: float
    max_r_hat: float
    nonconverged: int

    def row(self) -> dict:
        return dataclasses.asdict(self)


def aggregate(results: Iterable[TrialResult]) -> list[CellSummary]:
    """One summary per (experiment, condition, planner), in first-seen order."""
    groups: dict[tuple[str, str, str], list[TrialResult]] = {}
    for r in results:
        groups.setdefault((r.experiment, r.condition, r.planner), []).append(r)
    out = []
    for (experiment, condition, planner), rs in groups.items():
        n = len(rs)
        lava = sum(r.touched_lava for r in rs)
        target = sum(r.reached_target for r in rs)
        mean, lo, hi = t_interval([r.true_return for r in rs])
        rhats = [r.r_hat_max for r in rs if not math.isnan(r.r_hat_max)]
        out.append(CellSummary(
            experiment, condition, planner, rs[0].z_approx, rs[0].granularity, rs[0].baseline, n,
            lava / n, *wilson_interval(lava, n), target / n, *wilson_interval(target, n), mean, lo, hi,
            sum(r.fallback for r in rs),
            float(np.mean([r.infer_seconds for r in rs])),
            max(rhats) if rhats else math.nan,
            sum(rh > inference.R_HAT_CONVERGED for rh in rhats)))
    return out
