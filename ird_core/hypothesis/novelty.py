"""A hypothesis space with one more feature: *novel*, nonzero on test cells unlike every training
cell and 0 on every training cell (docs/experiments.md, "Robot-sized maps").

Why: in the latent conditions the hypothesis space is linear in the observations, and the
training cells' noise ties lava's value to what the proxy did in training; the longer the
horizon, the surer the posterior is of the proxy's own value of lava. A feature that is zero on
every training cell is invisible to the proxy's training behaviour, so its weight keeps its
prior, just as the lava indicator does in side_effects. That is IRD's own premise ("the designer
never saw this") made explicit in the robot's features.

The feature is computed from the hypothesis features alone, without terrain labels or knowledge
of lava: a test cell is novel when it is farther from every training cell than the training
cells are from each other (:func:`ird_core.planning.novelty.novel_cells`, the same rule as the
novelty-avoiding control).

Its value on a novel cell is the training cells' root-mean-square feature norm
(:func:`ird_core.posterior.calibration.feature_scale`): a novel cell is as large in feature space
as a typical training cell. Two invariants follow. Under the calibrated prior
(``sigma = 1 / (temperature * that norm)``) the novel weight adds a prior spread of
``1 / temperature`` to a novel cell's reward, the spread the rule gives a training cell's reward
(a value of 1 would add ``1 / (temperature * norm)``, about 0.63 against 5 in the 50-d latent
conditions). And the feature scales with the features, so rescaling every observation by ``c``
leaves the posterior over rewards unchanged, as the calibration promises for the features alone.
One-hot terrains have norm 1: there the value is 1. ``value="one"`` sets 1 on every novel cell
(results measured that way say so).

The proxy is untouched: its features and weights stay the designer's, so the literal plan does
not change; only the posterior and the IRD plans see the new feature.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ird_core.planning.novelty import novel_cells
from ird_core.posterior.calibration import feature_scale
from ird_core.worlds import lavaland

__all__ = ["NOVELTY_FEATURE", "NOVELTY_VALUES", "with_novelty_feature"]

#: The name of the added hypothesis feature.
NOVELTY_FEATURE: str = "novel"
#: The feature's value on a novel cell: the training cells' rms feature norm (the default), or 1.
NOVELTY_VALUES: tuple[str, ...] = ("feature_scale", "one")


def _with_column(features: np.ndarray, column: np.ndarray) -> np.ndarray:
    """``(H, W, d), (H, W) -> (H, W, d + 1)``."""
    return np.concatenate([np.asarray(features, dtype=np.float64), column[..., None].astype(np.float64)], axis=-1)


def with_novelty_feature(inst: lavaland.LavalandInstance, value: str = "feature_scale") -> lavaland.LavalandInstance:
    """``inst`` with the *novel* hypothesis feature appended (module docstring).

    Every training world (the first and ``extra_training_worlds``) gets a zero column; the test
    map gets ``value`` on its novel cells and 0 elsewhere: the training maps' rms feature norm
    (``"feature_scale"``) or 1 (``"one"``). Raises ``ValueError`` naming ``value`` if it is not one
    of :data:`NOVELTY_VALUES`, or ``feature_names`` if the instance already has a feature of that
    name.
    """
    if value not in NOVELTY_VALUES:
        raise ValueError(f"value: expected one of {NOVELTY_VALUES}, got {value!r}")
    if NOVELTY_FEATURE in inst.feature_names:
        raise ValueError(f"feature_names: already has a {NOVELTY_FEATURE!r} feature")
    worlds = list(inst.training_maps)
    on_novel = feature_scale(worlds) if value == "feature_scale" else 1.0
    novel = novel_cells(list(worlds), inst.test_features) * on_novel
    extra = tuple(dataclasses.replace(world, features=_with_column(world.features, np.zeros(world.features.shape[:2])))
                  for world in inst.extra_training_worlds)
    return dataclasses.replace(
        inst, feature_names=(*inst.feature_names, NOVELTY_FEATURE),
        train_features=_with_column(inst.train_features, np.zeros(inst.train_features.shape[:2])),
        test_features=_with_column(inst.test_features, novel), extra_training_worlds=extra)
