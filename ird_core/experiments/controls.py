"""The risk frontier and the control planners of a Lavaland trial (docs/spec.md section 5).

Frontier (``TrialSpec.frontier``): from each posterior, the per-step plan (training-features
baseline) at every risk level of :data:`FRONTIER_RISKS`; ``cvar`` at ``alpha = 1`` is the
risk-neutral IRD planner (the posterior mean reward) and ``min`` the paper's. Rows
``experiment = "frontier"``, ``planner = "<posterior>/<risk label>"``.

Controls (``TrialSpec.controls``), each answering "is it IRD's shape of uncertainty, or plain
caution?":

- ``prior_only``: the same risk-averse planner on samples of the prior alone (``beta = 0``: the
  posterior is the prior ``N(0, sigma^2 I)``, drawn exactly);
- ``novelty``: the literal proxy kept off cells unlike any training cell
  (:mod:`ird_core.planning.novelty`), no posterior;
- ``sample_z_<other>``: Sample-Z under the other counts reading (optimal vs MaxEnt), same seeds;
- ``sample_z_no_own``: Sample-Z without the candidate's own term in the normaliser.

Rows ``experiment = "controls"`` with the main planner's risk measure; with the frontier on, the
prior and the other reading also get frontier rows. Every control is paired with the main
planners by the trial seed.
"""

from __future__ import annotations

import math
from typing import Any, Callable

import numpy as np

from ird_core import planning, posterior
from ird_core.experiments.trial_rows import TrialResult, outcome
from ird_core.planning.novelty import novel_cells, novelty_avoiding_path
from ird_core.planning.risk_measures import Risk, check_risk
from ird_core.vocabulary import ProxyCounts, ZMethod
from ird_core.worlds import lavaland

__all__ = ["FRONTIER_RISKS", "frontier_results", "control_results"]

#: The frontier's risk levels, most cautious first within each measure.
FRONTIER_RISKS: tuple[Risk, ...] = (
    check_risk("min"),
    *(check_risk("cvar", a) for a in (0.05, 0.1, 0.25, 0.5, 1.0)),
    *(check_risk("mean_sd", lam) for lam in (3.0, 2.0, 1.0, 0.5)),
)

_GRANULARITY, _BASELINE = "per_step", "training_features"


def _row(experiment: str, spec: Any, planner: str, z_approx: str, inst: lavaland.LavalandInstance,
         plan: planning.Plan, diag: tuple[float, float, float]) -> TrialResult:
    return TrialResult(experiment, spec.condition, spec.seed, planner, z_approx, _GRANULARITY, _BASELINE,
                       *outcome(inst, plan.cells), plan.objective, plan.solver, False, *diag, plan.cells)


def _plan(inst: lavaland.LavalandInstance, scaled: np.ndarray, reference: np.ndarray, risk: Risk) -> planning.Plan:
    """The per-step plan of samples already scaled as the trial's IRD planners scale them
    (``spec.planning_samples``)."""
    level = None if risk.measure == "min" else risk.level
    return planning.plan_path(lavaland.test_mdp(inst), scaled, _GRANULARITY, _BASELINE, reference,
                              risk=risk.measure, risk_level=level)


def frontier_results(spec: Any, inst: lavaland.LavalandInstance, name: str, samples: "posterior.Posterior | np.ndarray",
                     reference: np.ndarray, diag: tuple[float, float, float]) -> list[TrialResult]:
    """One ``frontier`` row per :data:`FRONTIER_RISKS` level from ``samples``' per-step plans."""
    weights = samples.samples if isinstance(samples, posterior.Posterior) else samples
    scaled = spec.planning_samples(inst, weights)  # once for every level
    return [_row("frontier", spec, f"{name}/{risk.label()}", name, inst, _plan(inst, scaled, reference, risk), diag)
            for risk in FRONTIER_RISKS]


def _main_risk(spec: Any) -> Risk:
    return check_risk(spec.risk, None if spec.risk == "min" else spec.risk_level)


def _prior_samples(spec: Any, inst: lavaland.LavalandInstance) -> np.ndarray:
    seed = int(np.random.SeedSequence([int(spec.seed), 200]).generate_state(1)[0])
    dim = inst.test_features.shape[2]
    return spec.prior_sigma_for(inst) * np.random.default_rng(seed).standard_normal((spec.num_samples, dim))


def control_results(spec: Any, inst: lavaland.LavalandInstance, reference: np.ndarray,
                    posterior_of: Callable[[str, posterior.ObservationModel], posterior.Posterior]
                    ) -> list[TrialResult]:
    """The control rows of one trial (module docstring); ``posterior_of(method, model)`` draws a
    posterior of the trial with the trial's seeds."""
    risk, rows = _main_risk(spec), []
    nan3 = (0.0, math.nan, math.nan)
    prior = _prior_samples(spec, inst)
    scaled_prior = spec.planning_samples(inst, prior)
    rows.append(_row("controls", spec, "prior_only", "prior", inst, _plan(inst, scaled_prior, reference, risk), nan3))
    if spec.frontier:
        rows += frontier_results(spec, inst, "prior", prior, reference, nan3)
    cells = novelty_avoiding_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights,
                                  novel_cells(list(inst.training_maps), inst.test_features))
    rows.append(TrialResult("controls", spec.condition, spec.seed, "novelty", "novelty", "literal", "none",
                            *outcome(inst, cells), math.nan, "dp", False, *nan3,
                            tuple((int(r), int(c)) for r, c in cells)))
    if ZMethod.SAMPLE_Z in spec.z_methods:
        other = ProxyCounts.MAXENT if spec.counts == ProxyCounts.OPTIMAL else ProxyCounts.OPTIMAL
        for name, model in ((f"sample_z_{other}", spec.observation_model(other.value)),
                            ("sample_z_no_own", spec.observation_model(own_term=False))):
            post = posterior_of(ZMethod.SAMPLE_Z.value, model)
            diag = (math.nan, post.r_hat_max, post.acceptance_rate)
            ref = posterior.proxy_feature_expectations(inst, model) / (inst.train_horizon + 1)
            scaled = spec.planning_samples(inst, post.samples)
            rows.append(_row("controls", spec, name, name, inst, _plan(inst, scaled, ref, risk), diag))
            if spec.frontier and name != "sample_z_no_own":
                rows += frontier_results(spec, inst, name, post, ref, diag)
    return rows
