"""Posterior reward per terrain for the latent_raw condition: IRD is uncertain about lava
(the paper's section 4 argument, docs/spec.md section 5).

Samples the MaxEnt-Z IRD posterior (1000 draws by default) for a ``latent_raw`` Lavaland
instance, then shows and prints two views of the spread of the posterior reward by terrain:

1. ``w_i . mu_t``: each draw's reward for the mean observation of terrain ``t`` (box plots);
2. per-cell spread: the standard deviation over draws of ``w_i . F[cell]`` for every cell of the
   TEST map, grouped by the cell's true terrain (box plots; the mean is printed).

The designer never saw lava, so nothing in the training map pins the reward in lava's
direction of observation space: its spread is close to the prior's, while the safe terrains'
rewards are pinned by the proxy's behaviour.

    python scripts/plot_posterior_terrain.py [out/posterior_terrain.png] [--seed 0] [--beta 1.0]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from ird_core import posterior, style
from ird_core.checks import check_int, check_real
from ird_core.experiments.progress import step_progress
from ird_core.output_paths import file_problem, make_output_folder
from ird_core.vocabulary import ZMethod
from ird_core.worlds import lavaland
from ird_core.worlds.terrain import TERRAIN_NAMES, Terrain

__all__ = ["observed_terrains", "terrain_spreads", "print_spreads", "plot_spreads", "main"]



def observed_terrains(instance: lavaland.LavalandInstance) -> list[Terrain]:
    """The terrains with an observation mean: the latent conditions have no gold cells."""
    return [Terrain(k) for k in range(instance.observation_model.means.shape[0])]


def _cell_sd(samples: np.ndarray, instance: lavaland.LavalandInstance) -> np.ndarray:
    """``(H, W)``: the standard deviation over draws of ``w . F[cell]`` on the test map."""
    return np.std(np.einsum("kd,hwd->khw", samples, instance.test_features, optimize=True), axis=0)


def terrain_spreads(samples: np.ndarray, instance: lavaland.LavalandInstance) -> dict[str, dict[str, float]]:
    """Per terrain: mean and sd over draws of ``w . mu_t``, and the mean per-cell sd on the test map.

    Args:
        samples: ``(K, d)`` posterior draws.
    Returns:
        ``{terrain name: {"mean_reward", "sd_of_mean_reward", "cell_sd"}}`` (cell_sd NaN if the
        terrain is absent from the test map).
    """
    means = instance.observation_model.means  # (T, d), indexed by Terrain
    rewards = samples @ means.T  # (K, 4)
    cell_sd = _cell_sd(samples, instance)
    out = {}
    for terrain in observed_terrains(instance):
        mask = instance.test_labels == terrain
        out[TERRAIN_NAMES[terrain]] = {
            "mean_reward": float(rewards[:, terrain].mean()),
            "sd_of_mean_reward": float(rewards[:, terrain].std()),
            "cell_sd": float(cell_sd[mask].mean()) if mask.any() else float("nan"),
        }
    return out


def print_spreads(spreads: dict[str, dict[str, float]]) -> None:
    """The spreads as a table, then lava's spread over the largest safe terrain's."""
    print(f"{'terrain':<8} {'E[w.mu_t]':>10} {'sd(w.mu_t)':>11} {'mean per-cell sd (test map)':>28}")
    for name, row in spreads.items():
        print(f"{name:<8} {row['mean_reward']:>10.3f} {row['sd_of_mean_reward']:>11.3f} {row['cell_sd']:>28.3f}")
    safe = [TERRAIN_NAMES[t] for t in (Terrain.DIRT, Terrain.GRASS, Terrain.TARGET)]
    lava = TERRAIN_NAMES[Terrain.LAVA]
    for key, label in (("sd_of_mean_reward", "sd(w.mu_t)"), ("cell_sd", "per-cell sd")):
        ratio = spreads[lava][key] / max(spreads[name][key] for name in safe)
        print(f"lava / largest safe {label}: {ratio:.1f}x")


def plot_spreads(result: Any, instance: lavaland.LavalandInstance, beta: float, seed: int, out: Path) -> None:
    """Both views as box plots into ``out`` (a PNG; its folder is created), one box per observed
    terrain in the terrain's colour (:mod:`ird_core.style`)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rewards = result.samples @ instance.observation_model.means.T
    cell = _cell_sd(result.samples, instance)
    terrains = observed_terrains(instance)
    names = [TERRAIN_NAMES[t] for t in terrains]
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
    box = axes[0].boxplot([rewards[:, t] for t in terrains], tick_labels=names, patch_artist=True, showfliers=False)
    axes[0].axhline(0.0, color=style.NEUTRAL, lw=0.8)
    axes[0].set_ylabel(r"posterior reward $w_i \cdot \mu_{terrain}$")
    axes[0].set_title("Reward of each terrain's mean observation")
    groups = [cell[instance.test_labels == t] for t in terrains]
    box2 = axes[1].boxplot([g if g.size else [np.nan] for g in groups], tick_labels=names, patch_artist=True)
    axes[1].set_ylabel(r"sd over draws of $w_i \cdot F[cell]$")
    axes[1].set_title("Per-cell reward spread, test map")
    for b in (box, box2):
        for patch, name in zip(b["boxes"], names):
            patch.set_facecolor(style.terrain_color(name))
            patch.set_edgecolor(style.INK)
        for median in b["medians"]:
            median.set_color(style.INK)
    fig.suptitle(f"IRD posterior (MaxEnt-Z, beta={beta:g}, {result.num_samples} samples), latent_raw "
                 f"seed {seed}: lava is uncertain")
    fig.tight_layout()
    make_output_folder(out.parent, "out")
    fig.savefig(out, dpi=120)


def main(argv: list[str] | None = None) -> int:
    """Sample, print the spreads and write the figure; exit status 0, 2 on a bad argument."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("output", nargs="?", default="out/posterior_terrain.png")
    parser.add_argument("--seed", type=int, default=0, help="Lavaland instance and sampler seed")
    parser.add_argument("--beta", type=float, default=1.0)
    parser.add_argument("--samples", type=int, default=1000)
    args = parser.parse_args(argv)
    try:  # every argument checked before the sampler starts: argparse's status 2, naming it
        check_real("beta", args.beta, positive=False)
        check_int("samples", args.samples, 1)
        instance = lavaland.make_instance("latent_raw", args.seed)
        out = Path(args.output)
        if file_problem(out):  # before sampling: the figure would be lost at the end
            raise ValueError(f"output: {file_problem(out)}")
    except ValueError as exc:
        parser.error(str(exc))
    start = time.perf_counter()
    with step_progress("maxent_z MCMC") as progress:
        result = posterior.sample_posterior(
            instance.proxy_weights, lavaland.train_mdp(instance), args.beta, ZMethod.MAXENT_Z, args.samples, args.seed,
            proxy_features=posterior.proxy_feature_expectations(instance), progress=progress)
    elapsed = time.perf_counter() - start
    print(f"latent_raw seed {args.seed}, MaxEnt-Z, beta {args.beta:g}: {result.num_samples} samples in "
          f"{elapsed:.1f} s; acceptance {result.acceptance_rate:.2f}, R-hat {result.r_hat_max:.3f}, "
          f"ESS {result.ess_min:.0f}")
    print_spreads(terrain_spreads(result.samples, instance))
    plot_spreads(result, instance, args.beta, args.seed, out)
    print(f"wrote {out}")
    return 0
