"""The demo's rounds of questions as data, text and a picture (no ROS; used by ``ird_ros.apps.demo``).

- :class:`Outcome`: what Rob reported at the end of one plan (plus whether the path holds gold).
- :class:`RoundResult`: one question to the designer, its answer, and the plan Rob drove after it.
- :func:`terrain_counts`: cells of each terrain on each option path (what an option "is").
- :func:`rounds_table`: the text table of the literal plan, the IRD plan and every round.
- :func:`save_rounds_figure`: the picture: one column per stage (before the questions, then each
  round), the test map with the plans and the options asked on top, the risk maps below on one
  shared scale; colours from :mod:`ird_core.style`.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ird_core import style
from ird_core.render import draw_path, draw_risk, draw_terrain, halo_effects, terrain_handles
from ird_core.worlds.terrain import NUM_TERRAINS, TERRAIN_NAMES, Terrain
from ird_ros.web.page_state import option_letter

__all__ = ["Outcome", "RoundResult", "terrain_counts", "describe_counts", "rounds_table", "outcome_text",
           "rounds_figure", "save_rounds_figure", "PANEL_INCHES", "RISK_LABEL"]

PANEL_INCHES = 3.2
_DPI = 100
# Terrains an option is described by, in the order of the text.
_DESCRIBED = (Terrain.LAVA, Terrain.GOLD, Terrain.TARGET)


@dataclass(frozen=True)
class Outcome:
    """What Rob reported at the end of one plan; ``reached_gold`` from the world's terrain."""

    label: str
    cells: list[tuple[int, int]]
    objective: float
    touched_lava: bool
    reached_target: bool
    true_return: float
    reached_gold: bool = False


@dataclass(frozen=True)
class RoundResult:
    """One question: the options (q arrays of (T+1, 2) cells), the answer, the plan after it.

    ``risk_map`` is an (H, W) risk map (>= 0) of the posterior given the answer, in the unit of the
    rounds picture's other panels (the demo: the reward spread, ``ird_core.planning.reward_spread``);
    ``option_counts`` (q, NUM_TERRAINS) the cells of each terrain on each option."""

    index: int
    query_id: int
    information_gain: float
    options: tuple[np.ndarray, ...]
    chosen: int
    answered_by: str
    plan: Outcome
    option_counts: np.ndarray
    risk_map: np.ndarray | None = field(default=None, compare=False)


def terrain_counts(labels: np.ndarray, options: Sequence[np.ndarray]) -> np.ndarray:
    """(q, NUM_TERRAINS) int: how many cells of each terrain each option path visits (every cell
    counts, revisits too, like ``evaluation.true_return``).

    Args:
        labels: (H, W) Terrain labels.
        options: q (T+1, 2) (row, col) cell arrays (equal lengths).
    Raises:
        ValueError: ``options`` with a cell off the map or of unequal lengths.
    """
    labels = np.asarray(labels)
    try:
        cells = np.asarray(options, dtype=np.int64)
    except ValueError:
        raise ValueError("options: expected q paths of (row, col) cells of equal length") from None
    if cells.ndim != 3 or cells.shape[2] != 2:
        raise ValueError(f"options: expected q paths of (row, col) cells of equal length, got shape {cells.shape}")
    h, w = labels.shape
    if np.any(cells < 0) or np.any(cells[..., 0] >= h) or np.any(cells[..., 1] >= w):
        raise ValueError(f"options: a cell lies off the {h}x{w} map")
    on_path = labels[cells[..., 0], cells[..., 1]]  # (q, T+1)
    return (on_path[..., None] == np.arange(NUM_TERRAINS)).sum(axis=1)


def describe_counts(counts: np.ndarray) -> str:
    """``"lava 0, gold 2, target 3"``: the cells of lava, gold and target of one option."""
    return ", ".join(f"{TERRAIN_NAMES[t]} {int(counts[t])}" for t in _DESCRIBED)


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"


def rounds_table(literal: Outcome, before: Outcome, rounds: Sequence[RoundResult]) -> str:
    """One line per plan Rob drove: the literal plan, the IRD plan before any question, then per
    round the question (information gain in nats), the answer (the chosen option's lava, gold and
    target cells) and the outcome of the plan after it."""
    head = (f"  {'plan':<22} {'info gain':>9}  {'answer':<34} {'lava':>4} {'target':>6} {'gold':>4} "
            f"{'true return':>11}")
    rows = [head]

    def row(label: str, gain: str, answer: str, o: Outcome) -> str:
        return (f"  {label:<22} {gain:>9}  {answer:<34} {_yes(o.touched_lava):>4} {_yes(o.reached_target):>6} "
                f"{_yes(o.reached_gold):>4} {o.true_return:>11.2f}")

    rows.append(row("literal (proxy)", "-", "-", literal))
    rows.append(row("IRD, no questions", "-", "-", before))
    for r in rounds:
        # options by letter, as the designer's page and log name them
        answer = f"{option_letter(r.chosen)} of {len(r.options)} ({describe_counts(r.option_counts[r.chosen])})"
        rows.append(row(f"IRD after round {r.index}", f"{r.information_gain:.3f}", answer, r.plan))
    return "\n".join(rows)


def outcome_text(o: Outcome) -> str:
    """``"LAVA, target; return -5.8"``: what Rob reported at the end of one plan (``GOLD`` when he reached gold)."""
    parts = ["LAVA" if o.touched_lava else "no lava", "target" if o.reached_target else "no target"]
    if o.reached_gold:
        parts.append("GOLD")
    return f"{', '.join(parts)}; return {o.true_return:.1f}"


def _describe(counts: np.ndarray, labels: np.ndarray) -> str:
    """:func:`describe_counts` without gold on a map that has none."""
    shown = [t for t in _DESCRIBED if t != Terrain.GOLD or np.any(np.asarray(labels) == Terrain.GOLD)]
    return ", ".join(f"{TERRAIN_NAMES[t]} {int(counts[t])}" for t in shown)


def _draw_risk(ax, risk: np.ndarray | None, limits: tuple[float, float]):
    if risk is None:
        ax.axis("off")
        return None
    image = draw_risk(ax, risk, vmin=limits[0], vmax=limits[1], colorbar=False)
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_xlabel("")
    ax.set_ylabel("")
    return image


def _draw_options(ax, r: RoundResult) -> None:
    """The options asked: the chosen one solid, the others dashed, each a little offset."""
    q = len(r.options)
    for k, cells in enumerate(r.options):
        chosen = k == r.chosen
        color = style.CHOSEN_OPTION_COLOR if chosen else style.OTHER_OPTION_COLOR
        width = 3.0 if chosen else 1.5
        offset = (k - (q - 1) / 2) * 0.16
        ax.plot(cells[:, 1] + offset, cells[:, 0] + offset, linestyle="solid" if chosen else "dashed", color=color,
                lw=width, alpha=0.95, zorder=4, path_effects=halo_effects(color, width))


#: Default label of the risk row's colour bar (the demo passes the posterior's reward spread).
RISK_LABEL = "reward spread over the samples (sd)\none scale for every panel"


def rounds_figure(
    test_labels: np.ndarray,
    test_start: tuple[int, int],
    literal: Outcome,
    before: Outcome,
    risk_before: np.ndarray | None,
    rounds: Sequence[RoundResult],
    title: str,
    *,
    risk_label: str = RISK_LABEL,
) -> Figure:
    """The figure of :func:`save_rounds_figure` (not written)."""
    ncols = 1 + len(rounds)
    width_in, height_in = PANEL_INCHES * ncols + 1.0, 2 * PANEL_INCHES + 1.9
    fig = Figure(figsize=(width_in, height_in), dpi=_DPI)
    FigureCanvasAgg(fig)
    axes = fig.subplots(2, ncols, squeeze=False)
    fig.suptitle(title, fontsize=11, y=1.0 - 0.12 / height_in, va="top")
    limits = style.shared_risk_limits(risk_before, *(r.risk_map for r in rounds))
    literal_color, plan_color = style.planner_color("literal"), style.planner_color("ird")

    top = axes[0, 0]
    draw_terrain(top, test_labels, test_start, legend=False)
    draw_path(top, literal.cells, "literal", literal_color, -0.12)
    draw_path(top, before.cells, "IRD", plan_color, 0.12)
    top.set_title("before the questions", fontsize=9)
    top.set_xlabel(f"literal: {outcome_text(literal)}\nIRD: {outcome_text(before)}", fontsize=7)
    image = _draw_risk(axes[1, 0], risk_before, limits)
    axes[1, 0].set_title("risk map, proxy only", fontsize=8)

    for col, r in enumerate(rounds, start=1):
        ax = axes[0, col]
        draw_terrain(ax, test_labels, test_start, legend=False)
        _draw_options(ax, r)
        draw_path(ax, r.plan.cells, "plan", plan_color, 0.0)
        ax.set_title(f"round {r.index}: gain {r.information_gain:.2f} nats\n"
                     f"chose {r.chosen} ({_describe(r.option_counts[r.chosen], test_labels)})", fontsize=8)
        ax.set_xlabel(f"plan: {outcome_text(r.plan)}", fontsize=7)
        ax.set_ylabel("")
        image = _draw_risk(axes[1, col], r.risk_map, limits) or image
        axes[1, col].set_title(f"risk map after {r.index} answer{'s' if r.index > 1 else ''}", fontsize=8)

    handles: list = terrain_handles(test_labels)
    handles += [Line2D([], [], color=literal_color, lw=1.8, label="literal plan"),
                Line2D([], [], color=plan_color, lw=1.8, label="IRD plan (Rob drove it)")]
    if rounds:
        handles += [Line2D([], [], color=style.CHOSEN_OPTION_COLOR, lw=3.0, label="option the designer chose",
                           path_effects=halo_effects(style.CHOSEN_OPTION_COLOR, 3.0)),
                    Line2D([], [], color=style.OTHER_OPTION_COLOR, lw=1.5, ls="dashed", label="option not chosen",
                           path_effects=halo_effects(style.OTHER_OPTION_COLOR, 1.5))]
    handles.append(Line2D([], [], linestyle="none", label="start", **style.START_MARKER))
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 5), fontsize=7, frameon=False)
    bottom = 0.65 / height_in
    fig.subplots_adjust(left=0.5 / width_in, right=1.0 - 0.9 / width_in, bottom=bottom,
                        top=1.0 - 0.95 / height_in, wspace=0.25, hspace=0.5)
    if image is not None:  # one colour bar beside the risk row: the one scale of every risk panel
        bar_ax = fig.add_axes((1.0 - 0.78 / width_in, bottom + 0.02, 0.12 / width_in, 0.34))
        fig.colorbar(image, cax=bar_ax).set_label(risk_label, fontsize=8)
    return fig


def save_rounds_figure(
    path: "str | os.PathLike[str]",
    test_labels: np.ndarray,
    test_start: tuple[int, int],
    literal: Outcome,
    before: Outcome,
    risk_before: np.ndarray | None,
    rounds: Sequence[RoundResult],
    title: str,
    *,
    risk_label: str = RISK_LABEL,
) -> tuple[int, int]:
    """Write the PNG; returns its (width, height) in pixels.

    Columns: "before the questions" (the literal plan and the IRD plan), then one per round (the
    options asked: the chosen one solid white, the others dashed black; the plan Rob drove after the
    answer in blue). Top row on the test map (row 0 at the bottom), bottom row the risk map of the
    posterior at that stage. Every risk panel is drawn on ONE scale, 0 to the largest value of all
    panels (:func:`ird_core.style.shared_risk_limits`), labelled ``risk_label`` on the one colour
    bar: the maps must share a unit (the demo passes the reward spread, not the planner's maps,
    which are each relative to their own largest spread). Colours: :mod:`ird_core.style`; gold
    appears in the legend and the titles only on a map with gold.
    """
    fig = rounds_figure(test_labels, test_start, literal, before, risk_before, rounds, title, risk_label=risk_label)
    fig.savefig(path, dpi=_DPI)
    width_in, height_in = fig.get_size_inches()
    return int(round(width_in * _DPI)), int(round(height_in * _DPI))
