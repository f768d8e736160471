"""Run the designer-in-the-loop experiment (docs/spec.md section 7): answered queries vs risk aversion.

    ird-active [--trials N] [--out DIR] [--seed S] [--conditions C ...]
        [--workers W] [--scheduler tcp://HOST:PORT] [--size N] [--horizon T] [--num-samples K] ...

(``scripts/run_active.py`` is the same program.) For each condition (default: the paper's four
and pot_of_gold) N paired trials (trial i uses instance seed S + i in every condition): the
literal plan, the oracle plan (optimal under the true reward), and the IRD per-step plan
(training-features baseline) after 0, 1, 2, 3 and 5 answered queries (2 options each, on the
test map) for info-gain and random query selection, the posterior re-sampled (warm start) with
all evidence after every answer. The trial logic is ird_core.experiments.active.run_trial, a
pure function of its spec; trials run in a local process pool or on a Dask cluster
(ird_core.experiments.parallel), so the numbers do not depend on W or the scheduler.

Outputs in --out (default docs/results/active; ird_core.experiments.active_report): active.csv
(one row per condition x strategy x number of queries, 95% Wilson / Student-t intervals),
active_trials.csv (one row per trial x plan), active.md (tables, paired comparisons, wall
time), active_<condition>.png (mean true return vs number of queries, both strategies with 95%
bands, literal and oracle as lines), run.json.

Exit status: 0 done, 2 a bad argument (the message names it).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from ird_core.experiments import active, active_report, parallel
from ird_core.experiments.chunks import load_chunks
from ird_core.experiments.journal import open_journal
from ird_core.experiments.provenance import code_version
from ird_core.experiments.report import RunRecord
from ird_core.output_paths import make_output_folder
from ird_core.planning.sample_scale import SAMPLE_SCALES
from ird_core.posterior import METHODS
from ird_core.worlds.lavaland import ALL_CONDITIONS

__all__ = ["build_parser", "spec_settings", "run_active", "main"]

#: How active.md and run.json name the program.
COMMAND = "python scripts/run_active.py"


def build_parser() -> argparse.ArgumentParser:
    """The flags, defaulting to :class:`~ird_core.experiments.active.ActiveSpec`'s defaults."""
    d = active.ActiveSpec("side_effects", 0)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--trials", type=int, default=100, help="paired trials per condition")
    p.add_argument("--out", type=Path, default=Path("docs") / "results" / "active",
                   help="output folder, from the working directory (default docs/results/active: the "
                        "checkout's results when run from its root)")
    p.add_argument("--seed", type=int, default=0, help="base seed: trial i uses instance seed SEED + i")
    p.add_argument("--conditions", nargs="+", default=list(ALL_CONDITIONS), choices=ALL_CONDITIONS)
    parallel.add_arguments(p)
    p.add_argument("--strategies", nargs="+", default=list(d.strategies), choices=active.STRATEGIES)
    p.add_argument("--query-counts", nargs="+", type=int, default=list(d.query_counts))
    p.add_argument("--num-options", type=int, default=d.num_options)
    p.add_argument("--designer-beta", type=float, default=d.designer_beta)
    p.add_argument("--choice-beta", type=float, default=None, help="robot's answer rationality (default: designer's)")
    parallel.add_trial_arguments(p, d)
    p.set_defaults(prior_sigma=None)  # None: calibrated (ird_core.posterior.calibration)
    p.add_argument("--temperature", type=float, default=d.temperature,
                   help="the modelled designer's temperature (default: the calibrated designer's); without "
                        "--prior-sigma the prior follows it, sigma = 1 / (temperature * rms training feature norm)")
    p.add_argument("--method", default=d.method, choices=METHODS)
    p.add_argument("--warm-warmup", type=int, default=d.warm_warmup, help="warm-up of each re-sample after an answer")
    p.add_argument("--sample-scale", default=d.sample_scale, choices=SAMPLE_SCALES,
                   help="the IRD plans' samples: rescaled to span one unit over the training map before the "
                        "per-step min (training_spread, the default, as in the main experiment) or as they are")
    p.add_argument("--chains", default=d.chains, choices=active.CHAINS,
                   help="converged (default): the main experiment's recipe for --method, run until converged "
                        "(--num-chains, --warmup, --thin, --max-leapfrog are then not used); fixed: the small "
                        "fixed-length MaxEnt-Z chains those flags set")
    p.add_argument("--report-only", action="store_true",
                   help="run nothing: rewrite the report in --out from its active_trials.csv and run.json")
    p.add_argument("--merge", nargs="+", type=Path, default=None, metavar="DIR",
                   help="with --report-only: the report of the chunks in DIR... (runs of disjoint seeds with the "
                        "same settings, e.g. --seed 0 / 100 / 200 --trials 100) written into --out")
    return p


def spec_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The ActiveSpec keywords of the flags."""
    return dict(size=args.size, horizon=args.horizon, obs_dim=args.obs_dim, num_samples=args.num_samples,
                beta=args.beta, prior_sigma=args.prior_sigma, temperature=args.temperature, method=args.method,
                num_chains=args.num_chains,
                warmup=args.warmup, thin=args.thin, max_leapfrog=args.max_leapfrog, warm_warmup=args.warm_warmup,
                chains=args.chains, sample_scale=args.sample_scale,
                query_counts=tuple(sorted(set(args.query_counts))), strategies=tuple(args.strategies),
                num_options=args.num_options, designer_beta=args.designer_beta, choice_beta=args.choice_beta)


def run_active(args: argparse.Namespace, specs: list[active.ActiveSpec], settings: dict[str, Any],
               command: str) -> int:
    """Run ``specs``, write the report into ``args.out`` and print the headline. Exit status 0, 2
    when ``args.out`` cannot be made a folder (before any trial)."""
    try:
        make_output_folder(args.out)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    print(f"{len(specs)} trials ({args.trials} per condition x {len(args.conditions)} conditions), "
          f"{parallel.describe(args.workers, args.scheduler)}", file=sys.stderr)
    code = code_version()  # before any trial: the code that runs them
    journal, resumed = open_journal(args.out, code, specs)
    t0 = time.monotonic()
    per_trial = parallel.parallel_map(active.run_trial, specs, args.workers, args.scheduler, journal=journal)
    wall = time.monotonic() - t0
    results = [r for rs in per_trial for r in rs]
    summaries = active.aggregate(results)
    shown = dict(settings, trials=args.trials, seed=args.seed, workers=args.workers, scheduler=args.scheduler)
    if resumed:
        shown["resumed_trials"] = resumed
    active_report.write_report(args.out, results, summaries, args.conditions, RunRecord(command, wall, shown, code))
    journal.close()
    print("\n".join(active_report.headline(results, summaries, args.conditions, settings["query_counts"],
                                           settings["strategies"])))
    print(f"wall time {wall:.1f} s; outputs in {args.out}")
    return 0


def rewrite_report(out: Path, chunks: "list[Path] | None" = None) -> int:
    """Rewrite every report file in ``out`` from ``active_trials.csv`` and ``run.json`` of ``out``
    or of each chunk directory (:mod:`ird_core.experiments.chunks`: disjoint seeds, other settings
    equal); exit status 0, 2 when a file cannot be read or the chunks do not fit together."""
    try:
        merged, results = load_chunks(out, chunks, "active_trials.csv", active_report.read_results_csv,
                                      lambda r: (r.condition, r.seed, r.strategy, r.num_queries), lambda r: r.seed)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    conditions = list(dict.fromkeys(r.condition for r in results))
    try:
        make_output_folder(out)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    active_report.write_report(out, results, active.aggregate(results), conditions,
                               RunRecord(merged.command, merged.wall, merged.settings, merged.code))
    print(f"report rewritten in {out}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """The designer-in-the-loop experiment from the command line; exit status 0, 2 on a bad argument."""
    args = build_parser().parse_args(argv)
    if args.report_only:
        return rewrite_report(args.out, args.merge)
    if args.trials < 1:
        print("--trials must be >= 1", file=sys.stderr)
        return 2
    settings = spec_settings(args)
    try:
        specs = active.make_specs(args.conditions, args.trials, args.seed, **settings)
    except ValueError as exc:
        print(f"bad argument: {exc}", file=sys.stderr)
        return 2
    command = f"{COMMAND} " + " ".join(sys.argv[1:] if argv is None else argv)
    return run_active(args, specs, settings, command)
