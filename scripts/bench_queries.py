#!/usr/bin/env python3
"""Benchmark: one query round against one ``sample_posterior`` call (docs/spec.md section 7, issue target).

A query round = ``queries.propose_query`` (2 options, ``--strategy``, default evoi, among the rich
candidates of ``ird_core.designer.candidates`` for Rob's per-step plan with the training-features
baseline) on the test map from the posterior's 1000 samples, a simulated designer's answer (Boltzmann on the true returns), and
``posterior.sample_joint_posterior`` re-sampling 1000 draws with the answer added, warm started
from the previous posterior (``initial=``). Target: round <= 1.2 x one cold ``sample_posterior``
(same proxy, default sampler settings) on a 15x15 map with T = 30.

Each repeat runs the cold posterior, then the round from it, back to back (the machine's load
hits both alike); the table gives every repeat, the medians and their ratio, in wall and CPU time,
and the split R-hat of every warm-started re-sample (must stay <= 1.1). The verdict uses CPU time
(process time, single-threaded BLAS): other jobs on a shared machine inflate wall time.
``--cold-resample`` also times a cold re-sample with the answer, the alternative to warm starting.

    python scripts/bench_queries.py [--condition latent_raw] [--method maxent_z] [--strategy evoi] [--repeats 3]
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

# Single-threaded BLAS, as scripts/bench_inference.py (small products oversubscribe 2 cores).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from ird_core import posterior
from ird_core.designer import queries  # noqa: E402
from ird_core.designer.candidates import PlanSettings  # noqa: E402
from ird_core.experiments.trials import MAIN_BASELINE  # noqa: E402
from ird_core.worlds import evaluation, lavaland

TARGET_RATIO = 1.2


def timed(fn, *args, **kwargs):
    wall, cpu = time.perf_counter(), time.process_time()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - wall, time.process_time() - cpu


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--condition", default="latent_raw", choices=lavaland.ALL_CONDITIONS)
    parser.add_argument("--method", default="maxent_z", choices=posterior.METHODS)
    parser.add_argument("--seed", type=int, default=0, help="Lavaland instance seed")
    parser.add_argument("--strategy", default="evoi", choices=queries.STRATEGIES)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--samples", type=int, default=1000)
    parser.add_argument("--size", type=int, default=15)
    parser.add_argument("--horizon", type=int, default=30)
    parser.add_argument("--beta", type=float, default=1.0, help="proxy rationality")
    parser.add_argument("--answer-beta", type=float, default=1.0,
                        help="designer rationality: the simulated designer's and the one assumed by the robot")
    parser.add_argument("--cold-resample", action="store_true", help="also time a cold re-sample with the answer")
    args = parser.parse_args()

    inst = lavaland.make_instance(args.condition, args.seed, size=args.size, horizon=args.horizon)
    train, test = lavaland.train_mdp(inst), lavaland.test_mdp(inst)
    proxy_features = posterior.proxy_feature_expectations(inst)
    extra: dict = {}
    if args.method == "sample_z":  # the phi_i once, outside the timings of both (as a node would cache them)
        extra["proxy_sample_features"] = posterior.proxy_prior_features(inst, posterior.DEFAULT_NUM_PROXY_SAMPLES,
                                                                       args.seed)
    proxy = posterior.ProxyObservation(inst.proxy_weights, train, proxy_features, extra.get("proxy_sample_features"))
    rob = PlanSettings(MAIN_BASELINE, proxy_features / (inst.train_horizon + 1))

    rows = []
    warnings.simplefilter("ignore", RuntimeWarning)  # R-hat is printed instead
    for r in range(args.repeats):
        cold, cold_wall, cold_cpu = timed(posterior.sample_posterior, inst.proxy_weights, train, args.beta,
                                          args.method, args.samples, r, proxy_features=proxy_features, **extra)
        query, propose_wall, propose_cpu = timed(queries.propose_query, test, cold.samples, args.answer_beta, 2,
                                                 args.strategy, r, rob)
        returns = np.array([evaluation.true_return(inst.test_labels, cells) for cells in query.option_cells])
        chosen = queries.simulated_answer(returns, args.answer_beta, np.random.default_rng(r))
        evidence = [proxy, posterior.ChoiceObservation(query.option_features, chosen, args.answer_beta)]
        warm, warm_wall, warm_cpu = timed(posterior.sample_joint_posterior, evidence, args.beta, args.method,
                                          args.samples, 1000 + r, initial=cold)
        row = dict(cold=cold, cold_wall=cold_wall, cold_cpu=cold_cpu, query=query, propose_wall=propose_wall,
                   propose_cpu=propose_cpu, warm=warm, warm_wall=warm_wall, warm_cpu=warm_cpu)
        if args.cold_resample:
            again, row["again_wall"], _ = timed(posterior.sample_joint_posterior, evidence, args.beta, args.method,
                                                args.samples, 1000 + r)
            row["again"] = again
        rows.append(row)
        print(f"repeat {r + 1}/{args.repeats} done", flush=True)

    print(f"\n{args.condition} (d = {len(inst.feature_names)}), {args.size}x{args.size}, T = {args.horizon}, "
          f"{args.method}, {args.samples} samples, beta {args.beta:g}, answer beta {args.answer_beta:g}, "
          f"strategy {args.strategy}")
    header = (f"{'rep':>3} {'cold s':>7} {'cold CPU':>8} {'calls':>5} {'R-hat':>6} | {'propose s':>9} {'cands':>5} "
              f"{'IG':>5} | {'warm s':>6} {'calls':>5} {'R-hat':>6} {'ESS':>5} | {'round s':>7} {'round CPU':>9}")
    if args.cold_resample:
        header += f" | {'cold re-sample s':>16} {'R-hat':>6}"
    print(header)
    for r, row in enumerate(rows):
        line = (f"{r:>3} {row['cold_wall']:>7.2f} {row['cold_cpu']:>8.2f} {row['cold'].num_evaluations:>5d} "
                f"{row['cold'].r_hat_max:>6.3f} | {row['propose_wall']:>9.2f} {row['query'].num_candidates:>5d} "
                f"{row['query'].information_gain:>5.3f} | {row['warm_wall']:>6.2f} {row['warm'].num_evaluations:>5d} "
                f"{row['warm'].r_hat_max:>6.3f} {row['warm'].ess_min:>5.0f} | "
                f"{row['propose_wall'] + row['warm_wall']:>7.2f} {row['propose_cpu'] + row['warm_cpu']:>9.2f}")
        if args.cold_resample:
            line += f" | {row['again_wall']:>16.2f} {row['again'].r_hat_max:>6.3f}"
        print(line)
    median = lambda key: float(np.median([row[key] for row in rows]))  # noqa: E731
    round_wall = [row["propose_wall"] + row["warm_wall"] for row in rows]
    round_cpu = float(np.median([row["propose_cpu"] + row["warm_cpu"] for row in rows]))
    ratio_cpu = round_cpu / median("cold_cpu")
    ratio_wall = float(np.median([w / row["cold_wall"] for w, row in zip(round_wall, rows)]))
    ratio_calls = float(np.median([row["warm"].num_evaluations / row["cold"].num_evaluations for row in rows]))
    worst = max(row["warm"].r_hat_max for row in rows)
    print(f"median: sample_posterior {median('cold_wall'):.2f} s (CPU {median('cold_cpu'):.2f} s); query round "
          f"{float(np.median(round_wall)):.2f} s (CPU {round_cpu:.2f} s) = propose {median('propose_wall'):.2f} s "
          f"+ warm re-sample {median('warm_wall'):.2f} s")
    print(f"ratio round / sample_posterior: CPU {ratio_cpu:.2f} (target <= {TARGET_RATIO}: "
          f"{'met' if ratio_cpu <= TARGET_RATIO else 'MISSED'}); wall {ratio_wall:.2f} (median of back-to-back "
          f"pairs); sampler calls warm / cold {ratio_calls:.2f}")
    print(f"warm-started R-hat: max {worst:.3f} (<= {posterior.R_HAT_CONVERGED}: "
          f"{'holds' if worst <= posterior.R_HAT_CONVERGED else 'FAILS'})")
    print("CPU time decides: other jobs on a shared machine inflate wall time (single-threaded BLAS here).")
    print("calls: batched log-density(+gradient) calls of the sampler (warm-up included).")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
