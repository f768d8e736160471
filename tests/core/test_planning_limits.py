"""plan_path's time limit covers every stage of the trajectory solver: a limit too short for any
proof yields PlanningTimeout with a legal fallback path, its exact objective and a valid bound."""

from __future__ import annotations

import numpy as np
import pytest

from ird_core import planning
from ird_core.mdp import GridMDP
from ird_core.worlds import lavaland


@pytest.mark.parametrize("baseline", ["log_z", "initial_state"])
@pytest.mark.parametrize("solver", [None, "label-bb", "milp-highs"])
def test_tiny_time_limit_gives_a_fallback_plan(baseline: str, solver: str | None) -> None:
    inst = lavaland.make_instance("latent_raw", 0, size=15, horizon=30, obs_dim=50)
    weights = np.random.default_rng(0).normal(size=(16, inst.test_features.shape[2]))
    mdp = GridMDP(inst.test_features.astype(np.float64), inst.test_start, inst.test_horizon)
    with pytest.raises(planning.PlanningTimeout) as exc:
        planning.plan_path(mdp, weights, "trajectory", baseline, solver=solver, time_limit=1e-6)
    plan = exc.value.plan
    assert str(exc.value).startswith("time_limit: 1e-06 s passed")
    assert len(plan.cells) == mdp.horizon + 1 and plan.cells[0] == mdp.start
    assert plan.objective == planning.path_objective(mdp, plan.cells, weights, "trajectory", baseline)
    assert plan.bound >= plan.objective
