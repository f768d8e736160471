"""Literal and risk-averse planning against posterior samples (docs/spec.md section 4).

Modules: ``planners`` (``plan_path``, baselines, objectives), ``arguments`` (the checks a caller
can run before planning), ``risk`` (reward spread and risk map), ``sample_scale`` (samples in
units of their training spread), ``trajectory_solver`` (the exact
trajectory mode) with ``trajectory_bounds`` (its DP tables), ``trajectory_limits`` (time and work
limits) and ``trajectory_milp`` (its HiGHS MILP).
"""

from __future__ import annotations

from ird_core.planning.arguments import SOLVERS, check_plan_arguments, check_plan_size, check_start, plan_work
from ird_core.planning.planners import (
    Plan,
    PlanningTimeout,
    path_objective,
    per_step_reward,
    plan_path,
    reward_baselines,
    sample_cell_rewards,
)
from ird_core.planning.risk import reward_spread, risk_map
from ird_core.planning.sample_scale import SAMPLE_SCALES, normalise_samples, training_spread, worst_step_by_terrain
from ird_core.vocabulary import BASELINES, MODES, STATISTICS

__all__ = [
    "MODES",
    "BASELINES",
    "SOLVERS",
    "STATISTICS",
    "Plan",
    "PlanningTimeout",
    "check_start",
    "check_plan_arguments",
    "check_plan_size",
    "plan_work",
    "reward_baselines",
    "sample_cell_rewards",
    "per_step_reward",
    "path_objective",
    "plan_path",
    "reward_spread",
    "risk_map",
    "SAMPLE_SCALES",
    "normalise_samples",
    "training_spread",
    "worst_step_by_terrain",
]
