"""Rob's plan execution, free of ROS (the rob node is a thin shell around :class:`RobExecutor`).

Like nav2_simple_commander: the logic is plain Python, testable without DDS. Rob executes a
plan one cell per tick: tick ``k`` reports plan cell ``k`` (``step = k``, the start cell is step
0); the tick that reports the last cell (``step = T``) is the final one, with ``done = True``;
after that Rob idles (``tick()`` returns ``None``) until a new plan arrives. A new plan replaces
the current one at once and execution restarts at its first cell. :meth:`RobExecutor.stop` ends
the current plan where Rob is: it reports his current cell once more (``stopped = done = True``,
the same step and return; before the first tick, the start cell as step 0) and Rob idles.

Evaluation (docs/spec.md section 5) is ``ird_core.worlds.evaluation.evaluate_path`` of each
visited cell on the ground-truth terrain of the test map with the true per-terrain rewards
(:func:`ird_ros.jobs.ground_truth.evaluation_terrain`): ``true_return`` is the sum of the true
reward of every visited cell, the start included, so a finished plan of ``T + 1`` cells has the
same value as ``ird_core.worlds.evaluation.true_return``; ``touched_lava`` / ``reached_target``
are true once any visited cell is lava / a target (recognised by the class names). Rob's policy
for unknown terrain: a cell of unknown class, or of a terrain without a true reward, earns 0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ird_core.worlds.evaluation import evaluate_path
from ird_ros.jobs.ground_truth import evaluation_terrain

__all__ = ["UNKNOWN_TERRAIN", "RobStatusData", "RobExecutor"]

UNKNOWN_TERRAIN = "unknown"
"""``RobStatus.terrain`` of a cell whose class index has no name (``UNKNOWN_CLASS``)."""


@dataclass(frozen=True)
class RobStatusData:
    """One status report (the fields of ``ird_msgs/RobStatus``)."""

    row: int
    col: int
    terrain: str
    step: int
    horizon: int
    done: bool
    touched_lava: bool
    reached_target: bool
    true_return: float
    plan_label: str
    plan_stamp: Any
    stopped: bool = False


class RobExecutor:
    """Executes plans on the ground-truth test map; see the module docstring.

    Feed it the world (:meth:`set_terrain`, :meth:`set_rewards`) and plans (:meth:`set_plan`),
    then call :meth:`tick` at the execution rate. A plan received before the terrain and the
    rewards waits (``pending``) and starts once both are known. A terrain without an entry in
    the reward table (e.g. "unknown") earns 0. An empty reward table (a world file that gives no
    true rewards) is known too: Rob drives, and the return is NaN (not judged).
    """

    def __init__(self) -> None:
        self._labels: np.ndarray | None = None
        self._class_names: tuple[str, ...] = ()
        self._rewards: dict[str, float] | None = None  # None until the world says
        self._evaluation: tuple[np.ndarray, np.ndarray] | None = None  # (labels, reward) once ready
        self._cells: list[tuple[int, int]] | None = None
        self._stamp: Any = None
        self._label = ""
        self._index = 0
        self._done = True
        self._touched_lava = False
        self._reached_target = False
        self._return = 0.0

    # ------------------------------------------------------------------ inputs

    def set_terrain(self, classes: np.ndarray, class_names: Sequence[str]) -> None:
        """The ground-truth terrain: (H, W) class indices into ``class_names`` (255 = unknown)."""
        classes = np.asarray(classes)
        if classes.ndim != 2 or classes.size == 0:
            raise ValueError(f"classes: expected a non-empty (H, W) array, got shape {classes.shape}")
        self._labels = classes.copy()
        self._class_names = tuple(class_names)
        self._evaluation = None

    def set_rewards(self, terrain_names: Sequence[str], rewards: Sequence[float]) -> None:
        """The true reward per step on each terrain (by name)."""
        terrain_names, rewards = tuple(terrain_names), tuple(float(r) for r in rewards)
        if len(terrain_names) != len(rewards):
            raise ValueError(
                f"true_terrain_rewards: {len(rewards)} values for {len(terrain_names)} terrain_names"
            )
        if not all(math.isfinite(r) for r in rewards):
            raise ValueError("true_terrain_rewards: must be finite")
        self._rewards = dict(zip(terrain_names, rewards))
        self._evaluation = None

    @property
    def has_terrain(self) -> bool:
        return self._labels is not None

    @property
    def shape(self) -> tuple[int, int] | None:
        return None if self._labels is None else (int(self._labels.shape[0]), int(self._labels.shape[1]))

    def set_plan(self, cells: Sequence[tuple[int, int]], stamp: Any = None, label: str = "") -> None:
        """Replace the current plan; execution restarts at ``cells[0]`` on the next tick.

        Raises ``ValueError`` (and keeps the current plan) if a cell is off the known map.
        """
        path = [(int(r), int(c)) for r, c in cells]
        if not path:
            raise ValueError("plan: must contain at least one cell")
        if self._labels is not None:
            height, width = self._labels.shape
            for i, (r, c) in enumerate(path):
                if not (0 <= r < height and 0 <= c < width):
                    raise ValueError(f"plan: cell {i} ({r}, {c}) is off the {height}x{width} map")
        self._cells = path
        self._stamp = stamp
        self._label = str(label)
        self._index = 0
        self._done = False
        self._touched_lava = False
        self._reached_target = False
        self._return = 0.0

    def set_label(self, label: str) -> None:
        """Label of the current plan (plan info may arrive after the plan)."""
        self._label = str(label)

    @property
    def plan_stamp(self) -> Any:
        return self._stamp

    @property
    def active(self) -> bool:
        """A plan is being executed (it has cells left to report)."""
        return self._cells is not None and not self._done

    @property
    def ready(self) -> bool:
        """The terrain and the true rewards are known."""
        return self._labels is not None and self._rewards is not None

    @property
    def pending(self) -> bool:
        """A plan waits for the terrain or the true rewards."""
        return self.active and not self.ready

    # ------------------------------------------------------------------ execution

    def stop(self) -> RobStatusData | None:
        """End the current plan where Rob is and report it (``stopped``); ``None`` when idle or
        when the plan still waits for the terrain or rewards (then it is dropped unreported)."""
        if not self.active:
            return None
        if not self.ready:
            self._done = True
            return None
        if self._index == 0:  # stopped before the first move: Rob stands on the start cell
            status = self.tick()
            assert status is not None
        else:
            status = self._report(self._index - 1)
        self._done = True
        return RobStatusData(**{**status.__dict__, "done": True, "stopped": True})

    def _report(self, index: int) -> RobStatusData:
        """The status of plan cell ``index`` as already reported (no new evaluation)."""
        assert self._cells is not None
        row, col = self._cells[index]
        return RobStatusData(row=row, col=col, terrain=self.terrain_at(row, col), step=index,
                             horizon=len(self._cells) - 1, done=self._done, touched_lava=self._touched_lava,
                             reached_target=self._reached_target, true_return=self._return,
                             plan_label=self._label, plan_stamp=self._stamp)

    def terrain_at(self, row: int, col: int) -> str:
        assert self._labels is not None
        value = int(self._labels[row, col])
        if 0 <= value < len(self._class_names):
            return self._class_names[value]
        return UNKNOWN_TERRAIN

    def _evaluation_terrain(self) -> tuple[np.ndarray, np.ndarray]:
        """The ground truth as ``evaluate_path``'s labels and reward per label (Rob's policy:
        a terrain without a true reward earns 0)."""
        if self._evaluation is None:
            assert self._labels is not None and self._rewards is not None
            self._evaluation = evaluation_terrain(self._labels, self._class_names, self._rewards,
                                                  unrewarded_unknown=False)
        return self._evaluation

    def tick(self) -> RobStatusData | None:
        """Move to the next cell of the plan and report it; ``None`` when idle or waiting."""
        if not self.active or not self.ready:
            return None
        assert self._cells is not None
        height, width = self._labels.shape
        row, col = self._cells[self._index]
        if not (0 <= row < height and 0 <= col < width):  # the terrain changed under the plan
            self._done = True
            raise ValueError(f"plan: cell {self._index} ({row}, {col}) is off the {height}x{width} map")
        labels, reward = self._evaluation_terrain()
        outcome = evaluate_path(labels, [(row, col)], reward)  # unknown cells add 0 (Rob's policy)
        self._touched_lava |= outcome.touched_lava
        self._reached_target |= outcome.reached_target
        self._return += outcome.true_return if self._rewards else math.nan
        step = self._index
        horizon = len(self._cells) - 1
        self._done = step >= horizon
        self._index += 1
        return RobStatusData(
            row=row,
            col=col,
            terrain=self.terrain_at(row, col),
            step=step,
            horizon=horizon,
            done=self._done,
            touched_lava=self._touched_lava,
            reached_target=self._reached_target,
            true_return=self._return,
            plan_label=self._label,
            plan_stamp=self._stamp,
        )
