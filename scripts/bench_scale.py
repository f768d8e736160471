#!/usr/bin/env python3
"""Benchmark: a converged IRD posterior and a plan on robot-sized maps (issue 31's speed goals).

For each map size and horizon (``--sizes SIZE:HORIZON ...``, the first is the same-run
reference), each Z-method and each seed it runs one Lavaland trial's evidence, posterior and
plans with the experiments' settings, the chains run until split R-hat <= 1.05 and bulk ESS >=
``--min-ess`` (:func:`ird_core.experiments.scale_timing.time_trial`), and prints one row per run,
then the medians per size and method with their ratio to the reference size's.

    python scripts/bench_scale.py                                  # 15:30 32:60 64:120, MaxEnt-Z, seeds 0-2
    python scripts/bench_scale.py --sizes 15:30 64:120 128:240 --methods maxent_z sample_z --seeds 0
    python scripts/bench_scale.py --out scale_timing.csv           # every row as CSV too

Goals (docs/benchmarks.md, "Robot-sized maps"): at 64x64, T = 120, d = 50 a converged posterior
(evidence + sampling) within 10 s on a 2-core machine for both Z-methods, a plan within 1 s.
Times are wall clock of one process: run it on an otherwise idle machine. Ctrl-C (SIGINT) stops
a long run and still prints and writes the runs measured so far.
"""

from __future__ import annotations

import argparse
import csv
import os
import statistics
import sys
from pathlib import Path

# The hot path is single-threaded numpy; multithreaded BLAS only oversubscribes a small machine.
# Set before numpy is imported (importing it pins its thread pool).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from ird_core.experiments.progress import progress_bar  # noqa: E402
from ird_core.experiments.scale_cli import parse_size  # noqa: E402
from ird_core.experiments.scale_timing import TIMING_COLUMNS, ScaleTiming, time_trial  # noqa: E402
from ird_core.experiments.trials import Z_METHODS, TrialSpec  # noqa: E402
from ird_core.output_paths import file_problem  # noqa: E402
from ird_core.worlds.lavaland import CONDITIONS  # noqa: E402

#: The issue's goals: seconds for a converged posterior and for a plan at 64x64, T = 120.
POSTERIOR_GOAL_S, PLAN_GOAL_S = 10.0, 1.0


def format_row(r: ScaleTiming) -> str:
    """One run's line: phases in seconds, diagnostics, and whether it converged."""
    return (f"{r.size:>3}x{r.size:<3} {r.horizon:>4} {r.method:<9} {r.seed:>4} {r.dim:>3} | "
            f"{r.evidence_seconds:>8.2f} {r.sample_seconds:>7.2f} {r.posterior_seconds:>9.2f} | "
            f"{r.plan_seconds:>6.3f} {r.literal_seconds:>7.3f} | {r.r_hat_max:>6.3f} {r.ess_min:>5.0f} "
            f"{r.iterations:>5d} {r.evaluations:>6d} {'yes' if r.converged else 'NO'}")


def format_rows(rows: "list[ScaleTiming]") -> str:
    """A header, then one :func:`format_row` line per run."""
    head = (f"{'size':>7} {'T':>4} {'method':<9} {'seed':>4} {'d':>3} | {'evidence':>8} {'sample':>7} "
            f"{'posterior':>9} | {'plan':>6} {'literal':>7} | {'R-hat':>6} {'ESS':>5} {'iter':>5} {'calls':>6} conv")
    return "\n".join([head, "-" * len(head), *(format_row(r) for r in rows)])


def format_medians(rows: "list[ScaleTiming]") -> str:
    """Medians per (size, method), with their ratio to the first size's median (same method)."""
    groups: dict[tuple[int, int, str], list[ScaleTiming]] = {}
    for r in rows:
        groups.setdefault((r.size, r.horizon, r.method), []).append(r)
    reference: dict[str, tuple[float, float]] = {}
    head = (f"{'size':>7} {'T':>4} {'method':<9} {'runs':>4} | {'posterior s':>11} {'x ref':>6} | "
            f"{'plan s':>7} {'x ref':>6} | converged")
    lines = [head, "-" * len(head)]
    for (size, horizon, method), group in groups.items():
        post = statistics.median(r.posterior_seconds for r in group)
        plan = statistics.median(r.plan_seconds for r in group)
        ref_post, ref_plan = reference.setdefault(method, (post, plan))
        lines.append(f"{size:>3}x{size:<3} {horizon:>4} {method:<9} {len(group):>4} | {post:>11.2f} "
                     f"{post / max(ref_post, 1e-9):>5.1f}x | {plan:>7.3f} {plan / max(ref_plan, 1e-9):>5.1f}x | "
                     f"{sum(r.converged for r in group)}/{len(group)}")
    return "\n".join(lines)


def goal_lines(rows: "list[ScaleTiming]") -> list[str]:
    """The goals' verdicts at 64x64, T = 120 (nothing when that size was not run)."""
    out = []
    for method in Z_METHODS:
        group = [r for r in rows if (r.size, r.horizon, r.method) == (64, 120, method)]
        if not group:
            continue
        worst_post = max(r.posterior_seconds for r in group)
        worst_plan = max(r.plan_seconds for r in group)
        ok = worst_post <= POSTERIOR_GOAL_S and all(r.converged for r in group)
        out.append(f"goal {method} at 64x64, T = 120: converged posterior <= {POSTERIOR_GOAL_S:g} s: "
                   f"{'met' if ok else 'MISSED'} (worst {worst_post:.1f} s); plan <= {PLAN_GOAL_S:g} s: "
                   f"{'met' if worst_plan <= PLAN_GOAL_S else 'MISSED'} (worst {worst_plan:.3f} s)")
    return out


def main(argv: "list[str] | None" = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", nargs="+", type=parse_size, default=[(15, 30), (32, 60), (64, 120)],
                        metavar="SIZE:HORIZON", help="map sizes and horizons; the first is the reference")
    parser.add_argument("--methods", nargs="+", choices=Z_METHODS, default=["maxent_z"])
    parser.add_argument("--seeds", nargs="+", type=int, default=[0, 1, 2])
    parser.add_argument("--condition", choices=CONDITIONS, default="latent_raw")
    parser.add_argument("--novelty-feature", action="store_true", help="IRD's hypothesis gains the 'novel' feature")
    parser.add_argument("--min-ess", type=float, default=400.0, help="bulk ESS to reach (default 400)")
    parser.add_argument("--max-iterations", type=int, default=2000, help="cap on iterations per chain")
    parser.add_argument("--out", type=Path, default=None, help="also write every row to this CSV")
    args = parser.parse_args(argv)
    if args.min_ess < 0 or args.max_iterations < 1:
        parser.error("--min-ess must be >= 0 and --max-iterations >= 1")
    if args.out is not None and file_problem(args.out):  # before the runs: their rows would be lost
        parser.error(f"--out: {file_problem(args.out)}")
    try:  # every run's spec before the first: a seed no trial can use is named now
        runs = [(TrialSpec(args.condition, seed, size=size, horizon=horizon, novelty_feature=args.novelty_feature),
                 size, method) for size, horizon in args.sizes for method in args.methods for seed in args.seeds]
    except ValueError as exc:
        parser.error(str(exc))
    print(f"{args.condition}, {len(args.seeds)} seed(s), bulk ESS >= {args.min_ess:g}, R-hat <= 1.05; "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}", flush=True)
    for method in args.methods:  # not reported: loads the compiled engine and the caches first
        time_trial(TrialSpec(args.condition, 0, size=6, horizon=8, num_proxy_samples=10), method, 0.0, 1)
    rows: list[ScaleTiming] = []
    bar = progress_bar(len(runs), "scale runs", "run")
    try:
        for spec, size, method in runs:
            bar.set_postfix_str(f"{size}x{size} {method} seed {spec.seed}")
            rows.append(time_trial(spec, method, args.min_ess, args.max_iterations))
            bar.write(format_row(rows[-1]))  # each row as it is measured
            bar.update(1)
    except KeyboardInterrupt:  # a long run stopped by hand keeps, prints and writes what it measured
        print(f"\ninterrupted: {len(rows)} of {len(runs)} runs measured", file=sys.stderr)
    finally:
        bar.close()
    if not rows:
        return 130
    print()
    print(format_rows(rows))
    print()
    print(format_medians(rows))
    for line in goal_lines(rows):
        print(line)
    print("posterior = evidence (the proxy's and Sample-Z's proxies' feature counts) + sample (warm-up "
          "included); plan = the main IRD plan from all samples; literal = one exact DP (the same map "
          "without IRD). x ref: against the first size's median in this run.")
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)
        with open(args.out, "w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(TIMING_COLUMNS)
            writer.writerows([getattr(r, c) for c in TIMING_COLUMNS] for r in rows)
        print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
