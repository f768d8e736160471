"""More training worlds for a Lavaland instance: the designer tried her proxy on ``k`` maps.

In the paper the designer wrote the proxy for one training world, so IRD sees one observation
of it. :func:`with_training_worlds` gives an instance ``k - 1`` more training worlds drawn from
the same distribution, each with the same proxy: IRD then conditions on the proxy's behaviour in
every one of them (``ird_core.posterior.proxy_observations``, one term per world), as for a
world file with several training worlds.

Invariants:

- The instance's own first training world, test map, starts, observation model, classifier and
  proxy are untouched, so a ``k``-world instance is paired with the one-world instance of the
  same seed, and ``k = 1`` returns the instance itself.
- Extra world ``i`` (``1 <= i < k``) is seeded by child ``INSTANCE_STREAMS - 1 + i`` (9, 10, ...)
  of ``numpy.random.SeedSequence(seed)`` (:func:`ird_core.worlds.lavaland.make_instance` uses the
  children before), split into independent streams for its map, its start and its observations:
  world ``i`` is the same whatever ``k > i``.
- Each world is drawn as the first one is: the training map distribution (``train_map``, by
  default :data:`ird_core.worlds.terrain.TRAIN_MAP`, make_instance's) at the instance's size,
  one target, the start within ``3 T // 4`` moves of it, the instance's horizon. Hypothesis
  features: the condition's indicators (:func:`ird_core.worlds.lavaland.indicator_features`), or
  fresh observations from the instance's observation model in the latent conditions; proxy
  features: the same, but the classifier's class probabilities in latent_classifier.
- No extra world holds lava or gold (the training distribution has neither), so what the designer
  never saw stays unseen.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ird_core.vocabulary import Condition
from ird_core.worlds import lavaland
from ird_core.worlds.observations import sample_observations
from ird_core.worlds.terrain import TRAIN_MAP, MapConfig, choose_start, sample_terrain

__all__ = ["MAX_TRAINING_WORLDS", "check_training_worlds", "with_training_worlds"]

#: The most training worlds an instance may have (each adds one MDP pass per posterior evaluation).
MAX_TRAINING_WORLDS: int = 16


def check_training_worlds(count: object) -> int:
    """``count`` as an int in ``[1, MAX_TRAINING_WORLDS]``; ``ValueError`` naming ``training_worlds``."""
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or not 1 <= count <= MAX_TRAINING_WORLDS:
        raise ValueError(f"training_worlds must be an integer in [1, {MAX_TRAINING_WORLDS}], got {count!r}")
    return int(count)


def _extra_world(inst: lavaland.LavalandInstance, stream: np.random.SeedSequence, train_map: MapConfig
                 ) -> lavaland.TrainingWorld:
    """One more training world of ``inst`` from ``stream`` (module docstring)."""
    map_stream, start_stream, obs_stream = stream.spawn(3)
    height, width = inst.train_labels.shape
    config = dataclasses.replace(train_map, height=height, width=width)
    labels = sample_terrain(config, np.random.default_rng(map_stream))
    reach = max(1, (3 * inst.train_horizon) // 4)
    start = choose_start(labels, np.random.default_rng(start_stream), max_distance=reach)
    if inst.observation_model is None:
        features = proxy_features = lavaland.indicator_features(inst.condition, labels)
    else:
        features = sample_observations(inst.observation_model, labels, np.random.default_rng(obs_stream))
        proxy_features = features if inst.classifier is None else inst.classifier.predict_proba(features)
    return lavaland.TrainingWorld(labels, features, proxy_features, start, inst.train_horizon,
                                  np.asarray(inst.proxy_weights))


def with_training_worlds(inst: lavaland.LavalandInstance, count: int, train_map: MapConfig = TRAIN_MAP
                         ) -> lavaland.LavalandInstance:
    """``inst`` with ``count - 1`` more training worlds (``count`` in all; module docstring), drawn
    from ``train_map`` (pass the one ``inst`` was made with when it is not the default).

    Raises:
        ValueError: naming ``training_worlds`` when ``count`` is not an integer in
            ``[1, MAX_TRAINING_WORLDS]``, or when ``inst`` already has extra training worlds or is
            not a generated Lavaland instance (a world file's worlds are its own).
    """
    count = check_training_worlds(count)
    if count == 1:
        return inst
    if inst.extra_training_worlds or inst.condition not in tuple(Condition):
        raise ValueError(f"training_worlds: only a generated Lavaland instance with one training world gets more "
                         f"(condition {inst.condition!r}, {1 + len(inst.extra_training_worlds)} training worlds)")
    first = lavaland.INSTANCE_STREAMS
    streams = np.random.SeedSequence(inst.seed).spawn(first + count - 1)[first:]
    return dataclasses.replace(inst, extra_training_worlds=tuple(_extra_world(inst, s, train_map) for s in streams))
