"""The client side of the ``NavigateIrd`` action (``/ird/navigate``): typed goals, feedback, results.

``IrdClient.navigate(goal)`` / ``IrdClient.navigate_async(goal)`` use this module (the action
client logic lives here, so ``ird_client`` stays short)::

    result = ird.navigate(NavigationGoal(method="maxent_z", mode="per_step"), on_feedback=print)
    if result.status is NavigationStatus.SUCCEEDED:
        print(result.cells, result.true_return)

Invariants:

- Every goal ends in a :class:`NavigationResult`, never an exception from the server's side:
  SUCCEEDED, CANCELED (the cells driven until Rob stopped), ABORTED (the message says why) or
  REJECTED. REJECTED comes from the navigator (a bad field: ``field`` names it and ``message``
  starts with it), from the action protocol (a goal is already active: the navigator runs one
  goal at a time; ``field`` is ""), or from this module before sending (a value that does not fit
  the message's type, e.g. a negative ``seed``; ``field`` names it).
- ``touched_lava``, ``reached_target`` and ``true_return`` are None when the navigator had no
  ground truth to judge the driven cells (``true_return`` also when the world gives no true rewards).
- Waits spin the client's node through the ``spin_until`` it is given (no sleeps); a wait that
  runs out raises the client's timeout error.

rclpy and ``ird_msgs`` are imported when an action client is made, not when this module is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from typing import Any, Callable, Protocol

import numpy as np

from ird_ros.graph import names
from ird_ros.jobs.navigation import CURRENT_POSTERIOR, NavigationStatus, Stage

__all__ = [
    "NavigationGoal",
    "NavigationFeedback",
    "NavigationResult",
    "NavigationStatus",
    "NavigationHandle",
    "Stage",
    "CURRENT_POSTERIOR",
    "make_action_client",
    "send_goal",
]

BUSY_MESSAGE = (f"rejected by {names.ACTION_NAVIGATE}: a goal is active (the navigator runs one goal at a time; "
                f"cancel it or wait for its result)")

_INT32 = (-(2**31), 2**31 - 1)
_UINT32 = (0, 2**32 - 1)


class Spinner(Protocol):
    """``IrdClient.spin_until``: spin until ``condition()``; raise a timeout error naming ``what``."""

    def __call__(self, condition: Callable[[], bool], *, timeout: float, what: str) -> None: ...


@dataclass(frozen=True)
class NavigationGoal:
    """A navigation goal (``NavigateIrd.Goal``; the navigator validates every field).

    ``method`` "" = use the current ``/ird/posterior``; ``beta`` / ``num_samples`` 0 = the
    navigator's defaults; ``mode`` a PlanMode value (``literal``, ``per_step``, ``trajectory``);
    ``risk_measure`` "" = the planner's ``risk`` parameter, else ``min``, ``cvar`` or ``mean_sd`` with
    ``risk_level`` (alpha, lambda; 0 with "" = the planner's ``risk_level``); ``queries`` designer
    questions asked before driving.
    """

    method: str = "maxent_z"
    beta: float = 0.0
    num_samples: int = 0
    seed: int = 0
    mode: str = "per_step"
    baseline: str = "training_features"
    risk_measure: str = ""
    risk_level: float = 0.0
    queries: int = 0
    label: str = ""

    def to_msg(self) -> Any:
        """The ``NavigateIrd.Goal``; ``ValueError`` naming a field whose value the message cannot hold."""
        from ird_msgs.action import NavigateIrd

        for name, (low, high) in (("num_samples", _INT32), ("seed", _UINT32), ("queries", _INT32)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not low <= value <= high:
                raise ValueError(f"{name}: expected an integer in [{low}, {high}], got {value!r}")
        for name in ("beta", "risk_level"):
            if isinstance(getattr(self, name), bool) or not isinstance(getattr(self, name), (int, float)):
                raise ValueError(f"{name}: expected a number, got {getattr(self, name)!r}")
        for name in ("method", "mode", "baseline", "risk_measure", "label"):
            if not isinstance(getattr(self, name), str):
                raise ValueError(f"{name}: expected a string, got {getattr(self, name)!r}")
        return NavigateIrd.Goal(
            method=self.method, beta=float(self.beta), num_samples=int(self.num_samples), seed=int(self.seed),
            mode=self.mode, baseline=self.baseline, risk_measure=self.risk_measure,
            risk_level=float(self.risk_level), queries=int(self.queries), label=self.label)


@dataclass(frozen=True)
class NavigationFeedback:
    """One feedback message: the stage (a :class:`Stage` value), Rob's cell (None before he drives),
    the fraction of the plan driven and a one-line summary of the current posterior."""

    stage: str
    pose_cell: tuple[int, int] | None
    progress: float
    posterior_summary: str

    @classmethod
    def from_msg(cls, msg: Any) -> "NavigationFeedback":
        cell = (int(msg.row), int(msg.col)) if msg.has_pose else None
        return cls(str(msg.stage), cell, float(msg.progress), str(msg.posterior_summary))


@dataclass(frozen=True)
class NavigationResult:
    """How a goal ended (see the module docstring); ``cells`` (n, 2) int64, start cell first."""

    status: NavigationStatus
    message: str
    field: str
    cells: np.ndarray = dataclass_field(compare=False)
    touched_lava: bool | None
    reached_target: bool | None
    true_return: float | None
    objective: float

    @classmethod
    def rejected(cls, message: str, field: str = "") -> "NavigationResult":
        return cls(NavigationStatus.REJECTED, message, field, np.zeros((0, 2), dtype=np.int64), None, None, None,
                   math.nan)

    @classmethod
    def from_msg(cls, msg: Any, protocol_status: int) -> "NavigationResult":
        """The result message; an empty ``status`` (the server failed) falls back on the protocol's."""
        from action_msgs.msg import GoalStatus

        try:
            status = NavigationStatus(msg.status)
        except ValueError:
            status = NavigationStatus.CANCELED if protocol_status == GoalStatus.STATUS_CANCELED else (
                NavigationStatus.SUCCEEDED if protocol_status == GoalStatus.STATUS_SUCCEEDED
                else NavigationStatus.ABORTED)
        cells = np.array([[int(r), int(c)] for r, c in zip(msg.rows, msg.cols)], dtype=np.int64).reshape(-1, 2)
        judged = bool(msg.judged)
        true_return = float(msg.true_return) if judged and math.isfinite(msg.true_return) else None
        return cls(status, str(msg.message) or f"goal {status}", str(msg.field), cells,
                   bool(msg.touched_lava) if judged else None, bool(msg.reached_target) if judged else None,
                   true_return, float(msg.objective))


def make_action_client(node: Any) -> Any:
    """An ``rclpy.action.ActionClient`` of ``/ird/navigate`` on ``node``, its goal, cancel and result
    services with the navigator's deep QoS (``ird_ros.runtime.guard.action_qos``): with rclpy's
    default depth of 10 a burst of answers overflows the client's response readers, which receive
    the answers to every client of the action."""
    from rclpy.action import ActionClient

    from ird_msgs.action import NavigateIrd
    from ird_ros.runtime.guard import action_qos

    return ActionClient(node, NavigateIrd, names.ACTION_NAVIGATE, **action_qos())


class NavigationHandle:
    """A goal sent: ``done()``, ``cancel()``, ``result(timeout)`` (each wait spins the client)."""

    def __init__(self, spin_until: Spinner, send_future: Any = None, *,
                 rejected: NavigationResult | None = None) -> None:
        self._spin_until = spin_until
        self._send_future = send_future
        self._goal_handle: Any = None
        self._result_future: Any = None
        self._result = rejected

    def _sent(self) -> bool:
        """Whether the server answered the goal; on its answer, ask for the result. Polled from the
        spin conditions, not a done callback: a callback may be scheduled on a wait's temporary
        executor that is gone before it runs."""
        if self._result is None and self._goal_handle is None and self._send_future.done():
            handle = self._send_future.result()
            if handle is None or not handle.accepted:
                self._result = NavigationResult.rejected(BUSY_MESSAGE)
            else:
                self._goal_handle = handle
                self._result_future = handle.get_result_async()
        return self._result is not None or self._goal_handle is not None

    def done(self) -> bool:
        """Whether the goal has ended (its result is in)."""
        if not self._sent():
            return False
        if self._result is not None:
            return True
        return self._result_future is not None and bool(self._result_future.done())

    def cancel(self, timeout: float = 30.0) -> None:
        """Ask the navigator to cancel the goal (Rob stops where he is) and wait for its answer to the
        cancel request; the goal's result (CANCELED, or how it ended first) follows in :meth:`result`."""
        self._spin_until(self._sent, timeout=timeout, what=f"the answer of {names.ACTION_NAVIGATE} to the goal")
        if self._goal_handle is None or self.done():
            return
        future = self._goal_handle.cancel_goal_async()
        self._spin_until(future.done, timeout=timeout, what=f"the answer of {names.ACTION_NAVIGATE} to the cancel")

    def result(self, timeout: float = 600.0) -> NavigationResult:
        """The goal's result, waiting up to ``timeout`` s for it."""
        self._spin_until(self.done, timeout=timeout, what=f"the result of {names.ACTION_NAVIGATE}")
        if self._result is None:
            response = self._result_future.result()
            self._result = NavigationResult.from_msg(response.result, int(response.status))
        return self._result


def send_goal(action_client: Any, spin_until: Spinner, goal: NavigationGoal,
              on_feedback: Callable[[NavigationFeedback], None] | None = None) -> NavigationHandle:
    """Send ``goal`` through ``action_client`` (its server discovered); a goal whose values the message
    cannot hold is REJECTED here, naming the field, without being sent."""
    try:
        msg = goal.to_msg()
    except ValueError as exc:
        return NavigationHandle(spin_until, rejected=NavigationResult.rejected(str(exc), str(exc).split(":", 1)[0]))
    callback = None
    if on_feedback is not None:
        def callback(feedback_msg: Any) -> None:
            on_feedback(NavigationFeedback.from_msg(feedback_msg.feedback))
    return NavigationHandle(spin_until, action_client.send_goal_async(msg, feedback_callback=callback))
