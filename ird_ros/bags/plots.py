"""PNG plots of a recorded run (matplotlib, Agg backend; no ROS).

- ``plot_trajectories``: Rob's executed trajectories (odometry) and the plans over the
  ground-truth terrain, coloured by planner.
- ``plot_returns``: the true return of each mission over time (from ``/rob/status``).
- ``plot_posterior``: the IRD posterior as the reward of each terrain (``w . mean feature of the
  terrain``, one box per terrain present), whatever the posterior's dimension; per feature only
  without a feature map of the posterior's layers.
- ``plot_query_rounds``: each question to the designer: its options over the terrain, the
  chosen one solid.

Invariants: every colour is :mod:`ird_core.style`'s (terrains, ``planner_color`` of a mission's
label, options by role once answered and by index while open, the start marker); missions of one
colour differ in dash pattern and are offset a little, so identical paths stay visible; every
legend lies outside the plotting area (right of it or below the panels); the terrain legend lists
only the classes present on the map (no gold on a map without gold). Each ``*_figure`` function
returns the figure, its ``plot_*`` twin writes it.

matplotlib is imported inside the functions, so importing this module (and the bag analysis
that uses it) stays cheap and works without matplotlib until a plot is asked for.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ird_core import style
from ird_ros.bags.missions import Mission, Terrain
from ird_ros.bags.rounds import Round

__all__ = ["terrain_rewards", "feature_map", "trajectories_figure", "plot_trajectories", "plot_returns",
           "posterior_figure", "plot_posterior", "plot_query_rounds"]

_SHIFT = 0.1  # cells between the drawn lines of overlapping paths


def _figure(width: float, height: float, nrows: int = 1, ncols: int = 1, *, grid: bool = False) -> tuple[Any, Any]:
    """A figure with an Agg canvas (no pyplot state) and its axes: one ``Axes`` for a 1 x 1 figure,
    else (and always with ``grid``) an (nrows, ncols) array of them, so a panel loop over
    ``axes.flat`` works for any number of panels, one included."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height))
    FigureCanvasAgg(fig)
    return fig, fig.subplots(nrows, ncols, squeeze=not grid and nrows == ncols == 1)


def _save(fig: Any, path: str | Path) -> Path:
    """Write ``fig`` as a PNG at ``path`` (legends outside the axes included)."""
    path = Path(path)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def _halo(color: str, width: float) -> list:
    from matplotlib import patheffects

    return [patheffects.withStroke(linewidth=width + 2.0, foreground=style.halo_color(color)), patheffects.Normal()]


def _terrain_image(terrain: Terrain) -> tuple[np.ndarray, list[tuple[str, str]]]:
    """RGB image (H, W, 3) of a terrain and the legend entries (name, colour) of the classes present."""
    cols = [style.terrain_color(name) for name in terrain.class_names]
    rgb = np.array([style.hex_rgb(c) for c in [*cols, style.UNKNOWN_COLOR]])
    idx = terrain.classes.astype(int)
    idx = np.where(idx < len(cols), idx, len(cols))
    present = set(np.unique(idx).tolist())
    legend = [(name, c) for i, (name, c) in enumerate(zip(terrain.class_names, cols)) if i in present]
    if len(cols) in present:
        legend.append(("unknown", style.UNKNOWN_COLOR))
    return rgb[idx], legend


def _terrain_handles(legend: list[tuple[str, str]]) -> list:
    from matplotlib.patches import Patch

    return [Patch(facecolor=c, edgecolor=style.INK, label=n) for n, c in legend]


def _styles(labels: Sequence[str]) -> list[tuple[str, Any]]:
    """(colour, dashes) per label: the planner's colour, the k-th path of one colour dashed k."""
    seen: dict[str, int] = {}
    out = []
    for label in labels:
        color = style.planner_color(label)
        out.append((color, style.path_dashes(seen.get(color, 0))))
        seen[color] = seen.get(color, 0) + 1
    return out


def trajectories_figure(missions: list[Mission], terrain: Terrain | None, title: str = "") -> Any:
    """Rob's executed trajectories (odometry, thick) and plans (thin) over the terrain; each
    mission in its planner's colour, dashed apart from others of that colour and offset by
    ``0.1 * k`` cells so identical paths stay side by side; start (disc) and end (cross) marked."""
    fig, ax = _figure(7, 6.5)
    handles = []
    res = terrain.resolution if terrain is not None else 1.0
    if terrain is not None:
        img, legend = _terrain_image(terrain)
        ax.imshow(img, origin="lower", extent=terrain.extent, interpolation="nearest")
        handles += _terrain_handles(legend)
    n = len(missions)
    for k, (m, (color, dashes)) in enumerate(zip(missions, _styles([m.label for m in missions]))):
        shift = (k - (n - 1) / 2) * _SHIFT * res
        if len(m.plan_xy):
            ax.plot(m.plan_xy[:, 0] + shift, m.plan_xy[:, 1] + shift, color=color, lw=1.0, alpha=0.6, zorder=3)
        xy = m.odom[:, 1:] if len(m.odom) else m.plan_xy
        if len(xy):
            outcome = "LAVA" if m.touched_lava else ("target" if m.reached_target else "no target")
            (line,) = ax.plot(xy[:, 0] + shift, xy[:, 1] + shift, color=color, linestyle=dashes, lw=2.2, zorder=4,
                              path_effects=_halo(color, 2.2),
                              label=f"#{m.index} {m.label}: {outcome}, return {m.true_return:.2f}")
            ax.plot(xy[0, 0] + shift, xy[0, 1] + shift, linestyle="none", zorder=5, **style.START_MARKER)
            ax.plot(xy[-1, 0] + shift, xy[-1, 1] + shift, "X", color=color, ms=9, mec=style.halo_color(color),
                    zorder=6)
            handles.append(line)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.set_title(title or "Rob's trajectories (thick: odometry, thin: plan)")
    if handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, frameon=False)
    return fig


def plot_trajectories(missions: list[Mission], terrain: Terrain | None, path: str | Path, title: str = "") -> Path:
    """:func:`trajectories_figure` as a PNG at ``path``."""
    return _save(trajectories_figure(missions, terrain, title), path)


def plot_returns(missions: list[Mission], start_ns: int, path: str | Path) -> Path:
    """True return over time (from /rob/status), one line per mission in its planner's colour;
    the legend right of the plot."""
    fig, ax = _figure(8, 4.5)
    for m, (color, dashes) in zip(missions, _styles([m.label for m in missions])):
        if len(m.status_returns):
            t = (m.status_returns[:, 0] - start_ns) / 1e9
            ax.step(t, m.status_returns[:, 1], where="post", color=color, linestyle=dashes, lw=1.8,
                    marker=".", label=f"#{m.index} {m.label}")
    ax.axhline(0.0, color=style.NEUTRAL, lw=0.6)
    ax.set_xlabel("time since start of bag [s]")
    ax.set_ylabel("true return")
    ax.set_title("True return of Rob's executed plans")
    if missions:
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    return _save(fig, path)


def terrain_rewards(samples: np.ndarray, features: np.ndarray, classes: np.ndarray,
                    class_names: Sequence[str]) -> dict[str, np.ndarray]:
    """Per terrain present on the map: each sample's reward ``w . mu_t`` (``(K,)``), with ``mu_t``
    the mean feature vector of the map's cells of that terrain, in class order.

    Args:
        samples: (K, d) posterior samples; features: (H, W, d) map in the posterior's features;
        classes: (H, W) class indices into ``class_names`` (others: unknown, left out).
    """
    samples = np.asarray(samples, dtype=np.float64)
    features = np.asarray(features, dtype=np.float64)
    if features.ndim != 3 or features.shape[:2] != np.shape(classes) or features.shape[2] != samples.shape[1]:
        raise ValueError(f"features: shape {features.shape} does not match classes {np.shape(classes)} "
                         f"and {samples.shape[1]} weights")
    out = {}
    for t, name in enumerate(class_names):
        mask = np.asarray(classes) == t
        if mask.any():
            out[str(name)] = samples @ features[mask].mean(axis=0)
    return out


def feature_map(msg: Any) -> tuple[tuple[str, ...], np.ndarray]:
    """An ``ird_msgs/FeatureGrid`` read from a bag: its layer names and the (H, W, d) values."""
    h, w, layers = int(msg.info.height), int(msg.info.width), tuple(msg.layers)
    return layers, np.asarray(msg.data, dtype=np.float64).reshape(h, w, len(layers))


def posterior_figure(msg: Any, terrain: Terrain | None = None, features: Any = None) -> Any:
    """The posterior ``msg`` (an ``ird_msgs/RewardPosterior``) as the reward of each terrain:
    one box per terrain present on ``terrain`` (:func:`terrain_rewards` on ``features``, a
    FeatureGrid message with the posterior's layers on the terrain's grid), in the terrain's colour,
    with the proxy's reward of that terrain as a dot. Without such a map, one horizontal box per
    feature (readable at any dimension: the figure grows 0.22 inch per feature)."""
    names = list(msg.feature_names)
    d = len(names)
    samples = np.asarray(msg.samples, dtype=float).reshape(-1, d) if d else np.zeros((0, 0))
    proxy = np.asarray(msg.proxy_weights, dtype=float)
    title = (f"IRD posterior ({msg.method}, beta={msg.beta:g}, K={int(msg.num_samples)}, "
             f"R-hat max={msg.r_hat_max:.3f})")
    layers, values = feature_map(features) if features is not None else ((), None)
    by_terrain = (terrain is not None and values is not None and list(layers) == names and samples.size > 0
                  and values.shape[:2] == terrain.classes.shape)
    if by_terrain:
        rewards = terrain_rewards(samples, values, terrain.classes, terrain.class_names)
        fig, ax = _figure(max(5.0, 1.1 * len(rewards) + 2.5), 4.5)
        box = ax.boxplot(list(rewards.values()), tick_labels=list(rewards), patch_artist=True, showfliers=False)
        for patch, name in zip(box["boxes"], rewards):
            patch.set_facecolor(style.terrain_color(name))
            patch.set_edgecolor(style.INK)
        for median in box["medians"]:
            median.set_color(style.INK)
        if proxy.size == d:
            proxy_rewards = terrain_rewards(proxy[None, :], values, terrain.classes, terrain.class_names)
            ax.plot(range(1, len(rewards) + 1), [float(v[0]) for v in proxy_rewards.values()], "D",
                    color=style.LITERAL_COLOR, mec=style.INK, label="proxy's reward", zorder=5)
            ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        ax.axhline(0.0, color=style.NEUTRAL, lw=0.6)
        ax.set_ylabel("reward of one step (w . mean feature of the terrain)")
        ax.set_xlabel(f"terrain ({d} features per cell)")
    else:
        fig, ax = _figure(7.0, max(3.0, 0.22 * d + 1.5))
        if samples.size:
            ax.boxplot(samples, orientation="horizontal", showfliers=False)
            ax.set_yticks(range(1, d + 1), names, fontsize=7 if d > 20 else 8)
        if proxy.size == d and d:
            ax.plot(proxy, range(1, d + 1), "D", color=style.LITERAL_COLOR, mec=style.INK, label="proxy weights")
            ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
        ax.axvline(0.0, color=style.NEUTRAL, lw=0.6)
        ax.set_xlabel("weight")
    ax.set_title(title, fontsize=10)
    return fig


def plot_posterior(msg: Any, path: str | Path, terrain: Terrain | None = None, features: Any = None) -> Path:
    """:func:`posterior_figure` as a PNG at ``path``."""
    return _save(posterior_figure(msg, terrain, features), path)


def plot_query_rounds(rounds: list[Round], terrain: Terrain | None, path: str | Path) -> Path:
    """One panel per round: the options' paths over the terrain, each a little offset; answered:
    the chosen one solid white, the others dashed black (as the demo's ``rounds.png``); open: the
    options in their index colours (as the web page). One legend below the panels."""
    from matplotlib.lines import Line2D

    n = max(1, len(rounds))
    ncols = min(3, n)
    nrows = (n + ncols - 1) // ncols
    fig, axes = _figure(4.2 * ncols, 4.2 * nrows + 0.6, nrows, ncols, grid=True)
    res, (x0, y0) = (terrain.resolution, terrain.origin) if terrain is not None else (1.0, (0.0, 0.0))
    legend: list[tuple[str, str]] = []
    open_options = 0  # the most options of an open question
    for ax, r in zip(axes.flat, rounds):
        if terrain is not None:
            img, legend = _terrain_image(terrain)
            ax.imshow(img, origin="lower", extent=terrain.extent, interpolation="nearest")
        if r.answer is None:
            open_options = max(open_options, r.proposal.num_options)
        for k, cells in enumerate(r.proposal.options):
            xy = np.column_stack([x0 + (cells[:, 1] + 0.5) * res, y0 + (cells[:, 0] + 0.5) * res])
            chosen = r.chosen == k
            if r.answer is None:
                color, dashes, width = style.option_color(k), "solid", 2.0
            else:
                color = style.CHOSEN_OPTION_COLOR if chosen else style.OTHER_OPTION_COLOR
                dashes, width = ("solid", 3.0) if chosen else ("dashed", 1.6)
            shift = (k - (r.proposal.num_options - 1) / 2) * 0.08 * res
            ax.plot(xy[:, 0] + shift, xy[:, 1] + shift, color=color, linestyle=dashes, lw=width, zorder=4,
                    path_effects=_halo(color, width))
            ax.plot(xy[0, 0], xy[0, 1], linestyle="none", zorder=5, **style.START_MARKER)
        answer = "open" if r.answer is None else f"answer {r.chosen} by {r.answer.answered_by or 'client'}"
        ax.set_title(f"query {r.query_id} ({r.proposal.strategy}): gain {r.proposal.information_gain:.3f}\n{answer}",
                     fontsize=9)
        ax.set_aspect("equal")
    for ax in list(axes.flat)[len(rounds):]:
        ax.axis("off")
    handles = _terrain_handles(legend)
    handles += [Line2D([], [], color=style.CHOSEN_OPTION_COLOR, lw=3.0, label="option chosen",
                       path_effects=_halo(style.CHOSEN_OPTION_COLOR, 3.0)),
                Line2D([], [], color=style.OTHER_OPTION_COLOR, lw=1.6, ls="dashed", label="option not chosen",
                       path_effects=_halo(style.OTHER_OPTION_COLOR, 1.6))]
    handles += [Line2D([], [], color=style.option_color(k), lw=2.0, label=f"open question: option {k}",
                       path_effects=_halo(style.option_color(k), 2.0)) for k in range(open_options)]
    handles.append(Line2D([], [], linestyle="none", label="start", **style.START_MARKER))
    fig.legend(handles=handles, loc="lower center", ncol=min(len(handles), 5), fontsize=8, frameon=False)
    fig.suptitle("Questions to the designer")
    fig.tight_layout(rect=(0, 0.6 / (4.2 * nrows + 0.6), 1, 1))
    return _save(fig, path)
