"""The designer page's posterior per terrain in Gaussian-feature worlds (ROS-free).

In the latent conditions (``latent_raw``, ``latent_classifier``) the posterior's features are
observation dimensions ``obs_00 .. obs_{D-1}``, not terrains: a row per dimension would mean
nothing to the person answering. The world node publishes the condition, seed, horizon and test
start (``/world/proxy``) and the terrain of the test map (``/world/terrain``); the instance is a
pure function of those (``lavaland.make_instance``), so :func:`gaussian_instance` makes it again and
checks it against what was published (terrain, feature names, start). :func:`terrain_posterior`
then gives the page a row per terrain through
:func:`ird_core.experiments.posterior_terrain.terrain_spreads`: mean and sd over the draws of
``w . mu_t``, each draw's reward for the mean observation of terrain ``t``.

When the instance cannot be made again (a world file, another generator), :func:`observation_note`
keeps the rows per dimension and says so on the page.

The training map's terrain (:func:`training_classes`): the world node publishes the training map
only as features (``/world/train_features``), never as terrain. What terrain a training cell is:

- where every cell of a terrain on the test map has the same feature vector (indicators, two
  sensors, a world file's ``vectors``), the terrain whose test-map vector the cell has (a vector
  no terrain of the test map has, or that two terrains share, is unknown: 255);
- in a Gaussian world, the ``train_labels`` of the instance made again (:func:`gaussian_instance`),
  when its training features are the published ones.

The designer page draws a proxy-choice query's options on it, and the simulated designer judges
them by their true return on it.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ird_core.vocabulary import Condition
from ird_core.worlds import lavaland

__all__ = ["GAUSSIAN_CONDITIONS", "UNKNOWN", "gaussian_instance", "terrain_posterior", "observation_note",
           "training_classes"]

#: Conditions whose features are observation dimensions (a Gaussian per terrain).
GAUSSIAN_CONDITIONS: frozenset[str] = frozenset({Condition.LATENT_RAW.value, Condition.LATENT_CLASSIFIER.value})
#: Class of a cell whose terrain is not known (``ird_msgs/TerrainGrid.UNKNOWN``).
UNKNOWN: int = 255
#: Largest difference of two feature values that are "the same" (the maps travel as float32).
_SAME = 1e-5


def gaussian_instance(condition: str, seed: int, classes: np.ndarray, class_names: Sequence[str], horizon: int,
                      test_start: tuple[int, int], feature_names: Sequence[str]) -> lavaland.LavalandInstance | None:
    """The Lavaland instance the world node published, made again, or ``None`` when the condition
    is not Gaussian or the instance made does not match what was published.

    Args:
        condition, seed, horizon, test_start: ``/world/proxy``'s (``horizon`` = training horizon).
        classes, class_names: ``/world/terrain``'s (H x W labels, row 0 = bottom).
        feature_names: the posterior's (their count is the observation dimension).
    """
    if condition not in GAUSSIAN_CONDITIONS or len(feature_names) < 3:
        return None
    classes = np.asarray(classes)
    try:
        inst = lavaland.make_instance(condition, int(seed), size=tuple(classes.shape), horizon=int(horizon),
                                      obs_dim=len(feature_names))
    except ValueError:
        return None
    same = (tuple(inst.feature_names) == tuple(feature_names) and tuple(inst.terrain_names) == tuple(class_names)
            and inst.test_labels.shape == classes.shape and np.array_equal(inst.test_labels, classes)
            and tuple(int(v) for v in inst.test_start) == tuple(int(v) for v in test_start))
    return inst if same else None


def terrain_posterior(samples: np.ndarray, instance: lavaland.LavalandInstance) -> dict[str, Any]:
    """The page's posterior rows per terrain: ``feature_names`` (terrain names), ``mean``, ``std``
    (over the draws of ``w . mu_t``), ``features: "terrains"`` and ``feature_note``."""
    # imported here: ird_core.experiments takes a second to import, and only Gaussian worlds need it
    from ird_core.experiments.posterior_terrain import terrain_spreads

    spreads = terrain_spreads(np.asarray(samples, dtype=float), instance)
    dim = int(np.asarray(samples).shape[1])
    return {"feature_names": list(spreads), "mean": [row["mean_reward"] for row in spreads.values()],
            "std": [row["sd_of_mean_reward"] for row in spreads.values()], "features": "terrains",
            "feature_note": (f"Rewards per terrain: the reward of each terrain's mean observation "
                             f"(the posterior is over {dim} observation dimensions)")}


def observation_note(feature_names: Sequence[str]) -> dict[str, Any]:
    """What the page says when the rows stay per observation dimension."""
    return {"features": "observations",
            "feature_note": (f"These {len(feature_names)} features are observation dimensions, not terrains: "
                             "the terrains' observation means are not known here")}


def training_classes(train_features: np.ndarray, test_features: np.ndarray, test_classes: np.ndarray,
                     instance: lavaland.LavalandInstance | None = None) -> np.ndarray:
    """The training map's ``(H, W)`` uint8 classes (indices into the test terrain's class names,
    :data:`UNKNOWN` where not known; module docstring).

    Args:
        train_features: ``(H, W, d)`` ``/world/train_features``.
        test_features: ``(H', W', d)`` ``/world/test_features`` (the same layers).
        test_classes: ``(H', W')`` ``/world/terrain``'s classes.
        instance: a Gaussian world's instance made again (its classes are the terrain's), or None.
    """
    train = np.asarray(train_features, dtype=np.float64)
    if instance is not None and instance.train_features.shape == train.shape \
            and np.allclose(instance.train_features, train, rtol=1e-5, atol=_SAME):
        return np.asarray(instance.train_labels, dtype=np.uint8)
    out = np.full(train.shape[:2], UNKNOWN, dtype=np.uint8)
    test, classes = np.asarray(test_features, dtype=np.float64), np.asarray(test_classes)
    if test.ndim != 3 or test.shape[2] != train.shape[2] or test.shape[:2] != classes.shape:
        return out
    signatures: dict[int, np.ndarray] = {}
    for cls in np.unique(classes[classes != UNKNOWN]):
        vectors = test[classes == cls]
        if np.all(np.abs(vectors - vectors[0]) <= _SAME):  # one vector per terrain: a deterministic map
            signatures[int(cls)] = vectors[0]
    if not signatures:
        return out
    keys = np.array(list(signatures))
    same = np.all(np.abs(train[:, :, None, :] - np.stack(list(signatures.values()))) <= _SAME, axis=-1)  # (H, W, k)
    one = same.sum(axis=-1) == 1  # exactly one terrain has the cell's vector
    out[one] = keys[np.argmax(same, axis=-1)[one]]
    return out
