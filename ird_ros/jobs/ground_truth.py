"""The ground-truth terrain of the graph as the core's terrain labels, so that
``ird_core.worlds.evaluation.evaluate_path`` (docs/spec.md section 5) judges paths on it (no ROS).

A TerrainGrid holds class indices into its ``class_names`` (``UNKNOWN_CLASS`` 255 = unknown) and
``/world/proxy`` the true reward per terrain name. :func:`evaluation_terrain` maps them to the
labels ``evaluate_path`` reads: the standard terrains get their ``ird_core.worlds.terrain.Terrain``
label (so lava, target and gold are recognised by name, whatever the class order), other names
the labels after them in class order, and a class index past ``class_names`` label -1 (unknown,
counted in ``PathOutcome.unknown_cells``). A terrain without a true reward either earns 0 or is
unknown too: the caller's policy.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ird_core.vocabulary import TERRAIN_NAMES

__all__ = ["UNKNOWN_LABEL", "evaluation_terrain"]

UNKNOWN_LABEL = -1
"""The label of a cell ``evaluate_path`` counts as unknown (no entry in the reward table)."""


def evaluation_terrain(classes: np.ndarray, class_names: Sequence[str], rewards: Mapping[str, float], *,
                       unrewarded_unknown: bool) -> tuple[np.ndarray, np.ndarray]:
    """``(labels, reward)`` for ``evaluate_path(labels, cells, reward)``.

    Args:
        classes: (H, W) class indices into ``class_names``.
        class_names: the terrain classes' names.
        rewards: the true reward per terrain name.
        unrewarded_unknown: a class whose name has no reward is unknown (True) or earns 0 (False).
    Returns:
        labels (H, W) int64 and the reward per label (float64).
    """
    label_names = TERRAIN_NAMES + tuple(n for n in dict.fromkeys(class_names) if n not in TERRAIN_NAMES)
    reward = np.array([float(rewards.get(name, 0.0)) for name in label_names])
    lookup = np.full(256, UNKNOWN_LABEL, dtype=np.int64)  # class index -> label
    for index, name in enumerate(class_names[:256]):
        if not (unrewarded_unknown and name not in rewards):
            lookup[index] = label_names.index(name)
    return lookup[np.asarray(classes, dtype=np.int64)], reward
