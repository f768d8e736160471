"""The trajectory solver's stopping rules (docs/spec.md sections 4 and 8): a wall-clock
``time_limit`` and a deterministic ``work_limit`` counted in label expansions, and the exception
that carries the best path found when one of them stops a plan.

A plan finishes under ``work_limit`` exactly when its total count of label expansions is at most
the limit, so where it stops depends on its inputs only, never on the machine; under a work limit
alone the clock is never read.
"""

from __future__ import annotations

import math
import time

import numpy as np

__all__ = ["OutOfTime", "Limits", "check_work_limit"]


class OutOfTime(Exception):
    """A limit stopped the plan; carries the best path found (state indices or ``None``), the
    best proven upper bound, the solver that was running, ``reason``: ``"time"`` (``time_limit``
    passed) or ``"work"`` (``work_limit`` spent, or the label search's memory budget reached
    where a work limit rules out the MILP fallback), and ``work``, the label expansions spent."""

    def __init__(self, states: np.ndarray | None, bound: float = math.inf, solver: str = "",
                 reason: str = "time", message: str = "", work: int = 0) -> None:
        super().__init__(message or f"{reason} limit reached")
        self.states, self.bound, self.solver, self.reason, self.work = states, bound, solver, reason, work


class Limits:
    """A plan's stopping rules: a ``time.monotonic()`` deadline and a count of label expansions.

    The clock is read only when a deadline was set, so a plan under ``work_limit`` alone is a
    function of its inputs. ``work`` is the count spent so far.
    """

    def __init__(self, time_limit: float | None = None, work_limit: int | None = None) -> None:
        self.deadline = math.inf if time_limit is None else time.monotonic() + time_limit
        self.work_limit, self.work = work_limit, 0

    def time_up(self) -> bool:
        return not math.isinf(self.deadline) and time.monotonic() > self.deadline

    def check_time(self) -> None:
        if self.time_up():
            raise OutOfTime(None, reason="time")

    def spend(self, units: int) -> None:
        """Count ``units`` expansions; raise once the total passes ``work_limit``."""
        self.work += units
        if self.work_limit is not None and self.work > self.work_limit:
            raise OutOfTime(None, reason="work", message=f"work limit reached after {self.work} label expansions")


def check_work_limit(work_limit: object, solver: str | None) -> int | None:
    """``work_limit`` as an int >= 1 or ``None``.

    Raises:
        ValueError: naming ``work_limit``: not an int >= 1 (bools refused), or given with
            ``solver="milp-highs"`` (HiGHS's running time has no deterministic bound).
    """
    if work_limit is None:
        return None
    if isinstance(work_limit, bool) or not isinstance(work_limit, (int, np.integer)) or work_limit < 1:
        raise ValueError(f"work_limit: expected an int >= 1 (label expansions) or None, got {work_limit!r}")
    if solver == "milp-highs":
        raise ValueError("work_limit: not supported by solver='milp-highs' (HiGHS's running time has no "
                         "deterministic bound); use solver=None or 'label-bb', or time_limit")
    return int(work_limit)
