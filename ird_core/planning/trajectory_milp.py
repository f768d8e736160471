"""The trajectory mode's exact MILP (docs/spec.md section 4; the solver's step 5): binary edge
variables ``x[t, s, move]`` on the time-expanded graph restricted to (time, state) pairs reachable
from the start within the horizon AND whose best path through them (the DP bounds of
:mod:`ird_core.planning.trajectory_bounds`) could beat the incumbent; unit flow out of the start,
conservation at each inner (time, state), visit counts ``n[c] = sum of edges into c``, and
``z <= q_i(s_0) + sum_c q_i(c) n[c]`` per kept sample; maximise ``z``. HiGHS runs at zero gap
with 1e-9 feasibility tolerances on rewards normalised to ``|q| <= 1``, presolve off.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ird_core.mdp import GridMDP, successor_table
from ird_core.planning.trajectory_bounds import come_from, states_to_cells, to_go
from ird_core.planning.trajectory_limits import OutOfTime

if TYPE_CHECKING:
    from scipy.optimize import Bounds, LinearConstraint

__all__ = ["TrajectoryMilp", "promising_nodes", "build_trajectory_milp", "solve_trajectory_milp"]

# HiGHS settings for the trajectory MILP: zero optimality gap, tight feasibility tolerances (the
# problem is normalised so that per-cell rewards are at most 1 in magnitude), and no presolve:
# HiGHS 1.12's presolve has answered these models with a false "infeasible" and with a wrong
# "optimal" (a 1.40 path for a 3.22 optimum on a 2x2 map, T = 3; a hypothesis example in
# tests/core/test_planning.py); without it both solve exactly.
_HIGHS_OPTIONS = {
    "presolve": False,
    "mip_rel_gap": 0.0,
    "mip_abs_gap": 0.0,
    "mip_feasibility_tolerance": 1e-9,
    "primal_feasibility_tolerance": 1e-9,
}


def promising_nodes(mdp: GridMDP, q: np.ndarray, multipliers: np.ndarray, incumbent: float,
                    slack: float, incumbent_states: np.ndarray) -> np.ndarray:
    """``(T + 1, S)`` mask of the time-expanded nodes a path beating the incumbent may use.

    A node ``(t, s)`` is dropped when, for some simplex row ``lam``, the best ``lam``-weighted
    path through it (forward DP + backward DP) is no better than ``incumbent + slack``; nodes
    unreachable from the start by time ``t`` are dropped too. The incumbent's own nodes are
    always kept, so the MILP stays feasible.
    """
    rewards = multipliers @ q
    through = come_from(mdp, rewards) + to_go(mdp, rewards)  # (T+1, m, S)
    keep = through.min(axis=1) > incumbent + slack
    keep[np.arange(mdp.horizon + 1), incumbent_states] = True
    return keep


def _time_expanded_edges(mdp: GridMDP, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edges ``(t, s) -> (t + 1, s')`` between kept nodes.

    Args:
        nodes: ``(T + 1, S)`` boolean mask of kept (time, state) pairs.
    Returns:
        ``(E,)`` arrays ``time``, ``source`` state, ``target`` state.
    """
    table = successor_table(mdp.height, mdp.width)
    times, sources = np.nonzero(nodes[:-1])
    node, move = np.nonzero(table[sources] >= 0)
    times, sources, targets = times[node], sources[node], table[sources[node], move]
    alive = nodes[times + 1, targets]
    return times[alive], sources[alive], targets[alive]


@dataclass(frozen=True)
class TrajectoryMilp:
    """``max_xi min_i sum_t q_i(s_t)`` as a MILP over unit flows in the time-expanded graph.

    Variables, in order: ``x`` (E binaries, one per edge ``(t, s) -> (t + 1, s')``), ``n`` (C
    visit counts over ``t = 1..T`` of the cells edges enter), ``z`` (the objective, normalised).
    Rows: unit flow out of the start; conservation at each kept inner ``(t, s)``,
    ``1 <= t <= T - 1``; ``n[c] - sum of edges into c = 0``; ``z - sum_c q_i(c) n[c] <= q_i(s_0)``
    per sample.
    """

    cost: np.ndarray          # (V,)
    integrality: np.ndarray   # (V,)
    bounds: Bounds
    constraints: LinearConstraint
    edge_time: np.ndarray     # (E,)
    edge_source: np.ndarray   # (E,)
    edge_target: np.ndarray   # (E,)
    scale: float              # objective units per normalised unit

    @property
    def num_edges(self) -> int:
        return len(self.edge_time)


def build_trajectory_milp(mdp: GridMDP, q: np.ndarray, nodes: np.ndarray) -> TrajectoryMilp:
    """Assemble the sparse MILP, vectorised over edges, nodes and samples.

    Args:
        q: ``(K, S)`` shifted rewards of the kept samples.
        nodes: ``(T + 1, S)`` mask of kept (time, state) pairs; must contain a path from the start.
    """
    import scipy.sparse as sp  # noqa: PLC0415 - lazy: every node imports ird_core.planning, few solve a MILP/LP
    from scipy.optimize import Bounds, LinearConstraint  # noqa: PLC0415

    horizon, start = mdp.horizon, mdp.start_state
    e_time, e_src, e_dst = _time_expanded_edges(mdp, nodes)
    num_edges = len(e_time)
    edge_ids = np.arange(num_edges)
    cells = np.unique(e_dst)
    num_cells = len(cells)
    cell_col = np.full(mdp.num_states, -1)
    cell_col[cells] = np.arange(num_cells)
    num_vars = num_edges + num_cells + 1
    # Normalise rewards to magnitude <= 1 so HiGHS's absolute tolerances act as relative ones.
    used = np.union1d(cells, [start])
    scale = float(np.abs(q[:, used]).max()) or 1.0
    qs = q / scale

    node_row = np.full((horizon + 1, mdp.num_states), -1)
    inner = np.zeros_like(nodes)
    inner[1:horizon] = nodes[1:horizon]
    num_inner = int(inner.sum())
    node_row[inner] = np.arange(num_inner)
    into, out_of = node_row[e_time + 1, e_dst], node_row[e_time, e_src]
    has_in, has_out = into >= 0, out_of >= 0
    conservation = sp.csr_matrix(
        (np.concatenate([np.ones(has_in.sum()), -np.ones(has_out.sum())]),
         (np.concatenate([into[has_in], out_of[has_out]]),
          np.concatenate([edge_ids[has_in], edge_ids[has_out]]))),
        shape=(num_inner, num_vars))
    first = edge_ids[e_time == 0]
    source = sp.csr_matrix((np.ones(len(first)), (np.zeros(len(first), dtype=np.int64), first)),
                           shape=(1, num_vars))
    counts = sp.csr_matrix(
        (np.concatenate([np.ones(num_cells), -np.ones(num_edges)]),
         (np.concatenate([np.arange(num_cells), cell_col[e_dst]]),
          np.concatenate([num_edges + np.arange(num_cells), edge_ids]))),
        shape=(num_cells, num_vars))
    k = len(qs)
    samples = sp.hstack([sp.csr_matrix((k, num_edges)), sp.csr_matrix(-qs[:, cells]),
                         sp.csr_matrix(np.ones((k, 1)))], format="csr")
    matrix = sp.vstack([source, conservation, counts, samples], format="csr")
    row_lb = np.concatenate([[1.0], np.zeros(num_inner + num_cells), np.full(k, -np.inf)])
    row_ub = np.concatenate([[1.0], np.zeros(num_inner + num_cells), qs[:, start]])

    cost = np.zeros(num_vars)
    cost[-1] = -1.0  # milp minimises
    var_lb = np.concatenate([np.zeros(num_edges + num_cells), [-np.inf]])
    var_ub = np.concatenate([np.ones(num_edges), np.full(num_cells, float(horizon)), [np.inf]])
    integrality = np.concatenate([np.ones(num_edges), np.zeros(num_cells + 1)])
    return TrajectoryMilp(cost, integrality, Bounds(var_lb, var_ub), LinearConstraint(matrix, row_lb, row_ub),
                           e_time, e_src, e_dst, scale)


def _run_highs(model: TrajectoryMilp, options: dict) -> object:
    from scipy.optimize import milp  # noqa: PLC0415 - lazy: every node imports ird_core.planning, few solve a MILP/LP

    with warnings.catch_warnings():  # scipy warns that these HiGHS options are passed verbatim
        warnings.filterwarnings("ignore", message="Unrecognized options", category=RuntimeWarning)
        return milp(model.cost, integrality=model.integrality, bounds=model.bounds,
                    constraints=model.constraints, options=options)


def solve_trajectory_milp(mdp: GridMDP, model: TrajectoryMilp, deadline: float) -> tuple[np.ndarray, float]:
    """Solve the model with HiGHS; returns the path's ``(T + 1, 2)`` cells and the dual bound
    (an upper bound on the objective, in objective units).

    Raises:
        OutOfTime: HiGHS hit the time left before ``deadline``.
        RuntimeError: any other non-optimal HiGHS status.
    """
    res = _run_highs(model, _with_time_left(dict(_HIGHS_OPTIONS), deadline))
    dual = res.mip_dual_bound if res.mip_dual_bound is not None else res.fun
    bound = math.inf if dual is None or not np.isfinite(dual) else -float(dual) * model.scale
    if res.status == 1:
        states = None
        if res.x is not None:
            chosen = res.x[: model.num_edges] > 0.5
            cells = _path_from_edges(mdp, chosen, model.edge_time, model.edge_source, model.edge_target)
            states = cells[:, 0] * mdp.width + cells[:, 1]
        raise OutOfTime(states, bound)
    if res.status != 0 or res.x is None:
        raise RuntimeError(f"trajectory MILP not solved to optimality: status {res.status}: {res.message}")
    chosen = res.x[: model.num_edges] > 0.5
    return _path_from_edges(mdp, chosen, model.edge_time, model.edge_source, model.edge_target), bound


def _with_time_left(options: dict, deadline: float) -> dict:
    """HiGHS options with ``time_limit`` set to the time left before ``deadline``."""
    if math.isinf(deadline):
        return options
    left = deadline - time.monotonic()
    if left <= 0:
        raise OutOfTime(None)
    return dict(options, time_limit=left)


def _path_from_edges(
    mdp: GridMDP, chosen: np.ndarray, e_time: np.ndarray, e_src: np.ndarray, e_dst: np.ndarray
) -> np.ndarray:
    """Read the path off the chosen edges (exactly one per time step, chained from the start)."""
    t, src, dst = e_time[chosen], e_src[chosen], e_dst[chosen]
    order = np.argsort(t, kind="stable")
    t, src, dst = t[order], src[order], dst[order]
    if not (np.array_equal(t, np.arange(mdp.horizon)) and src[0] == mdp.start_state
            and np.array_equal(src[1:], dst[:-1])):
        raise RuntimeError("trajectory MILP: the chosen edges do not form one path from the start")
    return states_to_cells(mdp, np.concatenate([[mdp.start_state], dst]))
