"""PNG pictures of Lavaland maps, paths and risk maps (matplotlib, Agg backend, no display).

Row 0 is drawn at the bottom (``origin="lower"``), like ``nav_msgs/OccupancyGrid``: x is the
column, y the row. Colours follow the paper's figures: target yellow, dirt brown, grass green,
lava red; gold (pot_of_gold only) is orange, apart from the target's yellow
(:data:`ird_core.worlds.terrain.TERRAIN_COLORS`, indexed by :class:`ird_core.worlds.terrain.Terrain`). The legend lists the
terrains present on the map.

Figures are built on ``matplotlib.figure.Figure`` with an explicit Agg canvas, never
``pyplot``, so rendering touches no global state and works in threads and headless nodes.
:func:`save_mission_figure` writes exactly ``(PANEL_SIZE_INCHES * panels * DPI) x
(PANEL_SIZE_INCHES * DPI + title)`` pixels; see :func:`mission_figure_size`.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import BoundaryNorm, ListedColormap
from matplotlib.figure import Figure
from matplotlib.patches import Patch
from matplotlib.ticker import MaxNLocator

from ird_core.worlds.terrain import NUM_TERRAINS, TERRAIN_COLORS, TERRAIN_NAMES

__all__ = [
    "DPI",
    "PANEL_SIZE_INCHES",
    "TITLE_HEIGHT_INCHES",
    "draw_terrain",
    "draw_path",
    "draw_risk",
    "mission_figure_size",
    "save_mission_figure",
]

DPI: int = 100
PANEL_SIZE_INCHES: float = 4.0
TITLE_HEIGHT_INCHES: float = 0.5
# Path colours that stand out on every terrain colour and on the white background.
_PATH_COLORS: tuple[str, ...] = ("#1f3fff", "#ff00ff", "#00c8ff", "#000000", "#8a2be2")
_PATH_SPREAD: float = 0.2  # cells between the drawn lines of overlapping paths

_TERRAIN_CMAP = ListedColormap(list(TERRAIN_COLORS), name="lavaland")
_TERRAIN_NORM = BoundaryNorm(np.arange(NUM_TERRAINS + 1) - 0.5, NUM_TERRAINS)


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


def draw_terrain(ax: Axes, labels: np.ndarray, start: tuple[int, int] | None = None) -> None:
    """Draw an (H, W) terrain map, row 0 at the bottom, with a legend and the start if given."""
    labels = _check_labels(labels)
    ax.imshow(
        labels,
        cmap=_TERRAIN_CMAP,
        norm=_TERRAIN_NORM,
        origin="lower",
        interpolation="nearest",
    )
    _grid_axes(ax, *labels.shape)
    handles: list = [
        Patch(facecolor=TERRAIN_COLORS[k], edgecolor="black", label=TERRAIN_NAMES[k])
        for k in range(NUM_TERRAINS)
        if np.any(labels == k)
    ]
    if start is not None:
        row, col = start
        if not (0 <= row < labels.shape[0] and 0 <= col < labels.shape[1]):
            raise ValueError(f"start {start} is off the {labels.shape[0]}x{labels.shape[1]} map")
        (marker,) = ax.plot(
            col, row, marker="o", markersize=9, markerfacecolor="white",
            markeredgecolor="black", linestyle="none", label="start",
        )
        handles.append(marker)
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=7, frameon=False)


def draw_path(
    ax: Axes,
    cells: "Sequence[tuple[int, int]] | np.ndarray",
    label: str,
    color: str,
    offset: float = 0.0,
) -> None:
    """Draw a path of (row, col) cells as a line with its end marked; labelled for the legend.

    ``offset`` (in cells, added to row and col) keeps overlapping paths visible side by side.
    """
    path = _check_cells(cells)
    rows, cols = path[:, 0] + offset, path[:, 1] + offset
    ax.plot(cols, rows, color=color, linewidth=1.8, alpha=0.9, label=label)
    ax.plot(cols[-1], rows[-1], marker="*", markersize=12, color=color,
            markeredgecolor="black", linestyle="none")


def draw_risk(ax: Axes, risk_map: np.ndarray) -> None:
    """Draw an (H, W) risk map in 0..100 as a heat map with a colour bar."""
    risk = np.asarray(risk_map, dtype=np.float64)
    if risk.ndim != 2:
        raise ValueError(f"risk_map must be an (H, W) array, got shape {risk.shape}")
    if np.any(~np.isfinite(risk)) or risk.min() < 0 or risk.max() > 100:
        raise ValueError("risk_map values must be finite and within 0..100")
    image = ax.imshow(risk, cmap="inferno", vmin=0, vmax=100, origin="lower", interpolation="nearest")
    _grid_axes(ax, *risk.shape)
    ax.figure.colorbar(image, ax=ax, fraction=0.046, pad=0.04, label="risk (0..100)")


def mission_figure_size(with_risk: bool) -> tuple[int, int]:
    """(width, height) in pixels of :func:`save_mission_figure`'s PNG."""
    panels = 3 if with_risk else 2
    return (
        int(round(PANEL_SIZE_INCHES * panels * DPI)),
        int(round((PANEL_SIZE_INCHES + TITLE_HEIGHT_INCHES) * DPI)),
    )


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
) -> None:
    """Write a PNG: training map | test map with the paths | risk map (if given).

    Args:
        path: output file (.png).
        train_labels, test_labels: (H, W) Terrain labels (sizes may differ).
        paths: name -> (row, col) cells drawn on the test map, in order.
        risk_map: optional (H_test, W_test) risk in 0..100.
        title: figure title.
        train_start, test_start: optional start cells to mark.
        colors: optional name -> colour for the paths (default: a fixed high-contrast cycle).
    """
    train_labels = _check_labels(train_labels)
    test_labels = _check_labels(test_labels)
    if risk_map is not None and np.shape(risk_map) != test_labels.shape:
        raise ValueError(
            f"risk_map shape {np.shape(risk_map)} differs from test_labels {test_labels.shape}"
        )
    width_px, height_px = mission_figure_size(risk_map is not None)
    figure = Figure(figsize=(width_px / DPI, height_px / DPI), dpi=DPI)
    FigureCanvasAgg(figure)
    panels = 3 if risk_map is not None else 2
    axes = figure.subplots(1, panels)
    figure.suptitle(title, fontsize=11)

    draw_terrain(axes[0], train_labels, train_start)
    axes[0].set_title("training map", fontsize=9)
    draw_terrain(axes[1], test_labels, test_start)
    axes[1].set_title("test map", fontsize=9)
    for i, (name, cells) in enumerate(paths.items()):
        color = (colors or {}).get(name, _PATH_COLORS[i % len(_PATH_COLORS)])
        offset = (i - (len(paths) - 1) / 2) * _PATH_SPREAD
        draw_path(axes[1], cells, name, color, offset)
    if paths:
        # Terrain legend on the right, path legend below the test map.
        axes[1].add_artist(axes[1].get_legend())
        path_handles = [line for line in axes[1].get_lines() if not line.get_label().startswith("_")
                        and line.get_label() != "start"]
        axes[1].legend(handles=path_handles, loc="upper center", bbox_to_anchor=(0.5, -0.2),
                       ncol=min(3, len(path_handles)), fontsize=7, frameon=False)
    if risk_map is not None:
        draw_risk(axes[2], risk_map)
        axes[2].set_title("risk map", fontsize=9)
    # Margins in inches (room for tick labels, legends and the colour bar), as fractions.
    figure.subplots_adjust(
        left=0.6 / (width_px / DPI),
        right=1.0 - 0.9 / (width_px / DPI),
        bottom=0.2,
        top=0.88,
        wspace=0.6,
    )
    figure.savefig(os.fspath(path), dpi=DPI, format="png")
