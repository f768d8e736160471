#!/usr/bin/env python3
"""Benchmark: batched exact feature expectations vs a naive dense-tensor reference.

The reference is what a textbook MaxEnt IRL implementation does: a dense (S, A, S) transition
tensor, soft value iteration and a forward pass per weight vector, in a Python loop over weights.
Both are exact; the script checks they agree, then prints a table. A second table times the
two engines of the linear-space passes (``IRD_ENGINE=numpy``: the numpy loops; ``numba``: the
compiled loops of ``ird_core.mdp.linear_kernels``) at the sampler's batch sizes on the experiments'
map (15x15, T = 30, d = 50), checks that they agree bit for bit, and prints the ratio.

    python scripts/bench_mdp.py [--size 20] [--horizon 40] [--batch 256] [--dim 50]
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np
from scipy.special import logsumexp

from ird_core.mdp import (
    MOVES,
    GridMDP,
    cell_rewards,
    feature_expectations,
    linear_kernels,
    log_partition,
    log_partition_and_feature_expectations,
    successor_table,
)
from ird_core.mdp.passes import _log_visitation_exact


def dense_transitions(height: int, width: int) -> np.ndarray:
    """``(S, A, S)`` 0/1 tensor; an action that would leave the grid has no successor."""
    table = successor_table(height, width)
    s = height * width
    transitions = np.zeros((s, len(MOVES), s))
    rows, moves = np.nonzero(table >= 0)
    transitions[rows, moves, table[rows, moves]] = 1.0
    return transitions


def naive_feature_expectations(mdp: GridMDP, weights: np.ndarray, transitions: np.ndarray) -> np.ndarray:
    """One weight at a time over the dense tensor; ``(K, d)`` -> ``(K, d)``."""
    flat = mdp.features.reshape(mdp.num_states, -1)
    with np.errstate(divide="ignore"):
        log_p = np.log(transitions)
    legal = transitions.sum(axis=2) > 0  # (S, A)
    out = np.empty_like(weights)
    for k, w in enumerate(weights):
        r = flat @ w
        values = [r]
        q_all = []
        for _ in range(mdp.horizon):
            q = logsumexp(log_p + values[-1][None, None, :], axis=2)  # (S, A)
            q = np.where(legal, q, -np.inf)
            q_all.append(q)
            values.append(r + logsumexp(q, axis=1))
        values.reverse()
        q_all.reverse()
        d = np.zeros(mdp.num_states)
        d[mdp.start_state] = 1.0
        visits = d.copy()
        for t in range(mdp.horizon):
            policy = np.exp(q_all[t] - logsumexp(q_all[t], axis=1, keepdims=True))
            d = np.einsum("s,sa,sat->t", d, policy, transitions)
            visits += d
        out[k] = visits @ flat
    return out


def log_space_feature_expectations(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """The engine's exact log-space passes alone (its fallback, and the engine before the
    linear-space fast path); ``(K, d)`` -> ``(K, d)``."""
    log_visits, _ = _log_visitation_exact(mdp, cell_rewards(mdp, weights))
    return np.exp(log_visits).reshape(len(weights), -1) @ mdp.features.reshape(mdp.num_states, -1)


def best_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=20)
    parser.add_argument("--horizon", type=int, default=40)
    parser.add_argument("--batch", type=int, default=256)
    parser.add_argument("--dim", type=int, default=50)
    parser.add_argument("--naive-batch", type=int, default=8,
                        help="weights timed in the naive loop; its time is scaled to --batch (linear in K)")
    args = parser.parse_args()

    rng = np.random.default_rng(0)
    mdp = GridMDP(rng.normal(size=(args.size, args.size, args.dim)), (1, 2), args.horizon)
    weights = 0.3 * rng.normal(size=(args.batch, args.dim))
    transitions = dense_transitions(args.size, args.size)

    fast = feature_expectations(mdp, weights)
    subset = weights[: args.naive_batch]
    naive = naive_feature_expectations(mdp, subset, transitions)
    error = float(np.max(np.abs(fast[: args.naive_batch] - naive) / np.maximum(1.0, np.abs(naive))))

    log_space = log_space_feature_expectations(mdp, weights)
    error = max(error, float(np.max(np.abs(fast - log_space) / np.maximum(1.0, np.abs(log_space)))))

    t_fast = best_time(lambda: feature_expectations(mdp, weights), 3)
    t_log_space = best_time(lambda: log_space_feature_expectations(mdp, weights), 3)
    t_logz = best_time(lambda: log_partition(mdp, weights), 3)
    t_naive_subset = best_time(lambda: naive_feature_expectations(mdp, subset, transitions), 1)
    t_naive = t_naive_subset * args.batch / args.naive_batch

    print(f"map {args.size}x{args.size}, T = {args.horizon}, K = {args.batch}, d = {args.dim}; "
          f"max relative difference between the implementations: {error:.1e}")
    print(f"{'implementation':<52} {'wall time (s)':>14} {'speed-up':>9}")
    print(f"{'naive: per-weight loop, dense (S,A,S) tensor':<52} {t_naive:>14.3f} {'1.0x':>9}")
    print(f"{'  (timed on ' + str(args.naive_batch) + ' weights, scaled linearly)':<52} {t_naive_subset:>14.3f}")
    print(f"{'log-space passes only (the exact fallback), batched':<52} {t_log_space:>14.3f} "
          f"{t_naive / t_log_space:>8.1f}x")
    print(f"{'ird_core.mdp.feature_expectations (batched)':<52} {t_fast:>14.3f} {t_naive / t_fast:>8.1f}x")
    print(f"{'ird_core.mdp.log_partition (batched)':<52} {t_logz:>14.3f} {t_naive / t_logz:>8.1f}x")
    target = 30.0
    verdict = "PASS" if t_naive / t_fast >= target else "FAIL"
    print(f"target: feature_expectations >= {target:.0f}x faster than naive: {verdict}")
    engines_table()


def engines_table(batches: tuple[int, ...] = (4, 8, 32, 256), calls: int = 200) -> None:
    """numpy loops against compiled loops, per call of ``log_partition_and_feature_expectations``
    on the experiments' map (15x15, T = 30, d = 50), best of 3 rounds of ``calls`` calls."""
    if not linear_kernels.available():
        print("engines: numba is not installed, only the numpy loops run")
        return
    rng = np.random.default_rng(1)
    mdp = GridMDP(rng.normal(size=(15, 15, 50)), (7, 7), 30)
    print("\nengines of the linear-space passes, log Z and feature expectations per call (15x15, T = 30, d = 50)")
    print(f"{'weights':>8} {'numpy (ms)':>11} {'numba (ms)':>11} {'speed-up':>9}  bit for bit")
    saved = os.environ.get("IRD_ENGINE")
    try:
        for k in batches:
            weights = 0.3 * rng.normal(size=(k, 50))
            n = max(3, calls * 8 // max(k, 8))
            times, results = {}, {}
            for engine in ("numpy", "numba"):
                os.environ["IRD_ENGINE"] = engine
                results[engine] = log_partition_and_feature_expectations(mdp, weights)
                times[engine] = best_time(lambda: [log_partition_and_feature_expectations(mdp, weights)
                                                   for _ in range(n)], 3) / n
            same = all(np.array_equal(a, b) for a, b in zip(results["numpy"], results["numba"]))
            print(f"{k:>8} {times['numpy'] * 1e3:>11.3f} {times['numba'] * 1e3:>11.3f} "
                  f"{times['numpy'] / times['numba']:>8.1f}x  {'yes' if same else 'NO'}")
    finally:
        if saved is None:
            os.environ.pop("IRD_ENGINE", None)
        else:
            os.environ["IRD_ENGINE"] = saved


if __name__ == "__main__":
    main()
