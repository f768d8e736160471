"""The planners' argument checks (docs/spec.md sections 4 and 8): everything :func:`plan_path
<ird_core.planning.plan_path>` refuses before any planning, as functions a caller (the planner
node) can run first. Every error is a ``ValueError`` whose message starts with the field's name.
"""

from __future__ import annotations

import numpy as np

from ird_core.checks import MAX_ABS_FEATURE, MAX_ABS_WEIGHT, check_magnitude
from ird_core.planning.trajectory_limits import check_work_limit
from ird_core.vocabulary import Baseline, PlanMode, parse

__all__ = ["SOLVERS", "check_choice", "check_weights", "check_reference", "check_features", "check_start",
           "check_plan_arguments", "plan_work", "check_plan_size"]

#: Solvers a caller may request per mode (``None`` = automatic).
SOLVERS: dict[str, tuple[str, ...]] = {
    PlanMode.LITERAL: ("dp",),
    PlanMode.PER_STEP: ("dp",),
    PlanMode.TRAJECTORY: ("label-bb", "milp-highs"),
}


def check_choice(value: object, name: str, allowed: tuple[str, ...]) -> str:
    if not isinstance(value, str) or value not in allowed:
        raise ValueError(f"{name}: expected one of {allowed}, got {value!r}")
    return value


def check_weights(weights: np.ndarray, num_features: int) -> np.ndarray:
    """A finite ``(K, d)`` float64 batch with ``K >= 1``."""
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 2 or w.shape[0] < 1 or w.shape[1] != num_features:
        raise ValueError(f"weights: expected shape (K >= 1, {num_features}), got {w.shape}")
    if not np.all(np.isfinite(w)):
        raise ValueError("weights: contains NaN or infinite values")
    return check_magnitude("weights", w, MAX_ABS_WEIGHT)


def check_reference(reference_features: np.ndarray | None, num_features: int) -> np.ndarray | None:
    if reference_features is None:
        return None
    f = np.asarray(reference_features, dtype=np.float64)
    if f.shape != (num_features,):
        raise ValueError(f"reference_features: expected shape ({num_features},), got {f.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError("reference_features: contains NaN or infinite values")
    return check_magnitude("reference_features", f, MAX_ABS_WEIGHT)


def check_start(start: tuple[int, int], height: int, width: int) -> tuple[int, int]:
    """A start cell on an ``height x width`` map, as ``(row, col)`` ints.

    Raises:
        ValueError: naming ``start_row`` or ``start_col`` (the coordinate that is off the map).
    """
    row, col = (int(v) for v in start)
    if not 0 <= row < height:
        raise ValueError(f"start_row: {row} is off the map (height {height})")
    if not 0 <= col < width:
        raise ValueError(f"start_col: {col} is off the map (width {width})")
    return row, col


def check_plan_arguments(
    mode: str,
    baseline: str,
    weights: np.ndarray | None = None,
    num_features: int | None = None,
    reference_features: np.ndarray | None = None,
    *,
    solver: str | None = None,
    time_limit: float | None = None,
    work_limit: int | None = None,
) -> np.ndarray | None:
    """The argument checks of :func:`plan_path` that need no planning.

    A caller that must refuse a bad request before it queues the plan (the planner node) calls
    this first with what it has: ``weights`` and ``reference_features`` are checked only when
    given, against ``num_features`` (``d``).

    Returns:
        ``weights`` as a finite ``(K, d)`` float64 array (``None`` if not given).
    Raises:
        ValueError: naming ``mode``, ``baseline``, ``solver``, ``time_limit``, ``work_limit``,
            ``weights`` or ``reference_features``.
    """
    parse(PlanMode, mode, "mode")
    parse(Baseline, baseline, "baseline")
    if solver is not None:
        check_choice(solver, "solver", SOLVERS[mode])
    if time_limit is not None and (isinstance(time_limit, bool) or not isinstance(time_limit, (int, float))
                                   or not time_limit > 0):
        raise ValueError(f"time_limit: expected seconds > 0 or None, got {time_limit!r}")
    check_work_limit(work_limit, solver)
    if weights is None or num_features is None:
        return None
    w = check_weights(weights, num_features)
    if mode == PlanMode.LITERAL and len(w) != 1:
        raise ValueError(f"weights: literal mode takes exactly one weight vector (1, d), got {w.shape}")
    check_reference(reference_features, num_features)
    return w


def plan_work(num_samples: int, horizon: int, height: int, width: int) -> int:
    """``K x (T + 1) x H x W``: the size of the largest table a plan builds (the log_z baseline's
    and the trajectory solver's per-sample value tables), and the order of its time and memory."""
    return int(num_samples) * (int(horizon) + 1) * int(height) * int(width)


def check_plan_size(num_samples: int, horizon: int, height: int, width: int, max_work: int) -> None:
    """Refuse a plan whose :func:`plan_work` exceeds ``max_work`` before any work starts.

    Raises:
        ValueError: naming ``weights`` (the samples are what a request most easily inflates).
    """
    work = plan_work(num_samples, horizon, height, width)
    if work > max_work:
        raise ValueError(f"weights: {num_samples} samples x horizon {horizon} x {height}x{width} map = {work:.3g} "
                         f"exceeds max_plan_work={max_work:.3g}")


def check_features(features: np.ndarray) -> np.ndarray:
    f = np.asarray(features, dtype=np.float64)
    if f.ndim != 3 or min(f.shape) < 1:
        raise ValueError(f"features: expected shape (H, W, d) with every dimension >= 1, got {f.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError("features: contains NaN or infinite values")
    return check_magnitude("features", f, MAX_ABS_FEATURE)
