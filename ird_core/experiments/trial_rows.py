"""One planner's outcome in one Lavaland trial (docs/spec.md section 5): the row of ``trials.csv``
and how a path's outcome is judged on the instance's ground truth."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

from ird_core.worlds import evaluation, lavaland

__all__ = ["TrialResult", "TRIAL_COLUMNS", "outcome"]


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


def outcome(inst: lavaland.LavalandInstance, cells: Sequence[tuple[int, int]]) -> tuple[bool, bool, float]:
    """(touched lava, reached a target, true return; NaN without true rewards) of a path."""
    labels = inst.test_labels
    rewards = inst.true_terrain_reward
    return evaluation.touches_lava(labels, cells), evaluation.reaches_target(labels, cells), \
        (math.nan if rewards is None else evaluation.true_return(labels, cells, rewards))


#: The columns of ``trials.csv``: :class:`TrialResult`'s fields.
TRIAL_COLUMNS: tuple[str, ...] = (
    "experiment", "condition", "seed", "planner", "z_approx", "granularity", "baseline",
    "touched_lava", "reached_target", "true_return", "objective", "solver", "fallback",
    "infer_seconds", "r_hat_max", "acceptance_rate", "cells")
