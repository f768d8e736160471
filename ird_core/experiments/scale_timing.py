"""What a converged posterior and a plan cost on a map of a given size (``scripts/bench_scale.py``).

One timing (:func:`time_trial`) is one Lavaland trial's evidence, posterior and plans, with the
experiments' own settings (:class:`ird_core.experiments.trials.TrialSpec`, its Z-method's
``SamplerSettings``) except the stopping rule: the chains run until split R-hat
``<= RUN_UNTIL_R_HAT`` **and** bulk ESS ``>= min_ess`` (400 by default: Vehtari et al. 2021, four
chains), not the trials' ``num_samples / 2``, capped at ``max_iterations`` per chain. The phases:

- ``evidence_seconds``: the proxy observation (the proxy's feature counts in training and, for
  Sample-Z, the feature counts of its ``num_proxy_samples`` prior-drawn proxies);
- ``sample_seconds``: the sampler, warm-up included;
- ``plan_seconds``: the main IRD plan (per step, training-features baseline, the spec's risk
  measure) from all the posterior's samples; ``literal_seconds``: the literal proxy's plan (one
  exact DP), the plan a map of this size costs without IRD.

The draws are deterministic (seeded as the trials); the times are the machine's.
"""

from __future__ import annotations

import dataclasses
import time
import warnings
from dataclasses import dataclass

from ird_core import planning, posterior
from ird_core.experiments.trials import (
    MAIN_BASELINE,
    MAIN_GRANULARITY,
    Z_METHODS,
    TrialSpec,
    posterior_seeds,
    trial_instance,
)
from ird_core.vocabulary import ZMethod
from ird_core.worlds import lavaland

__all__ = ["ScaleTiming", "time_trial", "TIMING_COLUMNS"]


@dataclass(frozen=True)
class ScaleTiming:
    """One trial's costs at one map size (seconds, wall clock) and its posterior's diagnostics."""

    condition: str
    seed: int
    size: int
    horizon: int
    method: str
    dim: int  # the weight space's dimension
    evidence_seconds: float
    sample_seconds: float
    plan_seconds: float
    literal_seconds: float
    r_hat_max: float
    ess_min: float
    iterations: int  # post-warm-up iterations per chain
    evaluations: int  # batched log-density(+gradient) calls, warm-up included
    converged: bool  # R-hat and ESS both met before the cap
    stop_reason: str

    @property
    def posterior_seconds(self) -> float:
        """Evidence plus sampling: what a converged posterior costs from the proxy on."""
        return self.evidence_seconds + self.sample_seconds


#: The columns of a timing table (:class:`ScaleTiming`'s fields).
TIMING_COLUMNS: tuple[str, ...] = tuple(ScaleTiming.__dataclass_fields__)


def time_trial(spec: TrialSpec, method: str, min_ess: float = 400.0, max_iterations: int = 2000) -> ScaleTiming:
    """Time ``spec``'s evidence, posterior (``method``, run until R-hat and ``min_ess``) and plans.

    Raises:
        ValueError: naming ``method``, ``min_ess`` or ``max_iterations`` when out of range.
    """
    if method not in Z_METHODS:
        raise ValueError(f"method: expected one of {Z_METHODS}, got {method!r}")
    if not min_ess >= 0:
        raise ValueError(f"min_ess: must be >= 0, got {min_ess!r}")
    if int(max_iterations) < 1:
        raise ValueError(f"max_iterations: must be >= 1, got {max_iterations!r}")
    inst = trial_instance(spec)
    model = spec.observation_model()
    sampler_seed, evidence_seed = posterior_seeds(spec, method)  # the trial's own posterior
    start = time.perf_counter()
    observations = posterior.proxy_observations(
        inst, spec.num_proxy_samples if method == ZMethod.SAMPLE_Z else None, evidence_seed,
        spec.prior_sigma, observation_model=model)
    evidence = time.perf_counter() - start
    settings = spec.sampler(method).for_dim(observations[0].dim)
    options = settings.options()
    options["until_converged"] = dataclasses.replace(
        options["until_converged"], min_ess=float(min_ess), max_iterations=max(int(max_iterations), 1))
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # convergence is reported in the row
        post = posterior.sample_joint_posterior(observations, spec.beta, method, spec.num_samples, sampler_seed,
                                                spec.prior_sigma, observation_model=model, **options)
    sample = time.perf_counter() - start
    test = lavaland.test_mdp(inst)
    reference = posterior.proxy_feature_expectations(inst, model) / (inst.train_horizon + 1)
    start = time.perf_counter()
    planning.plan_path(test, post.samples, MAIN_GRANULARITY, MAIN_BASELINE, reference, **spec.main_risk())
    plan = time.perf_counter() - start
    start = time.perf_counter()
    planning.plan_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights[None], "literal")
    literal = time.perf_counter() - start
    return ScaleTiming(
        condition=spec.condition, seed=spec.seed, size=spec.size, horizon=spec.horizon, method=method,
        dim=int(observations[0].dim), evidence_seconds=evidence, sample_seconds=sample, plan_seconds=plan,
        literal_seconds=literal, r_hat_max=float(post.r_hat_max), ess_min=float(post.ess_min),
        iterations=int(post.iterations), evaluations=int(post.num_evaluations),
        converged=bool(post.r_hat_max <= post.run_until.r_hat and post.ess_min >= min_ess),
        stop_reason=str(post.stop_reason))
