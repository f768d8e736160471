"""Literal and risk-averse planning with posterior reward samples (docs/spec.md section 4).

Given ``K`` posterior samples ``w_i`` (a ``(K, d)`` batch) and a test map, a planner returns a
path of ``T + 1`` cells from the start and the exact value of the objective it maximises:

- ``literal``    ``sum_t (w . F[s_t] - b)`` for one weight vector (the proxy); ``K`` must be 1.
- ``per_step``   ``sum_t rho_i (w_i . F[s_t] - b_i)``: a per-cell reward, solved by exact DP.
- ``trajectory`` ``rho_i (w_i . phi(xi) - (T + 1) b_i)``: not an MDP; for the min solved
  exactly, by default with a branch and bound over the time-expanded graph whose bounds are
  exact DPs (``"label-bb"``), or as a mixed-integer program over unit flows in that graph with
  HiGHS (``"milp-highs"``), in :mod:`ird_core.planning.trajectory_solver`; for CVaR as the
  Rockafellar-Uryasev MILP of :mod:`ird_core.planning.trajectory_cvar` (``"milp-cvar"``).

``rho`` is the risk measure (:mod:`ird_core.planning.risk_measures`): ``min`` (the paper's
appendix, the default), ``cvar`` at level ``alpha`` (``alpha <= 1/K``: the min; 1: the mean,
i.e. planning on the posterior mean reward, risk-neutral) or ``mean_sd`` with ``lambda``
(per step only: its trajectory form is not concave). Samples may carry probabilities
(``sample_weights``, e.g. a posterior re-weighted by a hypothetical answer).

Per-step reward baselines ``b_i`` (:func:`reward_baselines`):

- ``none``               0.
- ``initial_state``      ``w_i . F[s_0]``, the reward of the start cell.
- ``training_features``  ``w_i . f_ref`` where the CALLER passes ``f_ref`` = the proxy's expected
  *training* feature counts ``phi~(w~)`` divided by (training horizon + 1), i.e. the average
  feature vector per visited state in training.
- ``log_z``              ``log Z_test(w_i) / (T + 1)`` on the given (test) MDP.

Shift invariance (adding a constant vector ``c`` to every cell's features): ``literal`` picks the
same path under every baseline (all paths shift by the same ``(T + 1) w . c``). For ``per_step``
and ``trajectory`` the shifted reward ``w_i . F[s] - b_i`` is unchanged exactly when ``b_i``
moves by ``w_i . c``: true for ``initial_state`` (``F[s_0]`` moves by ``c``), for ``log_z``
(every trajectory's return moves by ``(T + 1) w_i . c``, so ``log Z`` does too), and for
``training_features`` when ``f_ref`` comes from the equally shifted training map (per-state
averages move by ``c``). ``none`` is not invariant: the shift moves each sample's reward by a
different amount and so changes which sample is the minimum.

Everything is vectorised over samples and cells; Python loops run over time steps, solver
iterations and memory chunks only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ird_core.checks import MAX_ABS_FEATURE, check_magnitude
from ird_core.mdp import GridMDP, log_partition, optimal_path, validate_path
from ird_core.planning.arguments import check_plan_arguments, check_reference, check_weights
from ird_core.planning.risk_measures import MIN_RISK, Risk, check_risk, check_sample_weights, risk_statistic
from ird_core.planning.trajectory_cvar import plan_trajectory_cvar
from ird_core.planning.trajectory_bounds import states_to_cells
from ird_core.planning.trajectory_limits import OutOfTime
from ird_core.planning.trajectory_solver import plan_trajectory
from ird_core.vocabulary import Baseline, PlanMode, RiskMeasure, parse

__all__ = [
    "Plan",
    "PlanningTimeout",
    "reward_baselines",
    "sample_cell_rewards",
    "per_step_reward",
    "path_objective",
    "plan_path",
]


@dataclass(frozen=True)
class Plan:
    """A planned path and the exact value of the objective it maximises.

    Attributes:
        cells: ``T + 1`` ``(row, col)`` cells, the first one the start.
        objective: the objective of ``mode`` (baseline subtracted) evaluated exactly on ``cells``.
        mode: one of :data:`MODES`.
        baseline: one of :data:`BASELINES`.
        solver: ``"dp"`` (dynamic programming; ``literal``, ``per_step``), ``"label-bb"`` or
            ``"milp-highs"`` (``trajectory``, see :func:`plan_path`).
        bound: a proven upper bound on the optimum: ``objective`` itself once optimality is
            proven (DP, completed label search; for the MILP the smaller of the DP bounds and
            HiGHS's dual bound, at least ``objective``). Larger only in
            :class:`PlanningTimeout`'s plan.
        risk: the risk measure and level the objective uses (``min`` for ``literal``).
    """

    cells: tuple[tuple[int, int], ...]
    objective: float
    mode: str
    baseline: str
    solver: str
    bound: float = math.nan
    risk: Risk = MIN_RISK


class PlanningTimeout(RuntimeError):
    """``plan_path`` ran out of ``time_limit`` or ``work_limit`` before proving optimality.

    Attributes:
        plan: the best path found so far, its exact objective, and in ``plan.bound`` the best
            proven upper bound on the optimum (so ``plan.bound - plan.objective`` is the gap).
        reason: ``"time"`` or ``"work"``, the limit that stopped the plan (the message starts
            with its name, ``time_limit:`` or ``work_limit:``).
    """

    def __init__(self, message: str, plan: "Plan", reason: str = "time") -> None:
        super().__init__(message)
        self.plan, self.reason = plan, reason

# --------------------------------------------------------------------------- rewards


def reward_baselines(
    mdp: GridMDP,
    weights: np.ndarray,
    baseline: str,
    reference_features: np.ndarray | None = None,
) -> np.ndarray:
    """Per-step reward baselines ``b_i`` of each sample.

    Args:
        mdp: the test MDP (its start cell and, for ``log_z``, its trajectories).
        weights: ``(K, d)``.
        baseline: one of :data:`BASELINES`.
        reference_features: ``(d,)``, required for ``training_features``: the proxy's expected
            training feature counts already divided by (training horizon + 1).
    Returns:
        ``(K,)`` float64.
    """
    parse(Baseline, baseline, "baseline")
    w = check_weights(weights, mdp.num_features)
    reference = check_reference(reference_features, mdp.num_features)
    if baseline == Baseline.NONE:
        return np.zeros(len(w))
    if baseline == Baseline.INITIAL_STATE:
        return w @ mdp.features[mdp.start]
    if baseline == Baseline.TRAINING_FEATURES:
        if reference is None:
            raise ValueError("reference_features: required by the 'training_features' baseline")
        return w @ reference
    return log_partition(mdp, w) / (mdp.horizon + 1)


def sample_cell_rewards(
    mdp: GridMDP,
    weights: np.ndarray,
    baseline: str = "none",
    reference_features: np.ndarray | None = None,
) -> np.ndarray:
    """Baseline-shifted per-cell rewards ``q_i(s) = w_i . F[s] - b_i``.

    Returns:
        ``(K, H, W)``.
    """
    w = check_weights(weights, mdp.num_features)
    return _shifted_rewards(mdp, w, reward_baselines(mdp, w, baseline, reference_features))


def _shifted_rewards(mdp: GridMDP, w: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``(K, H, W)`` rewards ``w_i . F - b_i`` for checked ``w`` ``(K, d)`` and ``b`` ``(K,)``."""
    return np.einsum("hwd,kd->khw", mdp.features, w, optimize=True) - b[:, None, None]


def per_step_reward(
    mdp: GridMDP,
    weights: np.ndarray,
    baseline: str = "none",
    reference_features: np.ndarray | None = None,
) -> np.ndarray:
    """The per-step risk-averse reward ``min_i (w_i . F[s] - b_i)``; ``(K, d)`` -> ``(H, W)``."""
    return sample_cell_rewards(mdp, weights, baseline, reference_features).min(axis=0)


def path_objective(
    mdp: GridMDP,
    cells: "list[tuple[int, int]] | np.ndarray",
    weights: np.ndarray,
    mode: str,
    baseline: str = "none",
    reference_features: np.ndarray | None = None,
    *,
    risk: str = "min",
    risk_level: float | None = None,
    sample_weights: np.ndarray | None = None,
) -> float:
    """The objective of ``mode`` evaluated exactly on a legal path.

    ``literal``: ``w . phi - (T + 1) b``; ``per_step``: ``sum_t rho_i (w_i . F[s_t] - b_i)``;
    ``trajectory``: ``rho_i (w_i . phi - (T + 1) b_i)``, ``rho`` the risk measure.

    Args:
        cells: ``T + 1`` ``(row, col)`` cells starting at the start.
        weights: ``(K, d)`` (``K = 1`` for ``literal``).
        risk, risk_level, sample_weights: as :func:`plan_path`.
    """
    w = check_plan_arguments(mode, baseline, weights, mdp.num_features, reference_features)
    assert w is not None
    measure = check_risk(risk, risk_level)
    p = check_sample_weights(sample_weights, len(w))
    return _objective(mdp, validate_path(mdp, cells), w, reward_baselines(mdp, w, baseline, reference_features), mode,
                      measure, p)


def _objective(mdp: GridMDP, path: np.ndarray, w: np.ndarray, b: np.ndarray, mode: str,
               risk: Risk = MIN_RISK, p: "np.ndarray | None" = None) -> float:
    """:func:`path_objective` for a checked ``(T + 1, 2)`` path, ``w`` ``(K, d)``, ``b`` ``(K,)``."""
    visited = mdp.features[path[:, 0], path[:, 1]]  # (T+1, d)
    if mode == PlanMode.PER_STEP:
        if risk == MIN_RISK and p is None:
            return float((visited @ w.T - b).min(axis=1).sum())
        return float(risk_statistic((visited @ w.T - b).T, risk, p).sum())
    returns = w @ visited.sum(axis=0) - (mdp.horizon + 1) * b
    if risk == MIN_RISK and p is None:
        return float(np.min(returns))
    return float(risk_statistic(returns, risk, p))


# --------------------------------------------------------------------------- planning


def plan_path(
    mdp: GridMDP,
    weights: np.ndarray,
    mode: str,
    baseline: str = "none",
    reference_features: np.ndarray | None = None,
    *,
    risk: str = "min",
    risk_level: float | None = None,
    sample_weights: np.ndarray | None = None,
    solver: str | None = None,
    time_limit: float | None = None,
    work_limit: int | None = None,
) -> Plan:
    """Plan a path maximising the objective of ``mode`` under the risk measure ``risk``.

    ``literal`` and ``per_step`` are one per-cell reward each, solved by ``mdp.optimal_path``
    (exact DP, ties broken "stay" first).

    ``trajectory``, ``max_xi min_i f_i(xi)`` with ``f_i(xi) = sum_t q_i(s_t)`` and
    ``q_i = w_i . F - b_i``, is solved exactly by :func:`ird_core.planning.trajectory_solver.plan_trajectory`
    (sample reduction, DP and LP-relaxation bounds, incumbents, then the label search or the
    MILP; the module docstring explains each step and the exactness guarantee).

    The returned path is checked with ``validate_path`` and its objective is recomputed from
    its cells.

    Args:
        mdp: the test MDP.
        weights: ``(K, d)`` posterior samples (``(1, d)`` for ``literal``).
        mode: one of :data:`MODES`.
        baseline: one of :data:`BASELINES`.
        reference_features: ``(d,)``, for the ``training_features`` baseline (see
            :func:`reward_baselines`).
        risk: one of ``RISK_MEASURES`` (``"min"``, ``"cvar"``, ``"mean_sd"``); ignored by
            ``literal``. ``mean_sd`` is ``per_step`` only.
        risk_level: ``alpha`` in ``(0, 1]`` for ``cvar``, ``lambda`` in ``[0, 100]`` for
            ``mean_sd``, ``None`` for ``min``.
        sample_weights: ``None`` (uniform) or ``(K,)`` probabilities of the samples summing to 1.
        solver: ``None`` (automatic) or one of ``SOLVERS[mode]`` (trajectory CVaR: the MILP,
            ``time_limit`` only).
        time_limit: seconds > 0 for ``trajectory`` (``None``: no limit).
        work_limit: label expansions >= 1 for ``trajectory`` (``None``: no limit): a
            deterministic limit, so the same inputs stop at the same point on every machine
            (see :mod:`ird_core.planning.trajectory_solver`); not with ``solver="milp-highs"``. With
            both limits, whichever is reached first stops the plan.
    Returns:
        a :class:`Plan`.
    Raises:
        PlanningTimeout: a limit was reached first; its ``plan`` is the best path so far and its
            ``reason`` the limit (``"time"`` or ``"work"``).
        RuntimeError: HiGHS failed, ``solver="label-bb"`` ran out of memory budget, or the
            objective is not finite.
    """
    w = check_plan_arguments(mode, baseline, weights, mdp.num_features, reference_features,
                             solver=solver, time_limit=time_limit, work_limit=work_limit)
    assert w is not None
    measure = MIN_RISK if mode == PlanMode.LITERAL else check_risk(risk, risk_level)
    p = None if mode == PlanMode.LITERAL else check_sample_weights(sample_weights, len(w))
    if mode == PlanMode.TRAJECTORY and measure.measure == RiskMeasure.MEAN_SD:
        raise ValueError("risk: mean_sd is a per_step risk measure (its trajectory form is not concave); "
                         "use mode 'per_step' or risk 'cvar'")
    if mode == PlanMode.TRAJECTORY and (measure != MIN_RISK or p is not None) and work_limit is not None:
        raise ValueError("work_limit: trajectory CVaR and weighted samples are solved by the MILP, "
                         "which takes a time_limit only")
    check_magnitude("features", mdp.features, MAX_ABS_FEATURE)
    plan = _plan(mdp, w, mode, baseline, reference_features, solver, time_limit, work_limit, measure, p)
    if not np.isfinite(plan.objective):  # unreachable within the checked ranges; never a success
        raise RuntimeError(f"objective: {plan.objective!r} is not finite; no plan is returned")
    return plan


def _plan(mdp: GridMDP, w: np.ndarray, mode: str, baseline: str, reference_features: np.ndarray | None,
          solver: str | None, time_limit: float | None, work_limit: int | None = None,
          risk: Risk = MIN_RISK, p: "np.ndarray | None" = None) -> Plan:
    """:func:`plan_path` on checked arguments."""
    b = reward_baselines(mdp, w, baseline, reference_features)
    q = _shifted_rewards(mdp, w, b)
    if mode == PlanMode.LITERAL:  # the baseline shifts every path equally: plan on the raw reward
        cells = _dp_path(mdp, _shifted_rewards(mdp, w, np.zeros(1))[0])
        value = _objective(mdp, cells, w, b, mode)
        return Plan(_as_cells(cells), value, mode, baseline, "dp", value)
    if mode == PlanMode.PER_STEP:
        per_cell = q.min(axis=0) if risk == MIN_RISK and p is None else risk_statistic(q, risk, p)
        cells = _dp_path(mdp, per_cell)
        value = _objective(mdp, cells, w, b, mode, risk, p)
        return Plan(_as_cells(cells), value, mode, baseline, "dp", value, risk)
    try:
        if risk == MIN_RISK and p is None:
            cells, bound, used = plan_trajectory(mdp, q, solver=solver, time_limit=time_limit, work_limit=work_limit)
        else:
            cells, bound = plan_trajectory_cvar(mdp, q, risk if risk != MIN_RISK else Risk("cvar", 1e-12), p,
                                                time_limit)
            used = "milp-cvar"
    except OutOfTime as exc:
        cells = states_to_cells(mdp, exc.states)
        value = _objective(mdp, cells, w, b, mode, risk, p)
        plan = Plan(_as_cells(cells), value, mode, baseline, exc.solver, max(exc.bound, value), risk)
        limit = f"time_limit: {time_limit} s passed" if exc.reason == "time" else f"work_limit: {work_limit}: {exc}"
        raise PlanningTimeout(f"{limit} before the trajectory optimum was proven; "
                              f"best objective {value:.6g}, upper bound {plan.bound:.6g}", plan, exc.reason) from None
    value = _objective(mdp, cells, w, b, mode, risk, p)
    return Plan(_as_cells(cells), value, mode, baseline, used, max(bound, value), risk)


def _as_cells(cells: "list[tuple[int, int]] | np.ndarray") -> tuple[tuple[int, int], ...]:
    return tuple((int(r), int(c)) for r, c in np.asarray(cells).reshape(-1, 2))


def _dp_path(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """``optimal_path`` for an ``(H, W)`` reward, as a checked ``(T + 1, 2)`` array."""
    cells, _ = optimal_path(mdp, rewards)
    return validate_path(mdp, cells)
