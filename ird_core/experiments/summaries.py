"""The Lavaland experiments' aggregation (docs/spec.md section 5): one :class:`CellSummary` per
experiment x condition x planner of :func:`ird_core.experiments.trials.run_trial`'s results.

Invariants: fractions come with 95% Wilson score intervals, the mean true return with a 95%
Student-t interval, and every IRD planner's share of the literal-to-oracle return gap with a 95%
paired bootstrap interval over the seeds its literal and oracle rows share
(:mod:`ird_core.experiments.statistics`); literal and oracle rows have no gap (NaN). Summaries
come in the order their cells first appear in the results.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Iterable

import numpy as np

from ird_core.experiments.statistics import convergence, group_by, paired_gap_closed, proportion, t_interval
from ird_core.experiments.trials import TrialResult

__all__ = ["RESULT_COLUMNS", "CellSummary", "aggregate"]

#: The columns of ``results.csv``: :class:`CellSummary`'s fields.
RESULT_COLUMNS: tuple[str, ...] = (
    "experiment", "condition", "planner", "z_approx", "granularity", "baseline", "trials",
    "lava_fraction", "lava_ci_low", "lava_ci_high", "target_fraction", "target_ci_low",
    "target_ci_high", "mean_true_return", "return_ci_low", "return_ci_high", "gap_closed", "gap_ci_low",
    "gap_ci_high", "fallbacks",
    "mean_infer_seconds", "max_r_hat", "nonconverged")


@dataclass(frozen=True)
class CellSummary:
    """One (experiment, condition, planner) cell of :func:`aggregate`: fractions with 95% Wilson
    intervals, the mean true return with a 95% Student-t interval, the share of the
    literal-to-oracle gap closed with its 95% paired bootstrap interval (:mod:`.statistics`)."""

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
    gap_closed: float  # share of the literal-to-oracle gap (gap_closed()); NaN for literal and oracle
    gap_ci_low: float
    gap_ci_high: float
    fallbacks: int
    mean_infer_seconds: float
    max_r_hat: float
    nonconverged: int

    def row(self) -> dict[str, object]:
        """The summary as a ``{column: value}`` row (:data:`RESULT_COLUMNS`)."""
        return dataclasses.asdict(self)


def _paired_gap(groups: dict[tuple[str, str, str], list[TrialResult]], condition: str,
                rs: list[TrialResult]) -> tuple[float, float, float]:
    """``statistics.gap_closed`` of IRD results ``rs`` against the main literal and oracle of
    their condition, over the seeds all three have; NaN without them (literal and oracle rows too)."""
    literal, oracle = groups.get(("main", condition, "literal")), groups.get(("main", condition, "oracle"))
    if not rs[0].z_approx or literal is None or oracle is None:
        return math.nan, math.nan, math.nan
    return paired_gap_closed(*({r.seed: r.true_return for r in g} for g in (literal, oracle, rs)))


def aggregate(results: Iterable[TrialResult]) -> list[CellSummary]:
    """One summary per (experiment, condition, planner), in first-seen order."""
    groups = group_by(results, lambda r: (r.experiment, r.condition, r.planner))
    return [_summary(key, rs, _paired_gap(groups, key[1], rs)) for key, rs in groups.items()]


def _summary(key: tuple[str, str, str], rs: list[TrialResult], gap: tuple[float, float, float]) -> CellSummary:
    experiment, condition, planner = key
    first = rs[0]
    return CellSummary(
        experiment, condition, planner, first.z_approx, first.granularity, first.baseline, len(rs),
        *proportion([r.touched_lava for r in rs]), *proportion([r.reached_target for r in rs]),
        *t_interval([r.true_return for r in rs]), *gap,
        sum(r.fallback for r in rs), float(np.mean([r.infer_seconds for r in rs])),
        *convergence(r.r_hat_max for r in rs))
