"""PNG plots of a recorded run (matplotlib, Agg backend; no ROS).

- ``plot_trajectories``: Rob's executed trajectories (odometry) and the plans over the
  ground-truth terrain, one colour per mission.
- ``plot_returns``: the true return of each mission over time (from ``/rob/status``).
- ``plot_posterior``: the IRD posterior samples per feature with the proxy weights.
- ``plot_query_rounds``: each question to the designer: its options over the terrain, the
  chosen one solid.

matplotlib is imported inside the functions, so importing this module (and the bag analysis
that uses it) stays cheap and works without matplotlib until a plot is asked for.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ird_ros.bags.missions import Mission, Terrain
from ird_ros.bags.rounds import Round

__all__ = ["TERRAIN_COLORS", "UNKNOWN_COLOR", "plot_trajectories", "plot_returns", "plot_posterior",
           "plot_query_rounds"]

TERRAIN_COLORS = {
    "dirt": "#b08850",
    "grass": "#5fa84a",
    "target": "#f2d13a",
    "lava": "#e0401f",
    "gold": "#c9a227",
}
UNKNOWN_COLOR = "#9a9a9a"


def _pyplot() -> Any:
    """``matplotlib.pyplot`` on the non-interactive Agg backend (plots are files, never windows)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(fig: Any, path: str | Path) -> Path:
    """Write ``fig`` as a PNG at ``path`` and free it."""
    import matplotlib.pyplot as plt

    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110, bbox_inches="tight")
    plt.close(fig)
    return path


def _terrain_image(terrain: Terrain) -> tuple[np.ndarray, list[tuple[str, str]]]:
    """RGB image (H, W, 3) of a terrain and its legend entries (name, colour)."""
    from matplotlib import colors as mcolors
    from matplotlib import colormaps

    palette = colormaps["tab10"]
    cols = []
    for i, name in enumerate(terrain.class_names):
        cols.append(TERRAIN_COLORS.get(name, mcolors.to_hex(palette(i % 10))))
    rgb = np.array([mcolors.to_rgb(c) for c in cols] + [mcolors.to_rgb(UNKNOWN_COLOR)])
    idx = terrain.classes.astype(int)
    idx = np.where(idx < len(cols), idx, len(cols))
    legend = list(zip(terrain.class_names, cols))
    if (idx == len(cols)).any():
        legend.append(("unknown", UNKNOWN_COLOR))
    return rgb[idx], legend


def plot_trajectories(missions: list[Mission], terrain: Terrain | None, path: str | Path, title: str = "") -> Path:
    """Rob's executed trajectories (odometry, solid) and plans (dashed) over the terrain."""
    plt = _pyplot()
    from matplotlib.patches import Patch

    fig, ax = plt.subplots(figsize=(7, 6.5))
    handles = []
    if terrain is not None:
        img, legend = _terrain_image(terrain)
        ax.imshow(img, origin="lower", extent=terrain.extent, interpolation="nearest")
        handles += [Patch(facecolor=c, edgecolor="k", label=n) for n, c in legend]
    palette = plt.get_cmap("tab10")
    for k, m in enumerate(missions):
        color = palette(k % 10)
        if len(m.plan_xy):
            ax.plot(m.plan_xy[:, 0], m.plan_xy[:, 1], "--", color=color, lw=1.2, alpha=0.8)
        xy = m.odom[:, 1:] if len(m.odom) else m.plan_xy
        if len(xy):
            outcome = "LAVA" if m.touched_lava else ("target" if m.reached_target else "no target")
            (line,) = ax.plot(xy[:, 0], xy[:, 1], "-", color=color, lw=2.2,
                              label=f"#{m.index} {m.label}: {outcome}, return {m.true_return:.2f}")
            ax.plot(xy[0, 0], xy[0, 1], "o", color=color, ms=8, mec="k")
            ax.plot(xy[-1, 0], xy[-1, 1], "X", color=color, ms=9, mec="k")
            handles.append(line)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_aspect("equal")
    ax.set_title(title or "Rob's trajectories (solid: odometry, dashed: plan)")
    if handles:
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    return _save(fig, path)


def plot_returns(missions: list[Mission], start_ns: int, path: str | Path) -> Path:
    """True return over time (from /rob/status), one line per mission."""
    plt = _pyplot()

    fig, ax = plt.subplots(figsize=(8, 4.5))
    palette = plt.get_cmap("tab10")
    for k, m in enumerate(missions):
        if len(m.status_returns):
            t = (m.status_returns[:, 0] - start_ns) / 1e9
            ax.step(t, m.status_returns[:, 1], where="post", color=palette(k % 10), lw=1.8,
                    marker=".", label=f"#{m.index} {m.label}")
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("time since start of bag [s]")
    ax.set_ylabel("true return")
    ax.set_title("True return of Rob's executed plans")
    if missions:
        ax.legend(fontsize=8, loc="best")
    return _save(fig, path)


def plot_posterior(msg: Any, path: str | Path) -> Path:
    """Posterior samples per feature (box plots) with the proxy weights (red dots)."""
    plt = _pyplot()

    names = list(msg.feature_names)
    d = len(names)
    samples = np.asarray(msg.samples, dtype=float).reshape(-1, d) if d else np.zeros((0, 0))
    fig, ax = plt.subplots(figsize=(max(6.0, 0.5 * d + 2), 4.5))
    if samples.size:
        ax.boxplot(samples, showfliers=False)
        ax.set_xticks(range(1, d + 1), names, rotation=60 if d > 8 else 0, fontsize=8)
    proxy = np.asarray(msg.proxy_weights, dtype=float)
    if proxy.size == d and d:
        ax.plot(range(1, d + 1), proxy, "o", color="red", label="proxy weights")
        ax.legend(fontsize=8)
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_ylabel("weight")
    ax.set_title(f"IRD posterior ({msg.method}, beta={msg.beta:g}, K={int(msg.num_samples)}, "
                 f"R-hat max={msg.r_hat_max:.3f})")
    return _save(fig, path)


def plot_query_rounds(rounds: list[Round], terrain: Terrain | None, path: str | Path) -> Path:
    """One panel per round: the options' paths over the terrain (chosen: solid, others: dashed)."""
    plt = _pyplot()
    from matplotlib.patches import Patch

    n = max(1, len(rounds))
    ncols = min(3, n)
    nrows = (n + ncols - 1) // ncols
    fig, axes = plt.subplots(nrows, ncols, figsize=(4.2 * ncols, 4.2 * nrows), squeeze=False)
    palette = plt.get_cmap("tab10")
    res, (x0, y0) = (terrain.resolution, terrain.origin) if terrain is not None else (1.0, (0.0, 0.0))
    legend: list[tuple[str, str]] = []
    for ax, r in zip(axes.flat, rounds):
        if terrain is not None:
            img, legend = _terrain_image(terrain)
            ax.imshow(img, origin="lower", extent=terrain.extent, interpolation="nearest")
        for k, cells in enumerate(r.proposal.options):
            xy = np.column_stack([x0 + (cells[:, 1] + 0.5) * res, y0 + (cells[:, 0] + 0.5) * res])
            chosen = r.chosen == k
            # Offset each option a little so overlapping paths stay visible.
            shift = (k - (r.proposal.num_options - 1) / 2) * 0.08 * res
            ax.plot(xy[:, 0] + shift, xy[:, 1] + shift, "-" if chosen else "--", color=palette(k % 10),
                    lw=3.0 if chosen else 1.6, label=f"option {k}" + (" (chosen)" if chosen else ""))
            ax.plot(xy[0, 0], xy[0, 1], "o", color="k", ms=6)
        answer = "open" if r.answer is None else f"answer {r.chosen} by {r.answer.answered_by or 'client'}"
        ax.set_title(f"query {r.query_id} ({r.proposal.strategy}): gain {r.proposal.information_gain:.3f}\n{answer}",
                     fontsize=9)
        ax.set_aspect("equal")
        ax.legend(fontsize=7, loc="upper right")
    for ax in list(axes.flat)[len(rounds):]:
        ax.axis("off")
    if legend:
        fig.legend(handles=[Patch(facecolor=c, edgecolor="k", label=name) for name, c in legend],
                   loc="lower center", ncol=len(legend), fontsize=8)
    fig.suptitle("Questions to the designer")
    return _save(fig, path)
