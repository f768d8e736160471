"""ird_core.worlds.evaluation: the one evaluation of a path, and its thin functions."""

from __future__ import annotations

import numpy as np
import pytest

from ird_core.worlds import evaluation
from ird_core.worlds.lavaland import TRUE_TERRAIN_REWARD
from ird_core.worlds.terrain import Terrain

LABELS = np.array([[Terrain.DIRT, Terrain.GRASS, Terrain.TARGET],
                   [Terrain.LAVA, Terrain.GOLD, 7]], dtype=np.int8)


def test_outcome_of_a_path_on_known_terrain() -> None:
    path = [(0, 0), (0, 1), (1, 1), (1, 1), (0, 1), (0, 2)]
    outcome = evaluation.evaluate_path(LABELS, path)
    want = float(TRUE_TERRAIN_REWARD[[0, 1, 4, 4, 1, 2]].sum())
    assert outcome == evaluation.PathOutcome(want, False, True, True, 0)
    assert evaluation.true_return(LABELS, path) == want
    assert evaluation.reaches_gold(LABELS, path) and evaluation.reaches_target(LABELS, path)
    assert not evaluation.touches_lava(LABELS, path)


def test_unknown_terrain_adds_nothing_and_is_counted() -> None:
    path = [(1, 0), (1, 1), (1, 2), (1, 2)]
    outcome = evaluation.evaluate_path(LABELS, path)
    assert outcome.unknown_cells == 2 and outcome.touched_lava and outcome.reached_gold
    assert outcome.true_return == pytest.approx(-10.0 + 3.0)
    with pytest.raises(ValueError, match="cells"):
        evaluation.true_return(LABELS, path)
    extended = np.concatenate([TRUE_TERRAIN_REWARD, [0.0, 0.0, 0.5]])
    assert evaluation.true_return(LABELS, path, extended) == pytest.approx(-10.0 + 3.0 + 1.0)


def test_off_map_cells_are_refused() -> None:
    with pytest.raises(ValueError, match="off the map"):
        evaluation.evaluate_path(LABELS, [(0, 0), (2, 0)])
