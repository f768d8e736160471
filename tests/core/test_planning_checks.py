"""planning.check_plan_arguments / check_start: the planner node's up-front checks are plan_path's own.

For every argument combination, ``check_plan_arguments`` refuses exactly what ``plan_path``
refuses (same message), so a request the node accepts cannot fail later on an argument.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from ird_core import planning
from ird_core.mdp import GridMDP

MDP = GridMDP(np.random.default_rng(0).normal(size=(3, 4, 2)), (1, 2), 3)
WEIGHTS = {
    "one": np.array([[0.5, -1.0]]),
    "two": np.array([[0.5, -1.0], [1.0, 0.2]]),
    "wrong d": np.ones((2, 3)),
    "NaN": np.array([[math.nan, 1.0]]),
    "flat": np.array([0.5, -1.0]),
}
REFERENCES = {"none": None, "ok": np.array([0.1, 0.2]), "short": np.array([0.1]), "inf": np.array([math.inf, 0.0])}


def _message(call) -> str | None:  # type: ignore[no-untyped-def]
    try:
        call()
    except ValueError as exc:
        return str(exc)
    return None


@pytest.mark.parametrize("mode,baseline,weights,reference", list(itertools.product(
    planning.MODES + ("cautious",), ("none", "training_features", "mean"), WEIGHTS, REFERENCES)))
def test_check_plan_arguments_refuses_what_plan_path_refuses(mode: str, baseline: str, weights: str,
                                                             reference: str) -> None:
    w, ref = WEIGHTS[weights], REFERENCES[reference]
    checked = _message(lambda: planning.check_plan_arguments(mode, baseline, w, MDP.num_features, ref))
    planned = _message(lambda: planning.plan_path(MDP, w, mode, baseline, ref))
    if checked is not None:
        assert planned == checked
    else:
        # The only refusal left to plan_path: training_features without reference features.
        assert planned in (None, "reference_features: required by the 'training_features' baseline")
        assert (planned is None) == (baseline != "training_features" or ref is not None)


def test_choices_are_checked_without_weights() -> None:
    assert planning.check_plan_arguments("per_step", "log_z") is None
    assert _message(lambda: planning.check_plan_arguments("x", "none")).startswith("mode:")
    assert _message(lambda: planning.check_plan_arguments("literal", "x")).startswith("baseline:")
    assert _message(lambda: planning.check_plan_arguments("trajectory", "none", time_limit=0.0)).startswith(
        "time_limit:")


@pytest.mark.parametrize("row,col", list(itertools.product([-1, 0, 2, 3, 2**32], [-1, 0, 3, 4])))
def test_check_start_agrees_with_grid_mdp_and_names_the_coordinate(row: int, col: int) -> None:
    message = _message(lambda: planning.check_start((row, col), 3, 4))
    on_map = _message(lambda: GridMDP(MDP.features, (row, col), 3)) is None
    assert (message is None) == on_map
    if message is not None:
        assert message.startswith("start_row:" if not 0 <= row < 3 else "start_col:"), message
    else:
        assert planning.check_start((row, col), 3, 4) == (row, col)
