"""Trajectory CVaR, ``max_xi CVaR_alpha(R_1(xi), ..., R_K(xi))``, as an exact MILP (docs/spec.md section 4).

Rockafellar and Uryasev: ``CVaR_alpha(R) = max_z z - (1/alpha) sum_k p_k (z - R_k)^+``. With the
unit-flow path variables of :mod:`ird_core.planning.trajectory_milp` (``R_k`` linear in the visit
counts) and one ``u_k >= max(0, z - R_k)`` per sample, maximising
``z - sum_k (p_k / alpha) u_k`` over paths and ``z`` is a MILP whose optimum is the trajectory
CVaR optimum. ``alpha <= min p_k`` is the min objective of the trajectory mode.

Node pruning: ``CVaR_alpha <= mean``, so a (time, state) node whose best path by the mean reward
(one DP through it) cannot beat the incumbent is dropped; the incumbent (the per-step CVaR path,
or the mean's path, whichever is better under this objective) keeps its nodes. HiGHS runs with
the trajectory MILP's settings; the solve is bounded by wall-clock ``time_limit`` only (its work
has no deterministic bound), and past it the best path found is returned through
:class:`OutOfTime` with HiGHS's dual bound.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ird_core.mdp import GridMDP
from ird_core.mdp.optimal_paths import optimal_paths
from ird_core.planning.risk_measures import Risk, risk_statistic
from ird_core.planning.trajectory_limits import OutOfTime
from ird_core.planning.trajectory_milp import (
    TrajectoryMilp,
    build_trajectory_milp,
    promising_nodes,
    solve_trajectory_milp,
)

__all__ = ["trajectory_returns", "plan_trajectory_cvar"]


def trajectory_returns(q: np.ndarray, states: np.ndarray) -> np.ndarray:
    """``R_k = sum_t q_k(s_t)`` of one path; ``(K, S), (T + 1,) -> (K,)``."""
    return q[:, states].sum(axis=1)


def _path_states(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    cells = optimal_paths(mdp, rewards.reshape(1, mdp.height, mdp.width))[0]
    return cells[:, 0] * mdp.width + cells[:, 1]


def _with_cvar(model: TrajectoryMilp, probabilities: np.ndarray, alpha: float) -> TrajectoryMilp:
    """The min-MILP turned into the CVaR MILP: ``u_k`` columns appended (``z - u_k <= R_k``)."""
    import scipy.sparse as sp  # noqa: PLC0415 - lazy: every node imports ird_core.planning, few solve a MILP/LP
    from scipy.optimize import Bounds, LinearConstraint  # noqa: PLC0415

    k = len(probabilities)
    a = model.constraints.A
    rows = a.shape[0]
    u = sp.csr_matrix((-np.ones(k), (np.arange(rows - k, rows), np.arange(k))), shape=(rows, k))
    matrix = sp.hstack([a, u], format="csr")
    cost = np.concatenate([model.cost, probabilities / alpha])
    bounds = Bounds(np.concatenate([model.bounds.lb, np.zeros(k)]), np.concatenate([model.bounds.ub, np.full(k, np.inf)]))
    constraints = LinearConstraint(matrix, model.constraints.lb, model.constraints.ub)
    integrality = np.concatenate([model.integrality, np.zeros(k)])
    return TrajectoryMilp(cost, integrality, bounds, constraints, model.edge_time, model.edge_source,
                          model.edge_target, model.scale)


def plan_trajectory_cvar(mdp: GridMDP, q: np.ndarray, risk: Risk, probabilities: "np.ndarray | None",
                         time_limit: "float | None") -> tuple[np.ndarray, float]:
    """The trajectory CVaR optimum.

    Args:
        q: ``(K, H, W)`` baseline-shifted per-cell rewards.
        risk: a checked ``cvar`` :class:`Risk`.
        probabilities: ``None`` (uniform) or checked ``(K,)`` sample probabilities.
        time_limit: seconds, or ``None``.
    Returns:
        ``(T + 1, 2)`` cells and a proven upper bound on the objective.
    Raises:
        OutOfTime: the time limit passed first (with the best path and HiGHS's bound).
    """
    k = len(q)
    p = np.full(k, 1.0 / k) if probabilities is None else probabilities
    flat = q.reshape(k, -1)
    deadline = math.inf if time_limit is None else time.monotonic() + time_limit
    per_step = _path_states(mdp, risk_statistic(q, risk, probabilities))
    mean_path = _path_states(mdp, np.tensordot(p, q, axes=1))
    candidates = [per_step, mean_path]
    values = [float(risk_statistic(trajectory_returns(flat, s)[:, None], risk, probabilities)[0]) for s in candidates]
    incumbent = candidates[int(np.argmax(values))]
    best = max(values)
    slack = 1e-9 * (mdp.horizon + 1) * max(1.0, float(np.abs(flat).max()))
    nodes = promising_nodes(mdp, flat, p[None], best, -slack, incumbent)
    keep = p > 0
    model = _with_cvar(build_trajectory_milp(mdp, flat[keep], nodes), p[keep], risk.level)
    try:
        return solve_trajectory_milp(mdp, model, deadline)
    except OutOfTime as exc:  # the better of HiGHS's best path and the incumbent stands in
        states = incumbent
        if exc.states is not None:
            found = float(risk_statistic(trajectory_returns(flat, exc.states)[:, None], risk, probabilities)[0])
            states = exc.states if found > best else incumbent
        raise OutOfTime(states, exc.bound, "milp-cvar", "time") from None
