"""The experiments through the graph (``run_experiments.py --via-ros``): the ROS stack against the library.

Starts world, inference and planner with ``GraphLauncher`` (private domain, the world's
size/horizon/obs_dim and the sampler settings of this run), then per trial i:

1. ``/world/generate`` (condition i and Z method i, cycling over the run's lists; instance seed
   ``trial_seed(seed, i)``), waits for the matching latched world messages and checks them against
   ``lavaland.make_instance`` (docs/spec.md section 5);
2. ``/ird/infer`` on the world's training map and proxy (docs/spec.md section 3);
3. ``/ird/plan`` for the literal plan (proxy test features, proxy weights) and the main IRD plan
   (per_step / training_features on the node's posterior samples; docs/spec.md section 4), each
   compared cell by cell with ``planning.plan_path`` on the same samples and on the float32
   features the messages carry. Outcomes (lava, target, true return) come from the direct instance.

Any disagreement (or failed call) makes the exit code 1. Printed for information only: whether the
outcome equals that of the direct ``run_trial`` of the same seed, whose posterior comes from the same
library with the experiment's own seed derivation and sampler settings (so its samples, unlike the
plans above, are not expected to be identical).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from ird_core import experiments as ex
from ird_core import planning, posterior
from ird_core.mdp import GridMDP
from ird_core.vocabulary import Baseline
from ird_core.worlds import evaluation, lavaland
from ird_core.worlds.lavaland import LavalandInstance

__all__ = ["run_via_ros"]

#: Trials when ``--trials`` is not given (each one starts a sampler in the graph).
DEFAULT_TRIALS = 3


@dataclass(frozen=True)
class TrialCase:
    """One trial: its condition, instance seed and Z method, and the instance built directly."""

    condition: str
    seed: int
    method: str
    inst: LavalandInstance


@dataclass(frozen=True)
class PlanCheck:
    """One plan asked of ``/ird/plan`` and recomputed with ``planning.plan_path`` on ``mdp``."""

    label: str
    grid: Any
    weights: np.ndarray
    mode: str
    baseline: str
    mdp: GridMDP


def write_params(args: argparse.Namespace, folder: Path) -> Path:
    """The graph's parameter file with this run's world size and sampler settings."""
    from ird_ros.launch import default_params_file

    params = yaml.safe_load(Path(default_params_file()).read_text())
    params["world"]["ros__parameters"].update(height=args.size, width=args.size, horizon=args.horizon,
                                              obs_dim=args.obs_dim)
    inference = params.setdefault("inference", {}).setdefault("ros__parameters", {})
    inference.update(num_chains=args.num_chains, warmup=args.warmup, thin=args.thin)
    path = folder / "graph.yaml"
    path.write_text(yaml.safe_dump(params))
    return path


def trial_case(args: argparse.Namespace, settings: dict, index: int) -> TrialCase:
    condition = args.conditions[index % len(args.conditions)]
    seed = ex.trial_seed(args.seed, index)
    method = settings["z_methods"][index % len(settings["z_methods"])]
    inst = lavaland.make_instance(condition, seed, size=args.size, horizon=args.horizon, obs_dim=args.obs_dim)
    return TrialCase(condition, seed, method, inst)


def world_agrees(world: Any, inst: LavalandInstance) -> bool:
    """Whether the published maps, proxy and test start are the instance's (float32 on the wire)."""
    from ird_ros import conversions as conv

    train = conv.feature_grid_from_msg(world.train).features.astype(np.float64)
    test = conv.feature_grid_from_msg(world.test).features.astype(np.float64)
    return bool(np.allclose(train, inst.train_features, atol=1e-5, rtol=1e-6)
                and np.allclose(test, inst.test_features, atol=1e-5, rtol=1e-6)
                and np.allclose(world.proxy.weights, inst.proxy_weights)
                and (world.proxy.test_start_row, world.proxy.test_start_col) == inst.test_start)


def infer_request_of(args: argparse.Namespace, case: TrialCase, world: Any) -> Any:
    """``/ird/infer`` on the published training map with the instance's start, horizon and proxy."""
    from ird_ros.client import infer_request

    inst = case.inst
    return infer_request(world.train, inst.train_start, inst.train_horizon, inst.proxy_weights,
                         beta=args.beta, method=case.method, num_samples=args.num_samples, seed=case.seed,
                         prior_sigma=args.prior_sigma,
                         proxy_map=world.proxy_train if inst.classifier is not None else None)


def plan_checks(case: TrialCase, world: Any, samples: np.ndarray) -> list[PlanCheck]:
    """The literal plan on the proxy's test features and the main IRD plan on the node's samples."""
    from ird_ros import conversions as conv

    inst = case.inst
    test = conv.feature_grid_from_msg(world.test).features.astype(np.float64)
    proxy_test = inst.proxy_test_features.astype(np.float32).astype(np.float64)
    return [
        PlanCheck("literal", conv.feature_grid_to_msg(inst.proxy_test_features, inst.proxy_feature_names),
                  inst.proxy_weights[None], "literal", "none", GridMDP(proxy_test, inst.test_start, inst.test_horizon)),
        PlanCheck(f"ird_{case.method}", world.test, samples, ex.MAIN_GRANULARITY, ex.MAIN_BASELINE,
                  GridMDP(test, inst.test_start, inst.test_horizon)),
    ]


def compare_plan(ird: Any, case: TrialCase, check: PlanCheck, reference: np.ndarray, world_ok: bool,
                 r_hat: float, direct: ex.TrialResult) -> int:
    """Ask the node for ``check``'s plan, compare it with the library's and print the line; 1 if they
    (or the world) disagree or the call fails, else 0."""
    from ird_ros.client import plan_request

    inst, label = case.inst, check.label
    uses_reference = check.baseline == Baseline.TRAINING_FEATURES
    request = plan_request(inst.test_start, inst.test_horizon, check.mode, check.baseline, weights=check.weights,
                           reference_features=reference if uses_reference else (), grid=check.grid, label=label)
    result = ird.plan(request, timeout=300)
    if not result.ok:
        print(f"[via-ros] /ird/plan ({label}) failed: {result.message}", file=sys.stderr)
        return 1
    ros_cells = result.value.cells
    library = planning.plan_path(check.mdp, check.weights, check.mode, check.baseline,
                                 reference if uses_reference else None)
    same = ros_cells == tuple(library.cells)
    lava = evaluation.touches_lava(inst.test_labels, ros_cells)
    target = evaluation.reaches_target(inst.test_labels, ros_cells)
    true_return = evaluation.true_return(inst.test_labels, ros_cells)
    direct_same = (direct.touched_lava, direct.reached_target) == (lava, target)
    print(f"[via-ros] {case.condition} seed {case.seed} {label}: world {'agrees' if world_ok else 'DIFFERS'}, "
          f"cells {'agree' if same else 'DISAGREE'} (lava {lava}, target {target}, "
          f"return {true_return:.2f}); posterior r_hat {r_hat:.3f}; "
          f"direct run_trial outcome {'same' if direct_same else 'differs'} "
          f"(lava {direct.touched_lava}, target {direct.reached_target})")
    return 0 if (same and world_ok) else 1


def compare_trial(ird: Any, args: argparse.Namespace, settings: dict, index: int) -> int:
    """Trial ``index`` through the graph against the library; the number of disagreements."""
    case = trial_case(args, settings, index)
    generated = ird.generate_world(case.condition, case.seed, timeout=120)
    if not generated.ok:
        print(f"[via-ros] /world/generate failed: {generated.message}", file=sys.stderr)
        return 1
    world = ird.world(condition=case.condition, seed=case.seed, timeout=60)
    world_ok = world_agrees(world, case.inst)
    inferred = ird.infer(infer_request_of(args, case, world), timeout=600)
    if not inferred.ok:
        print(f"[via-ros] /ird/infer failed: {inferred.message}", file=sys.stderr)
        return 1
    node_posterior = inferred.unwrap()
    reference = posterior.proxy_feature_expectations(case.inst) / (case.inst.train_horizon + 1)
    spec = ex.TrialSpec(case.condition, case.seed, **dict(settings, z_methods=(case.method,), factorial=False))
    direct = {r.planner: r for r in ex.run_trial(spec)}
    return sum(compare_plan(ird, case, check, reference, world_ok, node_posterior.r_hat_max, direct[check.label])
               for check in plan_checks(case, world, node_posterior.samples))


def run_via_ros(args: argparse.Namespace, settings: dict) -> int:
    """Run ``args.trials`` trials (default 3) through the graph and compare them with direct library
    calls (see the module docstring); 0 if everything agrees, else 1."""
    from ird_ros.client import IrdClient
    from ird_ros.graph import names
    from ird_ros.graph.domains import domain_banner
    from ird_ros.launch import GraphLauncher

    trials = DEFAULT_TRIALS if args.trials is None else args.trials
    disagreements = 0
    with tempfile.TemporaryDirectory(prefix="ird_via_ros_") as tmp:
        with GraphLauncher(nodes=["world", "inference", "planner"], params=write_params(args, Path(tmp)),
                           private_domain=True, output="quiet") as graph:
            print("\n".join(f"[via-ros] {line}" for line in domain_banner(graph.domain_id).splitlines()),
                  flush=True)
            graph.wait_ready(120.0)
            with IrdClient(graph.domain_id, node_name="run_experiments_via_ros") as ird:
                ird.wait_ready(60, services=(names.SRV_GENERATE, names.SRV_INFER, names.SRV_PLAN))
                for index in range(trials):
                    disagreements += compare_trial(ird, args, settings, index)
    print(f"[via-ros] {'all agree' if disagreements == 0 else f'{disagreements} disagreement(s)'}")
    return 0 if disagreements == 0 else 1
