"""PNG pictures of Lavaland maps, paths and risk maps (matplotlib, Agg backend, no display).

Row 0 is drawn at the bottom (``origin="lower"``), like ``nav_msgs/OccupancyGrid``: x is the
column, y the row. Every colour comes from :mod:`ird_core.style`: terrains (target yellow, dirt
brown, grass green, lava red, gold orange), the literal plan magenta and IRD blue
(:func:`ird_core.style.planner_color` of the path's name), the risk colour map.

Invariants:

- the terrain legend lists only the terrains present on the map (no gold entry on a map
  without gold), and sits outside the map, like every legend here;
- a path's line and end marker have a halo (:func:`halo_effects`) and are drawn above the start
  marker, so a plan that stays at the start still shows its end marker; paths sharing a colour
  are told apart by :func:`ird_core.style.path_dashes` and every path is offset a little, so
  identical paths stay visible side by side;
- :func:`mission_figure` writes each path's outcome in its legend entry (given, or read off the
  test map: lava, target, gold only on a map with gold);
- a risk map is drawn on the scale it is given (``vmin``, ``vmax``) with that scale in the
  colour bar's label, never rescaled to its own maximum.

Figures are built on ``matplotlib.figure.Figure`` with an explicit Agg canvas, never
``pyplot``, so rendering touches no global state and works in threads and headless nodes.
:func:`save_mission_figure` writes exactly :func:`mission_figure_size` pixels.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib import patheffects
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.image import AxesImage
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

from ird_core import style
from ird_core.worlds.terrain import NUM_TERRAINS, TERRAIN_COLORS, TERRAIN_NAMES, Terrain

__all__ = [
    "DPI",
    "PANEL_SIZE_INCHES",
    "TITLE_HEIGHT_INCHES",
    "PATH_SPREAD",
    "halo_effects",
    "terrain_handles",
    "draw_terrain",
    "draw_start",
    "draw_path",
    "draw_risk",
    "path_outcome",
    "mission_figure_size",
    "mission_figure",
    "save_mission_figure",
]

DPI: int = 100
PANEL_SIZE_INCHES: float = 4.0
TITLE_HEIGHT_INCHES: float = 0.5
PATH_SPREAD: float = 0.2  # cells between the drawn lines of overlapping paths

_TERRAIN_CMAP = ListedColormap(list(TERRAIN_COLORS), name="lavaland")
_TERRAIN_NORM = BoundaryNorm(np.arange(NUM_TERRAINS + 1) - 0.5, NUM_TERRAINS)
_START_Z, _PATH_Z, _END_Z = 3, 4, 6


def _check_labels(labels: np.ndarray) -> np.ndarray:
    labels = np.asarray(labels)
    if labels.ndim != 2 or min(labels.shape) < 1:
        raise ValueError(f"labels must be a non-empty (H, W) array, got shape {labels.shape}")
    if not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"labels must hold integer Terrain labels, got dtype {labels.dtype}")
    if labels.min() < 0 or labels.max() >= NUM_TERRAINS:
        raise ValueError(f"labels holds values outside 0..{NUM_TERRAINS - 1}")
    return labels


def _check_cells(cells: "Sequence[tuple[int, int]] | np.ndarray") -> np.ndarray:
    path = np.asarray(cells, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != 2 or path.shape[0] < 1:
        raise ValueError(f"cells must be a non-empty list of (row, col), got shape {path.shape}")
    return path


def _grid_axes(ax: Axes, height: int, width: int) -> None:
    ax.set_xlim(-0.5, width - 0.5)
    ax.set_ylim(-0.5, height - 0.5)
    ax.set_aspect("equal")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.yaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("col (x)")
    ax.set_ylabel("row (y)")


def halo_effects(color: str, linewidth: float) -> list:
    """Path effects drawing a ``linewidth + 2`` outline in :func:`ird_core.style.halo_color` under a line."""
    return [patheffects.withStroke(linewidth=linewidth + 2.0, foreground=style.halo_color(color)),
            patheffects.Normal()]


def terrain_handles(labels: np.ndarray) -> list[Patch]:
    """Legend patches of the terrains present on ``labels``, in label order."""
    labels = _check_labels(labels)
    return [Patch(facecolor=TERRAIN_COLORS[k], edgecolor=style.INK, label=TERRAIN_NAMES[k])
            for k in range(NUM_TERRAINS) if np.any(labels == k)]


def draw_start(ax: Axes, start: tuple[int, int], shape: tuple[int, int]) -> Line2D:
    """The start cell's marker (below every path, so a plan that stays there shows its end)."""
    row, col = start
    if not (0 <= row < shape[0] and 0 <= col < shape[1]):
        raise ValueError(f"start {start} is off the {shape[0]}x{shape[1]} map")
    (marker,) = ax.plot(col, row, linestyle="none", label="start", zorder=_START_Z, **style.START_MARKER)
    return marker


def draw_terrain(ax: Axes, labels: np.ndarray, start: tuple[int, int] | None = None, *, legend: bool = True) -> None:
    """Draw an (H, W) terrain map, row 0 at the bottom, the start if given, and (``legend``) a
    legend of the terrains present and the start, outside the map on the right."""
    labels = _check_labels(labels)
    ax.imshow(labels, cmap=_TERRAIN_CMAP, norm=_TERRAIN_NORM, origin="lower", interpolation="nearest")
    _grid_axes(ax, *labels.shape)
    handles: list = terrain_handles(labels)
    if start is not None:
        handles.append(draw_start(ax, start, labels.shape))
    if legend:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=7, frameon=False)


def draw_path(
    ax: Axes,
    cells: "Sequence[tuple[int, int]] | np.ndarray",
    label: str,
    color: str,
    offset: float = 0.0,
    *,
    dashes: object = "solid",
    linewidth: float = 1.8,
) -> Line2D:
    """Draw a path of (row, col) cells as a haloed line with its end starred; the line is labelled
    for the legend and returned.

    ``offset`` (in cells, added to row and col) keeps overlapping paths visible side by side;
    ``dashes`` tells apart paths of one colour. Line and star lie above the start marker.
    """
    path = _check_cells(cells)
    rows, cols = path[:, 0] + offset, path[:, 1] + offset
    (line,) = ax.plot(cols, rows, color=color, linewidth=linewidth, linestyle=dashes, label=label, zorder=_PATH_Z,
                      path_effects=halo_effects(color, linewidth))
    ax.plot(cols[-1], rows[-1], marker="*", markersize=12, color=color, markeredgecolor=style.halo_color(color),
            linestyle="none", zorder=_END_Z)
    return line


def draw_risk(ax: Axes, risk_map: np.ndarray, *, vmin: float = 0.0, vmax: float = 100.0,
              label: str | None = "risk (0..100)", colorbar: bool = True) -> AxesImage:
    """Draw an (H, W) non-negative risk map on the fixed scale ``vmin..vmax`` (never its own
    maximum) in the style's risk colours; with ``colorbar`` a colour bar labelled ``label``."""
    risk = np.asarray(risk_map, dtype=np.float64)
    if risk.ndim != 2:
        raise ValueError(f"risk_map must be an (H, W) array, got shape {risk.shape}")
    if np.any(~np.isfinite(risk)) or risk.min() < 0:
        raise ValueError("risk_map values must be finite and >= 0")
    if not vmax > vmin:
        raise ValueError(f"risk scale: expected vmin < vmax, got {vmin}, {vmax}")
    image = ax.imshow(risk, cmap=style.risk_cmap(), vmin=vmin, vmax=vmax, origin="lower", interpolation="nearest")
    _grid_axes(ax, *risk.shape)
    if colorbar:
        ax.figure.colorbar(image, ax=ax, fraction=0.046, pad=0.04, label=label)
    return image


def path_outcome(labels: np.ndarray, cells: "Sequence[tuple[int, int]] | np.ndarray") -> str:
    """What a path does on a map, read off the map: ``"lava, target"``, ``"no lava, no target"``;
    ``", gold"`` / ``", no gold"`` only when the map has gold."""
    labels = _check_labels(labels)
    path = _check_cells(cells).astype(np.int64)
    on = labels[np.clip(path[:, 0], 0, labels.shape[0] - 1), np.clip(path[:, 1], 0, labels.shape[1] - 1)]
    parts = ["lava" if np.any(on == Terrain.LAVA) else "no lava",
             "target" if np.any(on == Terrain.TARGET) else "no target"]
    if np.any(labels == Terrain.GOLD):
        parts.append("gold" if np.any(on == Terrain.GOLD) else "no gold")
    return ", ".join(parts)


def mission_figure_size(with_risk: bool) -> tuple[int, int]:
    """(width, height) in pixels of :func:`save_mission_figure`'s PNG."""
    panels = 3 if with_risk else 2
    return (
        int(round(PANEL_SIZE_INCHES * panels * DPI)),
        int(round((PANEL_SIZE_INCHES + TITLE_HEIGHT_INCHES) * DPI)),
    )


def _draw_paths(ax: Axes, labels: np.ndarray, paths: Mapping[str, "Sequence[tuple[int, int]] | np.ndarray"],
                colors: Mapping[str, str], outcomes: Mapping[str, str] | None) -> list[Line2D]:
    lines, seen = [], {}
    for i, (name, cells) in enumerate(paths.items()):
        color = colors.get(name) or style.planner_color(name)
        same = seen.get(color, 0)
        seen[color] = same + 1
        offset = (i - (len(paths) - 1) / 2) * PATH_SPREAD
        note = (outcomes or {}).get(name) or path_outcome(labels, cells)
        lines.append(draw_path(ax, cells, f"{name}: {note}", color, offset, dashes=style.path_dashes(same)))
    return lines


def mission_figure(
    train_labels: np.ndarray,
    test_labels: np.ndarray,
    paths: Mapping[str, "Sequence[tuple[int, int]] | np.ndarray"],
    risk_map: np.ndarray | None = None,
    title: str = "Lavaland mission",
    *,
    train_start: tuple[int, int] | None = None,
    test_start: tuple[int, int] | None = None,
    colors: Mapping[str, str] | None = None,
    outcomes: Mapping[str, str] | None = None,
) -> Figure:
    """The figure of :func:`save_mission_figure` (not written)."""
    train_labels = _check_labels(train_labels)
    test_labels = _check_labels(test_labels)
    if risk_map is not None:
        if np.shape(risk_map) != test_labels.shape:
            raise ValueError(f"risk_map shape {np.shape(risk_map)} differs from test_labels {test_labels.shape}")
        if np.any(~np.isfinite(risk_map)) or np.min(risk_map) < 0 or np.max(risk_map) > 100:
            raise ValueError("risk_map values must be finite and within 0..100")
    width_px, height_px = mission_figure_size(risk_map is not None)
    width_in, height_in = width_px / DPI, height_px / DPI
    figure = Figure(figsize=(width_in, height_in), dpi=DPI)
    FigureCanvasAgg(figure)
    panels = 3 if risk_map is not None else 2
    axes = figure.subplots(1, panels)
    figure.suptitle(title, fontsize=11)

    draw_terrain(axes[0], train_labels, train_start)
    axes[0].set_title("training map", fontsize=9)
    draw_terrain(axes[1], test_labels, test_start)
    axes[1].set_title("test map", fontsize=9)
    lines = _draw_paths(axes[1], test_labels, paths, colors or {}, outcomes)
    if lines:  # the paths with their outcomes, below the maps (outside every map)
        figure.legend(handles=lines, loc="upper center", bbox_to_anchor=(0.5, 0.7 / height_in), ncol=min(2, len(lines)),
                      fontsize=8, frameon=False)
    if risk_map is not None:
        draw_risk(axes[2], np.asarray(risk_map, dtype=np.float64),
                  label="risk (100 = this map's largest spread)")
        axes[2].set_title("risk map", fontsize=9)
    # Margins in inches (room for tick labels, legends and the colour bar), as fractions.
    figure.subplots_adjust(
        left=0.6 / width_in,
        right=1.0 - 0.9 / width_in,
        bottom=1.0 / height_in,  # tick labels, then the path legend
        top=1.0 - (TITLE_HEIGHT_INCHES + 0.1) / height_in,
        wspace=0.6,
    )
    return figure


def save_mission_figure(
    path: "str | os.PathLike[str]",
    train_labels: np.ndarray,
    test_labels: np.ndarray,
    paths: Mapping[str, "Sequence[tuple[int, int]] | np.ndarray"],
    risk_map: np.ndarray | None = None,
    title: str = "Lavaland mission",
    *,
    train_start: tuple[int, int] | None = None,
    test_start: tuple[int, int] | None = None,
    colors: Mapping[str, str] | None = None,
    outcomes: Mapping[str, str] | None = None,
) -> None:
    """Write a PNG: training map | test map with the paths | risk map (if given).

    Args:
        path: output file (.png).
        train_labels, test_labels: (H, W) Terrain labels (sizes may differ).
        paths: name -> (row, col) cells drawn on the test map, in order.
        risk_map: optional (H_test, W_test) risk in 0..100 (the planner's: 100 = its largest spread).
        title: figure title.
        train_start, test_start: optional start cells to mark.
        colors: optional name -> colour (default :func:`ird_core.style.planner_color` of the name).
        outcomes: optional name -> outcome text for the legend (default :func:`path_outcome`).
    """
    figure = mission_figure(train_labels, test_labels, paths, risk_map, title, train_start=train_start,
                            test_start=test_start, colors=colors, outcomes=outcomes)
    figure.savefig(os.fspath(path), dpi=DPI, format="png")
