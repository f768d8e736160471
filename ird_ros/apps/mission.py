"""The mission of ``launch_graph.py --mission N``: Rob's navigation goals, one world per seed.

After the graph is ready, for each seed 0..N-1: ``/world/generate`` makes the world of that seed
(the params file's condition; with ``--world FILE`` the file's world stays and the seed seeds the
sampler only), then two goals go to the navigator's action ``/ird/navigate``, each driven by Rob
to the end: the literal plan (the proxy taken at its word) and the IRD plan (a fresh MaxEnt-Z
posterior, per-step risk-averse plan). One line is printed per goal, saying what Rob did (touched
lava, reached the target, stayed put: a goal "succeeds" once its plan ran to its end, even a plan
that keeps Rob at his start), and one for the whole mission::

    [mission] seed 0 literal: SUCCEEDED: touched lava (lava True, target False, true return -90.50, 13 cells)
    [mission] seed 0 ird: SUCCEEDED: reached the target (lava False, target True, true return 8.20, 13 cells)
    [mission] 1 seed(s): every goal ran to its end: 1 reached the target, 1 touched lava

A recorder (``--record``) gets every drive (``/plan``, ``/rob/status``, ``/odom``), so
``analyze_bag.py`` reads the bag's missions. The client is ``ird_ros.client.IrdClient``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from ird_ros.bags.missions import drive_outcome
from ird_ros.client import IrdClient
from ird_ros.client.navigation import NavigationGoal, NavigationResult, NavigationStatus

__all__ = ["mission_goals", "result_line", "goal_outcome", "summary_line", "run_mission", "MISSION_TIMEOUT"]

MISSION_TIMEOUT = 600.0
"""Seconds for one goal (inference, plan and Rob's drive)."""


def mission_goals(seed: int) -> list[NavigationGoal]:
    """The literal goal, then the IRD goal (MaxEnt-Z posterior, per-step plan) for ``seed``; each infers
    on the world's request itself, so a goal never plans on the posterior of another world."""
    return [NavigationGoal(method="maxent_z", mode="literal", seed=seed, label="literal"),
            NavigationGoal(method="maxent_z", mode="per_step", seed=seed, label="ird")]


def _flag(value: bool | None) -> str:
    return "-" if value is None else str(value)


def goal_outcome(result: NavigationResult) -> str:
    """What Rob did on a goal (``ird_ros.bags.missions.drive_outcome`` of its cells), or how the
    goal ended when it did not run to its end (``canceled``, ``aborted``, ...)."""
    if result.status is not NavigationStatus.SUCCEEDED:
        return result.status.name.lower()
    cells = [tuple(int(v) for v in c) for c in result.cells]
    moves = sum(1 for a, b in zip(cells, cells[1:]) if a != b)
    return drive_outcome(touched_lava=result.touched_lava, reached_target=result.reached_target, moves=moves)


def result_line(seed: int, label: str, result: NavigationResult) -> str:
    """One printed line per goal: status and what Rob did, then his lava, target and true return
    (or the message)."""
    head = f"[mission] seed {seed} {label}: {result.status.name}"
    if result.status is not NavigationStatus.SUCCEEDED:
        return f"{head} ({result.message})"
    ret = "-" if result.true_return is None else f"{result.true_return:.2f}"
    return (f"{head}: {goal_outcome(result)} (lava {_flag(result.touched_lava)}, target "
            f"{_flag(result.reached_target)}, true return {ret}, {len(result.cells)} cells)")


def summary_line(seeds: int, outcomes: Sequence[str], failed: int) -> str:
    """The mission's last line: how many goals ran to their end and what Rob did on them, by count."""
    counts: dict[str, int] = {}
    for outcome in outcomes:
        counts[outcome] = counts.get(outcome, 0) + 1
    did = ", ".join(f"{n} {outcome}" for outcome, n in counts.items())
    head = f"[mission] {seeds} seed(s): "
    return head + (f"every goal ran to its end: {did}" if not failed else f"{failed} failed; {did}")


def run_mission(domain_id: int, seeds: Sequence[int], *, generate: bool = True,
                echo: Callable[[str], Any] = print) -> int:
    """Every seed's goals through the graph in ``domain_id``; 0 if every goal succeeded, else 1.

    ``generate``: ask ``/world/generate`` for each seed's world first (False: keep the world)."""
    failed = 0
    outcomes: list[str] = []
    with IrdClient(domain_id, node_name="ird_mission") as ird:
        for seed in seeds:
            if generate:
                generated = ird.generate_world("", seed, timeout=MISSION_TIMEOUT)
                if not generated.ok:
                    echo(f"[mission] seed {seed}: /world/generate failed: {generated.message}")
                    failed += 1
                    continue
                ird.world(seed=seed, timeout=MISSION_TIMEOUT)  # its maps and proxy are out
            for goal in mission_goals(seed):
                result = ird.navigate(goal, timeout=MISSION_TIMEOUT)
                echo(result_line(seed, goal.label, result))
                outcomes.append(goal_outcome(result))
                failed += result.status is not NavigationStatus.SUCCEEDED
    echo(summary_line(len(seeds), outcomes, failed))
    return 0 if not failed else 1
