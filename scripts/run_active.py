#!/usr/bin/env python3
"""Run the designer-in-the-loop experiment (docs/spec.md section 7): answered queries vs risk aversion.

    .venv/bin/python scripts/run_active.py [--trials N] [--out DIR] [--seed S] [--conditions C ...]
        [--workers W] [--scheduler tcp://HOST:PORT] [--size N] [--horizon T] [--num-samples K] ...

For each condition (default: the paper's four and pot_of_gold) N paired trials (trial i uses
instance seed S + i in every condition): the literal plan, the oracle plan (optimal under the
true reward), and the IRD per-step plan (training-features baseline) after 0, 1, 2, 3 and 5
answered queries (2 options each, on the test map) for info-gain and random query selection,
the posterior re-sampled (warm start) with all evidence after every answer. The trial logic is
ird_core.experiments.active.run_trial, a pure function of its spec; trials run in a local process pool or on
a Dask cluster (scripts/_parallel.py), so the numbers do not depend on W or the scheduler.

Outputs in --out (default docs/results/active): active.csv (one row per condition x strategy x
number of queries, 95% Wilson / Student-t intervals), active_trials.csv (one row per trial x
plan), active.md (tables, paired comparisons, wall time), active_<condition>.png (mean true
return vs number of queries, both strategies with 95% bands, literal and oracle as lines),
run.json.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout
sys.path.insert(0, str(Path(__file__).resolve().parent))  # scripts/_parallel.py

import argparse  # noqa: E402
import csv  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402

import _parallel  # noqa: E402  (first: one BLAS thread per worker, before numpy loads)

from ird_core.experiments import active  # noqa: E402
from ird_core.posterior import METHODS  # noqa: E402
from ird_core.render import TERRAIN_COLORS  # noqa: E402
from ird_core.worlds.lavaland import ALL_CONDITIONS  # noqa: E402
from ird_core.worlds.terrain import Terrain  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
LABEL = {"info_gain": "info-gain queries", "random": "random queries", "literal": "literal", "oracle": "oracle"}
COLOUR = {"info_gain": "#4c72b0", "random": "#dd8452", "literal": "#c44e52", "oracle": "#55a868"}


def _fmt(v) -> str:
    if isinstance(v, bool):
        return str(int(v))
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.6g}"
    return str(v)


def write_csv(path: Path, columns: tuple[str, ...], rows: list[dict]) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for row in rows:
            w.writerow([_fmt(row[c]) for c in columns])


def _trial_row(r: active.ActiveResult) -> dict:
    row = dataclasses.asdict(r)
    row["cells"] = " ".join(f"{a},{b}" for a, b in r.cells)
    return row


def _pct(x: float) -> str:
    return "nan" if math.isnan(x) else f"{100 * x:.0f}"


def _num(x: float, digits: int = 2) -> str:
    return "nan" if math.isnan(x) else f"{x:.{digits}f}"


def markdown_table(summaries: list[active.ActiveSummary], condition: str) -> str:
    lines = ["| strategy | queries | trials | lava % [95% CI] | target % [95% CI] | gold % [95% CI] "
             "| mean true return [95% CI] | asked | info gain (nats) | R-hat>1.1 |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for s in summaries:
        if s.condition != condition:
            continue
        lines.append(
            f"| {s.strategy} | {s.num_queries} | {s.trials} "
            f"| {_pct(s.lava_fraction)} [{_pct(s.lava_ci_low)}, {_pct(s.lava_ci_high)}] "
            f"| {_pct(s.target_fraction)} [{_pct(s.target_ci_low)}, {_pct(s.target_ci_high)}] "
            f"| {_pct(s.gold_fraction)} [{_pct(s.gold_ci_low)}, {_pct(s.gold_ci_high)}] "
            f"| {_num(s.mean_return)} [{_num(s.return_ci_low)}, {_num(s.return_ci_high)}] "
            f"| {_num(s.mean_asked, 1)} | {_num(s.mean_information_gain, 3)} | {s.nonconverged} |")
    return "\n".join(lines)


def headline(results: list[active.ActiveResult], summaries: list[active.ActiveSummary],
             conditions: list[str], counts: tuple[int, ...], strategies: tuple[str, ...]) -> list[str]:
    """The three questions: one info-gain vs one random query (paired), the share of the
    literal-to-oracle gap closed by 3 queries, lava and gold after the queries."""
    lines = []
    one = 1 if 1 in counts else (min(c for c in counts if c > 0) if any(c > 0 for c in counts) else None)
    three = 3 if 3 in counts else max(counts)
    for c in conditions:
        if one is not None and set(strategies) >= {"info_gain", "random"}:
            mean, lo, hi, n = active.paired_difference(results, c, ("info_gain", one), ("random", one))
            verdict = "beats" if lo > 0 else ("is beaten by" if hi < 0 else "does not separate from")
            lines.append(f"- {c}: after {one} quer{'y' if one == 1 else 'ies'}, info-gain {verdict} random: paired "
                         f"return difference {_num(mean)} [{_num(lo)}, {_num(hi)}] (n = {n})")
        closed = ", ".join(f"{s} {_num(100 * active.gap_closed(summaries, c, s, three), 0)}%" for s in strategies)
        before = _num(100 * active.gap_closed(summaries, c, strategies[0], 0), 0) if 0 in counts else "nan"
        lines.append(f"- {c}: share of the literal-to-oracle return gap closed after {three} queries: {closed} "
                     f"(IRD without queries: {before}%)")
        by = {(s.strategy, s.num_queries): s for s in summaries if s.condition == c}
        for s in strategies:
            seq = "; ".join(f"{k}: lava {_pct(by[s, k].lava_fraction)}%, target {_pct(by[s, k].target_fraction)}%"
                            + (f", gold {_pct(by[s, k].gold_fraction)}%" if c == "pot_of_gold" else "")
                            for k in counts if (s, k) in by)
            lines.append(f"  - {s} by number of queries: {seq}")
    return lines


def write_markdown(path: Path, results, summaries, conditions, settings: dict, wall: float, command: str) -> None:
    counts, strategies = tuple(settings["query_counts"]), tuple(settings["strategies"])
    text = ["# Designer in the loop: answered queries vs risk aversion", "",
            f"Command: `{command}`", "",
            f"Wall time: {wall:.1f} s ({_parallel.describe(settings['workers'], settings['scheduler'])}).", "",
            "Settings: " + ", ".join(f"{k}={v}" for k, v in settings.items() if k not in ("workers", "scheduler")),
            "", "IRD plan: per_step x training_features (exact DP on all posterior samples), re-planned after every "
            "answer on the posterior re-sampled (warm start) with all evidence so far. Queries: 2 paths on the test "
            "map, chosen by expected information gain or uniformly among the samples' distinct optimal paths; "
            "answered by the simulated designer (Boltzmann on true return). literal = the proxy's plan, oracle = the "
            "true-reward optimum (exact DP). Intervals: 95% Wilson for fractions, 95% Student-t for mean returns "
            "and for paired differences. `asked` = questions really asked (a round is skipped when all samples "
            "plan the same path).", "",
            "## Headline", "", *headline(results, summaries, conditions, counts, strategies), ""]
    for c in conditions:
        text += [f"## {c}", "", markdown_table(summaries, c), ""]
    path.write_text("\n".join(text))


def plot_condition(out: Path, summaries: list[active.ActiveSummary], condition: str) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [s for s in summaries if s.condition == condition]
    fig, (ax, ax2) = plt.subplots(1, 2, figsize=(10, 3.8), dpi=110)
    for s in rows:
        if s.strategy in ("literal", "oracle"):
            ax.axhline(s.mean_return, color=COLOUR[s.strategy], lw=1.5, ls="--", label=f"{LABEL[s.strategy]}")
            ax.axhspan(s.return_ci_low, s.return_ci_high, color=COLOUR[s.strategy], alpha=0.12, lw=0)
    for strategy in ("info_gain", "random"):
        ss = sorted((s for s in rows if s.strategy == strategy), key=lambda s: s.num_queries)
        if not ss:
            continue
        x = [s.num_queries for s in ss]
        ax.plot(x, [s.mean_return for s in ss], marker="o", color=COLOUR[strategy], label=f"IRD, {LABEL[strategy]}")
        ax.fill_between(x, [s.return_ci_low for s in ss], [s.return_ci_high for s in ss], color=COLOUR[strategy],
                        alpha=0.2, lw=0)
        for name in ("lava", "target", "gold"):
            if name == "gold" and condition != "pot_of_gold":
                continue
            key = {"lava": "lava_fraction", "target": "target_fraction", "gold": "gold_fraction"}[name]
            ax2.plot(x, [getattr(s, key) for s in ss], color=TERRAIN_COLORS[Terrain[name.upper()]],
                     marker="o" if strategy == "info_gain" else "s", ls="-" if strategy == "info_gain" else ":",
                     label=f"{name}, {LABEL[strategy]}")
        ax.set_xticks(x)
        ax2.set_xticks(x)
    n = rows[0].trials if rows else 0
    ax.set_xlabel("answered queries")
    ax.set_ylabel("mean true return")
    ax.set_title(f"{condition.replace('_', ' ')}: true return ({n} paired trials, 95% CI)", fontsize=9)
    ax.legend(frameon=False, fontsize=7)
    ax2.set_xlabel("answered queries")
    ax2.set_ylabel("fraction of trials")
    ax2.set_ylim(-0.02, 1.02)
    ax2.set_title("IRD path: touches lava / reaches target / reaches gold\n(solid: info-gain, dotted: random)",
                  fontsize=8)
    ax2.legend(frameon=False, fontsize=6, ncol=2)
    for a in (ax, ax2):
        a.spines[["top", "right"]].set_visible(False)
    fig.tight_layout()
    path = out / f"active_{condition}.png"
    fig.savefig(path)
    plt.close(fig)
    return path


def build_parser() -> argparse.ArgumentParser:
    d = active.ActiveSpec("side_effects", 0)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--trials", type=int, default=100, help="paired trials per condition")
    p.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "active")
    p.add_argument("--seed", type=int, default=0, help="base seed: trial i uses instance seed SEED + i")
    p.add_argument("--conditions", nargs="+", default=list(ALL_CONDITIONS), choices=ALL_CONDITIONS)
    _parallel.add_arguments(p)
    p.add_argument("--strategies", nargs="+", default=list(d.strategies), choices=active.STRATEGIES)
    p.add_argument("--query-counts", nargs="+", type=int, default=list(d.query_counts))
    p.add_argument("--num-options", type=int, default=d.num_options)
    p.add_argument("--designer-beta", type=float, default=d.designer_beta)
    p.add_argument("--choice-beta", type=float, default=None, help="robot's answer rationality (default: designer's)")
    _parallel.add_trial_arguments(p, d)
    p.add_argument("--method", default=d.method, choices=METHODS)
    p.add_argument("--warm-warmup", type=int, default=d.warm_warmup, help="warm-up of each re-sample after an answer")
    return p


def spec_settings(args) -> dict:
    return dict(size=args.size, horizon=args.horizon, obs_dim=args.obs_dim, num_samples=args.num_samples,
                beta=args.beta, prior_sigma=args.prior_sigma, method=args.method, num_chains=args.num_chains,
                warmup=args.warmup, thin=args.thin, max_leapfrog=args.max_leapfrog, warm_warmup=args.warm_warmup,
                query_counts=tuple(sorted(set(args.query_counts))), strategies=tuple(args.strategies),
                num_options=args.num_options, designer_beta=args.designer_beta, choice_beta=args.choice_beta)


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    if args.trials < 1:
        print("--trials must be >= 1", file=sys.stderr)
        return 2
    settings = spec_settings(args)
    try:
        specs = active.make_specs(args.conditions, args.trials, args.seed, **settings)
    except ValueError as exc:
        print(f"bad argument: {exc}", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    command = "python scripts/run_active.py " + " ".join(sys.argv[1:] if argv is None else argv)
    print(f"{len(specs)} trials ({args.trials} per condition x {len(args.conditions)} conditions), "
          f"{_parallel.describe(args.workers, args.scheduler)}", file=sys.stderr)
    t0 = time.monotonic()
    per_trial = _parallel.parallel_map(active.run_trial, specs, args.workers, args.scheduler)
    wall = time.monotonic() - t0
    results = [r for rs in per_trial for r in rs]
    summaries = active.aggregate(results)
    write_csv(args.out / "active.csv", active.SUMMARY_COLUMNS, [dataclasses.asdict(s) for s in summaries])
    write_csv(args.out / "active_trials.csv", active.RESULT_COLUMNS, [_trial_row(r) for r in results])
    shown = dict(settings, trials=args.trials, seed=args.seed, workers=args.workers, scheduler=args.scheduler)
    write_markdown(args.out / "active.md", results, summaries, args.conditions, shown, wall, command)
    figures = [plot_condition(args.out, summaries, c) for c in args.conditions]
    (args.out / "run.json").write_text(json.dumps({"command": command, "wall_seconds": wall, "settings": shown,
                                                   "figures": [f.name for f in figures]}, indent=2, default=str))
    print("\n".join(headline(results, summaries, args.conditions, settings["query_counts"], settings["strategies"])))
    print(f"wall time {wall:.1f} s; outputs in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
