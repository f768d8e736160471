"""The designer-in-the-loop report (docs/spec.md section 7): ``active.csv``,
``active_trials.csv``, ``active.md`` (headline, tables), one figure per condition and ``run.json``.

Invariants: ``active.csv`` has one row per condition x strategy x number of queries
(``active.SUMMARY_COLUMNS``), ``active_trials.csv`` one row per trial x plan in run order
(``active.RESULT_COLUMNS``); the headline's comparisons are paired by seed
(:mod:`ird_core.experiments.statistics`). Figures take every colour from :mod:`ird_core.style`
(strategies and bounds: ``planner_color``; outcomes: the terrain's colour, gold only on
``pot_of_gold``); :func:`replot` redraws them from a committed ``active.csv``. matplotlib is
imported only when figures are drawn.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Sequence

from ird_core import style
from ird_core.experiments import active, active_endpoints
from ird_core.experiments.parallel import describe
from ird_core.experiments.report import RunRecord
from ird_core.experiments.tables import cells_text, number, percent, write_csv, write_run_json
from ird_core.vocabulary import QueryStrategy

__all__ = ["LABEL", "COLOUR", "markdown_table", "headline", "write_markdown", "read_summaries_csv",
           "read_results_csv", "condition_figure", "plot_condition", "replot", "write_report"]

LABEL: dict[str, str] = {QueryStrategy.EVOI: "EVOI queries", QueryStrategy.MAX_REGRET: "max-regret queries",
                         QueryStrategy.INFO_GAIN: "info-gain queries", QueryStrategy.RANDOM: "random queries",
                         active.ORACLE_QUERY: "oracle queries", "literal": "literal", "oracle": "oracle"}
COLOUR: dict[str, str] = {k: style.planner_color(k) for k in LABEL}
#: The outcome flags drawn per strategy: (name, summary field).
OUTCOMES: tuple[tuple[str, str], ...] = (("lava", "lava_fraction"), ("target", "target_fraction"),
                                         ("gold", "gold_fraction"))


def markdown_table(summaries: Sequence[active.ActiveSummary], condition: str) -> str:
    """The ``condition``'s rows as a markdown table."""
    lines = ["| strategy | queries | trials | lava % [95% CI] | target % [95% CI] | gold % [95% CI] "
             "| mean true return [95% CI] | asked | info gain (nats) | R-hat>1.1 |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for s in summaries:
        if s.condition != condition:
            continue
        lines.append(
            f"| {s.strategy} | {s.num_queries} | {s.trials} "
            f"| {percent(s.lava_fraction)} [{percent(s.lava_ci_low)}, {percent(s.lava_ci_high)}] "
            f"| {percent(s.target_fraction)} [{percent(s.target_ci_low)}, {percent(s.target_ci_high)}] "
            f"| {percent(s.gold_fraction)} [{percent(s.gold_ci_low)}, {percent(s.gold_ci_high)}] "
            f"| {number(s.mean_return)} [{number(s.return_ci_low)}, {number(s.return_ci_high)}] "
            f"| {number(s.mean_asked, 1)} | {number(s.mean_information_gain, 3)} | {s.nonconverged} |")
    return "\n".join(lines)


def _first_query_count(counts: tuple[int, ...]) -> int | None:
    """The count compared between strategies: 1, else the smallest positive one (None if none)."""
    return 1 if 1 in counts else (min(c for c in counts if c > 0) if any(c > 0 for c in counts) else None)


def _condition_headline(results: Sequence[active.ActiveResult], summaries: Sequence[active.ActiveSummary],
                        c: str, counts: tuple[int, ...], strategies: tuple[str, ...]) -> list[str]:
    lines = []
    one = _first_query_count(counts)
    three = 3 if 3 in counts else max(counts)
    if one is not None and QueryStrategy.RANDOM in strategies:
        for s in strategies:
            if s == QueryStrategy.RANDOM:
                continue
            mean, lo, hi, n = active_endpoints.versus(list(results), c, s, QueryStrategy.RANDOM, one)
            verdict = "beats" if lo > 0 else ("is beaten by" if hi < 0 else "does not separate from")
            lines.append(f"- {c}: after {one} quer{'y' if one == 1 else 'ies'}, {s} {verdict} random: paired "
                         f"return difference {number(mean)} [{number(lo)}, {number(hi)}] (n = {n})")
    closed = ", ".join(f"{s} {number(100 * active.gap_closed(list(summaries), c, s, three), 0)}%" for s in strategies)
    before = number(100 * active.gap_closed(list(summaries), c, strategies[0], 0), 0) if 0 in counts else "nan"
    lines.append(f"- {c}: share of the literal-to-oracle return gap closed after {three} queries: {closed} "
                 f"(IRD without queries: {before}%)")
    by = {(s.strategy, s.num_queries): s for s in summaries if s.condition == c}
    for s in strategies:
        seq = "; ".join(f"{k}: lava {percent(by[s, k].lava_fraction)}%, target {percent(by[s, k].target_fraction)}%"
                        + (f", gold {percent(by[s, k].gold_fraction)}%" if c == "pot_of_gold" else "")
                        for k in counts if (s, k) in by)
        lines.append(f"  - {s} by number of queries: {seq}")
    return lines


def headline(results: Sequence[active.ActiveResult], summaries: Sequence[active.ActiveSummary],
             conditions: Sequence[str], counts: tuple[int, ...], strategies: tuple[str, ...]) -> list[str]:
    """The three questions, per condition: one info-gain vs one random query (paired), the share
    of the literal-to-oracle gap closed by 3 queries, lava and gold after the queries."""
    return [line for c in conditions for line in _condition_headline(results, summaries, c, counts, strategies)]


def write_markdown(path: Path, results: Sequence[active.ActiveResult], summaries: Sequence[active.ActiveSummary],
                   conditions: Sequence[str], run: RunRecord) -> None:
    """``active.md``: command, wall time, settings, the headline and one table per condition."""
    settings = run.settings
    counts, strategies = tuple(settings["query_counts"]), tuple(settings["strategies"])
    text = ["# Designer in the loop: answered queries vs risk aversion", "",
            f"Command: `{run.command}`", "", f"Code: {run.code}", "",
            f"Wall time: {run.wall:.1f} s ({describe(settings['workers'], settings['scheduler'])}).", "",
            "Settings: " + ", ".join(f"{k}={v}" for k, v in settings.items() if k not in ("workers", "scheduler")),
            "", "IRD plan: per_step x training_features (exact DP on all posterior samples), re-planned after every "
            "answer on the posterior re-sampled (warm start) with all evidence so far. Queries: 2 paths on the test "
            "map among the rich candidates (Rob's plan, other risk levels, sample clusters, the samples' own "
            "optima, detours and deviations; ird_core.designer.candidates), chosen by the expected value of the "
            "answer for Rob's plan (evoi), maximum mutual regret (max_regret), expected information gain "
            "(info_gain), uniformly (random), or with the true reward (oracle_query, the headroom); answered by the "
            "simulated designer (Boltzmann on true return). literal = the proxy's plan, oracle = the true-reward "
            "optimum (exact DP). Regret = the oracle plan's true return minus the strategy's, per seed. Intervals: "
            "95% Wilson for fractions, 95% Student-t for mean returns and for paired differences. `asked` = "
            "questions really asked (a round is skipped when fewer than 2 candidates exist).", "",
            "## Goal check", "", *active_endpoints.goal_check(results, summaries, conditions), "",
            "## Headline", "", *headline(results, summaries, conditions, counts, strategies), ""]
    for c in conditions:
        text += [f"## {c}", "", active_endpoints.endpoint_table(results, summaries, c, strategies, counts), "",
                 markdown_table(summaries, c), ""]
    path.write_text("\n".join(text))


def _plot_returns(ax: Any, rows: list[active.ActiveSummary], strategy: str) -> list[int]:
    """A strategy's mean true return by number of queries with its 95% band; the counts drawn."""
    ss = sorted((s for s in rows if s.strategy == strategy), key=lambda s: s.num_queries)
    x = [s.num_queries for s in ss]
    if ss:
        ax.plot(x, [s.mean_return for s in ss], marker="o", color=COLOUR[strategy], label=f"IRD, {LABEL[strategy]}")
        ax.fill_between(x, [s.return_ci_low for s in ss], [s.return_ci_high for s in ss], color=COLOUR[strategy],
                        alpha=0.2, lw=0)
    return x


def _plot_outcomes(ax: Any, rows: list[active.ActiveSummary], strategy: str, condition: str) -> None:
    """A strategy's lava / target (/ gold on pot_of_gold) fractions by number of queries."""
    ss = sorted((s for s in rows if s.strategy == strategy), key=lambda s: s.num_queries)
    x = [s.num_queries for s in ss]
    for name, key in OUTCOMES:
        if name == "gold" and condition != "pot_of_gold":
            continue
        ax.plot(x, [getattr(s, key) for s in ss], color=style.terrain_color(name),
                marker="o" if strategy == QueryStrategy.EVOI else "s", ls="-" if strategy == QueryStrategy.EVOI else ":",
                label=f"{name}, {LABEL[strategy]}")


def _bounds(ax: Any, rows: list[active.ActiveSummary]) -> None:
    """Literal and oracle as dashed lines with their 95% bands."""
    for s in rows:
        if s.strategy in ("literal", "oracle"):
            ax.axhline(s.mean_return, color=COLOUR[s.strategy], lw=1.5, ls="--", label=f"{LABEL[s.strategy]}")
            ax.axhspan(s.return_ci_low, s.return_ci_high, color=COLOUR[s.strategy], alpha=0.12, lw=0)


def read_summaries_csv(path: Path) -> list[active.ActiveSummary]:
    """The summaries of an ``active.csv`` (:func:`write_report`'s, up to float printing)."""
    import csv
    import dataclasses as dc

    kinds = {f.name: f.type for f in dc.fields(active.ActiveSummary)}
    convert = {"int": lambda v: int(float(v)), "float": float, "str": str}
    with open(path, newline="") as handle:
        return [active.ActiveSummary(**{k: convert[str(getattr(kinds[k], "__name__", kinds[k]))](v)
                                        for k, v in row.items()}) for row in csv.DictReader(handle)]


def read_results_csv(path: Path) -> list[active.ActiveResult]:
    """The per-trial results of an ``active_trials.csv`` (:func:`write_report`'s)."""
    import csv

    def cells(text: str) -> tuple[tuple[int, int], ...]:
        numbers = [int(v) for v in text.replace("(", " ").replace(")", " ").replace(",", " ").replace(";", " ").split()]
        return tuple(zip(numbers[0::2], numbers[1::2]))

    flag = {"True": True, "False": False, "true": True, "false": False, "1": True, "0": False}
    with open(path, newline="") as handle:
        return [active.ActiveResult(
            row["condition"], int(row["seed"]), row["strategy"], int(row["num_queries"]), int(row["asked"]),
            flag[row["touched_lava"]], flag[row["reached_target"]], flag[row["reached_gold"]],
            float(row["true_return"]), float(row["information_gain"]), int(row["answers_correct"]),
            float(row["r_hat_max"]), cells(row["cells"]), flag[row.get("changed", "False")])
            for row in csv.DictReader(handle)]


def condition_figure(summaries: Sequence[active.ActiveSummary], condition: str) -> Any:
    """The figure of :func:`plot_condition` (not written)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = [s for s in summaries if s.condition == condition]
    fig = Figure(figsize=(10, 4.6), dpi=110)
    FigureCanvasAgg(fig)
    ax, ax2 = fig.subplots(1, 2)
    _bounds(ax, rows)
    for strategy in active.EXPERIMENT_STRATEGIES:
        x = _plot_returns(ax, rows, strategy)
        if not x:
            continue
        if strategy in (QueryStrategy.EVOI, QueryStrategy.RANDOM):
            _plot_outcomes(ax2, rows, strategy, condition)
        ax.set_xticks(x)
        ax2.set_xticks(x)
    n = rows[0].trials if rows else 0
    ax.set_xlabel("answered queries")
    ax.set_ylabel("mean true return")
    ax.set_title(f"{condition.replace('_', ' ')}: true return ({n} paired trials, 95% CI)", fontsize=9)
    ax.legend(frameon=False, fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.18))
    ax2.set_xlabel("answered queries")
    ax2.set_ylabel("fraction of trials")
    ax2.set_ylim(-0.02, 1.02)
    ax2.set_title("IRD path: touches lava / reaches target / reaches gold\n(solid: EVOI, dotted: random)",
                  fontsize=8)
    ax2.legend(frameon=False, fontsize=6, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.18))
    for a in (ax, ax2):
        a.spines[["top", "right"]].set_visible(False)
    fig.tight_layout()
    return fig


def plot_condition(out: Path, summaries: Sequence[active.ActiveSummary], condition: str) -> Path:
    """``active_<condition>.png``: mean true return vs number of queries (every strategy, literal
    and oracle as lines) and the IRD path's outcome fractions."""
    path = out / f"active_{condition}.png"
    condition_figure(summaries, condition).savefig(path)
    return path


def replot(out: Path) -> list[Path]:
    """Redraw every condition's figure in ``out`` from its ``active.csv`` (nothing is run)."""
    summaries = read_summaries_csv(out / "active.csv")
    return [plot_condition(out, summaries, c) for c in dict.fromkeys(s.condition for s in summaries)]


def write_report(out: Path, results: Sequence[active.ActiveResult], summaries: Sequence[active.ActiveSummary],
                 conditions: Sequence[str], run: RunRecord) -> list[Path]:
    """Every file of the report into ``out`` (which must exist); returns the figures written."""
    write_csv(out / "active.csv", active.SUMMARY_COLUMNS, (dataclasses.asdict(s) for s in summaries))
    write_csv(out / "active_trials.csv", active.RESULT_COLUMNS,
              (dict(dataclasses.asdict(r), cells=cells_text(r.cells)) for r in results))
    write_markdown(out / "active.md", results, summaries, conditions, run)
    figures = [plot_condition(out, summaries, c) for c in conditions]
    write_run_json(out / "run.json", run.command, run.wall, run.settings, figures, run.code)
    return figures

