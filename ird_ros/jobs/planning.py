"""The planner node's worker jobs (no ROS): a validated ``/ird/plan`` request as :class:`PlanJob`.

The plan (docs/spec.md section 4) is ``ird_core.planning.plan_path(mdp, weights, mode, baseline,
reference_features, time_limit=time_limit)``. When the request left ``reference_features`` empty
and the baseline needs them, :class:`ReferenceJob` computes them in the worker first: the proxy's
expected feature counts in the training MDP divided by (training horizon + 1), in the space of the
weights (``ird_core.posterior.proxy_feature_counts / (T + 1)``, as
``ird_core.posterior.proxy_feature_expectations / (T + 1)``).

A trajectory plan that reaches ``time_limit`` is answered with the best path found, its exact
objective and the proven upper bound (``PlanningTimeout.plan``), marked as a fallback.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ird_core import planning
from ird_core import posterior as core_inference
from ird_core.mdp import GridMDP
from ird_core.vocabulary import Baseline, PlanMode

__all__ = ["ReferenceJob", "PlanJob", "PlanOutcome", "reference_features", "run_plan"]


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
    try:
        return PlanOutcome(planning.plan_path(job.mdp, job.weights, job.mode, job.baseline, reference,
                                              time_limit=job.time_limit))
    except planning.PlanningTimeout as exc:
        return PlanOutcome(exc.plan, f"FALLBACK, not proven optimal: {exc}")
