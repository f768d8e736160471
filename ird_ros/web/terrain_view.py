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
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ird_core.vocabulary import Condition
from ird_core.worlds import lavaland

__all__ = ["GAUSSIAN_CONDITIONS", "gaussian_instance", "terrain_posterior", "observation_note"]

#: Conditions whose features are observation dimensions (a Gaussian per terrain).
GAUSSIAN_CONDITIONS: frozenset[str] = frozenset({Condition.LATENT_RAW.value, Condition.LATENT_CLASSIFIER.value})


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
