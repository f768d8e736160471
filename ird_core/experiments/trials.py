"""Lavaland experiments (docs/spec.md section 5): literal vs IRD, Sample-Z vs MaxEnt-Z, and the
appendix factorial of min-granularity x reward baseline. Pure numpy/scipy, no ROS.

One trial (:func:`run_trial`) = one seeded Lavaland instance of one condition:

1. ``literal``: the proxy's optimal path on the proxy's test features (for latent_classifier the
   classifier outputs with the designer's weights), ``planning.plan_path(mode="literal")``
   (the floor).
2. ``oracle``: the optimal path under the TRUE reward (the instance's ``true_terrain_reward`` per
   test cell), by exact dynamic programming: the ceiling, no path has a higher true return. A
   world file without true rewards has no oracle row.
3. For each Z-approximation (``sample_z``, ``maxent_z``): ONE posterior (seeded from the trial
   seed and the method), then from the same samples
   - the main-experiment IRD planner (Figure 4): :data:`MAIN_GRANULARITY` x
     :data:`MAIN_BASELINE` = ``per_step`` x ``training_features``. Why: it is the combination the
     paper's appendix recommends (the per-step min is the more robust granularity, the training
     features baseline the best baseline), it is solved exactly by dynamic programming on all
     ``K`` samples (no MILP, no subsample), so the main result does not depend on a solver
     time limit;
   - the factorial: ``per_step`` and ``trajectory`` x ``initial_state``, ``training_features``,
     ``log_z``, BOTH granularities on the same first ``factorial_samples`` posterior samples
     (draw-major pooled, so spread over the chains), so the granularity effect is not confounded
     with the number of samples. ``trajectory`` is the exact label search of
     ``ird_core.planning`` with a per-plan work limit (``traj_work_limit`` label expansions, not
     seconds, so a trial is the same on any machine); if the solver does not prove optimality
     within it, the trial falls back to the ``per_step`` plan of the same samples and baseline
     and is flagged (``fallback``), counted in the aggregated table.
4. Outcomes on the executed path (Rob executes plans exactly, so the executed path is the
   plan's cells): touched lava, reached a target, true return (``ird_core.worlds.lavaland``).

Seeding: trial ``i`` of a run with seed ``S`` uses instance seed ``S + i`` for every condition
(conditions are paired by seed, see ``lavaland``), the Sample-Z proxy prior features and the
posterior sampler get seeds derived with ``numpy.random.SeedSequence([trial_seed, k])`` (for
Lavaland the trial seed is the instance seed).
A trial is a pure function of its :class:`TrialSpec`, so results do not depend on the number
of workers or the order in which trials finish.

World files (``TrialSpec.world``, ``ird-experiments --world FILE``): the trial runs
on the file's instance (:func:`ird_core.worlds.world_file.load_world`; its size, horizons and
observations are the file's) and the posterior is the joint one over every training world of
the file (``posterior.proxy_observations``, docs/spec.md section 7). The world is fixed, so the trials of a
file differ only in the trial seed ``S + i``, which seeds the sampler and the Sample-Z proxies:
they measure how the outcome varies with the posterior's randomness, not with the map. The true
return uses the file's true rewards (NaN when the file gives none).

Aggregation: :mod:`ird_core.experiments.summaries` (one row per experiment x condition x planner).

Settings: :class:`TrialSpec`'s defaults are the paper's scale (15x15 maps, T = 30, 50-d
observations); :data:`QUICK` is the small setting for a fast look (8x8, T = 12, 10-d). The
sampler settings can differ per Z-approximation (:class:`SamplerSettings`,
``TrialSpec.sample_z_sampler`` / ``maxent_z_sampler``; ``None`` = the shared fields).
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from ird_core import mcmc, mdp, planning, posterior
from ird_core.checks import check_int, check_real
from ird_core.experiments.controls import control_results, frontier_results
from ird_core.experiments.trial_rows import TRIAL_COLUMNS, TrialResult, outcome
from ird_core.hypothesis import DEFAULT_RFF_FEATURES, HYPOTHESES, NOVELTY_VALUES, HypothesisSpace
from ird_core.planning.risk_measures import check_risk
from ird_core.planning.sample_scale import SAMPLE_SCALES, normalise_samples
from ird_core.vocabulary import PROXY_COUNTS, Baseline, PlanMode, ZMethod
from ird_core.worlds import evaluation, lavaland, world_file
from ird_core.worlds.training_worlds import check_training_worlds, with_training_worlds

__all__ = [
    "Z_METHODS",
    "RUN_UNTIL_R_HAT",
    "GRANULARITIES",
    "BASELINES",
    "MAIN_GRANULARITY",
    "MAIN_BASELINE",
    "SamplerSettings",
    "TrialSpec",
    "QUICK",
    "TrialResult",
    "trial_seed",
    "trial_instance",
    "trial_posterior",
    "posterior_seeds",
    "outcome",
    "make_specs",
    "run_trial",
    "TRIAL_COLUMNS",
]

#: The factorial's levels, in the order of the report's rows and columns.
Z_METHODS: tuple[str, ...] = (ZMethod.SAMPLE_Z.value, ZMethod.MAXENT_Z.value)
GRANULARITIES: tuple[str, ...] = (PlanMode.PER_STEP.value, PlanMode.TRAJECTORY.value)
BASELINES: tuple[str, ...] = (Baseline.INITIAL_STATE.value, Baseline.TRAINING_FEATURES.value, Baseline.LOG_Z.value)
MAIN_GRANULARITY = PlanMode.PER_STEP.value
MAIN_BASELINE = Baseline.TRAINING_FEATURES.value


#: Split R-hat at which a run-until-converged posterior stops (``SamplerSettings.max_iterations``):
#: below the reported threshold ``posterior.R_HAT_CONVERGED`` (1.1), so that stopping at the
#: first good check does not put the reported values just under it.
RUN_UNTIL_R_HAT: float = 1.05
#: Iterations per chain between a run-until-converged posterior's checks after its first
#: (``posterior.RunUntil.check_every``) in every default sampler setting: short blocks stop a
#: converged run soon after it converges (docs/benchmarks.md).
CHECK_EVERY: int = 16


@dataclass(frozen=True)
class SamplerSettings:
    """One Z-approximation's MCMC settings (``posterior.sample_joint_posterior``'s keywords).

    ``max_iterations`` 0: a fixed-length run (``thin * ceil(num_samples / num_chains)``
    iterations per chain after warm-up). Above 0: the same run, then extended until split R-hat
    ``<= RUN_UNTIL_R_HAT`` and bulk ESS ``>= num_samples / 2`` or ``max_iterations`` iterations
    per chain (``posterior.RunUntil``; no time budget, so a trial stays a pure function of its
    spec and reproduces bit for bit on any machine).

    ``kernel``: one of ``mcmc.KERNELS``. ``small``, if set, replaces these settings for weight
    spaces of at most ``small_dim`` dimensions (:meth:`for_dim`). ``give_up_after``: 0, or stop
    a run whose split R-hat is still above ``posterior.GIVE_UP_R_HAT`` after that many
    iterations (``posterior.RunUntil.give_up_after``). ``warmup_max_leapfrog``,
    ``trajectory_length``: the sampler's HMC options of those names (0: its defaults).
    ``check_every``: iterations between convergence checks after the first
    (``posterior.RunUntil.check_every``; 0: its default); every default below checks every
    :data:`CHECK_EVERY`.

    The defaults (``TrialSpec.sample_z_sampler`` / ``maxent_z_sampler``; their convergence
    and cost are in docs/benchmarks.md):

    - Sample-Z, d <= 10 (side_effects, reward_hacking): 8 chains of
      ``independence_elliptical`` (a t-proposal jump around the fitted Gaussian, then a slice
      move), 200 warm-up iterations, run until converged for at most 2000 iterations.
    - Sample-Z, d = 50: HMC, 4 chains, 100 warm-up iterations (at most 32 leapfrog steps each
      until the final buffer), then trajectories of 2.5 preconditioned units of at most 64
      steps, at most 300 iterations; a run still above ``posterior.GIVE_UP_R_HAT`` after 50
      iterations gives up.
    - MaxEnt-Z, d <= 10: HMC, 4 chains, 50 warm-up iterations, at most 16 leapfrog steps, at
      most 1000 iterations.
    - MaxEnt-Z, d > 10 (the latent conditions): HMC, 4 chains, 100 warm-up iterations (at most 32
      leapfrog steps until the final buffer), then at most 64 steps, at most 1000 iterations. With
      16 steps the calibrated designer's creased posterior in d = 50 mixes as a random walk:
      chains of 1000 iterations ended with R-hat 1.09-1.21 on tuning seeds 400-402, against
      1.05 after 80-208 iterations, in less time, with 64.

    Every default checks convergence every :data:`CHECK_EVERY` iterations. Sample-Z uses
    ``posterior.DEFAULT_NUM_PROXY_SAMPLES`` proxies: with fewer its posterior does not converge
    within these budgets.
    """

    num_chains: int
    warmup: int
    thin: int
    max_leapfrog: int
    max_iterations: int = 0
    kernel: str = "hmc"
    small_dim: int = 0
    small: "SamplerSettings | None" = None
    give_up_after: int = 0
    warmup_max_leapfrog: int = 0  # 0: the sampler's default
    trajectory_length: float = 0.0  # 0: the sampler's default
    check_every: int = 0  # 0: the sampler's default (posterior.RunUntil.check_every)

    def __post_init__(self) -> None:
        for name in ("num_chains", "thin", "max_leapfrog"):
            if int(getattr(self, name)) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)!r}")
        for name in ("warmup", "max_iterations", "small_dim", "give_up_after", "warmup_max_leapfrog", "check_every"):
            if int(getattr(self, name)) < 0:
                raise ValueError(f"{name} must be >= 0, got {getattr(self, name)!r}")
        if not (math.isfinite(self.trajectory_length) and self.trajectory_length >= 0):
            raise ValueError(f"trajectory_length must be a finite number >= 0, got {self.trajectory_length!r}")
        if self.kernel not in mcmc.KERNELS:
            raise ValueError(f"kernel must be one of {mcmc.KERNELS}, got {self.kernel!r}")

    def for_dim(self, dim: int) -> "SamplerSettings":
        """The settings for a ``dim``-dimensional weight space: ``small`` up to ``small_dim``."""
        return self.small if self.small is not None and dim <= self.small_dim else self

    def run_until(self) -> "posterior.RunUntil | None":
        """The ``until_converged`` criteria, or None for a fixed-length run."""
        if self.max_iterations == 0:
            return None
        return posterior.RunUntil(r_hat=RUN_UNTIL_R_HAT, min_ess=0.0, ess_per_sample=0.5,
                                  max_iterations=self.max_iterations, give_up_after=self.give_up_after,
                                  check_every=self.check_every)

    def settings(self) -> posterior.SamplerSettings:
        """This recipe as the sampler's keyword record (0 = the sampler's default -> None)."""
        return posterior.SamplerSettings(
            num_chains=self.num_chains, warmup=self.warmup, thin=self.thin, max_leapfrog=self.max_leapfrog,
            kernel=self.kernel, warmup_max_leapfrog=self.warmup_max_leapfrog or None,
            trajectory_length=self.trajectory_length or None, until_converged=self.run_until())

    def options(self) -> dict:
        """These settings as ``posterior.sample_joint_posterior``'s keyword arguments."""
        return self.settings().kwargs()


@dataclass(frozen=True)
class TrialSpec:
    """Everything one trial depends on (a trial is a pure function of this).

    Defaults are the experiment defaults of ``ird-experiments`` (:mod:`ird_core.experiments.cli`): the paper's scale
    (15x15 maps, T = 30, 50-d observations); :data:`QUICK` holds the small setting.
    ``num_chains``, ``warmup``, ``thin``, ``max_leapfrog`` are shared by both Z-approximations
    unless ``sample_z_sampler`` / ``maxent_z_sampler`` give that method its own
    (:meth:`sampler`). Every method returns ``num_samples`` draws (the main IRD planner uses all
    of them); the factorial uses the first ``factorial_samples`` for both granularities.
    """

    condition: str
    seed: int
    size: int = 15
    horizon: int = 30
    obs_dim: int = 50
    num_samples: int = 64
    beta: float = 50.0
    prior_sigma: "float | None" = None  # None: calibrated per instance, 1 / (temperature * feature scale)
    num_chains: int = 4
    warmup: int = 50
    thin: int = 4
    max_leapfrog: int = 16
    num_proxy_samples: int = posterior.DEFAULT_NUM_PROXY_SAMPLES  # Sample-Z converges with these (SamplerSettings)
    factorial_samples: int = 16
    traj_work_limit: int = 50_000
    z_methods: tuple[str, ...] = Z_METHODS
    factorial: bool = True
    world: str = ""  # a world file: the trial's instance (size, horizon, obs_dim unused); "" = Lavaland
    counts: str = "maxent"  # the observation model's counts (posterior.ObservationModel)
    temperature: float = posterior.CALIBRATED_TEMPERATURE  # the MaxEnt designer's temperature
    risk: str = "min"  # the main IRD planner's risk measure
    risk_level: float = math.nan  # its level (alpha of cvar, lambda of mean_sd)
    frontier: bool = False  # plan every risk level of FRONTIER_RISKS from every posterior
    controls: bool = False  # the control planners and posteriors (ird_core.experiments.controls)
    sample_scale: str = "training_spread"  # the IRD plans' samples: "training_spread" (planning.sample_scale) or "none"
    novelty_feature: bool = False  # IRD's hypothesis features gain "novel" (ird_core.hypothesis.novelty)
    novelty_value: str = "feature_scale"  # its value on novel cells: one of NOVELTY_VALUES
    hypothesis: str = "linear"  # latent conditions: "rff" = random Fourier features (ird_core.hypothesis.rff)
    rff_features: int = DEFAULT_RFF_FEATURES  # D of the "rff" hypothesis space
    training_worlds: int = 1  # Lavaland training worlds the proxy is observed in (ird_core.worlds.training_worlds)
    sample_z_sampler: SamplerSettings | None = SamplerSettings(
        4, 100, 4, 64, 300, small_dim=10, give_up_after=50, warmup_max_leapfrog=32, trajectory_length=2.5,
        check_every=CHECK_EVERY,
        small=SamplerSettings(8, 200, 4, 32, 2000, kernel="independence_elliptical", check_every=CHECK_EVERY))
    maxent_z_sampler: SamplerSettings | None = SamplerSettings(
        4, 100, 4, 64, 1000, small_dim=10, warmup_max_leapfrog=32, check_every=CHECK_EVERY,
        small=SamplerSettings(4, 50, 4, 16, 1000, check_every=CHECK_EVERY))

    def __post_init__(self) -> None:
        if self.world:
            check_int("seed", self.seed, 0)  # a world file's trial: the file gives map, horizon and features
        else:
            lavaland.check_instance_arguments(self.condition, self.seed, self.size, self.horizon, self.obs_dim)
        check_int("num_samples", self.num_samples, 1)
        check_int("num_proxy_samples", self.num_proxy_samples, 1)
        check_real("beta", self.beta, positive=False)
        SamplerSettings(self.num_chains, self.warmup, self.thin, self.max_leapfrog)  # names the bad field
        if self.prior_sigma is not None and not (math.isfinite(self.prior_sigma) and self.prior_sigma > 0):
            raise ValueError(f"prior_sigma must be a finite number > 0 or None, got {self.prior_sigma!r}")
        if not 1 <= self.factorial_samples <= self.num_samples:
            raise ValueError(f"factorial_samples must be in 1..num_samples={self.num_samples}, "
                             f"got {self.factorial_samples!r}")
        for method in self.z_methods:
            if method not in Z_METHODS:
                raise ValueError(f"z_methods must be drawn from {Z_METHODS}, got {method!r}")
        if self.sample_scale not in SAMPLE_SCALES:
            raise ValueError(f"sample_scale must be one of {SAMPLE_SCALES}, got {self.sample_scale!r}")
        if self.counts not in PROXY_COUNTS:
            raise ValueError(f"counts must be one of {PROXY_COUNTS}, got {self.counts!r}")
        self.observation_model()
        check_risk(self.risk, None if self.risk == "min" else self.risk_level)
        if self.novelty_value not in NOVELTY_VALUES:
            raise ValueError(f"novelty_value must be one of {NOVELTY_VALUES}, got {self.novelty_value!r}")
        if self.hypothesis not in HYPOTHESES:
            raise ValueError(f"hypothesis must be one of {HYPOTHESES}, got {self.hypothesis!r}")
        if isinstance(self.rff_features, bool) or not isinstance(self.rff_features, (int, np.integer)) \
                or self.rff_features < 1:
            raise ValueError(f"rff_features must be an integer >= 1, got {self.rff_features!r}")
        check_training_worlds(self.training_worlds)
        if self.world and self.training_worlds != 1:
            raise ValueError(f"training_worlds: a world file's trial has the file's own training worlds, "
                             f"got {self.training_worlds!r}")
        limit = self.traj_work_limit
        if isinstance(limit, bool) or not isinstance(limit, (int, np.integer)) or limit < 1:
            raise ValueError(f"traj_work_limit must be an integer >= 1 (label expansions), got {limit!r}")

    def hypothesis_space(self) -> HypothesisSpace:
        """IRD's hypothesis space of this spec (``hypothesis``, ``rff_features``, ``novelty_*``)."""
        return HypothesisSpace(self.hypothesis, self.rff_features, self.novelty_feature, self.novelty_value)

    def observation_model(self, counts: str = "", own_term: bool = True) -> posterior.ObservationModel:
        """The posteriors' observation model (``counts`` overrides the spec's)."""
        return posterior.ObservationModel(counts or self.counts, self.temperature, own_term)

    def prior_sigma_for(self, inst: lavaland.LavalandInstance) -> float:
        """The prior standard deviation of ``inst``'s hypothesis space: the spec's, or the calibrated
        one of its temperature and training features (``posterior.calibration``)."""
        return posterior.resolve_prior_sigma(self.prior_sigma, self.temperature, inst.training_maps)

    def planning_samples(self, inst: lavaland.LavalandInstance, samples: np.ndarray) -> np.ndarray:
        """The samples the IRD planners use: ``samples`` in units of their training spread
        (:func:`ird_core.planning.sample_scale.normalise_samples`), or unchanged with ``"none"``."""
        if self.sample_scale == "none":
            return samples
        return normalise_samples(samples, inst.training_maps)

    def main_risk(self) -> dict:
        """``plan_path``'s risk keywords of the main IRD planner."""
        return {"risk": self.risk, "risk_level": None if self.risk == "min" else self.risk_level}

    def sampler(self, method: str) -> SamplerSettings:
        """``method``'s sampler settings: its own field if set, else the shared ones."""
        own = getattr(self, f"{method}_sampler")
        return own if own is not None else SamplerSettings(self.num_chains, self.warmup, self.thin, self.max_leapfrog)


#: The small setting for a fast look (``ird-experiments --quick``; ``ird_core.experiments.active``'s defaults).
QUICK: dict = {"size": 8, "horizon": 12, "obs_dim": 10, "num_samples": 64, "num_chains": 4, "warmup": 50, "thin": 4,
               "max_leapfrog": 16, "num_proxy_samples": 100, "factorial_samples": 10, "traj_work_limit": 1_000_000,
               "sample_z_sampler": None, "maxent_z_sampler": None}


def trial_seed(base_seed: int, index: int) -> int:
    """Instance seed of trial ``index``: ``base_seed + index`` (paired across conditions)."""
    return int(base_seed) + int(index)


def make_specs(conditions: Iterable[str], trials: int, seed: int, **settings) -> list[TrialSpec]:
    """Specs of ``trials`` trials per condition, ordered condition-major."""
    return [TrialSpec(condition=c, seed=trial_seed(seed, i), **settings)
            for c in conditions for i in range(trials)]


def _derived_seed(seed: int, *keys: int) -> int:
    return int(np.random.SeedSequence([int(seed), *keys]).generate_state(1)[0])


def posterior_seeds(spec: TrialSpec, method: str) -> tuple[int, int]:
    """The seeds of ``spec``'s posterior under ``method``: the sampler's, and the proxy
    observations' (Sample-Z's prior-drawn proxies), both derived from ``spec.seed``."""
    return _derived_seed(spec.seed, Z_METHODS.index(method) + 1) % (2**31), _derived_seed(spec.seed, 100)


def trial_posterior(spec: TrialSpec, inst: lavaland.LavalandInstance, method: str,
                    model: "posterior.ObservationModel | None" = None) -> posterior.Posterior:
    """The joint posterior over the instance's training worlds (one for Lavaland), under the
    spec's observation model or ``model`` (the controls' other readings: same seeds)."""
    model = spec.observation_model() if model is None else model
    sampler_seed, evidence_seed = posterior_seeds(spec, method)
    observations = posterior.proxy_observations(
        inst, spec.num_proxy_samples if method == ZMethod.SAMPLE_Z else None, evidence_seed,
        spec.prior_sigma, observation_model=model)
    settings = spec.sampler(method).for_dim(observations[0].dim)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # R-hat is recorded per trial instead
        return posterior.sample_joint_posterior(
            observations, spec.beta, method, spec.num_samples, sampler_seed, spec.prior_sigma,
            observation_model=model, **settings.options())


def trial_instance(spec: TrialSpec) -> lavaland.LavalandInstance:
    """The spec's instance: its world file's, else ``make_instance(condition, seed, ...)`` with
    ``training_worlds`` training worlds (the first is the one-world instance's); with
    ``novelty_feature``, its hypothesis features gain the *novel* feature (``novelty_value`` on
    novel cells); with ``hypothesis`` "rff", the latent conditions' hypothesis features are random
    Fourier features (applied first)."""
    if spec.world:
        inst = world_file.load_world(spec.world)
    else:
        inst = with_training_worlds(lavaland.make_instance(spec.condition, spec.seed, size=spec.size,
                                                           horizon=spec.horizon, obs_dim=spec.obs_dim),
                                    spec.training_worlds)
    return spec.hypothesis_space().apply(inst)


def run_trial(spec: TrialSpec) -> list[TrialResult]:
    """Run one trial: literal and oracle plans, and per Z-approximation one posterior and its IRD plans."""
    inst = trial_instance(spec)
    results: list[TrialResult] = []
    literal = planning.plan_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights[None], "literal")
    results.append(TrialResult("main", spec.condition, spec.seed, "literal", "", "literal", "none",
                               *outcome(inst, literal.cells), literal.objective, literal.solver, False,
                               0.0, math.nan, math.nan, literal.cells))
    test = lavaland.test_mdp(inst)
    if inst.true_terrain_reward is not None:
        true_cells = np.asarray(inst.true_terrain_reward, dtype=np.float64)[inst.test_labels]
        cells, value = mdp.optimal_path(test, true_cells)
        oracle = tuple((int(r), int(c)) for r, c in cells)
        results.append(TrialResult("main", spec.condition, spec.seed, "oracle", "", "oracle", "none",
                                   *outcome(inst, oracle), value, "dp", False, 0.0, math.nan, math.nan, oracle))
    reference = posterior.proxy_feature_expectations(inst, spec.observation_model()) / (inst.train_horizon + 1)
    for method in spec.z_methods:
        t0 = time.perf_counter()
        post = trial_posterior(spec, inst, method)
        seconds = time.perf_counter() - t0
        diag = (seconds, post.r_hat_max, post.acceptance_rate)
        samples = spec.planning_samples(inst, post.samples)
        main = planning.plan_path(test, samples, MAIN_GRANULARITY, MAIN_BASELINE, reference, **spec.main_risk())
        results.append(TrialResult("main", spec.condition, spec.seed, f"ird_{method}", method,
                                   MAIN_GRANULARITY, MAIN_BASELINE, *outcome(inst, main.cells),
                                   main.objective, main.solver, False, *diag, main.cells))
        if spec.frontier:
            results += frontier_results(spec, inst, method, post, reference, diag)
        if spec.factorial:
            plans = _factorial_plans(test, samples[: spec.factorial_samples], reference, spec.traj_work_limit)
            for (gran, base), (plan, fallback) in plans.items():
                results.append(TrialResult("factorial", spec.condition, spec.seed, f"{method}/{gran}/{base}",
                                           method, gran, base, *outcome(inst, plan.cells), plan.objective,
                                           plan.solver, fallback, *diag, plan.cells))
    if spec.controls:
        results += control_results(spec, inst, reference, lambda method, model: trial_posterior(spec, inst, method, model))
    return results


def _factorial_plans(test: mdp.GridMDP, samples: np.ndarray, reference: np.ndarray, work_limit: int
                     ) -> dict[tuple[str, str], tuple[planning.Plan, bool]]:
    """Every granularity x baseline plan of the same ``(N, d)`` samples, with its fallback flag
    (the trajectory solver hit ``work_limit`` label expansions: the per_step plan of the same
    samples stands in). A work limit, not a time limit, so a trial is the same on any machine."""
    plans: dict[tuple[str, str], tuple[planning.Plan, bool]] = {}
    for base in BASELINES:
        plans[PlanMode.PER_STEP, base] = (planning.plan_path(test, samples, PlanMode.PER_STEP, base, reference), False)
    for base in BASELINES:
        try:
            plans[PlanMode.TRAJECTORY, base] = (planning.plan_path(test, samples, PlanMode.TRAJECTORY, base, reference,
                                                            work_limit=work_limit), False)
        except RuntimeError:
            plans[PlanMode.TRAJECTORY, base] = (plans[PlanMode.PER_STEP, base][0], True)
    return plans
