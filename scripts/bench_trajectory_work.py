#!/usr/bin/env python3
"""Calibrate the trajectory planner's ``work_limit`` (label expansions) on paper-scale plans.

The problems are the experiment's own: for each condition and seed, the trial's MaxEnt-Z
posterior (``experiments._posterior``), its first ``factorial_samples`` draws, the test map and
the training reference features, and the factorial's trajectory plans (one per baseline of
``experiments.BASELINES``), as ``experiments._factorial_plans`` makes them. Each plan runs
capped at ``--cap`` seconds of wall time and at the largest ``--limits`` value of work; the label
expansions it spends are traced against the clock (wall and CPU), so one run gives, for every
``--limits`` value, the share of plans that finish within it (exactly: a plan finishes iff the
work it needs is within the limit) and the seconds each plan spends under it (its time when the
count first passes the limit, or its whole time if it finishes). The wall-clock cap is loose: a
time limit is checked between chunks, and one search step's merging and dominance pass on
millions of labels can run for seconds past it.

    .venv/bin/python scripts/bench_trajectory_work.py [--seeds 3] [--cap 15] [--limits 1e5 3e5 1e6 3e6]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from ird_core import planning, posterior
from ird_core.experiments import trials as experiments
from ird_core.planning import trajectory_solver as TS
from ird_core.worlds import lavaland

CONDITIONS = ("side_effects", "reward_hacking", "latent_raw", "latent_classifier")


class _Traced(TS.Limits):
    """The solver's limits, recording (work, wall seconds, CPU seconds) at every spend."""

    last: "_Traced | None" = None

    def __init__(self, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
        super().__init__(*args, **kwargs)
        self.trace: list[tuple[int, float, float]] = []
        _Traced.last = self

    def spend(self, units: int) -> None:
        self.trace.append((self.work + units, time.perf_counter(), time.process_time()))
        super().spend(units)


def run_plan(test, samples, base, reference, cap: float, cap_work: int) -> dict:  # type: ignore[no-untyped-def]
    """One factorial trajectory plan under the caps; its work, times and trace."""
    wall0, cpu0 = time.perf_counter(), time.process_time()
    try:
        planning.plan_path(test, samples, "trajectory", base, reference, time_limit=cap, work_limit=cap_work)
        finished = True
    except planning.PlanningTimeout:
        finished = False
    wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
    limits = _Traced.last
    assert limits is not None
    trace = np.array(limits.trace, dtype=float).reshape(-1, 3) - [0.0, wall0, cpu0]
    return {"base": base, "finished": finished, "work": limits.work, "wall": wall, "cpu": cpu, "trace": trace}


def under_limit(plan: dict, limit: float) -> tuple[bool, float, float]:
    """(finishes, wall s, CPU s) of ``plan`` under ``work_limit=limit``; NaN times when the
    capped run stopped on the time cap before reaching the limit."""
    if plan["finished"] and plan["work"] <= limit:
        return True, plan["wall"], plan["cpu"]
    trace = plan["trace"]
    passed = np.flatnonzero(trace[:, 0] > limit)
    if len(passed) == 0:
        return False, float("nan"), float("nan")
    return False, float(trace[passed[0], 1]), float(trace[passed[0], 2])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seeds", type=int, default=3, help="seeds per condition")
    parser.add_argument("--cap", type=float, default=15.0, help="wall seconds per uncapped plan")
    parser.add_argument("--limits", type=float, nargs="+", default=[1e5, 3e5, 1e6, 3e6])
    args = parser.parse_args()
    TS.Limits = _Traced  # type: ignore[misc]
    cap_work = int(max(args.limits))
    plans = []
    for condition in CONDITIONS:
        for seed in range(args.seeds):
            spec = experiments.TrialSpec(condition, seed)
            inst = experiments.trial_instance(spec)
            post = experiments._posterior(spec, inst, "maxent_z")
            test = lavaland.test_mdp(inst)
            reference = posterior.proxy_feature_expectations(inst) / (inst.train_horizon + 1)
            samples = post.samples[: spec.factorial_samples]
            for base in experiments.BASELINES:
                plan = run_plan(test, samples, base, reference, args.cap, cap_work)
                plans.append(plan)
                print(f"{condition:18s} {seed} {base:18s} {'done' if plan['finished'] else 'cap '} "
                      f"work {plan['work']:>10d}  wall {plan['wall']:6.2f} s  cpu {plan['cpu']:6.2f} s", flush=True)

    done = [p for p in plans if p["finished"]]
    work = np.array([p["work"] for p in done], dtype=float)
    wall = np.array([p["wall"] for p in done])
    cpu = np.array([p["cpu"] for p in done])
    quantiles = (0.25, 0.5, 0.75, 0.9, 1.0)
    print(f"\n{len(done)} of {len(plans)} plans finished within the caps ({args.cap:g} s, {cap_work:.3g} units)")
    print("quantile       " + "  ".join(f"{q:>9.2f}" for q in quantiles))
    print("work needed    " + "  ".join(f"{np.quantile(work, q):9.3g}" for q in quantiles))
    print("wall seconds   " + "  ".join(f"{np.quantile(wall, q):9.3g}" for q in quantiles))
    print("CPU seconds    " + "  ".join(f"{np.quantile(cpu, q):9.3g}" for q in quantiles))
    searched = work > 0
    if searched.any():
        print(f"units per wall second (plans that searched, total work / total time): "
              f"{work[searched].sum() / wall[searched].sum():.3g}; per CPU second "
              f"{work[searched].sum() / cpu[searched].sum():.3g}")
    print(f"\n{'work_limit':>10s}  {'finish':>12s}  {'mean wall s':>11s}  {'mean CPU s':>10s}")
    for limit in args.limits:
        rows = [under_limit(p, limit) for p in plans]
        finished = sum(r[0] for r in rows)
        known = [r for r in rows if np.isfinite(r[1])]
        note = "" if len(known) == len(rows) else f"  ({len(rows) - len(known)} plans hit the time cap first)"
        print(f"{limit:10.3g}  {finished:3d}/{len(rows):3d} {finished / len(rows):5.0%}  "
              f"{np.mean([r[1] for r in known]):11.3f}  {np.mean([r[2] for r in known]):10.3f}{note}")


if __name__ == "__main__":
    main()
