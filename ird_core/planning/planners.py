"""Literal and risk-averse planning with posterior reward samples (docs/spec.md section 4).

Given ``K`` posterior samples ``w_i`` (a ``(K, d)`` batch) and a test map, a planner returns a
path of ``T + 1`` cells from the start and the exact value of the objective it maximises:

- ``literal``    ``sum_t (w . F[s_t] - b)`` for one weight vector (the proxy); ``K`` must be 1.
- ``per_step``   ``sum_t min_i (w_i . F[s_t] - b_i)``: a per-cell reward, solved by exact DP.
- ``trajectory`` ``min_i (w_i . phi(xi) - (T + 1) b_i)``: not an MDP; solved exactly, by default
  with a branch and bound over the time-expanded graph whose bounds are exact DPs
  (``"label-bb"``), or as a mixed-integer program over unit flows in that graph with HiGHS
  (``"milp-highs"``). The solver lives in :mod:`ird_core.planning.trajectory_solver`.

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

from ird_core.checks import MAX_ABS_FEATURE, MAX_ABS_WEIGHT, check_magnitude
from ird_core.mdp import GridMDP, log_partition, optimal_path, validate_path
from ird_core.planning.trajectory_solver import OutOfTime, check_work_limit, plan_trajectory, states_to_cells
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
]

#: Solvers a caller may request per mode (``None`` = automatic).
SOLVERS: dict[str, tuple[str, ...]] = {
    "literal": ("dp",),
    "per_step": ("dp",),
    "trajectory": ("label-bb", "milp-highs"),
}


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
    """

    cells: tuple[tuple[int, int], ...]
    objective: float
    mode: str
    baseline: str
    solver: str
    bound: float = math.nan


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


# --------------------------------------------------------------------------- validation


def _check_choice(value: object, name: str, allowed: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(f"{name}: expected one of {allowed}, got {value!r}")
    return value


def _check_weights(weights: np.ndarray, num_features: int) -> np.ndarray:
    """A finite ``(K, d)`` float64 batch with ``K >= 1``."""
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 2 or w.shape[0] < 1 or w.shape[1] != num_features:
        raise ValueError(f"weights: expected shape (K >= 1, {num_features}), got {w.shape}")
    if not np.all(np.isfinite(w)):
        raise ValueError("weights: contains NaN or infinite values")
    return check_magnitude("weights", w, MAX_ABS_WEIGHT)


def _check_reference(reference_features: np.ndarray | None, num_features: int) -> np.ndarray | None:
    if reference_features is None:
        return None
    f = np.asarray(reference_features, dtype=np.float64)
    if f.shape != (num_features,):
        raise ValueError(f"reference_features: expected shape ({num_features},), got {f.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError("reference_features: contains NaN or infinite values")
    return check_magnitude("reference_features", f, MAX_ABS_WEIGHT)


def check_start(start: tuple[int, int], height: int, width: int) -> tuple[int, int]:
    """A start cell on an ``height x width`` map, as ``(row, col)`` ints.

    Raises:
        ValueError: naming ``start_row`` or ``start_col`` (the coordinate that is off the map).
    """
    row, col = (int(v) for v in start)
    if not 0 <= row < height:
        raise ValueError(f"start_row: {row} is off the map (height {height})")
    if not 0 <= col < width:
        raise ValueError(f"start_col: {col} is off the map (width {width})")
    return row, col


def check_plan_arguments(
    mode: str,
    baseline: str,
    weights: np.ndarray | None = None,
    num_features: int | None = None,
    reference_features: np.ndarray | None = None,
    *,
    solver: str | None = None,
    time_limit: float | None = None,
    work_limit: int | None = None,
) -> np.ndarray | None:
    """The argument checks of :func:`plan_path` that need no planning.

    A caller that must refuse a bad request before it queues the plan (the planner node) calls
    this first with what it has: ``weights`` and ``reference_features`` are checked only when
    given, against ``num_features`` (``d``).

    Returns:
        ``weights`` as a finite ``(K, d)`` float64 array (``None`` if not given).
    Raises:
        ValueError: naming ``mode``, ``baseline``, ``solver``, ``time_limit``, ``work_limit``,
            ``weights`` or ``reference_features``.
    """
    _check_choice(mode, "mode", MODES)
    _check_choice(baseline, "baseline", BASELINES)
    if solver is not None:
        _check_choice(solver, "solver", SOLVERS[mode])
    if time_limit is not None and (isinstance(time_limit, bool) or not isinstance(time_limit, (int, float))
                                   or not time_limit > 0):
        raise ValueError(f"time_limit: expected seconds > 0 or None, got {time_limit!r}")
    check_work_limit(work_limit, solver)
    if weights is None or num_features is None:
        return None
    w = _check_weights(weights, num_features)
    if mode == "literal" and len(w) != 1:
        raise ValueError(f"weights: literal mode takes exactly one weight vector (1, d), got {w.shape}")
    _check_reference(reference_features, num_features)
    return w


def plan_work(num_samples: int, horizon: int, height: int, width: int) -> int:
    """``K x (T + 1) x H x W``: the size of the largest table a plan builds (the log_z baseline's
    and the trajectory solver's per-sample value tables), and the order of its time and memory."""
    return int(num_samples) * (int(horizon) + 1) * int(height) * int(width)


def check_plan_size(num_samples: int, horizon: int, height: int, width: int, max_work: int) -> None:
    """Refuse a plan whose :func:`plan_work` exceeds ``max_work`` before any work starts.

    Raises:
        ValueError: naming ``weights`` (the samples are what a request most easily inflates).
    """
    work = plan_work(num_samples, horizon, height, width)
    if work > max_work:
        raise ValueError(f"weights: {num_samples} samples x horizon {horizon} x {height}x{width} map = {work:.3g} "
                         f"exceeds max_plan_work={max_work:.3g}")


def _check_features(features: np.ndarray) -> np.ndarray:
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 3 or min(f.shape) < 1:
        raise ValueError(f"features: expected shape (H, W, d) with every dimension >= 1, got {f.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError("features: contains NaN or infinite values")
    return check_magnitude("features", f, MAX_ABS_FEATURE)


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
    _check_choice(baseline, "baseline", BASELINES)
    w = _check_weights(weights, mdp.num_features)
    reference = _check_reference(reference_features, mdp.num_features)
    if baseline == "none":
        return np.zeros(len(w))
    if baseline == "initial_state":
        return w @ mdp.features[mdp.start]
    if baseline == "training_features":
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
    w = _check_weights(weights, mdp.num_features)
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
) -> float:
    """The objective of ``mode`` evaluated exactly on a legal path.

    ``literal``: ``w . phi - (T + 1) b``; ``per_step``: ``sum_t min_i (w_i . F[s_t] - b_i)``;
    ``trajectory``: ``min_i (w_i . phi - (T + 1) b_i)``.

    Args:
        cells: ``T + 1`` ``(row, col)`` cells starting at the start.
        weights: ``(K, d)`` (``K = 1`` for ``literal``).
    """
    w = check_plan_arguments(mode, baseline, weights, mdp.num_features, reference_features)
    assert w is not None
    return _objective(mdp, validate_path(mdp, cells), w, reward_baselines(mdp, w, baseline, reference_features), mode)


def _objective(mdp: GridMDP, path: np.ndarray, w: np.ndarray, b: np.ndarray, mode: str) -> float:
    """:func:`path_objective` for a checked ``(T + 1, 2)`` path, ``w`` ``(K, d)``, ``b`` ``(K,)``."""
    visited = mdp.features[path[:, 0], path[:, 1]]  # (T+1, d)
    if mode == "per_step":
        return float((visited @ w.T - b).min(axis=1).sum())
    return float(np.min(w @ visited.sum(axis=0) - (mdp.horizon + 1) * b))


# --------------------------------------------------------------------------- planning


def plan_path(
    mdp: GridMDP,
    weights: np.ndarray,
    mode: str,
    baseline: str = "none",
    reference_features: np.ndarray | None = None,
    *,
    solver: str | None = None,
    time_limit: float | None = None,
    work_limit: int | None = None,
) -> Plan:
    """Plan a path maximising the objective of ``mode``.

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
        solver: ``None`` (automatic) or one of ``SOLVERS[mode]``.
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
    check_magnitude("features", mdp.features, MAX_ABS_FEATURE)
    plan = _plan(mdp, w, mode, baseline, reference_features, solver, time_limit, work_limit)
    if not np.isfinite(plan.objective):  # unreachable within the checked ranges; never a success
        raise RuntimeError(f"objective: {plan.objective!r} is not finite; no plan is returned")
    return plan


def _plan(mdp: GridMDP, w: np.ndarray, mode: str, baseline: str, reference_features: np.ndarray | None,
          solver: str | None, time_limit: float | None, work_limit: int | None = None) -> Plan:
    """:func:`plan_path` on checked arguments."""
    b = reward_baselines(mdp, w, baseline, reference_features)
    q = _shifted_rewards(mdp, w, b)
    if mode == "literal":  # the baseline shifts every path equally: plan on the raw reward
        cells = _dp_path(mdp, _shifted_rewards(mdp, w, np.zeros(1))[0])
        value = _objective(mdp, cells, w, b, mode)
        return Plan(_as_cells(cells), value, mode, baseline, "dp", value)
    if mode == "per_step":
        cells = _dp_path(mdp, q.min(axis=0))
        value = _objective(mdp, cells, w, b, mode)
        return Plan(_as_cells(cells), value, mode, baseline, "dp", value)
    try:
        cells, bound, used = plan_trajectory(mdp, q, solver=solver, time_limit=time_limit, work_limit=work_limit)
    except OutOfTime as exc:
        cells = states_to_cells(mdp, exc.states)
        value = _objective(mdp, cells, w, b, mode)
        plan = Plan(_as_cells(cells), value, mode, baseline, exc.solver, max(exc.bound, value))
        limit = f"time_limit: {time_limit} s passed" if exc.reason == "time" else f"work_limit: {work_limit}: {exc}"
        raise PlanningTimeout(f"{limit} before the trajectory optimum was proven; "
                              f"best objective {value:.6g}, upper bound {plan.bound:.6g}", plan, exc.reason) from None
    value = _objective(mdp, cells, w, b, mode)
    return Plan(_as_cells(cells), value, mode, baseline, used, max(bound, value))


def _as_cells(cells: "list[tuple[int, int]] | np.ndarray") -> tuple[tuple[int, int], ...]:
    return tuple((int(r), int(c)) for r, c in np.asarray(cells).reshape(-1, 2))


def _dp_path(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """``optimal_path`` for an ``(H, W)`` reward, as a checked ``(T + 1, 2)`` array."""
    cells, _ = optimal_path(mdp, rewards)
    return validate_path(mdp, cells)


# --------------------------------------------------------------------------- risk map


def reward_spread(features: np.ndarray, weights: np.ndarray, statistic: str = "std") -> np.ndarray:
    """Per-cell spread of the posterior reward ``w_i . F[cell]`` over the samples.

    ``std`` is the population standard deviation (ddof 0), ``range`` is max - min. Rewards are
    taken relative to the first sample (``(w_i - w_0) . F``), which leaves both statistics
    unchanged and makes identical samples give exactly 0.

    Args:
        features: ``(H, W, d)``.
        weights: ``(K, d)``.
        statistic: one of :data:`STATISTICS`.
    Returns:
        ``(H, W)`` float64, >= 0.
    """
    f = _check_features(features)
    w = _check_weights(weights, f.shape[2])
    _check_choice(statistic, "statistic", STATISTICS)
    rewards = np.einsum("hwd,kd->khw", f, w - w[:1], optimize=True)
    if statistic == "std":
        return rewards.std(axis=0)
    return np.ptp(rewards, axis=0)


def risk_map(
    features: np.ndarray,
    weights: np.ndarray,
    statistic: str = "std",
    reference: float | None = None,
) -> np.ndarray:
    """The reward spread as a Nav2-style ``OccupancyGrid`` cost layer.

    ``cost = ceil(100 * spread / reference)`` clipped to ``[0, 100]``, where ``reference`` is the
    map's largest spread by default (that cell costs 100) or a fixed spread given by the caller
    (for costs comparable across maps). Any positive spread costs at least 1; a posterior whose
    samples agree everywhere costs 0 everywhere; -1 (unknown) is never produced. Monotone: more
    spread never costs less.

    Args:
        features: ``(H, W, d)``.
        weights: ``(K, d)``.
        statistic: one of :data:`STATISTICS`.
        reference: ``> 0`` fixed spread mapped to 100, or ``None``.
    Returns:
        ``(H, W)`` int8 in ``0..100``, row 0 first (the OccupancyGrid data order).
    """
    spread = reward_spread(features, weights, statistic)
    if reference is not None and not (np.isfinite(reference) and reference > 0):
        raise ValueError(f"reference: expected a finite spread > 0 or None, got {reference!r}")
    scale = float(spread.max()) if reference is None else float(reference)
    if scale <= 0.0:
        return np.zeros(spread.shape, dtype=np.int8)
    return np.clip(np.ceil(100.0 * (spread / scale)), 0, 100).astype(np.int8)
