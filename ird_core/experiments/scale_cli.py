"""``scripts/diagnose_scale.py``: the scale diagnosis (:mod:`ird_core.experiments.scale`) over map
sizes, horizons, betas and seeds, as a markdown table and a csv.

    python scripts/diagnose_scale.py --sizes 15:30 32:60 64:120 --seeds 6
    python scripts/diagnose_scale.py --sizes 32:60 --betas 50 25 --conditions latent_raw side_effects

One row per (condition, size, horizon, beta, method): trials, the posterior's lava value
relative to dirt (median over trials of its mean and of its spread over samples), the share of
samples valuing lava below dirt (mean), how often the main IRD plan touches lava and parks on it,
how often a lava cell is the map's best per-step-min cell, the target's standing (median over
trials of the target's posterior-mean reward above the median dirt cell, in dirt spreads, for
IRD and for the proxy; how often the plan reaches a target; how often a target cell is the best
safe cell for the per-step min) and the median inference time.
The script pins BLAS to one thread per process before numpy loads (the pool uses every core).
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import itertools
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from ird_core.experiments.parallel import add_arguments, describe, parallel_map
from ird_core.experiments.scale import DIAGNOSIS_COLUMNS, ScaleDiagnosis, diagnose
from ird_core.experiments.trials import Z_METHODS, TrialSpec
from ird_core.output_paths import file_problem
from ird_core.vocabulary import CONDITIONS

__all__ = ["main", "parse_size", "summary_table"]


def parse_size(text: str) -> tuple[int, int]:
    """``"SIZE:HORIZON"`` -> ``(size, horizon)``, both >= 3 and >= 1."""
    try:
        size, horizon = (int(part) for part in text.split(":"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"--sizes: expected SIZE:HORIZON such as 32:60, got {text!r}") from None
    if size < 3 or horizon < 1:
        raise argparse.ArgumentTypeError(f"--sizes: size must be >= 3 and horizon >= 1, got {text!r}")
    return size, horizon


def _run(job: tuple[TrialSpec, str]) -> ScaleDiagnosis:
    return diagnose(*job)


def summary_table(rows: Sequence[ScaleDiagnosis]) -> str:
    """The markdown table of the module docstring, groups in first-seen order."""
    groups: dict[tuple, list[ScaleDiagnosis]] = {}
    for row in rows:
        method = row.method + (" + novel" if row.novelty_feature else "")
        groups.setdefault((row.condition, row.size, row.horizon, row.beta, method), []).append(row)
    lines = ["| condition | map | T | beta | method | trials | lava - dirt: mean (median) | sd over samples "
             "(median) | samples valuing lava below dirt | IRD touches lava | parks on lava | a lava cell is "
             "the best cell | target signal: IRD / proxy (median, dirt sds) | IRD reaches the target | the target is "
             "the best safe cell | inference s (median) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for (condition, size, horizon, beta, method), group in groups.items():
        def share(flags: list[bool]) -> str:
            return f"{100 * np.mean(flags):.0f}% ({sum(flags)}/{len(flags)})"
        lines.append(
            f"| {condition} | {size}x{size} | {horizon} | {beta:g} | {method} | {len(group)} "
            f"| {np.median([r.lava_value_mean for r in group]):+.2f} | {np.median([r.lava_value_sd for r in group]):.2f} "
            f"| {100 * np.mean([r.share_below for r in group]):.0f}% | {share([r.lava_steps > 0 for r in group])} "
            f"| {share([r.parked for r in group])} | {share([r.lava_margin > 0 for r in group])} "
            f"| {np.median([r.target_signal for r in group]):.1f} / {np.median([r.proxy_target_signal for r in group]):.1f} "
            f"| {share([r.reached_target for r in group])} | {share([r.target_margin > 0 for r in group])} "
            f"| {np.median([r.infer_seconds for r in group]):.1f} |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=parse_size, nargs="+", default=[(15, 30), (32, 60), (64, 120)],
                        metavar="SIZE:HORIZON")
    parser.add_argument("--conditions", nargs="+", choices=CONDITIONS, default=["latent_raw"])
    parser.add_argument("--methods", nargs="+", choices=Z_METHODS, default=["maxent_z"])
    parser.add_argument("--betas", type=float, nargs="+", default=[TrialSpec.beta])
    parser.add_argument("--novelty-feature", action="store_true",
                        help="add the hypothesis feature 'novel' (ird_core.hypothesis.novelty)")
    parser.add_argument("--seeds", type=int, default=6, help="trials per cell: seeds SEED .. SEED + N - 1")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None, help="write the rows as csv here")
    add_arguments(parser)
    args = parser.parse_args(argv)
    if args.seeds < 1:
        parser.error(f"--seeds: expected >= 1, got {args.seeds}")
    try:
        jobs = [(TrialSpec(condition=c, seed=args.seed + i, size=size, horizon=horizon, beta=beta, factorial=False,
                           z_methods=(method,), novelty_feature=args.novelty_feature), method)
                for c, (size, horizon), beta, method, i in itertools.product(
                    args.conditions, args.sizes, args.betas, args.methods, range(args.seeds))]
    except ValueError as exc:  # a seed or beta the trials cannot use, named before any work
        parser.error(str(exc))
    if args.out is not None:  # checked before any work; an earlier file is replaced only at the end
        problem = file_problem(args.out)
        if problem:
            parser.error(f"--out: {problem}")
    print(f"{len(jobs)} diagnoses, {describe(args.workers, args.scheduler)}", file=sys.stderr)
    rows = parallel_map(_run, jobs, args.workers, args.scheduler, desc="diagnoses")
    print(summary_table(rows))
    if args.out is not None:
        args.out.parent.mkdir(parents=True, exist_ok=True)  # file_problem found that it can be made
        with args.out.open("w", newline="") as handle:
            writer = csv.writer(handle)
            writer.writerow(DIAGNOSIS_COLUMNS)
            writer.writerows(dataclasses.astuple(row) for row in rows)
    return 0
