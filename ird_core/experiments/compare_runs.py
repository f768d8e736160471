"""Runs side by side: the IRD planner's lava and target rates as one setting varies across run
folders (``scripts/compare_runs.py``).

A run folder is what ``run_experiments.py --out`` writes (``results.csv``, ``run.json``). Each
run is placed by the value of one setting of its ``run.json`` (``x``, e.g. ``training_worlds``;
a run that does not record it ran with the :class:`~ird_core.experiments.trials.TrialSpec`
default) and grouped into series by another (``series``, e.g. ``novelty_feature``). The figure
has one column per condition: lava on top, target below, each the planner's main-experiment
fraction with its 95% Wilson interval, beside the goal's bars (lava 2%; target 0.8 x the
literal proxy's rate on the same trials, per run).

Invariants: every number drawn is a ``results.csv`` number (nothing is recomputed); a folder
that is not a run, a setting :class:`TrialSpec` does not have, two runs at the same
(x, series, condition), or a planner no run has is a ``ValueError`` naming it before anything
is drawn.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import Any, NamedTuple, Sequence

from ird_core import style
from ird_core.experiments.frontier_report import GOAL_LAVA, GOAL_TARGET_RATIO, goal_check
from ird_core.experiments.report import ORDER, read_results_csv
from ird_core.experiments.summaries import CellSummary
from ird_core.experiments.trials import TrialSpec
from ird_core.output_paths import file_problem

__all__ = ["RunPoint", "load_run", "load_runs", "comparison_figure", "summary_lines", "main"]

_DEFAULTS = {f.name: f.default for f in dataclasses.fields(TrialSpec) if f.default is not dataclasses.MISSING}


class RunPoint(NamedTuple):
    """One run's planner summary in one condition, placed at ``x`` in ``series``."""

    x: float
    series: str
    condition: str
    ird: CellSummary
    literal: CellSummary


def _setting(settings: dict[str, Any], name: str, what: str) -> Any:
    if name not in _DEFAULTS:
        raise ValueError(f"{what}: {name!r} is not a trial setting (one of {', '.join(sorted(_DEFAULTS))})")
    return settings.get(name, _DEFAULTS[name])


def load_run(folder: Path, x: str, series: str, planner: str) -> list[RunPoint]:
    """The points of one run folder (module docstring); ``ValueError`` naming the folder, ``x``
    or ``series`` when it is not a run or the setting does not exist or is not a number."""
    folder = Path(folder)
    for name in ("results.csv", "run.json"):
        if not (folder / name).is_file():
            raise ValueError(f"{folder}: not a run folder (no {name}; run_experiments.py --out writes one)")
    try:
        settings = json.loads((folder / "run.json").read_text())["settings"]
        summaries = read_results_csv(folder / "results.csv")
    except (ValueError, KeyError, TypeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{folder}: not a readable run (run.json needs its settings, results.csv the "
                         f"report's columns): {type(exc).__name__}: {exc}") from None
    if not isinstance(settings, dict):
        raise ValueError(f"{folder}: run.json's settings are not a mapping")
    value = _setting(settings, x, "x")
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"x: {x!r} is {value!r} in {folder}, not a number")
    label = f"{series} = {_setting(settings, series, 'series')}" if series else "IRD"
    main = {(s.condition, s.planner): s for s in summaries if s.experiment == "main"}
    return [RunPoint(float(value), label, condition, main[condition, planner], main[condition, "literal"])
            for condition in ORDER if (condition, planner) in main and (condition, "literal") in main]


def load_runs(folders: Sequence[Path], x: str, series: str = "", planner: str = "ird_maxent_z",
              conditions: Sequence[str] = ()) -> list[RunPoint]:
    """Every folder's points (only ``conditions``' when given); ``ValueError`` naming the clash,
    an unknown condition or the planner (module docstring)."""
    if not folders:
        raise ValueError("runs: at least one run folder is needed")
    unknown = [c for c in conditions if c not in ORDER]
    if unknown:
        raise ValueError(f"conditions: unknown {unknown} (known: {', '.join(ORDER)})")
    points, seen = [], {}
    for folder in folders:
        for point in load_run(folder, x, series, planner):
            if conditions and point.condition not in conditions:
                continue
            key = (point.x, point.series, point.condition)
            if key in seen:
                raise ValueError(f"{folder}: {point.condition} at {x} = {point.x:g} ({point.series}) is also in "
                                 f"{seen[key]}; merge such runs first (run_experiments.py --report-only --merge)")
            seen[key] = folder
            points.append(point)
    if not points:
        raise ValueError(f"planner: no run has {planner!r} beside the literal planner in its main experiment")
    return points


def _new_figure(ncols: int) -> tuple[Any, Any]:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(3.6 * ncols + 0.6, 5.4), dpi=110)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(2, ncols, squeeze=False, sharex=True)


def comparison_figure(points: Sequence[RunPoint], x: str, planner: str = "ird_maxent_z") -> Any:
    """The figure of :func:`load_runs`' points (module docstring)."""
    conditions = [c for c in ORDER if any(p.condition == c for p in points)]
    series = list(dict.fromkeys(p.series for p in points))
    fig, axes = _new_figure(len(conditions))
    colours = [style.IRD_COLOR, style.IRD_ALT_COLOR, *style.FALLBACK_COLORS]
    for col, condition in enumerate(conditions):
        lava_ax, target_ax = axes[0, col], axes[1, col]
        for i, name in enumerate(series):
            mine = sorted((p for p in points if p.condition == condition and p.series == name), key=lambda p: p.x)
            if not mine:
                continue
            xs = [p.x for p in mine]
            for ax, field in ((lava_ax, "lava"), (target_ax, "target")):
                mid = [getattr(p.ird, f"{field}_fraction") for p in mine]
                err = [[m - getattr(p.ird, f"{field}_ci_low") for m, p in zip(mid, mine)],
                       [getattr(p.ird, f"{field}_ci_high") - m for m, p in zip(mid, mine)]]
                ax.errorbar(xs, mid, yerr=err, marker="o", capsize=3, color=colours[i % len(colours)], label=name)
            target_ax.plot(xs, [GOAL_TARGET_RATIO * p.literal.target_fraction for p in mine], linestyle="--",
                           marker="_", color=colours[i % len(colours)], alpha=0.6,
                           label=f"{GOAL_TARGET_RATIO:g} x literal ({name})")
        lava_ax.axhline(GOAL_LAVA, color=style.LITERAL_COLOR, linestyle=":", linewidth=1,
                        label=f"lava bar {GOAL_LAVA:.0%}")
        lava_ax.set_title(condition.replace("_", " "))
        target_ax.set_xlabel(x.replace("_", " "))
        for ax, label in ((lava_ax, "fraction touching lava"), (target_ax, "fraction reaching the target")):
            ax.set_ylim(0, 1)
            ax.spines[["top", "right"]].set_visible(False)
            if col == 0:
                ax.set_ylabel(label)
        target_ax.set_xticks(sorted({p.x for p in points}))
    legend: dict[str, Any] = {}
    for ax in axes.flat:
        for handle, label in zip(*ax.get_legend_handles_labels()):
            legend.setdefault(label, handle)
    fig.suptitle(f"{planner}: lava and target against {x.replace('_', ' ')} (95% Wilson CI)", fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.86))
    fig.legend(legend.values(), legend.keys(), loc="upper center", bbox_to_anchor=(0.5, 0.95),
               ncol=min(len(legend), 3), frameon=False, fontsize=8)
    return fig


def summary_lines(points: Sequence[RunPoint], x: str) -> list[str]:
    """One line per point: its series and x, then the frontier report's goal check
    (``frontier_report.goal_check``: lava, target and gap closed against the goal's bars)."""
    ordered = sorted(points, key=lambda p: (ORDER.index(p.condition), p.series, p.x))
    return [f"{p.series}, {x} = {p.x:g}, {p.ird.trials} trials: {goal_check([p.literal, p.ird])[0][2:]}"
            for p in ordered]


def main(argv: "Sequence[str] | None" = None) -> int:
    """``compare_runs.py RUN... --x SETTING [--series SETTING] [--planner P] [--conditions C...]
    --out FILE.png``; exit status 2 naming a bad argument before anything is drawn."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", type=Path, metavar="RUN", help="run folders (run_experiments.py --out)")
    parser.add_argument("--x", default="training_worlds", help="the setting on the x axis (default training_worlds)")
    parser.add_argument("--series", default="", help="the setting that tells series apart (default: one series)")
    parser.add_argument("--planner", default="ird_maxent_z", help="the planner drawn (default ird_maxent_z)")
    parser.add_argument("--conditions", nargs="+", default=[], metavar="C",
                        help="only these conditions (default: every condition of the runs)")
    parser.add_argument("--out", type=Path, required=True, help="the PNG to write")
    args = parser.parse_args(argv)
    problem = file_problem(args.out)
    if problem:
        parser.error(f"--out: {problem}")
    try:
        points = load_runs(args.runs, args.x, args.series, args.planner, args.conditions)
    except (ValueError, OSError) as exc:
        parser.error(str(exc))
    print("\n".join(summary_lines(points, args.x)), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)  # file_problem found that it can be made
    comparison_figure(points, args.x, args.planner).savefig(args.out)
    print(f"wrote {args.out}", file=sys.stderr)
    return 0
