"""The Lavaland experiments' report (docs/spec.md section 5): ``trials.csv``, ``results.csv``,
``results.md``, Figure 4's bar charts, the factorial's charts and ``run.json``.

Invariants: ``trials.csv`` has one row per trial x planner in run order (:data:`TRIAL_COLUMNS`),
``results.csv`` one row per experiment x condition x planner (:data:`RESULT_COLUMNS`); tables and
figures list the paper's conditions in the paper's order, then a world file's. Figures take every
colour from :mod:`ird_core.style` (``planner_color``: literal magenta, IRD blue, oracle grey;
``baseline_color``), keep their legends outside the bars, and mark a bar of height 0 with a
line and a "0%" (or "0") label, so a 0% bar is visible. :func:`replot` redraws the figures from a
report's committed ``results.csv`` (:func:`read_results_csv`) without running anything.
matplotlib is imported only when figures are drawn.
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path
from typing import Any, Mapping, Sequence

from ird_core import style
from ird_core.experiments.provenance import NOT_RECORDED
from ird_core.experiments.summaries import RESULT_COLUMNS, CellSummary
from ird_core.experiments.tables import cells_text, percent, write_csv, write_run_json
from ird_core.experiments.trials import (
    BASELINES,
    GRANULARITIES,
    MAIN_BASELINE,
    MAIN_GRANULARITY,
    TRIAL_COLUMNS,
    Z_METHODS,
    TrialResult,
)
from ird_core.vocabulary import ZMethod
from ird_core.worlds.lavaland import CONDITIONS, FILE_CONDITION

__all__ = ["ORDER", "Z_LABEL", "RunRecord", "write_trials_csv", "read_trials_csv", "write_results_csv",
           "read_results_csv",
           "markdown_table", "claim_check", "factorial_note", "write_markdown", "figure4_figures", "factorial_figures",
           "plot_figures", "replot", "write_report"]

#: Tables and figures: the paper's conditions, then a world file.
ORDER: tuple[str, ...] = CONDITIONS + (FILE_CONDITION,)
Z_LABEL: dict[str, str] = {ZMethod.SAMPLE_Z: "IRD Sample-Z", ZMethod.MAXENT_Z: "IRD MaxEnt-Z"}
#: (planner, label, colour) of Figure 4's bars (colours: :func:`ird_core.style.planner_color`).
FIGURE4: tuple[tuple[str, str, str], ...] = tuple(
    (key, label, style.planner_color(key)) for key, label in (
        ("literal", "Literal"), ("ird_sample_z", Z_LABEL["sample_z"]), ("ird_maxent_z", Z_LABEL["maxent_z"]),
        ("oracle", "Oracle")))


@dataclasses.dataclass(frozen=True)
class RunRecord:
    """How a run was made, as the report states it: the command line, its wall time (s),
    settings (the trial settings plus ``trials``, ``seed``, ``workers``, ``scheduler``) and the
    code that ran (``provenance.code_version`` read when the run started)."""

    command: str
    wall: float
    settings: Mapping[str, Any]
    code: str = NOT_RECORDED


def write_trials_csv(path: Path, results: Sequence[TrialResult]) -> None:
    """``trials.csv``: one row per trial x planner."""
    write_csv(path, TRIAL_COLUMNS, (dict(dataclasses.asdict(r), cells=cells_text(r.cells)) for r in results))


def read_trials_csv(path: Path) -> list[TrialResult]:
    """The rows of a ``trials.csv`` (:func:`write_trials_csv`'s inverse up to the csv's 6 significant
    digits), gzipped when ``path`` ends in ``.gz`` (the committed ``docs/results/trials.csv.gz``);
    ``ValueError`` / ``KeyError`` naming the bad row or column."""
    import csv
    import gzip

    def cells(text: str) -> tuple[tuple[int, int], ...]:
        return tuple((int(a), int(b)) for a, _, b in (pair.partition(",") for pair in text.split()))

    flag = {"0": False, "1": True}
    out = []
    with (gzip.open(path, "rt", newline="") if Path(path).suffix == ".gz" else open(path, newline="")) as handle:
        for line, row in enumerate(csv.DictReader(handle), start=2):
            try:
                out.append(TrialResult(
                    row["experiment"], row["condition"], int(row["seed"]), row["planner"], row["z_approx"],
                    row["granularity"], row["baseline"], flag[row["touched_lava"]], flag[row["reached_target"]],
                    float(row["true_return"]), float(row["objective"]), row["solver"], flag[row["fallback"]],
                    float(row["infer_seconds"]), float(row["r_hat_max"]), float(row["acceptance_rate"]),
                    cells(row["cells"])))
            except (KeyError, ValueError) as exc:
                raise ValueError(f"{path.name} line {line}: {exc!r}") from None
    return out


def write_results_csv(path: Path, summaries: Sequence[CellSummary]) -> None:
    """``results.csv``: one row per experiment x condition x planner."""
    write_csv(path, RESULT_COLUMNS, (s.row() for s in summaries))


def _gap(s: CellSummary) -> str:
    if math.isnan(s.gap_closed):
        return "-"
    return f"{percent(s.gap_closed)} [{percent(s.gap_ci_low)}, {percent(s.gap_ci_high)}]"


def read_results_csv(path: Path) -> list[CellSummary]:
    """The summaries of a ``results.csv`` (:func:`write_results_csv`'s inverse, up to float printing)."""
    import csv

    fields = {f.name: f.type for f in dataclasses.fields(CellSummary)}
    out = []
    with open(path, newline="") as handle:
        for row in csv.DictReader(handle):
            out.append(CellSummary(**{k: (int(float(v)) if fields[k] in (int, "int") else
                                          float(v) if fields[k] in (float, "float") else v)
                                      for k, v in row.items()}))
    return out


def markdown_table(summaries: Sequence[CellSummary], experiment: str) -> str:
    """The ``experiment``'s (``main`` or ``factorial``) rows as a markdown table."""
    lines = [("| condition | planner | trials | lava % [95% CI] | target % [95% CI] | mean true return [95% CI] "
              "| gap closed % [95% CI] | fallbacks | R-hat>1.1 |"),
             "|---|---|---|---|---|---|---|---|---|"]
    for s in summaries:
        if s.experiment != experiment:
            continue
        lines.append(
            f"| {s.condition} | {s.planner} | {s.trials} "
            f"| {percent(s.lava_fraction)} [{percent(s.lava_ci_low)}, {percent(s.lava_ci_high)}] "
            f"| {percent(s.target_fraction)} [{percent(s.target_ci_low)}, {percent(s.target_ci_high)}] "
            f"| {s.mean_true_return:.2f} [{s.return_ci_low:.2f}, {s.return_ci_high:.2f}] | {_gap(s)} "
            f"| {s.fallbacks} | {s.nonconverged} |")
    return "\n".join(lines)


def claim_check(summaries: Sequence[CellSummary]) -> list[str]:
    """The paper's claims (Figure 4: IRD touches lava less than the literal planner), checked on
    the main experiment, one line per Z-approximation x condition."""
    main = {(s.condition, s.planner): s for s in summaries if s.experiment == "main"}
    conditions = sorted({c for c, _ in main}, key=lambda c: ORDER.index(c))
    lines = []
    for z in Z_METHODS:
        for c in conditions:
            lit, ird = main.get((c, "literal")), main.get((c, f"ird_{z}"))
            if lit is None or ird is None:
                continue
            below = ird.lava_fraction < lit.lava_fraction
            disjoint = ird.lava_ci_high < lit.lava_ci_low
            lines.append(f"- {Z_LABEL[z]}, {c}: IRD lava {percent(ird.lava_fraction)}% vs literal "
                         f"{percent(lit.lava_fraction)}%: "
                         f"{'below' if below else 'NOT below'}, 95% intervals {'do not overlap' if disjoint else 'OVERLAP'}; "
                         + ("no literal-to-oracle return gap to close" if math.isnan(ird.gap_closed)
                            else f"closes {_gap(ird)}% of the literal-to-oracle return gap"))
    return lines


def factorial_note(results: Sequence[TrialResult], settings: Mapping[str, Any]) -> str:
    """The factorial's paragraph: which samples its plans use and how many trajectory plans fell
    back to the per-step plan; empty without trajectory plans."""
    traj = [r for r in results if r.granularity == "trajectory"]
    if not traj:
        return ""
    num_samples = settings["num_samples"]
    return (f"Per-step and trajectory plans both use the same first {settings['factorial_samples']} of the "
            f"{num_samples} posterior samples (the main IRD planner uses all {num_samples}). "
            f"Trajectory plans: exact solver, at most {settings['traj_work_limit']:,} label expansions per plan; "
            f"{sum(r.fallback for r in traj)} of {len(traj)} trajectory plans hit the limit and fell back to the "
            f"per-step plan of the same samples (column `fallbacks`).")


def write_markdown(path: Path, summaries: Sequence[CellSummary], run: RunRecord, fallbacks_note: str) -> None:
    """``results.md``: command, wall time, settings, Figure 4's table and claim check, the factorial."""
    settings = run.settings
    text = [
        "# Lavaland experiment results",
        "",
        f"Command: `{run.command}`",
        "",
        f"Code: {run.code}",
        "",
        f"Wall time: {run.wall:.1f} s ({settings['workers']} worker(s), "
        f"{settings['scheduler'] or 'local process pool'}).",
        "",
        "Settings: " + ", ".join(f"{k}={v}" for k, v in settings.items() if k not in ("workers", "scheduler")),
        "",
        f"Main IRD planner: granularity `{MAIN_GRANULARITY}`, baseline `{MAIN_BASELINE}` "
        "(exact DP on all posterior samples).",
        ("Intervals: 95% Wilson score for fractions, 95% Student-t for the mean true return. "
         "Gap closed: the share of the literal-to-oracle mean true return gap an IRD planner closes "
         "((IRD - literal) / (oracle - literal); 100 = oracle, 0 = literal, negative = below literal), "
         "95% paired percentile bootstrap over trials (2000 resamples, seed 0)."),
        "",
        "## Figure 4: literal vs IRD",
        "",
        markdown_table(summaries, "main"),
        "",
        "Claim check (IRD lava below literal, non-overlapping 95% intervals):",
        "",
        *claim_check(summaries),
        "",
        "## Appendix factorial: granularity x baseline (same posterior per trial and Z-approximation)",
        "",
        fallbacks_note,
        "",
        markdown_table(summaries, "factorial"),
        "",
    ]
    path.write_text("\n".join(text))


def _mark_zero_bars(ax: Any, xs: Any, heights: Any, tops: Any, width: float, colour: str, text: str) -> None:
    """A bar of height 0 is invisible: draw it as a thick line on the axis with ``text`` above its
    error bar (``tops``: the upper ends of the intervals)."""
    for x, h, top in zip(xs, heights, tops):
        if h == 0:
            ax.plot([x - width / 2, x + width / 2], [0, 0], color=colour, lw=3, solid_capstyle="butt", zorder=3,
                    clip_on=False)
            ax.annotate(text, (x, max(0.0, float(top)) if math.isfinite(top) else 0.0), xytext=(0, 2),
                        textcoords="offset points", ha="center", va="bottom", fontsize=6, color=style.INK)


def _figure4_bars(ax: Any, main: dict[tuple[str, str], CellSummary], conditions: list[str],
                  planners: list[tuple[str, str, str]], fields: tuple[str, str, str], zero: str) -> None:
    """One group of bars per condition, one bar per planner, with its interval as error bar; a
    bar of height 0 marked (:func:`_mark_zero_bars`, label ``zero``)."""
    import numpy as np

    width = 0.8 / max(len(planners), 1)
    x = np.arange(len(conditions))
    for j, (key, label, colour) in enumerate(planners):
        ss = [main.get((c, key)) for c in conditions]
        mid, low, high = (np.array([math.nan if s is None else getattr(s, a) for s in ss]) for a in fields)
        err = np.nan_to_num(np.clip([mid - low, high - mid], 0, None))
        xs = x + (j - (len(planners) - 1) / 2) * width
        ax.bar(xs, mid, width, yerr=err, capsize=3, label=label, color=colour, ecolor=style.INK)
        _mark_zero_bars(ax, xs, mid, high, width, colour, zero)
    ax.set_xticks(x, [c.replace("_", " ") for c in conditions])


def _new_figure(width: float, height: float, ncols: int = 1, **kwargs: Any) -> tuple[Any, Any]:
    """A figure with an Agg canvas (no pyplot state) and its axes."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), dpi=110)
    FigureCanvasAgg(fig)
    return fig, fig.subplots(1, ncols, **kwargs)


def figure4_figures(summaries: Sequence[CellSummary]) -> dict[str, Any]:
    """``{"figure4_lava.png": Figure, "figure4_return.png": Figure}``: lava fraction (Wilson
    intervals) and mean true return (t intervals) per condition, literal / IRD Sample-Z / IRD
    MaxEnt-Z / oracle; the legend above the axes."""
    main = {(s.condition, s.planner): s for s in summaries if s.experiment == "main"}
    conditions = [c for c in ORDER if (c, "literal") in main]
    planners = [p for p in FIGURE4 if any((c, p[0]) in main for c in conditions)]
    n = main[conditions[0], "literal"].trials if conditions else 0
    figures = {}
    for name, field, ylabel, title in (
            ("figure4_lava.png", "lava", "fraction of runs touching lava",
             f"Lavaland: lava encounters ({n} trials per bar, 95% Wilson CI)"),
            ("figure4_return.png", "return", "mean true return",
             f"Lavaland: true return ({n} trials per bar, 95% t CI)")):
        fig, ax = _new_figure(8.5, 3.6)
        _figure4_bars(ax, main, conditions, planners,
                      ("lava_fraction", "lava_ci_low", "lava_ci_high") if field == "lava" else
                      ("mean_true_return", "return_ci_low", "return_ci_high"), "0%" if field == "lava" else "0")
        ax.set_ylabel(ylabel)
        if field == "lava":
            ax.set_ylim(0, 1)
        else:
            ax.axhline(0, color=style.INK, linewidth=0.6)
        ax.set_title(title, pad=22)
        ax.legend(frameon=False, ncol=len(planners), loc="lower center", bbox_to_anchor=(0.5, 1.0), fontsize=8)
        ax.spines[["top", "right"]].set_visible(False)
        fig.tight_layout()
        figures[name] = fig
    return figures


def plot_figure4(out: Path, summaries: Sequence[CellSummary]) -> list[Path]:
    """:func:`figure4_figures` written into ``out``."""
    files = []
    for name, fig in figure4_figures(summaries).items():
        fig.savefig(out / name)
        files.append(out / name)
    return files


def _factorial_bars(ax: Any, fact: dict[tuple[str, str, str, str], CellSummary], condition: str, z: str,
                    legend: bool) -> None:
    """One condition's granularity x baseline lava fractions with Wilson error bars."""
    import numpy as np

    for gi, g in enumerate(GRANULARITIES):
        for bi, b in enumerate(BASELINES):
            s = fact.get((condition, z, g, b))
            if s is None:
                continue
            pos = gi * (len(BASELINES) + 1) + bi
            ax.bar(pos, s.lava_fraction, 0.9, color=style.baseline_color(b), ecolor=style.INK,
                   yerr=np.clip([[s.lava_fraction - s.lava_ci_low], [s.lava_ci_high - s.lava_fraction]], 0, 1),
                   capsize=2, label=b if (gi == 0 and legend) else None)
            _mark_zero_bars(ax, [pos], [s.lava_fraction], [s.lava_ci_high], 0.9, style.baseline_color(b), "0%")
    ax.set_xticks([1, 1 + len(BASELINES) + 1], ["per step", "trajectory"])
    ax.set_title(condition.replace("_", " "), fontsize=9)
    ax.spines[["top", "right"]].set_visible(False)


def factorial_figures(summaries: Sequence[CellSummary]) -> dict[str, Any]:
    """``{"factorial_<z>.png": Figure}`` per Z-approximation run: per condition, lava fraction by
    granularity x baseline."""
    import numpy as np

    main = {(s.condition, s.planner) for s in summaries if s.experiment == "main"}
    conditions = [c for c in ORDER if (c, "literal") in main]
    fact = {(s.condition, s.z_approx, s.granularity, s.baseline): s for s in summaries if s.experiment == "factorial"}
    figures = {}
    for z in Z_METHODS:
        if not any(k[1] == z for k in fact):
            continue
        fig, axes = _new_figure(2.3 * len(conditions) + 0.8, 3.0, len(conditions), sharey=True)
        axes = np.atleast_1d(axes)
        for ax, c in zip(axes, conditions):
            _factorial_bars(ax, fact, c, z, legend=c == conditions[0])
        axes[0].set_ylabel("fraction touching lava")
        axes[0].set_ylim(0, 1)
        fig.legend(loc="upper center", ncol=3, frameon=False, fontsize=8)
        fig.suptitle(f"{Z_LABEL[z]}: min granularity x reward baseline", y=0.02, va="bottom", fontsize=9)
        fig.tight_layout(rect=(0, 0.06, 1, 0.9))
        figures[f"factorial_{z}.png"] = fig
    return figures


def plot_factorial(out: Path, summaries: Sequence[CellSummary]) -> list[Path]:
    """:func:`factorial_figures` written into ``out``."""
    files = []
    for name, fig in factorial_figures(summaries).items():
        fig.savefig(out / name)
        files.append(out / name)
    return files


def plot_figures(out: Path, summaries: Sequence[CellSummary]) -> list[Path]:
    """Every figure of the report (:func:`plot_figure4`, :func:`plot_factorial`)."""
    return plot_figure4(out, summaries) + plot_factorial(out, summaries)


def replot(out: Path) -> list[Path]:
    """Redraw every figure of the report in ``out`` from its ``results.csv`` (nothing is run)."""
    return plot_figures(out, read_results_csv(out / "results.csv"))


def write_report(out: Path, results: Sequence[TrialResult], summaries: Sequence[CellSummary],
                 run: RunRecord) -> list[Path]:
    """Every file of the report into ``out`` (which must exist); returns the figures written."""
    write_trials_csv(out / "trials.csv", results)
    write_results_csv(out / "results.csv", summaries)
    write_markdown(out / "results.md", summaries, run, factorial_note(results, run.settings))
    figures = plot_figures(out, summaries)
    write_run_json(out / "run.json", run.command, run.wall, run.settings, figures, run.code)
    return figures
