"""The demo's query-round helpers (ird_ros.apps.demo_rounds, no ROS): terrain counts of option
paths against a brute-force count and lavaland's path predicates, the table's rows, and the
picture's size and layout (one column per stage)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ird_core.worlds import evaluation, lavaland
from ird_core.worlds.terrain import NUM_TERRAINS, Terrain
from ird_ros.apps import demo_rounds as dr


def _random_paths(rng: np.random.Generator, q: int, length: int, h: int, w: int) -> list[np.ndarray]:
    return [np.column_stack([rng.integers(0, h, length), rng.integers(0, w, length)]) for _ in range(q)]


def _outcome(label: str, cells, lava=False, target=True, gold=False, ret=1.0):
    return dr.Outcome(label, [tuple(map(int, c)) for c in cells], 0.0, lava, target, ret, gold)


def test_terrain_counts_match_brute_force_and_lavaland() -> None:
    rng = np.random.default_rng(0)
    for _ in range(20):
        h, w = rng.integers(1, 6, 2)
        labels = rng.integers(0, NUM_TERRAINS, (h, w))
        paths = _random_paths(rng, int(rng.integers(2, 5)), int(rng.integers(1, 8)), h, w)
        counts = dr.terrain_counts(labels, paths)
        assert counts.shape == (len(paths), NUM_TERRAINS)
        for k, cells in enumerate(paths):
            brute = [sum(1 for r, c in cells if labels[r, c] == t) for t in range(NUM_TERRAINS)]
            assert counts[k].tolist() == brute
            assert counts[k].sum() == len(cells)  # revisits count, like true_return
            assert (counts[k, Terrain.LAVA] > 0) == evaluation.touches_lava(labels, cells)
            assert (counts[k, Terrain.GOLD] > 0) == evaluation.reaches_gold(labels, cells)
            assert (counts[k, Terrain.TARGET] > 0) == evaluation.reaches_target(labels, cells)
            reward = np.asarray(lavaland.TRUE_TERRAIN_REWARD)
            assert counts[k] @ reward == pytest.approx(evaluation.true_return(labels, cells))


@pytest.mark.parametrize("cells", [[[[0, 0], [3, 0]], [[0, 0], [0, 0]]], [[[0, -1]], [[0, 0]]],
                                   [[[0, 0], [0, 1]], [[0, 0]]]])
def test_terrain_counts_refuse_bad_options(cells) -> None:
    labels = np.zeros((3, 3), dtype=int)
    with pytest.raises(ValueError, match="options"):
        dr.terrain_counts(labels, [np.array(c) for c in cells])


def test_rounds_table_has_a_row_per_plan_with_the_answer() -> None:
    labels = np.full((4, 4), Terrain.DIRT)
    labels[1, 1], labels[2, 2], labels[3, 3] = Terrain.GOLD, Terrain.LAVA, Terrain.TARGET
    options = (np.array([[0, 0], [1, 1], [1, 1]]), np.array([[0, 0], [1, 0], [2, 2]]))
    counts = dr.terrain_counts(labels, options)
    plan = _outcome("IRD after 1", options[0], gold=True, target=False, ret=6.1)
    rounds = [dr.RoundResult(1, 7, 0.4567, options, 0, "simulated", plan, counts),
              dr.RoundResult(2, 8, 0.1, options, 1, "web", _outcome("IRD after 2", options[1], lava=True, ret=-9.8),
                             counts)]
    lines = dr.rounds_table(_outcome("literal", options[1], lava=True, ret=-9.8),
                            _outcome("IRD", options[0], ret=0.3), rounds).splitlines()
    assert len(lines) == 1 + 2 + len(rounds)
    assert lines[3].split()[:5] == ["IRD", "after", "round", "1", "0.457"]
    assert "A of 2 (lava 0, gold 2, target 0)" in lines[3]  # options by letter, as on the designer's page
    assert "B of 2 (lava 1, gold 0, target 0)" in lines[4]
    # lava, target, gold, true return: the last four columns.
    assert lines[3].split()[-4:] == ["no", "no", "yes", "6.10"]
    assert lines[4].split()[-4:] == ["yes", "yes", "no", "-9.80"]
    assert lines[1].split()[-4:] == ["yes", "yes", "no", "-9.80"]


def test_describe_counts_names_lava_gold_target() -> None:
    counts = np.arange(NUM_TERRAINS)  # dirt 0, grass 1, target 2, lava 3, gold 4
    assert dr.describe_counts(counts) == "lava 3, gold 4, target 2"


@pytest.mark.parametrize("num_rounds", [0, 1, 3])
def test_rounds_figure_has_one_column_per_stage(tmp_path: Path, num_rounds: int) -> None:
    rng = np.random.default_rng(num_rounds)
    labels = rng.integers(0, NUM_TERRAINS, (6, 6))
    paths = _random_paths(rng, 2, 5, 6, 6)
    counts = dr.terrain_counts(labels, paths)
    risk = rng.uniform(0, 100, (6, 6))
    rounds = [dr.RoundResult(i + 1, i + 1, 0.2, tuple(paths), i % 2, "simulated", _outcome("p", paths[i % 2]),
                             counts, risk) for i in range(num_rounds)]
    out = tmp_path / "rounds.png"
    size = dr.save_rounds_figure(out, labels, (0, 0), _outcome("literal", paths[0]), _outcome("IRD", paths[1]),
                                 risk, rounds, "title")
    with Image.open(out) as img:
        assert img.size == size
    assert size[0] == round((dr.PANEL_INCHES * (1 + num_rounds) + 1.0) * 100)
    # A wider picture per round: the columns keep their size.
    assert size[1] == round((2 * dr.PANEL_INCHES + 1.9) * 100)
