"""Each posterior sample measured in the units of what the designer saw (docs/spec.md section 4).

The risk-averse planners compare samples cell by cell: the per-step min takes
``min_i (w_i . F[s] - b_i)``. Rewards are only defined up to a positive scale (Proposition 1's
invariance holds per sample, not across samples), so without a common unit a sample that
happens to be large dominates the min on *every* cell: an ordinary dirt step can be charged more
than lava's worst case through the sample's size alone (reward_hacking, seed 403, unscaled: the
worst per-step value of dirt -4.23, of lava -2.87).

The unit used here is each sample's **training spread**: the range of its per-cell rewards over
the training maps, ``s_i = max_c w_i . F_train[c] - min_c w_i . F_train[c]``. Dividing ``w_i``
(and so its baseline, which is linear in ``w_i`` for ``none``, ``initial_state`` and
``training_features``) by ``s_i`` makes every sample span exactly one unit over the terrains
the designer saw, so

- on training terrain, no sample's per-step reward differs from another training cell's by more
  than 1: an ordinary step costs at most one unit below the best training cell, whatever the
  sample's size;
- terrain the designer never saw (lava) keeps whatever value the sample gives it *relative to*
  that range, so the posterior's uncertainty about it still drives the min;
- the plan is invariant to rescaling any sample by a positive factor (``normalise(c_i w_i)`` is
  ``normalise(w_i)``): the per-sample version of Proposition 1.

The spread uses the training features only (never test labels or lava). A sample whose spread
is below ``RELATIVE_FLOOR * |w_i| * m`` (``m`` the training cells' mean feature norm: the size
the sample's rewards would have), or below ``max_j |w_ij| / MAX_SCALED_WEIGHT``, is divided by
that floor instead: it barely distinguishes the training terrains, and the floor keeps its
weights within ``MAX_SCALED_WEIGHT``. Both floors scale with the sample, so the per-sample
invariance holds with them. An all-zero sample is returned unchanged.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from ird_core.planning.arguments import check_weights

__all__ = ["SAMPLE_SCALES", "RELATIVE_FLOOR", "MAX_SCALED_WEIGHT", "training_spread", "normalise_samples", "worst_step_by_terrain"]

#: How the IRD planners scale samples: unchanged, or by their training spread.
SAMPLE_SCALES: tuple[str, ...] = ("none", "training_spread")
#: Smallest spread used, relative to the sample's own size on the training cells (module docstring).
RELATIVE_FLOOR: float = 1e-3
#: No scaled weight exceeds this (a second floor, ``max |w_i| / MAX_SCALED_WEIGHT``; well inside
#: ``ird_core.checks.MAX_ABS_WEIGHT``, so scaled samples stay plannable).
MAX_SCALED_WEIGHT: float = 1e3


def _training_cells(training_features: "np.ndarray | Sequence[np.ndarray]", d: int) -> np.ndarray:
    """The distinct feature vectors ``(n, d)`` of one ``(H, W, d)`` map or a sequence of them."""
    maps = [training_features] if isinstance(training_features, np.ndarray) else list(training_features)
    if not maps:
        raise ValueError("training_features: expected at least one (H, W, d) map")
    cells = []
    for i, f in enumerate(maps):
        f = np.asarray(f, dtype=np.float64)
        if f.ndim != 3 or f.shape[2] != d or f.shape[0] * f.shape[1] == 0:
            raise ValueError(f"training_features[{i}]: expected shape (H, W, {d}), got {f.shape}")
        if not np.all(np.isfinite(f)):
            raise ValueError(f"training_features[{i}]: contains NaN or infinite values")
        cells.append(f.reshape(-1, d))
    return np.unique(np.concatenate(cells), axis=0)


def _check(weights: np.ndarray) -> np.ndarray:
    if np.ndim(weights) != 2:
        raise ValueError(f"weights: expected shape (K, d), got {np.shape(weights)}")
    return check_weights(weights, np.shape(weights)[1])


def training_spread(weights: np.ndarray, training_features: "np.ndarray | Sequence[np.ndarray]") -> np.ndarray:
    """``s_i``: the range of sample ``i``'s per-cell reward over the training maps.

    Args:
        weights: ``(K, d)`` samples.
        training_features: one ``(H, W, d)`` training map or a sequence of them (several
            training worlds), in the samples' feature space.
    Returns:
        ``(K,)`` ranges ``>= 0``.
    """
    w = _check(weights)
    rewards = _training_cells(training_features, w.shape[1]) @ w.T  # (n, K)
    return rewards.max(axis=0) - rewards.min(axis=0)


def normalise_samples(weights: np.ndarray, training_features: "np.ndarray | Sequence[np.ndarray]") -> np.ndarray:
    """``w_i / s_i``: every sample spanning one unit over the training maps (module docstring).

    Args:
        weights: ``(K, d)`` samples.
        training_features: one ``(H, W, d)`` training map or a sequence of them.
    Returns:
        ``(K, d)`` rescaled samples (positive factors: each sample's ranking of paths is kept).
    """
    w = _check(weights)
    cells = _training_cells(training_features, w.shape[1])
    rewards = cells @ w.T  # (n, K)
    floor = np.maximum(RELATIVE_FLOOR * np.linalg.norm(w, axis=1) * float(np.linalg.norm(cells, axis=1).mean()),
                       np.abs(w).max(axis=1) / MAX_SCALED_WEIGHT)
    scale = np.maximum(rewards.max(axis=0) - rewards.min(axis=0), floor)
    return w / np.where(scale > 0.0, scale, 1.0)[:, None]


def worst_step_by_terrain(cell_rewards: np.ndarray, labels: np.ndarray, names: Sequence[str]) -> dict[str, float]:
    """The worst per-step value the planner charges on each terrain: ``min`` over its cells.

    The diagnostic of the scale problem: with the per-step min's rewards ``(H, W)``
    (:func:`ird_core.planning.per_step_reward`) and the map's terrain labels, lava's worst case
    should lie below every safe terrain's.

    Args:
        cell_rewards: ``(H, W)`` per-step rewards.
        labels: ``(H, W)`` integer terrain labels indexing ``names``.
        names: terrain names.
    Returns:
        ``{name: worst value}`` for the terrains present on the map.
    """
    r = np.asarray(cell_rewards, dtype=np.float64)
    lab = np.asarray(labels)
    if r.shape != lab.shape or r.ndim != 2:
        raise ValueError(f"labels: expected the shape of cell_rewards {r.shape}, got {lab.shape}")
    return {names[int(k)]: float(r[lab == k].min()) for k in np.unique(lab)}
