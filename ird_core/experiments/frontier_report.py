"""The risk frontier's report (docs/spec.md section 5): ``frontier.md`` and one
``frontier_<condition>.png`` per condition, from the summaries of the ``frontier`` and
``controls`` rows (:mod:`ird_core.experiments.controls`).

The table lists, per condition, every posterior x risk level and every control with lava %,
target %, the target rate relative to the literal proxy's, the mean true return and the share of
the literal-to-oracle gap closed, all with their 95% intervals. The goal check judges the main
IRD planners (``experiment = "main"``) against the issue's bar: lava <= 2%, a target in at least
80% of the literal proxy's target rate, at least 90% of the gap closed (point estimates; the
intervals are printed beside them). The pictures put lava % against target % and mean true
return against target %, one line per posterior through its risk levels (CVaR from the min to
the mean, mean - lambda sd), the literal and oracle as points, 95% intervals as bars.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from ird_core import style
from ird_core.experiments.summaries import CellSummary

if TYPE_CHECKING:
    from ird_core.experiments.report import RunRecord

__all__ = ["GOAL_LAVA", "GOAL_TARGET_RATIO", "GOAL_GAP", "goal_check", "frontier_markdown", "plot_frontier",
           "write_frontier"]

#: The bar a default must clear in every condition (issue 26).
GOAL_LAVA, GOAL_TARGET_RATIO, GOAL_GAP = 0.02, 0.8, 0.9


def _pct(x: float) -> str:
    return "-" if not math.isfinite(x) else f"{100 * x:.0f}"


def _by(summaries: Sequence[CellSummary], condition: str) -> dict[str, CellSummary]:
    return {s.planner: s for s in summaries if s.condition == condition}


def goal_check(summaries: Sequence[CellSummary]) -> list[str]:
    """One line per condition x main IRD planner: PASS or what misses, by how much."""
    lines = []
    for condition in dict.fromkeys(s.condition for s in summaries):
        rows = _by([s for s in summaries if s.experiment == "main"], condition)
        literal = rows.get("literal")
        for name, s in rows.items():
            if not name.startswith("ird_") or literal is None:
                continue
            want_target = GOAL_TARGET_RATIO * literal.target_fraction
            misses = []
            if s.lava_fraction > GOAL_LAVA:
                misses.append(f"lava {_pct(s.lava_fraction)}% > {_pct(GOAL_LAVA)}%")
            if s.target_fraction < want_target:
                misses.append(f"target {_pct(s.target_fraction)}% < {100 * want_target:.1f}% (0.8 x literal's "
                              f"{_pct(literal.target_fraction)}%)")
            if not s.gap_closed >= GOAL_GAP:
                misses.append(f"gap closed {_pct(s.gap_closed)}% [{_pct(s.gap_ci_low)}, {_pct(s.gap_ci_high)}] "
                              f"< {_pct(GOAL_GAP)}%")
            verdict = "PASS" if not misses else "MISS: " + "; ".join(misses)
            lines.append(f"- {condition}, {name}: lava {_pct(s.lava_fraction)}%, target {_pct(s.target_fraction)}%, "
                         f"gap closed {_pct(s.gap_closed)}%: {verdict}")
    return lines


def frontier_markdown(summaries: Sequence[CellSummary]) -> str:
    """The frontier table of every condition (module docstring)."""
    out = ["| condition | planner | trials | lava % [95% CI] | target % [95% CI] | target / literal | "
           "mean true return [95% CI] | gap closed % [95% CI] | R-hat>1.1 |", "|---|---|---|---|---|---|---|---|---|"]
    for condition in dict.fromkeys(s.condition for s in summaries):
        rows = _by(summaries, condition)
        literal = rows.get("literal")
        for s in rows.values():
            if s.experiment not in ("main", "frontier", "controls"):
                continue
            ratio = (s.target_fraction / literal.target_fraction
                     if literal is not None and literal.target_fraction > 0 else math.nan)
            out.append(f"| {condition} | {s.planner} | {s.trials} | {_pct(s.lava_fraction)} "
                       f"[{_pct(s.lava_ci_low)}, {_pct(s.lava_ci_high)}] | {_pct(s.target_fraction)} "
                       f"[{_pct(s.target_ci_low)}, {_pct(s.target_ci_high)}] | "
                       f"{'-' if not math.isfinite(ratio) else f'{ratio:.2f}'} | {s.mean_true_return:.2f} "
                       f"[{s.return_ci_low:.2f}, {s.return_ci_high:.2f}] | {_pct(s.gap_closed)} "
                       f"[{_pct(s.gap_ci_low)}, {_pct(s.gap_ci_high)}] | {s.nonconverged} |")
    return "\n".join(out)


def _series(rows: dict[str, CellSummary]) -> dict[str, list[CellSummary]]:
    """Frontier rows grouped by posterior and measure: ``"sample_z cvar"`` -> rows by level."""
    series: dict[str, list[CellSummary]] = {}
    for name, s in rows.items():
        if s.experiment != "frontier":
            continue
        post, _, label = name.partition("/")
        measure = "mean_sd" if label.startswith("mean_sd") else "cvar"  # min belongs to the cvar line
        series.setdefault(f"{post} {measure}", []).append(s)
    return series


def plot_frontier(out: Path, summaries: Sequence[CellSummary]) -> list[Path]:
    """``frontier_<condition>.png`` per condition with frontier rows."""
    import matplotlib  # noqa: PLC0415 - plotting only when a report is written

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    paths = []
    for condition in dict.fromkeys(s.condition for s in summaries if s.experiment == "frontier"):
        rows = _by(summaries, condition)
        fig, (ax_lava, ax_ret) = plt.subplots(1, 2, figsize=(12, 4.8))
        for key, series in _series(rows).items():
            post, measure = key.split(" ")
            color = style.planner_color(f"ird_{post}" if post in ("sample_z", "maxent_z") else post)
            kw: dict[str, Any] = dict(color=color, marker="o" if measure == "cvar" else "s",
                                      linestyle="-" if measure == "cvar" else "--", label=key, markersize=4)
            x = [100 * s.target_fraction for s in series]
            ax_lava.errorbar(x, [100 * s.lava_fraction for s in series],
                             yerr=[[100 * (s.lava_fraction - s.lava_ci_low) for s in series],
                                   [100 * (s.lava_ci_high - s.lava_fraction) for s in series]], capsize=2, **kw)
            ax_ret.errorbar(x, [s.mean_true_return for s in series],
                            yerr=[[s.mean_true_return - s.return_ci_low for s in series],
                                  [s.return_ci_high - s.mean_true_return for s in series]], capsize=2, **kw)
        for name in ("literal", "oracle", "novelty", "prior_only"):
            s = rows.get(name)
            if s is None:
                continue
            color = style.planner_color(name)
            ax_lava.plot(100 * s.target_fraction, 100 * s.lava_fraction, marker="*", markersize=12, color=color,
                         linestyle="none", label=name)
            ax_ret.plot(100 * s.target_fraction, s.mean_true_return, marker="*", markersize=12, color=color,
                        linestyle="none", label=name)
        ax_lava.axhline(100 * GOAL_LAVA, color=style.NEUTRAL, linewidth=0.8, linestyle=":")
        ax_lava.set(xlabel="target reached (%)", ylabel="touched lava (%)", title=f"{condition}: lava vs target")
        ax_ret.set(xlabel="target reached (%)", ylabel="mean true return", title=f"{condition}: return vs target")
        handles, labels = ax_lava.get_legend_handles_labels()
        fig.legend(handles, labels, loc="center left", bbox_to_anchor=(1.0, 0.5), fontsize=8)
        fig.tight_layout()
        path = out / f"frontier_{condition}.png"
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        paths.append(path)
    return paths


def write_frontier(out: Path, summaries: Sequence[CellSummary], run: "RunRecord") -> list[Path]:
    """``frontier.md`` and the pictures when the run has frontier or control rows; else nothing."""
    if not any(s.experiment in ("frontier", "controls") for s in summaries):
        return []
    text = ["# Risk frontier and controls", "", f"Command: `{run.command}`", "", f"Code: {run.code}", "",
            "Per-step plans, training-features baseline, from the same posterior samples as the main planners. "
            "`cvar1` is the posterior mean (risk-neutral IRD), `min` the paper's worst case; `prior` plans on the "
            "prior alone (beta = 0); `novelty` is the literal proxy kept off cells unlike any training cell. "
            "Intervals: 95% Wilson (fractions), Student-t (return), paired bootstrap (gap closed).", "",
            "## Goal check (main planners: lava <= 2%, target >= 0.8 x literal, gap closed >= 90%)", "",
            *goal_check(summaries), "", "## Frontier", "", frontier_markdown(summaries), ""]
    (out / "frontier.md").write_text("\n".join(text), encoding="utf-8")
    return [out / "frontier.md", *plot_frontier(out, summaries)]
