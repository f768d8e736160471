"""The end of a mission, shared by the end-to-end graph tests: ask /ird/plan for the IRD
per-step plan (training-features baseline) of given posterior samples and wait until Rob has
driven it (RobStatus done for that plan's stamp)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ird_msgs.srv import PlanPath
from ird_ros.client.waits import call_service, spin_until
from ird_ros.graph import names


def drive_ird_plan(node: Any, proxy: Any, samples: Any, reference: np.ndarray,
                   status: list) -> dict[str, Any]:
    """Plan from ``proxy``'s test start and horizon; ``status`` collects /rob/status messages.

    Returns ``plan_cells`` (T+1 (row, col)), ``final`` (Rob's last status for the plan) and
    ``statuses`` (all of them).
    """
    plan_req = PlanPath.Request()
    plan_req.start_row, plan_req.start_col = proxy.test_start_row, proxy.test_start_col
    plan_req.horizon = proxy.test_horizon
    plan_req.mode, plan_req.baseline, plan_req.label = "per_step", "training_features", "ird"
    plan_req.weights = list(samples)
    plan_req.reference_features = list(reference)
    plan = call_service(node, node.create_client(PlanPath, names.SRV_PLAN), plan_req, timeout=120)
    assert plan.success, plan.message
    stamp = plan.path.header.stamp
    spin_until(node, lambda: any(s.done and s.plan_stamp == stamp for s in status), timeout=60,
               what="Rob finishing the plan")
    return {
        "plan_cells": list(zip(plan.rows, plan.cols)),
        "final": [s for s in status if s.done and s.plan_stamp == stamp][-1],
        "statuses": [s for s in status if s.plan_stamp == stamp],
    }
