"""Literal and risk-averse planning against posterior samples (docs/spec.md section 4)."""

from __future__ import annotations

from ird_core.planning.planners import (
    BASELINES,
    MODES,
    SOLVERS,
    STATISTICS,
    Plan,
    PlanningTimeout,
    check_plan_arguments,
    check_plan_size,
    check_start,
    path_objective,
    per_step_reward,
    plan_path,
    plan_work,
    reward_baselines,
    reward_spread,
    risk_map,
    sample_cell_rewards,
)

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
]
