"""The planner node's worker jobs (no ROS): a validated ``/ird/plan`` request as :class:`PlanJob`.

The plan (docs/spec.md section 4) is ``ird_core.planning.plan_path(mdp, weights, mode, baseline,
reference_features, risk=risk.measure, risk_level=risk.level, time_limit=time_limit)``: never a
``work_limit`` (trajectory CVaR is solved by a MILP that takes a time limit only). When the
request left ``reference_features`` empty and the baseline needs them, :class:`ReferenceJob`
computes them in the worker first: the proxy's expected feature counts in the training MDP divided
by (training horizon + 1), in the space of the weights (``ird_core.posterior.proxy_feature_counts
/ (T + 1)``, as ``ird_core.posterior.proxy_feature_expectations / (T + 1)``).

A trajectory plan that reaches ``time_limit`` is answered with the best path found, its exact
objective and the proven upper bound (``PlanningTimeout.plan``), marked as a fallback.

The risk measure of a request (:func:`request_risk`): ``risk`` "" is the planner's default
measure and, when ``risk_level`` is 0 or NaN, its default level; a level of 0 or NaN is "none"
for ``min``; everything is then checked by ``ird_core.planning.risk_measures.check_risk`` (a
``ValueError`` naming ``risk`` or ``risk_level``, or the caller's names for them), and ``mean_sd``
is refused for ``trajectory`` as ``plan_path`` would, before any work. ``literal`` ignores the
measure (``plan_path`` plans its one weight vector and reports ``min``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ird_core import planning
from ird_core import posterior as core_inference
from ird_core.mdp import GridMDP
from ird_core.planning.risk_measures import MIN_RISK, Risk, check_risk
from ird_core.vocabulary import Baseline, PlanMode, RiskMeasure

__all__ = ["ReferenceJob", "PlanJob", "PlanOutcome", "reference_features", "run_plan", "request_risk",
           "risk_text", "reported_level"]


def _unset(level: float) -> bool:
    """A level of 0 or NaN: none given (the message default is 0)."""
    return level == 0.0 or math.isnan(level)


def request_risk(risk: str, risk_level: float, default: Risk, mode: object = None, *,
                 fields: tuple[str, str] = ("risk", "risk_level")) -> Risk:
    """The checked risk of a request (module doc): ``risk`` "" = ``default``'s measure, with
    ``default``'s level unless ``risk_level`` is set.

    Args:
        risk, risk_level: the request's fields.
        default: the planner's checked default (its parameters ``risk`` and ``risk_level``).
        mode: the plan's mode (``trajectory`` refuses ``mean_sd``), or ``None`` (not known yet).
        fields: the caller's names of the two fields, used in the messages.
    Raises:
        ValueError: starting with ``fields[0]`` or ``fields[1]``.
    """
    level = float(risk_level)
    measure = risk if risk else default.measure
    if not risk and _unset(level):
        level = default.level
    try:
        checked = check_risk(measure, None if measure == RiskMeasure.MIN and _unset(level) else level)
    except ValueError as exc:
        name, rest = str(exc).split(":", 1)
        hint = f" (risk '' = the planner's default {default.measure!r})" if not risk else ""
        raise ValueError(f"{fields[0] if name == 'risk' else fields[1]}:{rest}{hint}") from None
    if checked.measure == RiskMeasure.MEAN_SD and mode == PlanMode.TRAJECTORY:
        raise ValueError(f"{fields[0]}: mean_sd is a per_step risk measure (its trajectory form is not concave); "
                         "use mode 'per_step' or risk 'cvar'" + ("" if risk else " (risk '' = the planner's default)"))
    return checked


def reported_level(risk: Risk) -> float:
    """The level as messages carry it: alpha or lambda, 0 for ``min`` (whose level is NaN)."""
    return 0.0 if risk.measure == RiskMeasure.MIN else float(risk.level)


def risk_text(mode: str, measure: str, level: float) -> str:
    """What a plan maximised, for people: ``"per-step CVaR alpha=0.25"``, ``"trajectory min"``,
    ``"per-step mean - 1 sd"``, ``"literal (the proxy's reward)"``."""
    if mode == PlanMode.LITERAL:
        return "literal (the proxy's reward)"
    granularity = {PlanMode.PER_STEP: "per-step", PlanMode.TRAJECTORY: "trajectory"}.get(mode, str(mode))
    if measure == RiskMeasure.CVAR:
        return f"{granularity} CVaR alpha={level:g}"
    if measure == RiskMeasure.MEAN_SD:
        return f"{granularity} mean - {level:g} sd"
    return f"{granularity} {measure or RiskMeasure.MIN.value}"


@dataclass(frozen=True)
class ReferenceJob:
    """The inputs of the default ``reference_features`` (see the module doc).

    Attributes:
        proxy_mdp: the training map in the proxy's features ``(H, W, p)``, the proxy's training
            start and horizon.
        proxy_weights: ``(p,)``.
        target_features: the training map in the features of the plan's weights, ``(H, W, d)``.
    """

    proxy_mdp: GridMDP
    proxy_weights: np.ndarray
    target_features: np.ndarray


@dataclass(frozen=True)
class PlanJob:
    """A validated request, as the worker process gets it: ``plan_path``'s arguments, with
    ``reference_job`` standing in for ``reference_features`` when those are to be computed."""

    mdp: GridMDP
    weights: np.ndarray
    mode: PlanMode
    baseline: Baseline
    reference_features: np.ndarray | None
    reference_job: ReferenceJob | None
    time_limit: float | None
    risk: Risk = MIN_RISK
    scale_features: "np.ndarray | tuple[np.ndarray, ...] | None" = None  # (H, W, d) training map(s): samples
    # scaled by their spread over them


def reference_features(job: ReferenceJob) -> np.ndarray:
    """``f_ref`` (d,): the proxy's expected training counts of ``target_features`` / (T + 1)."""
    counts = core_inference.proxy_feature_counts(job.proxy_mdp, job.proxy_weights, job.target_features)
    return counts / (job.proxy_mdp.horizon + 1)


@dataclass(frozen=True)
class PlanOutcome:
    """What the worker returns: the plan, and why it is a fallback (``""`` if it is optimal)."""

    plan: planning.Plan
    fallback: str = ""


def run_plan(job: PlanJob) -> PlanOutcome:
    """The worker-process job: the default reference features if asked for, then plan_path.

    A trajectory plan that runs out of ``time_limit`` answers with the best path found, its
    exact objective and the proven upper bound (``PlanningTimeout.plan``), marked as a fallback.
    """
    reference = job.reference_features
    if reference is None and job.reference_job is not None:
        reference = reference_features(job.reference_job)
    weights = job.weights if job.scale_features is None else planning.normalise_samples(job.weights,
                                                                                          job.scale_features)
    try:
        return PlanOutcome(planning.plan_path(job.mdp, weights, job.mode, job.baseline, reference,
                                              risk=job.risk.measure, risk_level=job.risk.level,
                                              time_limit=job.time_limit))
    except planning.PlanningTimeout as exc:
        return PlanOutcome(exc.plan, f"FALLBACK, not proven optimal: {exc}")
