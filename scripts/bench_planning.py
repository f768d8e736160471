#!/usr/bin/env python3
"""Benchmark: risk-averse planners against naive references, in the same run.

- ``per_step`` on a 50x50 map, T = 100, K = 1000, d = 50 (target < 0.5 s), against a reference
  that builds the per-cell minimum with a Python loop over samples.
- ``trajectory`` on 15x15, T = 30, K = 50, d = 50 with posterior-like weights (a mean plus a
  spread of 0.3 of its scale per coordinate), on Gaussian features and on Lavaland-like features
  (four terrain means in 50-d plus noise), several seeds (target < 10 s for the worst seed).
  References: the MILP over the bound-pruned graph (``solver="milp-highs"``) and a naive MILP
  (full time-expanded grid, no reachability or bound pruning, no sample reduction, sample rows
  over edge variables, HiGHS defaults with zero gap) under a time limit.
- A small case (5x5, T = 7) where brute-force enumeration is feasible cross-checks all of them.

Every solver's objective is compared (``agree`` column); a mismatch exits with status 1.

    python scripts/bench_planning.py [--repeats 3] [--seeds 4] [--naive-limit 60] [--log-z]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
import warnings
from typing import Callable

import numpy as np
import scipy.sparse as sp
from scipy.optimize import Bounds, LinearConstraint, milp

from ird_core import planning
from ird_core.mdp import GridMDP, optimal_path, successor_table
from ird_core.mdp.enumeration import all_trajectories, trajectory_features

ROWS: list[tuple] = []
MISMATCHES: list[str] = []


def posterior_like(rng: np.random.Generator, k: int, d: int, spread: float = 0.3) -> np.ndarray:
    """``(K, d)`` samples around a random mean, like an IRD posterior."""
    mean = rng.normal(size=d) / np.sqrt(d)
    return mean + spread * rng.normal(size=(k, d)) / np.sqrt(d)


def gaussian_map(rng: np.random.Generator, size: int, d: int) -> np.ndarray:
    return rng.normal(size=(size, size, d))


def lavaland_like_map(rng: np.random.Generator, size: int, d: int) -> np.ndarray:
    """Cells labelled lava / dirt / grass / target (5 / 60 / 30 / 5 %), observed as their
    terrain's 50-d mean plus noise (the latent conditions of section 5)."""
    means = rng.normal(size=(4, d))
    labels = rng.choice(4, size=(size, size), p=[0.05, 0.6, 0.3, 0.05])
    return means[labels] + 0.3 * rng.normal(size=(size, size, d))


def timed(fn: Callable[[], object], repeats: int) -> tuple[float, object]:
    """Median wall time of ``repeats`` calls and the last result."""
    times, out = [], None
    for _ in range(repeats):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def record(mode: str, solver: str, case: str, t: int, k: int, d: int, seconds: float | None,
           target: float | None, objective: float | None, reference: float | None, note: str = "") -> None:
    agree = "-"
    if objective is not None and reference is not None:
        ok = abs(objective - reference) <= 1e-9 * max(1.0, abs(reference))
        agree = "yes" if ok else "NO"
        if not ok:
            MISMATCHES.append(f"{mode}/{solver}/{case}: {objective!r} != {reference!r}")
    verdict = "-" if target is None or seconds is None else ("pass" if seconds < target else "FAIL")
    ROWS.append((mode, solver, case, t, k, d, "timeout" if seconds is None else f"{seconds:.3f}",
                 "-" if target is None else f"< {target:g}", verdict, agree, note))


# --------------------------------------------------------------------------- naive references


def naive_per_step(mdp: GridMDP, weights: np.ndarray, b: np.ndarray) -> float:
    """Per-cell minimum with a Python loop over samples, then the same DP."""
    flat = mdp.features.reshape(mdp.num_states, -1)
    worst = np.full(mdp.num_states, np.inf)
    for w, bi in zip(weights, b):
        worst = np.minimum(worst, flat @ w - bi)
    cells, _ = optimal_path(mdp, worst.reshape(mdp.height, mdp.width))
    return float(sum(worst[r * mdp.width + c] for r, c in cells))


def naive_trajectory_milp(mdp: GridMDP, weights: np.ndarray, b: np.ndarray, limit: float) -> float | None:
    """The textbook MILP: every (t, s) of the grid, every sample, rows over edge variables."""
    horizon, s_count = mdp.horizon, mdp.num_states
    table = successor_table(mdp.height, mdp.width)
    src, move = np.nonzero(table >= 0)
    dst = table[src, move]
    per_t = len(src)
    e_time = np.repeat(np.arange(horizon), per_t)
    e_src, e_dst = np.tile(src, horizon), np.tile(dst, horizon)
    n_edges = len(e_time)
    ids = np.arange(n_edges)
    # Flow rows: node (t, s) for t = 0..T-1: out - in = [t == 0 and s == start].
    inner = e_time < horizon - 1  # edges entering a node that has out-edges
    rows = np.concatenate([e_time * s_count + e_src, (e_time[inner] + 1) * s_count + e_dst[inner]])
    cols = np.concatenate([ids, ids[inner]])
    vals = np.concatenate([np.ones(n_edges), -np.ones(int(inner.sum()))])
    flow = sp.csr_matrix((vals, (rows, cols)), shape=(horizon * s_count, n_edges + 1))
    supply = np.zeros(horizon * s_count)
    supply[mdp.start_state] = 1.0
    rewards = (mdp.features.reshape(s_count, -1) @ weights.T - b).T  # (K, S)
    samples = sp.hstack([sp.csr_matrix(-rewards[:, e_dst]), sp.csr_matrix(np.ones((len(weights), 1)))])
    a = sp.vstack([flow, samples], format="csr")
    lb = np.concatenate([supply, np.full(len(weights), -np.inf)])
    ub = np.concatenate([supply, rewards[:, mdp.start_state]])
    cost = np.zeros(n_edges + 1)
    cost[-1] = -1.0
    res = milp(cost, integrality=np.r_[np.ones(n_edges), 0.0],
               bounds=Bounds(np.r_[np.zeros(n_edges), -np.inf], np.r_[np.ones(n_edges), np.inf]),
               constraints=LinearConstraint(a, lb, ub), options={"mip_rel_gap": 0.0, "time_limit": limit})
    if res.status != 0:
        return None
    chosen = res.x[:n_edges] > 0.5
    order = np.argsort(e_time[chosen])
    states = np.r_[mdp.start_state, e_dst[chosen][order]]
    phi = mdp.features.reshape(s_count, -1)[states].sum(axis=0)
    return float(np.min(weights @ phi - (horizon + 1) * b))


def brute_trajectory(mdp: GridMDP, weights: np.ndarray, b: np.ndarray) -> float:
    phi = trajectory_features(mdp, all_trajectories(mdp))
    return float((phi @ weights.T - (mdp.horizon + 1) * b).min(axis=1).max())


# --------------------------------------------------------------------------- benchmarks


def bench_per_step(repeats: int, with_log_z: bool) -> None:
    rng = np.random.default_rng(0)
    size, horizon, k, d = 50, 100, 1000, 50
    mdp = GridMDP(gaussian_map(rng, size, d), (size // 2, size // 2), horizon)
    weights = posterior_like(rng, k, d)
    case = f"{size}x{size} gaussian"
    baselines = ["none", "initial_state"] + (["log_z"] if with_log_z else [])
    for baseline in baselines:
        reps = 1 if baseline == "log_z" else repeats
        seconds, plan = timed(lambda: planning.plan_path(mdp, weights, "per_step", baseline), reps)
        b = planning.reward_baselines(mdp, weights, baseline)
        naive_seconds, naive = timed(lambda: naive_per_step(mdp, weights, b), reps)
        note = "log Z of 1000 samples dominates" if baseline == "log_z" else ""
        record("per_step", f"dp/{baseline}", case, horizon, k, d, seconds,
               None if baseline == "log_z" else 0.5, plan.objective, naive, note)
        record("per_step", f"naive-loop/{baseline}", case, horizon, k, d, naive_seconds, None, naive, None,
               "baselines precomputed")


def bench_trajectory(repeats: int, seeds: int, naive_limit: float) -> None:
    size, horizon, k, d = 15, 30, 50, 50
    for kind, make in (("gaussian", gaussian_map), ("lavaland-like", lavaland_like_map)):
        for baseline in ("initial_state", "none"):
            times, milp_times, objectives, solvers = [], [], [], set()
            for seed in range(seeds):
                rng = np.random.default_rng(seed)
                mdp = GridMDP(make(rng, size, d), (size // 2, size // 2), horizon)
                weights = posterior_like(rng, k, d)
                seconds, plan = timed(lambda: planning.plan_path(mdp, weights, "trajectory", baseline), repeats)
                times.append(seconds)
                milp_seconds, milp_plan = timed(
                    lambda: planning.plan_path(mdp, weights, "trajectory", baseline, solver="milp-highs",
                                               time_limit=naive_limit), 1)
                milp_times.append(milp_seconds)
                objectives.append((plan.objective, milp_plan.objective))
                solvers.add(plan.solver)
            case = f"{size}x{size} {kind} ({seeds} seeds)"
            default = "/".join(sorted(solvers))
            record("trajectory", f"{default}/{baseline}", case, horizon, k, d, max(times), 10.0, None, None,
                   f"median {statistics.median(times):.3f} s; worst seed shown")
            # The two exact solvers must agree on every seed.
            worst = max(objectives, key=lambda pair: abs(pair[0] - pair[1]))
            record("trajectory", f"milp-highs/{baseline}", case, horizon, k, d, max(milp_times), None,
                   worst[1], worst[0], f"median {statistics.median(milp_times):.3f} s; bound-pruned graph")
    # The naive MILP on one instance (seed 0, Gaussian, initial_state).
    rng = np.random.default_rng(0)
    mdp = GridMDP(gaussian_map(rng, size, d), (size // 2, size // 2), horizon)
    weights = posterior_like(rng, k, d)
    b = planning.reward_baselines(mdp, weights, "initial_state")
    plan = planning.plan_path(mdp, weights, "trajectory", "initial_state")
    start = time.perf_counter()
    naive = naive_trajectory_milp(mdp, weights, b, naive_limit)
    elapsed = time.perf_counter() - start
    record("trajectory", "naive-milp/initial_state", f"{size}x{size} gaussian (seed 0)", horizon, k, d,
           None if naive is None else elapsed, None, plan.objective if naive is not None else None, naive,
           f"time limit {naive_limit:g} s" if naive is None else "")


def bench_small_cross_check(repeats: int, naive_limit: float) -> None:
    """A size where brute force and the naive MILP finish: all four must agree."""
    size, horizon, k, d = 5, 7, 20, 50
    rng = np.random.default_rng(7)
    mdp = GridMDP(gaussian_map(rng, size, d), (2, 2), horizon)
    weights = posterior_like(rng, k, d, spread=1.0)
    case = f"{size}x{size} gaussian, wide"
    for baseline in ("none", "initial_state"):
        b = planning.reward_baselines(mdp, weights, baseline)
        brute_seconds, brute = timed(lambda: brute_trajectory(mdp, weights, b), 1)
        for solver in ("label-bb", "milp-highs"):
            seconds, plan = timed(lambda: planning.plan_path(mdp, weights, "trajectory", baseline, solver=solver),
                                  repeats)
            record("trajectory", f"{solver}/{baseline}", case, horizon, k, d, seconds, None, plan.objective, brute)
        start = time.perf_counter()
        naive = naive_trajectory_milp(mdp, weights, b, naive_limit)
        record("trajectory", f"naive-milp/{baseline}", case, horizon, k, d,
               None if naive is None else time.perf_counter() - start, None, naive, brute)
        record("trajectory", f"brute-force/{baseline}", case, horizon, k, d, brute_seconds, None, None, None,
               f"{len(all_trajectories(mdp))} trajectories")


def print_table() -> None:
    header = ("mode", "solver/baseline", "map", "T", "K", "d", "time [s]", "target", "result", "agree", "note")
    widths = [max(len(str(row[i])) for row in [header, *ROWS]) for i in range(len(header))]
    for row in [header, tuple("-" * w for w in widths), *ROWS]:
        print("  ".join(str(v).ljust(w) for v, w in zip(row, widths)).rstrip())


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--naive-limit", type=float, default=60.0, help="seconds for the naive MILP")
    parser.add_argument("--log-z", action="store_true", help="also time per_step with the log_z baseline")
    args = parser.parse_args()
    warnings.simplefilter("ignore", RuntimeWarning)
    bench_per_step(args.repeats, args.log_z)
    bench_trajectory(args.repeats, args.seeds, args.naive_limit)
    bench_small_cross_check(args.repeats, args.naive_limit)
    print_table()
    for line in MISMATCHES:
        print("MISMATCH", line)
    return 1 if MISMATCHES else 0


if __name__ == "__main__":
    sys.exit(main())
