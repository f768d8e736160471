"""Exact solver of the ``trajectory`` planning mode (docs/spec.md section 4).

``max_xi min_i f_i(xi)`` with ``f_i(xi) = sum_t q_i(s_t)`` and ``q_i = w_i . F - b_i`` (``K``
baseline-shifted per-cell rewards) is not an MDP: the minimum over samples does not decompose
over time steps. :func:`plan_trajectory` solves it exactly:

1. Samples that cannot change the minimum are dropped: duplicate ``q_i`` rows, and ``q_i``
   dominated on every reachable cell by another sample's (``q_j <= q_i``).
2. Bounds. Each sample's own DP optimum bounds the objective from above; so does
   ``max_xi lam . f(xi)`` (one DP) for any ``lam`` on the simplex. The best ``lam`` gives the
   LP relaxation (mixtures of paths), found by column generation: a master LP over path
   columns (HiGHS) priced by DP. Every bound used is an exact DP value, never an LP float.
3. Incumbents: the per-step path, the bottleneck sample's path, the generated columns, then
   beam searches. If the incumbent reaches the upper bound it is returned at once.
4. ``"label-bb"`` (default): breadth-first branch and bound over the time-expanded graph.
   Labels are partial paths (their return vectors); a label is pruned when the bounds of
   step 2 applied to its completions cannot beat the incumbent, or when another label at
   the same node is at least as good for every sample; labels with the same multiset of
   visited cells merge. Memory is capped; past the cap the automatic choice falls back on
   the MILP.
5. ``"milp-highs"``: binary edge variables ``x[t, s, move]`` on the time-expanded graph
   restricted to (time, state) pairs reachable from the start within the horizon AND whose
   best path through them (DP bounds of step 2) could beat the incumbent; unit flow out of
   the start, conservation at each inner (time, state), visit counts
   ``n[c] = sum of edges into c``, and ``z <= q_i(s_0) + sum_c q_i(c) n[c]`` per kept
   sample; maximise ``z``. HiGHS runs at zero gap with 1e-9 feasibility tolerances on
   rewards normalised to ``|q| <= 1``, HiGHS's presolve off (it gave wrong answers on these
   models).

Limits. ``time_limit`` is wall-clock seconds. ``work_limit`` counts label expansions: the child
labels the label searches generate (every beam search and the exact search, before pruning),
checked per memory chunk. A plan finishes under ``work_limit`` exactly when its total count is
at most the limit, so where it stops depends on its inputs only, never on the machine; under a
work limit alone the clock is never read. The column-generation LP is bounded by its round count,
and the MILP is never used under a work limit (its time has no deterministic bound): where the
automatic choice would fall back on it, the plan stops as if out of work. Either limit raises
:class:`OutOfTime` with the best path so far and a proven upper bound.

No relaxation is ever returned as a plan: the LP relaxation only supplies bounds. Exactness:
a path better than the returned one by more than ``2e-12 * (T + 1) * max|q|`` (float rounding
slack) does not exist, for ``label-bb``; for ``milp-highs`` up to HiGHS's tolerances as well.

States are flat indices ``s = row * W + col`` (``S = H * W``); rewards arrive as ``(K, S)``
(or ``(K, H, W)`` for :func:`plan_trajectory`). Everything is vectorised over samples, labels,
cells and edges; Python loops run over time steps, solver iterations and memory chunks only.
The public entry point is :func:`plan_trajectory` (limits and their exception in
:mod:`ird_core.planning.trajectory_limits`, the MILP in :mod:`ird_core.planning.trajectory_milp`);
:mod:`ird_core.planning` wraps it into ``plan_path``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ird_core.mdp import GridMDP, successor_table
from ird_core.planning.trajectory_bounds import best_returns as _best_returns
from ird_core.planning.trajectory_bounds import path_states as _path_states
from ird_core.planning.trajectory_bounds import start_distance as _start_distance
from ird_core.planning.trajectory_bounds import states_to_cells
from ird_core.planning.trajectory_bounds import to_go as _to_go
from ird_core.planning.trajectory_bounds import trajectory_value as _trajectory_value
from ird_core.planning.trajectory_limits import Limits, OutOfTime, check_work_limit
from ird_core.planning.trajectory_milp import build_trajectory_milp, promising_nodes, solve_trajectory_milp

__all__ = ["plan_trajectory"]
# Relative slack when comparing an exactly recomputed path value with a DP bound: only float
# rounding of two summation orders separates them.
_CERTIFY_RTOL = 1e-12
# Column-generation rounds for the LP relaxation (each: one small LP and one DP).
_COLUMN_GENERATION_ITERATIONS = 200
# Labels of a node checked as dominators of the others (by the largest sum of returns).
_DOMINANCE_DEPTH = 16
# Beam widths of the incumbent-improving heuristic run before the exact label search.
_BEAM_WIDTHS = (256, 4096)
# Largest number of label entries (labels x samples) the trajectory label search may hold.
_LABEL_BUDGET = 20_000_000
# Largest K * K * R boolean work (R = reachable cells) spent on pruning dominated samples.
_DOMINANCE_BUDGET = 400_000_000


class _BudgetExceeded(Exception):
    """The label search would need more memory than its budget."""


def _reduce_samples(q: np.ndarray) -> np.ndarray:
    """Indices of the samples that matter for ``min_i sum_t q_i(s_t)``.

    Merges identical rows, then drops a sample ``i`` when another distinct sample ``j`` has
    ``q_j <= q_i`` on every cell (``i`` is then never below ``j`` on any path). The minimal
    rows survive, and every dropped row lies above one of them.

    Args:
        q: ``(K, R)`` shifted rewards on the reachable cells.
    Returns:
        sorted ``(K',)`` int64 indices into ``q``, ``K' >= 1``.
    """
    _, first = np.unique(q, axis=0, return_index=True)
    kept = np.sort(first)
    rows = q[kept]
    k, r = rows.shape
    if k * k * r > _DOMINANCE_BUDGET:  # too costly: keep every distinct sample
        return kept
    block = max(1, 20_000_000 // max(1, k * r))
    dominated = np.zeros(k, dtype=bool)
    for lo in range(0, k, block):  # blocks of samples, vectorised over pairs and cells
        leq = np.all(rows[None, :, :] <= rows[lo : lo + block, None, :], axis=2)  # [i, j]: q_j <= q_i
        leq[np.arange(leq.shape[0]), np.arange(lo, lo + leq.shape[0])] = False
        dominated[lo : lo + block] = leq.any(axis=1)
    return kept[~dominated]


@dataclass(frozen=True)
class _Relaxation:
    """The LP relaxation ``max over mixtures of paths of min_i E[f_i]`` (equal to the MILP's LP
    relaxation, the time-expanded flow polytope being integral), by column generation.

    Every multiplier row ``lam`` lies on the simplex, so ``max_xi lam . f(xi)`` (one exact DP)
    bounds the trajectory objective from above whatever the LP's accuracy.
    """

    multipliers: np.ndarray       # (m, K), rows on the simplex
    bound: float                  # min over rows of max_xi lam . f(xi)
    paths: tuple[np.ndarray, ...]  # the generated columns, as state indices


def _lp_relaxation(mdp: GridMDP, q: np.ndarray, seeds: list[np.ndarray], tol: float,
                   limits: Limits | None = None) -> _Relaxation:
    """Column generation: master LP over path columns (HiGHS), pricing by exact DP.

    Args:
        q: ``(K, S)`` shifted rewards.
        seeds: initial paths (state indices).
        tol: stop once pricing improves the master value by at most ``tol``.
        limits: past their deadline no further round starts (the rounds done so far give
            valid, if looser, bounds); the work limit does not apply (the round count bounds it).
    """
    from scipy.optimize import linprog  # noqa: PLC0415 - lazy: every node imports ird_core.planning, few solve a MILP/LP

    k = len(q)
    paths = list(seeds)
    returns = [q[:, p].sum(axis=1) for p in paths]  # each (K,)
    multipliers, bound = [], np.inf
    for _ in range(_COLUMN_GENERATION_ITERATIONS):
        if multipliers and limits is not None and limits.time_up():
            break
        columns = np.stack(returns, axis=1)  # (K, m)
        m = columns.shape[1]
        # max z  s.t.  z <= columns @ mu,  sum(mu) = 1,  mu >= 0.
        res = linprog(np.r_[np.zeros(m), -1.0], A_ub=np.c_[-columns, np.ones(k)], b_ub=np.zeros(k),
                      A_eq=np.r_[np.ones(m), 0.0][None, :], b_eq=[1.0],
                      bounds=[(0.0, None)] * m + [(None, None)], method="highs")
        if res.status != 0:
            break  # the bound so far (and the per-sample bounds) remain valid
        lam = np.clip(-res.ineqlin.marginals, 0.0, None)
        lam = lam / lam.sum() if lam.sum() > 0 else np.full(k, 1.0 / k)
        states = _path_states(mdp, lam @ q)
        priced = float((lam @ q)[states].sum())
        multipliers.append(lam)
        bound = min(bound, priced)
        if priced <= -res.fun + tol or any(np.array_equal(states, p) for p in paths):
            break
        paths.append(states)
        returns.append(q[:, states].sum(axis=1))
    return _Relaxation(np.array(multipliers).reshape(-1, k), bound, tuple(paths))


def _dominated(labels: np.ndarray, nodes: np.ndarray, depth: int) -> np.ndarray:
    """Labels dominated (``P_a >= P_b`` for every sample) by one of the ``depth`` labels with
    the largest ``sum(P)`` at the same node.

    Labels are totally ordered by (node, larger sum, index); a label is only dropped for an
    earlier one, so every dropped label is dominated by a kept one and the optimum survives.

    Args:
        labels: ``(N, K)`` return vectors; nodes: ``(N,)`` states.
    Returns:
        ``(N,)`` bool, True where dominated.
    """
    order = np.lexsort((-labels.sum(axis=1), nodes))
    sorted_nodes = nodes[order]
    starts = np.flatnonzero(np.r_[True, sorted_nodes[1:] != sorted_nodes[:-1]])
    sizes = np.diff(np.r_[starts, len(order)])
    group = np.repeat(np.arange(len(starts)), sizes)
    rank = np.arange(len(order)) - starts[group]
    ranked = labels[order]
    dominated = np.zeros(len(order), dtype=bool)
    for j in range(depth):  # compare everyone with the j-th best label of its node
        later = np.flatnonzero(rank > j)
        if len(later) == 0:
            break
        dominated[later] |= np.all(ranked[starts[group[later]] + j] >= ranked[later], axis=1)
    out = np.zeros(len(order), dtype=bool)
    out[order] = dominated
    return out


def _label_search(mdp: GridMDP, q: np.ndarray, multipliers: np.ndarray, incumbent: float,
                  slack: float, limits: Limits | None = None, beam: int | None = None) -> np.ndarray | None:
    """Exact branch and bound over the time-expanded graph, breadth first (or a beam search).

    A label is a partial path to ``(t, s)`` with return vector ``P`` (K,). It is pruned when no
    completion can beat ``incumbent + slack``, by the bounds ``min_i (P_i + V_i(t, s))`` (each
    sample alone) and ``lam . P + V_lam(t, s)`` for every multiplier row ``lam`` (because
    ``min_i f_i <= lam . f``), and when another label at the same node is at least as good for
    every sample (:func:`_dominated`). Only visit counts matter, so labels at the same node with the
    same multiset of visited states (reorderings of stays make many) are merged; the multiset
    is keyed exactly by two order-free 64-bit sums of per-state random integers (a false merge
    needs a 128-bit collision).

    With ``beam`` set, only the ``beam`` labels with the highest bound survive each step: a
    fast heuristic for a better incumbent, exact no more.

    Args:
        q: ``(K, S)`` shifted rewards; multipliers: ``(m, K)`` simplex rows.
        limits: checked before each memory chunk; every child label generated counts one unit
            of work (``None``: no limits).
        beam: ``None`` (exact) or the beam width.
    Returns:
        states of the best path beating ``incumbent + slack``, or ``None`` if there is none.
    Raises:
        _BudgetExceeded: more than ``_LABEL_BUDGET`` label entries at some time step.
        OutOfTime: a limit of ``limits`` was reached.
    """
    limits = Limits() if limits is None else limits
    k = len(q)
    if (mdp.horizon + 1) * mdp.num_states * (k + len(multipliers)) > _LABEL_BUDGET:
        raise _BudgetExceeded(f"bound tables of {k + len(multipliers)} rows over {mdp.horizon + 1} steps")
    succ = successor_table(mdp.height, mdp.width)
    per_sample = _to_go(mdp, q).transpose(0, 2, 1)  # (T+1, S, K)
    combined = _to_go(mdp, multipliers @ q).transpose(0, 2, 1)  # (T+1, S, m)
    q_t = q.T
    state_keys = np.random.default_rng(0x12D).integers(0, 2**63, size=(mdp.num_states, 2), dtype=np.uint64)
    labels, nodes = q_t[[mdp.start_state]], np.array([mdp.start_state])
    keys = state_keys[[mdp.start_state]]
    parents: list[np.ndarray] = []
    node_history = [nodes]
    chunk = max(1, 4_000_000 // (5 * (k + len(multipliers))))
    for t in range(1, mdp.horizon + 1):
        kept = []
        for lo in range(0, len(labels), chunk):  # bounded memory; vectorised inside
            limits.check_time()
            nxt = succ[nodes[lo : lo + chunk]]
            parent, move = np.nonzero(nxt >= 0)
            child = nxt[parent, move]
            limits.spend(len(child))
            parent += lo
            value = labels[parent] + q_t[child]
            bound = np.minimum((value + per_sample[t][child]).min(axis=1),
                               (value @ multipliers.T + combined[t][child]).min(axis=1))
            alive = bound > incumbent + slack
            kept.append((parent[alive], child[alive], value[alive], bound[alive]))
        parent, child, value, bound = (np.concatenate(a) for a in zip(*kept))
        if len(child) == 0:
            return None
        key = np.concatenate([child[:, None].astype(np.uint64), keys[parent] + state_keys[child]], axis=1)
        _, first = np.unique(key, axis=0, return_index=True)
        first = first[~_dominated(value[first], child[first], _DOMINANCE_DEPTH)]
        if beam is not None and len(first) > beam:  # keep the most promising labels
            first = first[np.argpartition(-bound[first], beam)[:beam]]
        elif len(first) * k > _LABEL_BUDGET:
            raise _BudgetExceeded(f"{len(first)} labels of {k} samples at step {t}")
        labels, nodes, keys = value[first], child[first], key[first, 1:]
        parents.append(parent[first])
        node_history.append(nodes)
    final = labels.min(axis=1)
    best = int(np.argmax(final))
    if final[best] <= incumbent + slack:
        return None
    states = np.empty(mdp.horizon + 1, dtype=np.int64)
    for t in range(mdp.horizon, 0, -1):  # backtrack the parent pointers
        states[t] = node_history[t][best]
        best = int(parents[t - 1][best])
    states[0] = mdp.start_state
    return states


def plan_trajectory(
    mdp: GridMDP, q_cells: np.ndarray, *, solver: str | None, time_limit: float | None,
    work_limit: int | None = None,
) -> tuple[np.ndarray, float, str]:
    """Best path for ``min_i sum_t q_i(s_t)`` (see the module docstring for the algorithm).

    Args:
        mdp: the test MDP (grid, start, horizon ``T``).
        q_cells: ``(K, H, W)`` baseline-shifted per-cell rewards ``q_i``.
        solver: ``None`` (label search, falling back on the MILP past its memory budget unless
            ``work_limit`` is set), ``"label-bb"`` or ``"milp-highs"``.
        time_limit: seconds > 0, or ``None`` for no limit.
        work_limit: label expansions >= 1, or ``None`` for no limit; not with ``"milp-highs"``.
    Returns:
        ``(cells, bound, solver)``: the path's checked ``(T + 1, 2)`` cells, a proven upper
        bound on the optimum, and the solver that finished.
    Raises:
        OutOfTime: a limit was reached first (carries the best path, the bound so far and
            which limit, ``reason``).
        ValueError: ``work_limit`` with ``solver="milp-highs"``.
        RuntimeError: HiGHS failed, or ``solver="label-bb"`` ran out of memory budget.
    """
    limits = Limits(time_limit, check_work_limit(work_limit, solver))
    q_all = q_cells.reshape(len(q_cells), -1)
    dist = _start_distance(mdp)
    reach = np.flatnonzero(dist <= mdp.horizon)
    q = q_all[_reduce_samples(q_all[:, reach])]
    slack = _CERTIFY_RTOL * (mdp.horizon + 1) * float(np.abs(q[:, reach]).max())
    own_best = _best_returns(mdp, q)
    seeds = [_path_states(mdp, q.min(axis=0)), _path_states(mdp, q[int(np.argmin(own_best))])]
    relaxation = _lp_relaxation(mdp, q, seeds, tol=slack, limits=limits)
    upper = min(relaxation.bound, float(own_best.min()))
    values = [_trajectory_value(q, p) for p in relaxation.paths]
    best, incumbent = relaxation.paths[int(np.argmax(values))], max(values)
    used = "milp-highs" if solver == "milp-highs" else "label-bb"
    try:
        if used == "label-bb":
            if incumbent >= upper - slack:  # the LP relaxation is tight: no branching needed
                return states_to_cells(mdp, best), upper, used
            try:
                for width in _BEAM_WIDTHS:  # cheap heuristics first: a better incumbent prunes more
                    found = _label_search(mdp, q, relaxation.multipliers, incumbent, slack, limits, beam=width)
                    if found is not None:
                        best, incumbent = found, _trajectory_value(q, found)
                found = _label_search(mdp, q, relaxation.multipliers, incumbent, slack, limits)
            except _BudgetExceeded as exc:
                if solver == "label-bb":
                    raise RuntimeError(f"trajectory label search over budget ({exc}); "
                                       "use solver='milp-highs'") from exc
                if work_limit is not None:  # the MILP's time has no deterministic bound
                    raise OutOfTime(None, reason="work", message=f"label search memory budget reached ({exc}) "
                                    f"after {limits.work} label expansions; no MILP fallback under a work limit"
                                    ) from None
                used = "milp-highs"  # automatic choice: fall back on the MILP
            else:
                if found is not None and _trajectory_value(q, found) > incumbent:
                    best, incumbent = found, _trajectory_value(q, found)
                return states_to_cells(mdp, best), incumbent, used
        limits.check_time()
        multipliers = np.concatenate([relaxation.multipliers, np.eye(len(q))])
        model = build_trajectory_milp(mdp, q, promising_nodes(mdp, q, multipliers, incumbent, slack, best))
        cells, dual_bound = solve_trajectory_milp(mdp, model, limits.deadline)
    except OutOfTime as exc:
        found = exc.states
        if found is not None and _trajectory_value(q, found) > incumbent:
            best, incumbent = found, _trajectory_value(q, found)
        bound = max(incumbent, min(upper, exc.bound))
        raise OutOfTime(best, bound, used, exc.reason, str(exc), limits.work) from None
    found = cells[:, 0] * mdp.width + cells[:, 1]
    if _trajectory_value(q, found) > incumbent:  # else keep the incumbent (HiGHS tolerance)
        best, incumbent = found, _trajectory_value(q, found)
    return states_to_cells(mdp, best), max(incumbent, min(upper, dual_bound)), used
