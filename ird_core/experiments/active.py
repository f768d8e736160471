"""The designer in the loop (docs/spec.md section 7): does asking the designer a few questions
recover what risk-averse IRD gives up? Pure numpy/scipy, no ROS, no parallelism (the command
line, :mod:`ird_core.experiments.active_cli`, maps :func:`run_trial` over seeds).

One trial (:func:`run_trial`) = one seeded Lavaland instance of one condition:

1. ``literal``: the proxy's optimal path on the test map (the floor, as in Figure 4).
2. ``oracle``: the optimal path under the TRUE reward, i.e. the per-cell
   :data:`ird_core.worlds.lavaland.TRUE_TERRAIN_REWARD` of the test map, by exact dynamic programming
   (the ceiling: no path has a higher true return).
3. IRD: the posterior given the proxy (MaxEnt-Z by default), the main IRD planner of the
   experiments (``per_step`` x ``training_features``, exact DP on every sample). Then, per query
   strategy (``info_gain``, ``random``), up to ``max(query_counts)`` rounds: propose a query of
   ``num_options`` paths on the test map (the query world: the map the robot is about to drive,
   where lava and gold are) from the current samples, let the simulated designer answer
   (Boltzmann on each option's true return, ``designer_beta``), add the answer as a
   ``ChoiceObservation`` (``choice_beta``) to all the evidence so far, re-sample the posterior
   (warm-started from the previous one) and, at each count in ``query_counts``, plan again.
   ``num_queries = 0`` is the same posterior and plan for both strategies.

Pairing: both strategies start from the same posterior and, in round ``j``, use the same
sampler and designer seeds (derived from the instance seed and ``j`` only), so they differ only
in the questions asked. Every number is a pure function of the :class:`ActiveSpec`.

When the posterior samples plan fewer distinct paths on the test map than ``num_options``
there is nothing to ask (``queries.NotEnoughCandidates``): the round is skipped, the posterior
and plan stay as they are, and the record says so (``asked`` counts the questions really
asked).

Choice model. The simulated designer answers by the Boltzmann rule on the options' true
returns with ``designer_beta`` (default 1: a 1-unit better path is chosen with probability 0.73,
a 3-unit better one with 0.95; lava costs 10, so lava questions are answered almost surely
right). The robot's ``ChoiceObservation`` uses ``choice_beta``, by default the same number: the
robot knows how reliable its designer is, and with ``w`` = the true weights (indicator
conditions) its choice model is exactly the designer's. A path's feature counts span ``T + 1``
cells, so one answer already moves the posterior by several prior standard deviations along
the options' feature difference.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Iterable, Sequence

import numpy as np

from ird_core import mdp, planning, posterior
from ird_core.checks import check_int, check_real
from ird_core.designer import queries
from ird_core.designer.candidates import PlanSettings
from ird_core.experiments import statistics
from ird_core.experiments.trials import MAIN_BASELINE, QUICK, TrialSpec, trial_seed
from ird_core.planning.sample_scale import SAMPLE_SCALES
from ird_core.vocabulary import STRATEGIES, PlanMode, ZMethod, parse
from ird_core.worlds import evaluation, lavaland

__all__ = [
    "STRATEGIES",
    "ORACLE_QUERY",
    "EXPERIMENT_STRATEGIES",
    "QUERY_COUNTS",
    "DEFAULT_DESIGNER_BETA",
    "CHAINS",
    "ActiveSpec",
    "ActiveResult",
    "ActiveSummary",
    "SUMMARY_COLUMNS",
    "RESULT_COLUMNS",
    "make_specs",
    "run_trial",
    "aggregate",
    "paired_difference",
    "gap_closed",
]

QUERY_COUNTS: tuple[int, ...] = (0, 1, 2, 3, 5)
DEFAULT_DESIGNER_BETA: float = 1.0
#: The query chosen with the true reward (``queries.propose_oracle_query``): the headroom.
ORACLE_QUERY: str = "oracle_query"
#: ``ActiveSpec.chains``: the posteriors' chain recipes (:meth:`ActiveSpec.sampler_options`).
CHAINS: tuple[str, ...] = ("fixed", "converged")
#: The experiment's strategies: the library's, then the oracle query.
EXPERIMENT_STRATEGIES: tuple[str, ...] = STRATEGIES + (ORACLE_QUERY,)


# The Lavaland experiments' small sampler settings, shared so that both experiments stay comparable.
_SMALL = TrialSpec("side_effects", 0, **QUICK)


@dataclass(frozen=True)
class ActiveSpec:
    """Everything one trial depends on. The map and the observations are the paper's (15x15,
    T = 30, 50-d observations in the latent conditions, as in Figure 4); the sampler settings are
    the main experiment's recipe for ``method``, run until converged (``chains="converged"``,
    :meth:`sampler_options`; 64 samples, beta 50), or with ``chains="fixed"`` the small
    fixed-length ones (4 chains; warm-up and leapfrog cap per weight-space size,
    :meth:`chain_settings`), with MaxEnt-Z by default. The designer model is the
    calibrated one (``temperature``; ``prior_sigma`` None: ``1 / (temperature * feature scale)``,
    ``ird_core.posterior.calibration``)."""

    condition: str
    seed: int
    size: int = 15
    horizon: int = 30
    obs_dim: int = TrialSpec.obs_dim
    num_samples: int = _SMALL.num_samples
    beta: float = _SMALL.beta
    prior_sigma: "float | None" = None
    temperature: float = posterior.CALIBRATED_TEMPERATURE
    method: str = ZMethod.MAXENT_Z.value
    num_chains: int = _SMALL.num_chains
    warmup: "int | None" = None  # None: per weight-space size (:meth:`chain_settings`)
    thin: int = _SMALL.thin
    max_leapfrog: "int | None" = None  # None: per weight-space size (:meth:`chain_settings`)
    # Warm-up of each re-sample after an answer; None: the library's ``DEFAULT_WARM_WARMUP`` (50
    # for MaxEnt-Z; shorter warm-ups leave more re-samples unconverged, docs/benchmarks.md).
    warm_warmup: "int | None" = None
    # Chain recipe (:meth:`sampler_options`): "converged", the main experiment's recipe for the
    # spec's method, run until converged; "fixed", the small fixed-length MaxEnt-Z chains.
    chains: str = "converged"
    # The IRD plans' samples, as in the main experiment (``TrialSpec.sample_scale``):
    # "training_spread" rescales each to span one unit over the training map before the per-step
    # min (Rob's plan and the plan the queries are about), "none" plans them as they are.
    sample_scale: str = "training_spread"
    query_counts: tuple[int, ...] = QUERY_COUNTS
    strategies: tuple[str, ...] = EXPERIMENT_STRATEGIES
    num_options: int = 2
    designer_beta: float = DEFAULT_DESIGNER_BETA
    choice_beta: "float | None" = None  # None: designer_beta

    @property
    def answer_beta(self) -> float:
        """The rationality the robot assumes for an answer."""
        return self.designer_beta if self.choice_beta is None else float(self.choice_beta)

    def chain_settings(self, dim: int) -> dict:
        """``warmup``, ``max_leapfrog`` and ``warmup_max_leapfrog`` of a cold posterior in ``dim``
        dimensions: the spec's where given, else the experiments' MaxEnt-Z recipe for that size
        (``TrialSpec.maxent_z_sampler.for_dim``: 50 and 16 up to d = 10, 100 and 64 with 32-step
        warm-up trajectories above, where 16-step chains stay unconverged on the calibrated
        designer's posterior)."""
        recipe = TrialSpec("side_effects", 0).maxent_z_sampler.for_dim(dim)
        return dict(warmup=recipe.warmup if self.warmup is None else self.warmup,
                    max_leapfrog=recipe.max_leapfrog if self.max_leapfrog is None else self.max_leapfrog,
                    warmup_max_leapfrog=recipe.warmup_max_leapfrog or None)

    def sampler_options(self, dim: int, warm: bool) -> dict:
        """``posterior.sample_joint_posterior``'s sampler keywords for a posterior in ``dim``
        dimensions: the cold one (``warm`` False) or a re-sample after an answer, warm-started
        from the previous posterior (``warm`` True, warm-up ``warm_warmup``).

        ``chains`` "fixed": ``num_chains`` HMC chains of ``thin * ceil(num_samples / num_chains)``
        iterations with :meth:`chain_settings`'s warm-up and leapfrog caps, for both methods.
        "converged": the main experiment's recipe for ``method`` at that size
        (``TrialSpec.sampler(method).for_dim(dim)``: its kernel, chains and warm-up, run until
        split R-hat <= 1.05 and bulk ESS >= num_samples / 2 or its iteration cap or give-up rule
        stops it), for the cold posterior and every re-sample; ``num_chains``, ``thin``,
        ``warmup`` and ``max_leapfrog`` are not used."""
        if self.chains == "converged":
            options = TrialSpec(self.condition, self.seed).sampler(self.method).for_dim(dim).options()
            if warm:
                options["warmup"] = self.warm_warmup
            return options
        chain = self.chain_settings(dim)
        return dict(num_chains=self.num_chains, thin=self.thin, max_leapfrog=chain["max_leapfrog"],
                    warmup_max_leapfrog=chain["warmup_max_leapfrog"],
                    warmup=self.warm_warmup if warm else chain["warmup"])

    def __post_init__(self) -> None:
        if self.sample_scale not in SAMPLE_SCALES:
            raise ValueError(f"sample_scale: expected one of {SAMPLE_SCALES}, got {self.sample_scale!r}")
        if self.chains not in CHAINS:
            raise ValueError(f"chains: expected one of {CHAINS}, got {self.chains!r}")
        if self.chains == "converged" and (self.warmup is not None or self.max_leapfrog is not None):
            raise ValueError("warmup, max_leapfrog: the 'converged' chains use the main experiment's recipe; "
                             "leave them unset (None) or choose chains='fixed'")
        if self.prior_sigma is not None and not (math.isfinite(self.prior_sigma) and self.prior_sigma > 0):
            raise ValueError(f"prior_sigma must be a finite number > 0 or None, got {self.prior_sigma!r}")
        lavaland.check_instance_arguments(self.condition, self.seed, self.size, self.horizon, self.obs_dim)
        parse(ZMethod, self.method, "method")
        check_real("beta", self.beta, positive=False)
        posterior.ObservationModel(temperature=self.temperature)  # names temperature when out of range
        for name, least in (("num_samples", 1), ("num_chains", 1), ("thin", 1)):
            check_int(name, getattr(self, name), least)
        for name, least in (("warmup", 0), ("max_leapfrog", 1), ("warm_warmup", 0)):
            if getattr(self, name) is not None:
                check_int(name, getattr(self, name), least)
        counts = tuple(self.query_counts)
        if not counts or any(not isinstance(c, (int, np.integer)) or c < 0 for c in counts) \
                or list(counts) != sorted(set(counts)):
            raise ValueError(f"query_counts: expected increasing non-negative integers, got {counts!r}")
        for s in self.strategies:
            if s not in EXPERIMENT_STRATEGIES:
                raise ValueError(f"strategies: expected a subset of {EXPERIMENT_STRATEGIES}, got {s!r}")
        if self.num_options < 2:
            raise ValueError(f"num_options: expected >= 2, got {self.num_options}")
        for name in ("designer_beta", "choice_beta"):
            value = getattr(self, name)
            if value is None and name == "choice_beta":
                continue
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"{name}: expected a finite value >= 0, got {value!r}")


@dataclass(frozen=True)
class ActiveResult:
    """One plan's outcome in one trial. ``strategy`` is ``literal``, ``oracle``, ``info_gain`` or
    ``random``; ``num_queries`` the answers planned on (0 for literal and oracle), ``asked``
    how many of them were real questions (fewer when the samples had nothing left to ask),
    ``information_gain`` the mean expected information gain (nats) of the questions asked so far
    (NaN if none), ``answers_correct`` how many answers picked an option of the highest true
    return, ``r_hat_max`` the posterior's diagnostic (NaN for literal and oracle)."""

    condition: str
    seed: int
    strategy: str
    num_queries: int
    asked: int
    touched_lava: bool
    reached_target: bool
    reached_gold: bool
    true_return: float
    information_gain: float
    answers_correct: int
    r_hat_max: float
    cells: tuple[tuple[int, int], ...]
    changed: bool = False


def make_specs(conditions: Iterable[str], trials: int, seed: int = 0, **settings) -> list[ActiveSpec]:
    """``trials`` specs per condition (instance seeds ``seed + i``, paired across conditions)."""
    return [ActiveSpec(c, trial_seed(seed, i), **settings) for c in conditions for i in range(trials)]


def _seed(seed: int, *keys: int) -> int:
    return int(np.random.SeedSequence([int(seed), *keys]).generate_state(1)[0] % (2**31))


def _result(inst: lavaland.LavalandInstance, strategy: str, num_queries: int, cells: Sequence[tuple[int, int]], *,
            asked: int = 0,
            gains: "list[float] | None" = None, correct: int = 0, r_hat: float = math.nan,
            changed: bool = False) -> ActiveResult:
    labels = inst.test_labels
    return ActiveResult(inst.condition, inst.seed, strategy, num_queries, asked,
                        evaluation.touches_lava(labels, cells), evaluation.reaches_target(labels, cells),
                        evaluation.reaches_gold(labels, cells), evaluation.true_return(labels, cells),
                        float(np.mean(gains)) if gains else math.nan, correct, r_hat,
                        tuple((int(r), int(c)) for r, c in cells), bool(changed))


def run_trial(spec: ActiveSpec) -> list[ActiveResult]:
    """Literal, oracle, and per strategy the IRD plan after each count of answered queries."""
    inst = lavaland.make_instance(spec.condition, spec.seed, size=spec.size, horizon=spec.horizon,
                                  obs_dim=spec.obs_dim)
    test = lavaland.test_mdp(inst)
    out = [_result(inst, "literal", 0, planning.plan_path(lavaland.test_mdp(inst, proxy=True),
                                                          inst.proxy_weights[None], "literal").cells)]
    true_cells = lavaland.TRUE_TERRAIN_REWARD[inst.test_labels].astype(np.float64)
    out.append(_result(inst, "oracle", 0, mdp.optimal_path(test, true_cells)[0]))

    # Sample-Z's proxy counts are computed once, in the proxy's own space (latent_classifier),
    # and shared by every re-sample, like the proxy's own counts.
    num_proxy = posterior.DEFAULT_NUM_PROXY_SAMPLES if spec.method == ZMethod.SAMPLE_Z else None
    model = posterior.ObservationModel(temperature=spec.temperature)
    proxy, = posterior.proxy_observations(inst, num_proxy, _seed(inst.seed, 2), spec.prior_sigma,
                                          observation_model=model)
    reference = proxy.proxy_features / (inst.train_horizon + 1)

    resampled: dict[tuple, posterior.Posterior] = {}

    def sample(evidence: list, round_index: int, initial: "posterior.Posterior | None") -> posterior.Posterior:
        # Strategies that asked the same questions and got the same answers share the re-sample
        # (its seeds depend on the round only, so it would be the same draw).
        key = (round_index, id(initial)) + tuple((o.option_features.tobytes(), o.chosen) for o in evidence[1:])
        if key not in resampled:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # R-hat is recorded per result instead
                resampled[key] = posterior.sample_joint_posterior(
                    evidence, spec.beta, spec.method, spec.num_samples, _seed(inst.seed, 1, round_index),
                    spec.prior_sigma, initial=initial, observation_model=model,
                    **spec.sampler_options(proxy.dim, warm=initial is not None))
        return resampled[key]

    rob = PlanSettings(MAIN_BASELINE, reference, inst.training_maps if spec.sample_scale == "training_spread" else None)

    def plan(post: posterior.Posterior) -> tuple[tuple[int, int], ...]:
        return planning.plan_path(test, rob.scaled(post.samples), PlanMode.PER_STEP, MAIN_BASELINE, reference).cells

    def propose(strategy: str, samples: np.ndarray, j: int) -> "queries.Query | None":
        try:
            if strategy == ORACLE_QUERY:
                return queries.propose_oracle_query(test, samples, spec.answer_beta, true_cells, spec.designer_beta,
                                                    spec.num_options, rob, seed=_seed(inst.seed, 2, j))
            return queries.propose_query(test, samples, spec.answer_beta, spec.num_options, strategy,
                                         seed=_seed(inst.seed, 2, j), plan=rob)
        except queries.NotEnoughCandidates:
            return None  # nothing to ask

    first = sample([proxy], 0, None)
    first_cells = plan(first)
    last = max(spec.query_counts)
    for strategy in spec.strategies:
        post, cells, evidence = first, first_cells, [proxy]
        gains: list[float] = []
        correct = 0
        for j in range(last + 1):
            if j > 0:
                query = propose(strategy, post.samples, j)
                if query is not None:
                    returns = np.array([evaluation.true_return(inst.test_labels, c) for c in query.option_cells])
                    designer = np.random.default_rng(_seed(inst.seed, 3, j))
                    chosen = queries.simulated_answer(returns, spec.designer_beta, designer)
                    correct += bool(returns[chosen] == returns.max())
                    gains.append(float(query.information_gain))
                    evidence = evidence + [posterior.ChoiceObservation(query.option_features, chosen,
                                                                       spec.answer_beta)]
                    post = sample(evidence, j, post)
                    cells = plan(post)
            if j in spec.query_counts:
                out.append(_result(inst, strategy, j, cells, asked=len(gains), gains=gains, correct=correct,
                                   r_hat=post.r_hat_max, changed=cells != first_cells))
    return out


# --------------------------------------------------------------------------- aggregation

SUMMARY_COLUMNS: tuple[str, ...] = (
    "condition", "strategy", "num_queries", "trials", "lava_fraction", "lava_ci_low", "lava_ci_high",
    "target_fraction", "target_ci_low", "target_ci_high", "gold_fraction", "gold_ci_low", "gold_ci_high",
    "mean_return", "return_ci_low", "return_ci_high", "mean_asked", "mean_information_gain",
    "answers_correct_fraction", "max_r_hat", "nonconverged", "changed_fraction")

RESULT_COLUMNS: tuple[str, ...] = (
    "condition", "seed", "strategy", "num_queries", "asked", "touched_lava", "reached_target",
    "reached_gold", "true_return", "information_gain", "answers_correct", "r_hat_max", "cells", "changed")


@dataclass(frozen=True)
class ActiveSummary:
    """One (condition, strategy, num_queries) cell: fractions with 95% Wilson intervals, the
    mean true return with a 95% Student-t interval (:mod:`ird_core.experiments.statistics`)."""

    condition: str
    strategy: str
    num_queries: int
    trials: int
    lava_fraction: float
    lava_ci_low: float
    lava_ci_high: float
    target_fraction: float
    target_ci_low: float
    target_ci_high: float
    gold_fraction: float
    gold_ci_low: float
    gold_ci_high: float
    mean_return: float
    return_ci_low: float
    return_ci_high: float
    mean_asked: float
    mean_information_gain: float
    answers_correct_fraction: float
    max_r_hat: float
    nonconverged: int
    changed_fraction: float = math.nan


def aggregate(results: Iterable[ActiveResult]) -> list[ActiveSummary]:
    """One summary per (condition, strategy, num_queries), in first-seen order."""
    groups = statistics.group_by(results, lambda r: (r.condition, r.strategy, r.num_queries))
    return [_summary(key, rs) for key, rs in groups.items()]


def _summary(key: tuple[str, str, int], rs: list[ActiveResult]) -> ActiveSummary:
    condition, strategy, count = key
    gains = [r.information_gain for r in rs if not math.isnan(r.information_gain)]
    asked = sum(r.asked for r in rs)
    return ActiveSummary(
        condition, strategy, count, len(rs), *statistics.proportion([r.touched_lava for r in rs]),
        *statistics.proportion([r.reached_target for r in rs]), *statistics.proportion([r.reached_gold for r in rs]),
        *statistics.t_interval([r.true_return for r in rs]),
        asked / len(rs), float(np.mean(gains)) if gains else math.nan,
        sum(r.answers_correct for r in rs) / asked if asked else math.nan,
        *statistics.convergence(r.r_hat_max for r in rs), sum(r.changed for r in rs) / len(rs))


def _returns_by_seed(results: Iterable[ActiveResult], condition: str, strategy: str, count: int) -> dict[int, float]:
    return {r.seed: r.true_return for r in results
            if r.condition == condition and r.strategy == strategy and r.num_queries == count}


def paired_difference(results: "list[ActiveResult]", condition: str, a: tuple[str, int],
                      b: tuple[str, int]) -> tuple[float, float, float, int]:
    """Mean per-trial difference of true return, ``(strategy, count)`` ``a`` minus ``b``, on the
    seeds both have: ``(mean, ci_low, ci_high, n)`` with a 95% Student-t interval."""
    return statistics.paired_difference(_returns_by_seed(results, condition, *a),
                                        _returns_by_seed(results, condition, *b))


def gap_closed(summaries: "list[ActiveSummary]", condition: str, strategy: str, count: int) -> float:
    """Share of the literal-to-oracle mean-return gap that ``strategy`` after ``count`` queries
    closes: ``(R - R_literal) / (R_oracle - R_literal)`` (1 = oracle, 0 = literal, negative =
    below literal; NaN without the three cells or with no gap)."""
    by = {(s.condition, s.strategy, s.num_queries): s.mean_return for s in summaries}
    try:
        low, high, value = by[condition, "literal", 0], by[condition, "oracle", 0], by[condition, strategy, count]
    except KeyError:
        return math.nan
    return statistics.gap_share(low, high, value)
