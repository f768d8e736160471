"""The navigator's ROS-free logic: goal validation, stages, Rob's drive and its judgement.

The navigator node (:mod:`ird_ros.nodes.navigator`) serves the ``NavigateIrd`` action; everything
it decides without ROS lives here, testable without DDS (``tests/test_navigation_goals.py``).

Invariants:

- :func:`check_goal` refuses a bad goal before any work starts, with a ``ValueError`` whose
  message starts with the field's name (``method: ...``, ``queries: ...``); the ranges are the
  inference service's (``beta`` in ``ird_core.checks.BETA_RANGE``, ``num_samples`` up to the
  navigator's ``max_num_samples``) and the planner's (``mode`` / ``baseline`` through
  ``ird_core.planning.check_plan_arguments``).
- Risk measures (docs/spec.md section 4): ``risk_measure`` is passed to ``/ird/plan`` as its
  ``risk`` and ``risk_level`` as its ``risk_level``. "" is the planner's default (its parameters;
  ``CheckedGoal.risk_measure`` None), its level only checked to be finite in ``[0, MAX_LAMBDA]``
  here (the planner checks it against its default measure). A named measure is checked as the
  planner checks it (:func:`ird_ros.jobs.planning.request_risk`: ``min`` with level 0, ``cvar``'s
  alpha in (0, 1], ``mean_sd``'s lambda in [0, 100] and never with ``trajectory``), refusals
  naming ``risk_measure`` or ``risk_level``.
- :func:`check_goal_work` refuses, before any work, a goal whose samples the planner (its
  ``max_plan_work``) or the designer questions (the inference node's ``max_query_work``) would
  refuse only after the inference, naming ``num_samples`` and the limit; and resolves ``risk_measure``
  "" against the planner's default measure as the planner will.
- A :class:`DriveTracker` follows Rob's statuses of ONE plan (matched by the plan's stamp key):
  the driven cells are the plan's cells up to the last step Rob reported, start cell first; the
  drive is over at the first status with ``done`` (finished or ``stopped``), or at Rob's first
  status of a NEWER plan (``replaced_by``: someone else's ``/plan`` replaced ours, and Rob drives
  that one now; statuses of older plans are ignored).
- :func:`judge` evaluates driven cells with ``ird_core.worlds.evaluation.evaluate_path`` on the
  ground truth with Rob's policy (a terrain without a true reward earns 0; no true rewards at all:
  the return is NaN), so it equals Rob's own ``RobStatus`` verdict for the same cells.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Mapping, Sequence

import numpy as np

from ird_core import planning
from ird_core.checks import MAX_TEXT_LENGTH, check_real
from ird_core.planning.risk_measures import MAX_LAMBDA, MIN_RISK, Risk
from ird_core.vocabulary import RISK_MEASURES, Baseline, PlanMode, RiskMeasure, ZMethod, parse
from ird_core.worlds.evaluation import evaluate_path
from ird_ros.jobs.ground_truth import evaluation_terrain
from ird_ros.jobs.planning import request_risk
from ird_ros.jobs.work import query_work

__all__ = [
    "NavigationStatus",
    "Stage",
    "RiskMeasure",
    "RISK_MEASURES",
    "CURRENT_POSTERIOR",
    "DEFAULT_LABEL",
    "GoalLimits",
    "CheckedGoal",
    "check_goal",
    "DownstreamLimits",
    "check_goal_work",
    "posterior_summary",
    "Judgement",
    "judge",
    "DriveTracker",
]

CURRENT_POSTERIOR = ""
"""``method`` of a goal that uses the current ``/ird/posterior`` instead of inferring."""

DEFAULT_LABEL = "navigate"
"""The plan label of a goal with an empty ``label``."""


class NavigationStatus(StrEnum):
    """How a navigation goal ended (``NavigateIrd.Result.status``)."""

    SUCCEEDED = "succeeded"
    CANCELED = "canceled"
    ABORTED = "aborted"
    REJECTED = "rejected"


class Stage(StrEnum):
    """What the navigator is doing (``NavigateIrd.Feedback.stage``), in the order it does it."""

    INFERRING = "inferring"
    ASKING = "asking"
    PLANNING = "planning"
    DRIVING = "driving"


@dataclass(frozen=True)
class GoalLimits:
    """The navigator's parameters a goal is checked against and defaulted from."""

    max_queries: int = 5
    max_num_samples: int = 100000
    default_beta: float = 5.0
    default_num_samples: int = 40


@dataclass(frozen=True)
class CheckedGoal:
    """A validated goal with its defaults filled in (``method`` None = the current posterior;
    ``risk_measure`` None = the planner's default measure, ``risk_level`` then passed as given)."""

    method: ZMethod | None
    beta: float
    num_samples: int
    seed: int
    mode: PlanMode
    baseline: Baseline
    risk_measure: RiskMeasure | None
    risk_level: float
    queries: int
    label: str

    @property
    def uses_current_posterior(self) -> bool:
        return self.method is None


def _integer(name: str, value: object, low: int, high: int, high_name: str = "") -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= int(value) <= high:
        bound = f"{high_name}={high}" if high_name else str(high)
        raise ValueError(f"{name}: expected an integer in [{low}, {bound}], got {value!r}")
    return int(value)


def check_goal(*, method: object, beta: object, num_samples: object, seed: object, mode: object,
               baseline: object, risk_measure: object, risk_level: object, queries: object, label: object,
               limits: GoalLimits) -> CheckedGoal:
    """A goal's fields validated in message order and defaulted (see the module docstring).

    Raises:
        ValueError: naming the first bad field.
    """
    z_method = None if method == CURRENT_POSTERIOR else parse(ZMethod, method, "method")
    beta_value = check_real("beta", beta, positive=False)
    samples = _integer("num_samples", num_samples, 0, limits.max_num_samples, "max_num_samples")
    seed_value = _integer("seed", seed, 0, 2**32 - 1)
    planning.check_plan_arguments(mode, baseline)  # ValueError naming mode or baseline
    measure, level = _checked_risk(risk_measure, risk_level, mode)
    asked = _integer("queries", queries, 0, limits.max_queries, "max_queries")
    if not isinstance(label, str):
        raise ValueError(f"label: expected a string, got {label!r}")
    if len(label) > MAX_TEXT_LENGTH:  # the planner's limit on a plan's label
        raise ValueError(f"label: {len(label)} characters exceed {MAX_TEXT_LENGTH}")
    return CheckedGoal(
        method=z_method,
        beta=beta_value if beta_value > 0 else float(limits.default_beta),
        num_samples=samples or int(limits.default_num_samples),
        seed=seed_value,
        mode=PlanMode(mode),
        baseline=Baseline(baseline),
        risk_measure=measure,
        risk_level=level,
        queries=asked,
        label=label or DEFAULT_LABEL,
    )


@dataclass(frozen=True)
class DownstreamLimits:
    """What the planner and the inference node will hold a goal's requests to (their parameters
    ``max_plan_work``, ``max_horizon``, ``risk`` / ``risk_level``, ``max_query_work``); None = not
    known (that check is left to the service)."""

    max_plan_work: float | None = None
    max_horizon: int | None = None
    default_risk: Risk | None = None
    max_query_work: float | None = None


#: ``num_options`` of the navigator's ``/ird/query`` requests (0 = the inference node's 2).
QUERY_OPTIONS = 2


def check_goal_work(goal: CheckedGoal, *, horizon: int, height: int, width: int, num_features: int,
                    limits: DownstreamLimits) -> Risk | None:
    """Refuse a checked goal that the planner or ``/ird/query`` would refuse only after the
    inference, before any work starts; returns the risk measure the plan will use (``None`` when
    the planner's default is not known).

    Args:
        goal: the checked goal.
        horizon: the test horizon T (``/world/proxy``); height, width: the test map's grid;
            num_features: d of the posterior (the training map's layers).
        limits: the downstream nodes' limits.
    Raises:
        ValueError: naming ``num_samples`` (with the limit and the largest value that fits),
            ``risk_measure`` / ``risk_level``, or ``horizon`` (the world's test horizon).
    """
    if limits.max_horizon is not None and horizon > limits.max_horizon:
        raise ValueError(f"horizon: the world's test horizon {horizon} exceeds the planner's "
                         f"max_horizon={limits.max_horizon}")
    risk = None
    if limits.default_risk is not None:  # as the planner resolves it, literal plans included
        risk = request_risk(str(goal.risk_measure or ""), goal.risk_level, limits.default_risk, goal.mode,
                            fields=("risk_measure", "risk_level"))
    if goal.uses_current_posterior:  # no inference: a service's refusal comes at once anyway
        return risk
    k, cells = goal.num_samples, int(height) * int(width)
    if limits.max_plan_work is not None and goal.mode != PlanMode.LITERAL:
        work = planning.plan_work(k, horizon, height, width)
        if work > limits.max_plan_work:
            fits = int(limits.max_plan_work // ((int(horizon) + 1) * max(cells, 1)))
            raise ValueError(f"num_samples: {k} samples x (horizon {horizon} + 1) x {height}x{width} cells = "
                             f"{work:.3g} exceeds the planner's max_plan_work={limits.max_plan_work:.3g} "
                             f"(/ird/plan would refuse the plan after the inference): at most {fits} samples fit")
    if limits.max_query_work is not None and goal.queries > 0:
        work = query_work(k, height, width, horizon, num_features, QUERY_OPTIONS)
        if work > limits.max_query_work:
            fits = _largest(lambda n: query_work(n, height, width, horizon, num_features, QUERY_OPTIONS)
                            <= limits.max_query_work, k)
            raise ValueError(f"num_samples: {k} samples on a {height}x{width} map (d={num_features}, horizon "
                             f"{horizon}) make each of the {goal.queries} question(s) /ird/query work {work:.3g}, "
                             f"more than the inference node's max_query_work={limits.max_query_work:.3g}: at "
                             f"most {fits} samples fit with queries")
    return risk


def _largest(fits: Any, high: int) -> int:
    """The largest n in [0, high] with ``fits(n)`` (``fits`` monotone decreasing, ``fits(0)`` assumed)."""
    low = 0
    while low < high:
        mid = (low + high + 1) // 2
        if fits(mid):
            low = mid
        else:
            high = mid - 1
    return low


def _checked_risk(risk_measure: object, risk_level: object, mode: object) -> tuple[RiskMeasure | None, float]:
    """The goal's measure (None = the planner's default) and level as ``/ird/plan`` will get
    them (module doc); ``ValueError`` naming ``risk_measure`` or ``risk_level``."""
    if risk_measure != "" and risk_measure not in RISK_MEASURES:
        raise ValueError(f"risk_measure: expected one of {list(RISK_MEASURES)} or \"\" (the planner's default), "
                         f"got {risk_measure!r}")
    level = check_real("risk_level", risk_level, positive=False, ranged=False)
    if level > MAX_LAMBDA:
        raise ValueError(f"risk_level: {level:g} is outside [0, {MAX_LAMBDA:g}] (cvar's alpha <= 1, mean_sd's "
                         f"lambda <= {MAX_LAMBDA:g})")
    if risk_measure == "":
        return None, level
    assert isinstance(risk_measure, str)
    request_risk(risk_measure, level, MIN_RISK, mode, fields=("risk_measure", "risk_level"))
    return RiskMeasure(risk_measure), level


def posterior_summary(method: str, num_samples: int, r_hat_max: float, converged: bool = True,
                      answers: int = 0) -> str:
    """One line about a posterior, e.g. ``maxent_z, 64 samples, R-hat 1.02``."""
    text = f"{method or 'posterior'}, {int(num_samples)} samples, R-hat {r_hat_max:.2f}"
    if answers:
        text += f", {answers} answer{'s' if answers != 1 else ''}"
    return text if converged else text + ", not converged"


@dataclass(frozen=True)
class Judgement:
    """The ground truth's verdict on driven cells (``evaluate_path``)."""

    touched_lava: bool
    reached_target: bool
    true_return: float


def judge(cells: Sequence[tuple[int, int]], classes: np.ndarray, class_names: Sequence[str],
          rewards: Mapping[str, float]) -> Judgement:
    """``cells`` judged on the ground-truth terrain ``classes`` (H, W) with the true ``rewards`` per
    terrain name (Rob's policy: see the module docstring)."""
    labels, reward = evaluation_terrain(classes, class_names, rewards, unrewarded_unknown=False)
    outcome = evaluate_path(labels, [(int(r), int(c)) for r, c in cells], reward)
    return Judgement(outcome.touched_lava, outcome.reached_target,
                     outcome.true_return if rewards else math.nan)


@dataclass
class DriveTracker:
    """Rob's drive of one plan: feed it every ``/rob/status`` (:meth:`feed`); see the module docstring.

    ``plan_key`` is the plan's stamp key (``ird_ros.stamps.stamp_key``), ``plan_cells`` its T+1 cells.
    """

    plan_key: Any
    plan_cells: tuple[tuple[int, int], ...]
    last_step: int = -1
    cell: tuple[int, int] | None = None
    final: Any = None
    stopped: bool = False
    replaced_by: tuple[Any, str] | None = None  # (stamp key, label) of the newer plan Rob drives instead
    _steps: dict[int, tuple[int, int]] = field(default_factory=dict)

    def other_plan(self, key: Any, label: str = "") -> bool:
        """Take a status that is not of this plan: True (recorded in ``replaced_by``) when it is the
        first of a newer plan than this one (its stamp key is greater) while this drive is not
        over, i.e. another ``/plan`` replaced ours; older plans' statuses change nothing."""
        if key == self.plan_key or self.final is not None or self.replaced_by is not None or not key > self.plan_key:
            return False
        self.replaced_by = (key, str(label))
        return True

    @property
    def over(self) -> bool:
        """The drive is over: finished, stopped, or replaced by a newer plan."""
        return self.final is not None or self.replaced_by is not None

    def feed(self, key: Any, step: int, row: int, col: int, done: bool, stopped: bool = False,
             status: Any = None) -> bool:
        """Take one status (its plan's stamp key and fields); True if it belongs to this plan."""
        if key != self.plan_key or self.final is not None:
            return False
        self._steps[int(step)] = (int(row), int(col))
        self.last_step = max(self.last_step, int(step))
        self.cell = (int(row), int(col))
        if done:
            self.final = status if status is not None else True
            self.stopped = bool(stopped)
        return True

    @property
    def done(self) -> bool:
        return self.final is not None

    @property
    def horizon(self) -> int:
        return len(self.plan_cells) - 1

    @property
    def progress(self) -> float:
        """Fraction of the plan driven, in [0, 1]."""
        if self.last_step < 0:
            return 0.0
        return 1.0 if self.horizon <= 0 else min(1.0, self.last_step / self.horizon)

    @property
    def cells(self) -> list[tuple[int, int]]:
        """The driven cells, start first: Rob's reported cell per step, the plan's where none came."""
        return [self._steps.get(k, self.plan_cells[k]) for k in range(min(self.last_step + 1, len(self.plan_cells)))]
