"""The mission of ``launch_graph.py --mission N``: Rob's navigation goals, one world per seed.

After the graph is ready, for each seed 0..N-1: ``/world/generate`` makes the world of that seed
(the params file's condition; with ``--world FILE`` the file's world stays and the seed seeds the
sampler only), then two goals go to the navigator's action ``/ird/navigate``, each driven by Rob
to the end: the literal plan (the proxy taken at its word) and the IRD plan (a fresh MaxEnt-Z
posterior, per-step risk-averse plan). One line is printed per goal::

    [mission] seed 0 literal: SUCCEEDED, lava True, target False, true return -90.50, 13 cells
    [mission] seed 0 ird: SUCCEEDED, lava False, target True, true return 8.20, 13 cells

A recorder (``--record``) gets every drive (``/plan``, ``/rob/status``, ``/odom``), so
``analyze_bag.py`` reads the bag's missions. The client is ``ird_ros.client.IrdClient``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

from ird_ros.client import IrdClient
from ird_ros.client.navigation import NavigationGoal, NavigationResult, NavigationStatus

__all__ = ["mission_goals", "result_line", "run_mission", "MISSION_TIMEOUT"]

MISSION_TIMEOUT = 600.0
"""Seconds for one goal (inference, plan and Rob's drive)."""


def mission_goals(seed: int) -> list[NavigationGoal]:
    """The literal goal, then the IRD goal (MaxEnt-Z posterior, per-step plan) for ``seed``; each infers
    on the world's request itself, so a goal never plans on the posterior of another world."""
    return [NavigationGoal(method="maxent_z", mode="literal", seed=seed, label="literal"),
            NavigationGoal(method="maxent_z", mode="per_step", seed=seed, label="ird")]


def _flag(value: bool | None) -> str:
    return "-" if value is None else str(value)


def result_line(seed: int, label: str, result: NavigationResult) -> str:
    """One printed line per goal: status, then Rob's lava, target and true return (or the message)."""
    head = f"[mission] seed {seed} {label}: {result.status.name}"
    if result.status is not NavigationStatus.SUCCEEDED:
        return f"{head} ({result.message})"
    ret = "-" if result.true_return is None else f"{result.true_return:.2f}"
    return (f"{head}, lava {_flag(result.touched_lava)}, target {_flag(result.reached_target)}, "
            f"true return {ret}, {len(result.cells)} cells")


def run_mission(domain_id: int, seeds: Sequence[int], *, generate: bool = True,
                echo: Callable[[str], Any] = print) -> int:
    """Every seed's goals through the graph in ``domain_id``; 0 if every goal succeeded, else 1.

    ``generate``: ask ``/world/generate`` for each seed's world first (False: keep the world)."""
    failed = 0
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
                failed += result.status is not NavigationStatus.SUCCEEDED
    echo(f"[mission] {len(seeds)} seed(s), {'every goal succeeded' if not failed else f'{failed} failed'}")
    return 0 if not failed else 1
