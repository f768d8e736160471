"""The end of a mission, shared by the end-to-end graph tests: ask /ird/plan for the IRD
per-step plan (training-features baseline) of given posterior samples and wait until Rob has
driven it (RobStatus done for that plan's stamp)."""

from __future__ import annotations

from typing import Any

import numpy as np

from ird_ros.client import IrdClient, plan_request


def drive_ird_plan(ird: IrdClient, proxy: Any, samples: np.ndarray, reference: np.ndarray) -> dict[str, Any]:
    """Plan from ``proxy``'s test start and horizon (``ird.watch_rob()`` called before).

    Returns ``plan_cells`` (T+1 (row, col)), ``final`` (Rob's last status for the plan) and
    ``statuses`` (all of them).
    """
    request = plan_request((proxy.test_start_row, proxy.test_start_col), proxy.test_horizon, "per_step",
                           "training_features", weights=samples, reference_features=reference, label="ird")
    result = ird.plan(request, timeout=120)
    assert result.ok, result.message
    drive = ird.wait_for_rob(result.unwrap(), timeout=60)
    return {"plan_cells": list(result.unwrap().cells), "final": drive.final, "statuses": list(drive.statuses),
            "plan_message": result.message}
