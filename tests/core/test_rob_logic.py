"""Rob's ROS-free execution logic against ird_core.worlds.lavaland's evaluation functions."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ird_core.worlds import evaluation, lavaland
from ird_core.worlds.terrain import TERRAIN_NAMES, Terrain
from ird_ros.jobs.rob_logic import RobExecutor


def _executor(labels: np.ndarray) -> RobExecutor:
    rob = RobExecutor()
    rob.set_terrain(labels, TERRAIN_NAMES)
    rob.set_rewards(TERRAIN_NAMES, lavaland.TRUE_TERRAIN_REWARD)
    return rob


def _run(rob: RobExecutor) -> list:
    statuses = []
    for _ in range(10_000):
        status = rob.tick()
        if status is None:
            break
        statuses.append(status)
    return statuses


def _random_walk(rng: np.random.Generator, shape: tuple[int, int], length: int) -> list[tuple[int, int]]:
    h, w = shape
    cells = [(int(rng.integers(h)), int(rng.integers(w)))]
    moves = [(0, 0), (1, 0), (-1, 0), (0, 1), (0, -1)]
    while len(cells) < length:
        r, c = cells[-1]
        dr, dc = moves[int(rng.integers(len(moves)))]
        if 0 <= r + dr < h and 0 <= c + dc < w:
            cells.append((r + dr, c + dc))
    return cells


@settings(max_examples=100, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), length=st.integers(1, 40))
def test_final_status_matches_lavaland(seed: int, length: int) -> None:
    rng = np.random.default_rng(seed)
    labels = rng.integers(0, 4, size=(6, 7)).astype(np.int8)
    cells = _random_walk(rng, labels.shape, length)
    rob = _executor(labels)
    rob.set_plan(cells, stamp=("s", seed), label="lbl")
    statuses = _run(rob)
    assert [(s.row, s.col) for s in statuses] == cells
    assert [s.step for s in statuses] == list(range(length))
    assert [s.done for s in statuses] == [False] * (length - 1) + [True]
    final = statuses[-1]
    assert final.horizon == length - 1
    assert final.touched_lava == evaluation.touches_lava(labels, cells)
    assert final.reached_target == evaluation.reaches_target(labels, cells)
    assert final.true_return == pytest.approx(evaluation.true_return(labels, cells), abs=1e-12)
    assert final.plan_label == "lbl" and final.plan_stamp == ("s", seed)
    # Every intermediate status evaluates the prefix executed so far.
    for k, status in enumerate(statuses):
        prefix = cells[: k + 1]
        assert status.terrain == TERRAIN_NAMES[labels[prefix[-1]]]
        assert status.true_return == pytest.approx(evaluation.true_return(labels, prefix), abs=1e-12)
        assert status.touched_lava == evaluation.touches_lava(labels, prefix)
    assert rob.tick() is None and not rob.active


def test_new_plan_restarts_at_its_first_cell() -> None:
    labels = np.zeros((3, 3), dtype=np.int8)
    labels[2, 2] = Terrain.LAVA
    rob = _executor(labels)
    rob.set_plan([(1, 1), (1, 2), (2, 2)], label="a")
    assert rob.tick().row == 1
    second = rob.tick()
    assert (second.row, second.col, second.step) == (1, 2, 1)
    rob.set_plan([(0, 0), (0, 1)], label="b")  # replaces the current plan
    statuses = _run(rob)
    assert [(s.row, s.col, s.step) for s in statuses] == [(0, 0, 0), (0, 1, 1)]
    assert statuses[-1].done and not statuses[-1].touched_lava
    assert statuses[-1].true_return == pytest.approx(0.2)
    assert statuses[-1].plan_label == "b"


def test_plan_waits_for_terrain_and_rewards() -> None:
    rob = RobExecutor()
    rob.set_plan([(0, 0), (0, 1)])
    assert rob.pending and rob.tick() is None
    rob.set_terrain(np.zeros((2, 2), dtype=np.uint8), TERRAIN_NAMES)
    assert rob.pending and rob.tick() is None
    rob.set_rewards(TERRAIN_NAMES, lavaland.TRUE_TERRAIN_REWARD)
    assert not rob.pending
    assert [s.step for s in _run(rob)] == [0, 1]


def test_rejects_bad_inputs_and_keeps_the_current_plan() -> None:
    rob = _executor(np.zeros((2, 2), dtype=np.int8))
    rob.set_plan([(0, 0), (1, 0)], label="good")
    with pytest.raises(ValueError, match="plan: cell 1"):
        rob.set_plan([(0, 0), (2, 0)])
    with pytest.raises(ValueError, match="plan: must contain"):
        rob.set_plan([])
    assert [s.plan_label for s in _run(rob)] == ["good", "good"]
    with pytest.raises(ValueError, match="true_terrain_rewards"):
        rob.set_rewards(("dirt",), (1.0, 2.0))
    with pytest.raises(ValueError, match="true_terrain_rewards"):
        rob.set_rewards(("dirt",), (float("nan"),))
    with pytest.raises(ValueError, match="classes"):
        rob.set_terrain(np.zeros(3), TERRAIN_NAMES)


def test_unknown_class_has_no_reward() -> None:
    labels = np.array([[255, 2]], dtype=np.uint8)
    rob = _executor(labels)
    rob.set_plan([(0, 0), (0, 1)])
    statuses = _run(rob)
    assert statuses[0].terrain == "unknown" and statuses[0].true_return == 0.0
    assert statuses[1].reached_target and statuses[1].true_return == pytest.approx(1.0)


def test_an_empty_reward_table_drives_with_an_unjudged_return() -> None:
    """A world file without true rewards: Rob waits for the (empty) table, then drives; the
    return is NaN, while lava and target are still reported."""
    labels = np.array([[Terrain.DIRT, Terrain.LAVA], [Terrain.TARGET, Terrain.GRASS]], dtype=np.int8)
    rob = RobExecutor()
    rob.set_terrain(labels, TERRAIN_NAMES)
    rob.set_plan([(0, 0), (0, 1), (1, 1), (1, 0)])
    assert rob.pending and rob.tick() is None  # no table yet: waits
    rob.set_rewards((), ())
    statuses = _run(rob)
    assert [s.step for s in statuses] == [0, 1, 2, 3]
    last = statuses[-1]
    assert last.done and last.touched_lava and last.reached_target
    assert np.isnan(last.true_return)
