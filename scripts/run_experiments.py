#!/usr/bin/env python3
r"""Run the Lavaland experiments (IRD paper Figure 4 and the appendix factorial).

    .venv/bin/python scripts/run_experiments.py [--quick] [--trials N] [--out DIR] [--seed S]
        [--workers W] [--scheduler tcp://HOST:PORT] [--via-ros] [--conditions C ...]
        [--size N] [--horizon T] [--obs-dim D] [--num-samples K] [--beta B] ...
        [--factorial-samples N] [--traj-work-limit N] [--z-sampler METHOD FIELD=VALUE ...]

With no flags: the paper's scale, 15x15 maps, T = 30, 50-d observations, 100 paired trials per
condition, both Z-approximations, 1000 Sample-Z proxies and the full factorial. --quick: the small setting for a fast
look (8x8, T = 12, 10-d, 64 samples from 4 chains, warm-up 50, thin 4, at most 16 leapfrog
steps, 100 Sample-Z proxies, factorial on 10 samples; ird_core.experiments.QUICK); flags given
with --quick override it. --z-sampler sample_z num_chains=8 warmup=200 gives one
Z-approximation its own sampler settings (the numeric fields of
ird_core.experiments.SamplerSettings; the others keep that method's defaults).

Every condition x planner gets N seeded trials (trial i uses instance seed S + i, paired over
conditions). One trial = one Lavaland instance: the literal plan, the oracle plan (optimal
under the true reward), and per Z-approximation ONE posterior whose samples feed every IRD
planner (ird_core.experiments.run_trial): the main planner on all samples, the factorial's
per-step and trajectory plans on the same first --factorial-samples samples. Locally the
trials run in a process pool (W workers, default = cores); with --scheduler on a Dask
distributed cluster (same trial function; both in scripts/_parallel.py, tqdm progress on
stderr). A trial is a pure function of its spec, so the numbers do not depend on W, the
scheduler or completion order: a Dask run reproduces a local run bit for bit.

A local Dask cluster (three shells in the checkout; the workers import ird_core from it):

    .venv/bin/dask scheduler --host 127.0.0.1 --port 8786 --no-dashboard
    PYTHONPATH=$PWD OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
        .venv/bin/dask worker tcp://127.0.0.1:8786 --nworkers 2 --nthreads 1 --no-dashboard
    .venv/bin/python scripts/run_experiments.py --scheduler tcp://127.0.0.1:8786

Outputs in --out (default out/experiments): results.csv (one row per experiment x condition x
planner, with the share of the literal-to-oracle return gap each IRD planner closes and its
95% paired bootstrap interval), trials.csv (one row per trial x planner), results.md (tables +
settings + wall time), figure4_lava.png (lava fraction per condition: literal / IRD Sample-Z /
IRD MaxEnt-Z / oracle, 95% Wilson error bars), figure4_return.png (mean true return, 95%
Student-t error bars), factorial_<z>.png (per condition, granularity x baseline), run.json.
The wall time is printed last.

--world FILE (a world file, e.g. worlds/figure1.yaml): the trials run on the file's instance
instead of Lavaland (condition ``file``; --conditions, --size, --horizon, --obs-dim unused).
The world is fixed, so trial i differs only in its seed SEED + i, which seeds the posterior
sampler and the Sample-Z proxies: N trials measure how the plans vary with the posterior's
randomness on that one map. The posterior is the joint one over every training world of the
file. A bad file: exit status 2 with the loader's message (file, key, value).

--via-ros: instead, run a few trials (--trials, default 3 here) through the ROS graph's
services (/world/generate, /ird/infer, /ird/plan) and compare the planned cells with direct
library calls; exit status 1 on any disagreement.
"""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout
sys.path.insert(0, str(Path(__file__).resolve().parent))  # scripts/_parallel.py

import argparse  # noqa: E402
import csv  # noqa: E402
import dataclasses  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import time  # noqa: E402

import _parallel  # noqa: E402  (first: one BLAS thread per worker, before numpy loads)

from ird_core import experiments as ex  # noqa: E402
from ird_core.worlds.lavaland import CONDITIONS, FILE_CONDITION  # noqa: E402

ORDER = CONDITIONS + (FILE_CONDITION,)  # tables and figures: the paper's conditions, then a world file

ROOT = Path(__file__).resolve().parents[1]
Z_LABEL = {"sample_z": "IRD Sample-Z", "maxent_z": "IRD MaxEnt-Z"}
# (planner, label, colour) of Figure 4's bars
FIGURE4 = (("literal", "Literal", "#c44e52"), ("ird_sample_z", Z_LABEL["sample_z"], "#4c72b0"),
           ("ird_maxent_z", Z_LABEL["maxent_z"], "#55a868"), ("oracle", "Oracle", "#8c8c8c"))
# TrialSpec fields set by a flag of the same name (dashes for underscores); --quick's fields among them
SPEC_FLAGS = ("size", "horizon", "obs_dim", "num_samples", "beta", "prior_sigma", "num_chains", "warmup",
              "thin", "max_leapfrog", "num_proxy_samples", "factorial_samples", "traj_work_limit")
# --z-sampler's FIELD=VALUE fields: SamplerSettings' integer and real ones.
Z_SAMPLER_INTS = tuple(f.name for f in dataclasses.fields(ex.SamplerSettings) if f.type in ("int", int))
Z_SAMPLER_REALS = tuple(f.name for f in dataclasses.fields(ex.SamplerSettings) if f.type in ("float", float))


# --------------------------------------------------------------------------- running


def _flatten(per_trial: list[list[ex.TrialResult]]) -> list[ex.TrialResult]:
    return [r for rs in per_trial for r in rs]


def run_local(specs: list[ex.TrialSpec], workers: int, progress=None) -> list[ex.TrialResult]:
    """Run specs in a process pool; results in spec order."""
    return _flatten(_parallel.map_local(ex.run_trial, specs, workers, progress))


def run_dask(specs: list[ex.TrialSpec], client, progress=None) -> list[ex.TrialResult]:
    """Run specs on a Dask distributed client; results in spec order."""
    return _flatten(_parallel.map_dask(ex.run_trial, specs, client, progress))


# --------------------------------------------------------------------------- outputs


def _fmt(v) -> str:
    if isinstance(v, float):
        return "nan" if math.isnan(v) else f"{v:.6g}"
    return str(v)


def write_trials_csv(path: Path, results: list[ex.TrialResult]) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(ex.TRIAL_COLUMNS)
        for r in results:
            row = dataclasses.asdict(r)
            row["cells"] = " ".join(f"{a},{b}" for a, b in r.cells)
            w.writerow([_fmt(row[c]) if not isinstance(row[c], bool) else int(row[c]) for c in ex.TRIAL_COLUMNS])


def write_results_csv(path: Path, summaries: list[ex.CellSummary]) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(ex.RESULT_COLUMNS)
        for s in summaries:
            row = s.row()
            w.writerow([_fmt(row[c]) for c in ex.RESULT_COLUMNS])


def _pct(x: float) -> str:
    return "nan" if math.isnan(x) else f"{100 * x:.0f}"


def _gap(s: ex.CellSummary) -> str:
    if math.isnan(s.gap_closed):
        return "-"
    return f"{_pct(s.gap_closed)} [{_pct(s.gap_ci_low)}, {_pct(s.gap_ci_high)}]"


def markdown_table(summaries: list[ex.CellSummary], experiment: str) -> str:
    lines = [("| condition | planner | trials | lava % [95% CI] | target % [95% CI] | mean true return [95% CI] "
              "| gap closed % [95% CI] | fallbacks | R-hat>1.1 |"),
             "|---|---|---|---|---|---|---|---|---|"]
    for s in summaries:
        if s.experiment != experiment:
            continue
        lines.append(
            f"| {s.condition} | {s.planner} | {s.trials} | {_pct(s.lava_fraction)} [{_pct(s.lava_ci_low)}, {_pct(s.lava_ci_high)}] "
            f"| {_pct(s.target_fraction)} [{_pct(s.target_ci_low)}, {_pct(s.target_ci_high)}] "
            f"| {s.mean_true_return:.2f} [{s.return_ci_low:.2f}, {s.return_ci_high:.2f}] | {_gap(s)} "
            f"| {s.fallbacks} | {s.nonconverged} |")
    return "\n".join(lines)


def claim_check(summaries: list[ex.CellSummary]) -> list[str]:
    """The paper's claims, checked on the main experiment."""
    main = {(s.condition, s.planner): s for s in summaries if s.experiment == "main"}
    conditions = sorted({c for c, _ in main}, key=lambda c: ORDER.index(c))
    lines = []
    for z in ex.Z_METHODS:
        for c in conditions:
            lit, ird = main.get((c, "literal")), main.get((c, f"ird_{z}"))
            if lit is None or ird is None:
                continue
            below = ird.lava_fraction < lit.lava_fraction
            disjoint = ird.lava_ci_high < lit.lava_ci_low
            lines.append(f"- {Z_LABEL[z]}, {c}: IRD lava {_pct(ird.lava_fraction)}% vs literal {_pct(lit.lava_fraction)}%: "
                         f"{'below' if below else 'NOT below'}, 95% intervals {'do not overlap' if disjoint else 'OVERLAP'}; "
                         + ("no literal-to-oracle return gap to close" if math.isnan(ird.gap_closed)
                            else f"closes {_gap(ird)}% of the literal-to-oracle return gap"))
    return lines


def write_markdown(path: Path, summaries, settings: dict, wall: float, command: str, fallbacks_note: str) -> None:
    text = [
        "# Lavaland experiment results",
        "",
        f"Command: `{command}`",
        "",
        f"Wall time: {wall:.1f} s ({settings['workers']} worker(s), {settings['scheduler'] or 'local process pool'}).",
        "",
        "Settings: " + ", ".join(f"{k}={v}" for k, v in settings.items() if k not in ("workers", "scheduler")),
        "",
        f"Main IRD planner: granularity `{ex.MAIN_GRANULARITY}`, baseline `{ex.MAIN_BASELINE}` (exact DP on all posterior samples).",
        ("Intervals: 95% Wilson score for fractions, 95% Student-t for the mean true return. "
         "Gap closed: the share of the literal-to-oracle mean true return gap an IRD planner closes "
         "((IRD - literal) / (oracle - literal); 100 = oracle, 0 = literal, negative = below literal), "
         "95% paired percentile bootstrap over trials (2000 resamples, seed 0)."),
        "",
        "## Figure 4: literal vs IRD",
        "",
        markdown_table(summaries, "main"),
        "",
        "Claim check (IRD lava below literal, non-overlapping 95% intervals):",
        "",
        *claim_check(summaries),
        "",
        "## Appendix factorial: granularity x baseline (same posterior per trial and Z-approximation)",
        "",
        fallbacks_note,
        "",
        markdown_table(summaries, "factorial"),
        "",
    ]
    path.write_text("\n".join(text))


def plot_figures(out: Path, summaries: list[ex.CellSummary]) -> list[Path]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    files = []
    main = {(s.condition, s.planner): s for s in summaries if s.experiment == "main"}
    conditions = [c for c in ORDER if (c, "literal") in main]
    planners = [p for p in FIGURE4 if any((c, p[0]) in main for c in conditions)]
    n = main[conditions[0], "literal"].trials if conditions else 0
    for name, field, ylabel, title in (
            ("figure4_lava.png", "lava", "fraction of runs touching lava",
             f"Lavaland: lava encounters ({n} trials per bar, 95% Wilson CI)"),
            ("figure4_return.png", "return", "mean true return",
             f"Lavaland: true return ({n} trials per bar, 95% t CI)")):
        fig, ax = plt.subplots(figsize=(8.5, 3.4), dpi=110)
        width = 0.8 / max(len(planners), 1)
        x = np.arange(len(conditions))
        for j, (key, label, colour) in enumerate(planners):
            ss = [main.get((c, key)) for c in conditions]
            mid, low, high = (np.array([math.nan if s is None else getattr(s, a) for s in ss]) for a in (
                ("lava_fraction", "lava_ci_low", "lava_ci_high") if field == "lava" else
                ("mean_true_return", "return_ci_low", "return_ci_high")))
            err = np.nan_to_num(np.clip([mid - low, high - mid], 0, None))
            ax.bar(x + (j - (len(planners) - 1) / 2) * width, mid, width, yerr=err, capsize=3, label=label,
                   color=colour)
        ax.set_xticks(x, [c.replace("_", " ") for c in conditions])
        ax.set_ylabel(ylabel)
        if field == "lava":
            ax.set_ylim(0, 1)
        else:
            ax.axhline(0, color="black", linewidth=0.6)
        ax.set_title(title)
        ax.legend(frameon=False, ncol=len(planners), loc="upper left", fontsize=8)
        ax.spines[["top", "right"]].set_visible(False)
        fig.tight_layout()
        path = out / name
        fig.savefig(path)
        plt.close(fig)
        files.append(path)

    fact = {(s.condition, s.z_approx, s.granularity, s.baseline): s for s in summaries if s.experiment == "factorial"}
    colours = {"initial_state": "#8172b2", "training_features": "#4c72b0", "log_z": "#ccb974"}
    for z in ex.Z_METHODS:
        if not any(k[1] == z for k in fact):
            continue
        fig, axes = plt.subplots(1, len(conditions), figsize=(2.3 * len(conditions) + 0.8, 3.0), dpi=110, sharey=True)
        axes = np.atleast_1d(axes)
        for ax, c in zip(axes, conditions):
            for gi, g in enumerate(ex.GRANULARITIES):
                for bi, b in enumerate(ex.BASELINES):
                    s = fact.get((c, z, g, b))
                    if s is None:
                        continue
                    pos = gi * (len(ex.BASELINES) + 1) + bi
                    ax.bar(pos, s.lava_fraction, 0.9, color=colours[b],
                           yerr=np.clip([[s.lava_fraction - s.lava_ci_low], [s.lava_ci_high - s.lava_fraction]], 0, 1),
                           capsize=2,
                           label=b if (gi == 0 and c == conditions[0]) else None)
            ax.set_xticks([1, 1 + len(ex.BASELINES) + 1], ["per step", "trajectory"])
            ax.set_title(c.replace("_", " "), fontsize=9)
            ax.spines[["top", "right"]].set_visible(False)
        axes[0].set_ylabel("fraction touching lava")
        axes[0].set_ylim(0, 1)
        fig.legend(loc="upper center", ncol=3, frameon=False, fontsize=8)
        fig.suptitle(f"{Z_LABEL[z]}: min granularity x reward baseline", y=0.02, va="bottom", fontsize=9)
        fig.tight_layout(rect=(0, 0.06, 1, 0.9))
        path = out / f"factorial_{z}.png"
        fig.savefig(path)
        plt.close(fig)
        files.append(path)
    return files


# --------------------------------------------------------------------------- ROS


def run_via_ros(args, settings: dict) -> int:
    """Run trials through the graph's services and compare with direct library calls.

    Starts world, inference and planner with ``GraphLauncher`` (private domain, the world's
    size/horizon/obs_dim set to this run's), then per trial: ``/world/generate`` (condition,
    seed), waits for the matching latched world messages, checks them against
    ``make_instance``, calls ``/ird/infer`` (trial i: condition i and Z method i, cycling) on the world's
    training map and proxy, and ``/ird/plan`` for the literal plan (proxy test features, proxy
    weights) and the main IRD plan (per_step / training_features on the node's posterior
    samples). The node's plans are compared with ``planning.plan_path`` on the same samples
    (and on the float32 features the messages carry); outcomes come from the direct instance.
    Returns 1 on any disagreement. Also printed, for information only: whether the outcome
    (lava, target) equals that of the direct ``run_trial`` of the same seed, whose posterior
    comes from the same library but with the experiment's own seed derivation and sampler
    settings (so its samples, unlike the plans above, are not expected to be identical).
    """
    import tempfile

    import numpy as np
    import yaml

    from ird_core import planning
    from ird_core.mdp import GridMDP
    from ird_core.worlds import lavaland
    from ird_ros import conversions as conv
    from ird_ros.graph import names
    from ird_ros.launch.launcher import GraphLauncher, default_params_file
    from ird_ros.testing import call_service, ros_context, spin_until

    trials = 3 if args.trials is None else args.trials
    params = yaml.safe_load(Path(default_params_file()).read_text())
    params["world"]["ros__parameters"].update(height=args.size, width=args.size, horizon=args.horizon,
                                              obs_dim=args.obs_dim)
    inf = params.setdefault("inference", {}).setdefault("ros__parameters", {})
    inf.update(num_chains=args.num_chains, warmup=args.warmup, thin=args.thin)
    tmp = tempfile.TemporaryDirectory(prefix="ird_via_ros_")
    params_file = Path(tmp.name) / "graph.yaml"
    params_file.write_text(yaml.safe_dump(params))
    disagreements = 0
    graph = GraphLauncher(nodes=["world", "inference", "planner"], params=params_file, private_domain=True,
                          output="quiet")
    graph.start()
    try:
        graph.wait_ready(120.0)
        import rclpy  # noqa: F401

        from ird_msgs.msg import FeatureGrid, ProxyReward
        from ird_msgs.srv import GenerateWorld, InferReward, PlanPath

        with ros_context(graph.domain_id) as ctx:
            import rclpy.node

            node = rclpy.node.Node("run_experiments_via_ros", context=ctx)
            latest: dict[str, object] = {}
            qos = names.latched_qos()
            for topic, typ in ((names.TOPIC_TRAIN_FEATURES, FeatureGrid), (names.TOPIC_TEST_FEATURES, FeatureGrid),
                               (names.TOPIC_TRAIN_PROXY_FEATURES, FeatureGrid), (names.TOPIC_PROXY, ProxyReward)):
                node.create_subscription(typ, topic, lambda m, t=topic: latest.__setitem__(t, m), qos)
            gen = node.create_client(GenerateWorld, names.SRV_GENERATE)
            infer = node.create_client(InferReward, names.SRV_INFER)
            plan = node.create_client(PlanPath, names.SRV_PLAN)
            for client in (gen, infer, plan):
                spin_until(node, client.service_is_ready, timeout=60, what=client.srv_name)

            def stamp(msg) -> tuple[int, int]:
                return msg.header.stamp.sec, msg.header.stamp.nanosec

            for i in range(trials):
                condition = args.conditions[i % len(args.conditions)]
                seed = ex.trial_seed(args.seed, i)
                method = settings["z_methods"][i % len(settings["z_methods"])]
                req = GenerateWorld.Request(condition=condition, seed=seed)
                res = call_service(node, gen, req, timeout=120)
                if not res.success:
                    print(f"[via-ros] /world/generate failed: {res.message}", file=sys.stderr)
                    disagreements += 1
                    continue

                def complete() -> bool:
                    proxy = latest.get(names.TOPIC_PROXY)
                    if proxy is None or proxy.condition != condition or proxy.seed != seed:
                        return False
                    return all(t in latest and stamp(latest[t]) == stamp(proxy)
                               for t in (names.TOPIC_TRAIN_FEATURES, names.TOPIC_TEST_FEATURES,
                                         names.TOPIC_TRAIN_PROXY_FEATURES))

                spin_until(node, complete, timeout=60, what=f"world messages of {condition} seed {seed}")
                proxy_msg = latest[names.TOPIC_PROXY]
                train_msg, test_msg = latest[names.TOPIC_TRAIN_FEATURES], latest[names.TOPIC_TEST_FEATURES]
                proxy_train_msg = latest[names.TOPIC_TRAIN_PROXY_FEATURES]
                inst = lavaland.make_instance(condition, seed, size=args.size, horizon=args.horizon, obs_dim=args.obs_dim)
                train = conv.feature_grid_from_msg(train_msg).features.astype(np.float64)
                test = conv.feature_grid_from_msg(test_msg).features.astype(np.float64)
                world_ok = (np.allclose(train, inst.train_features, atol=1e-5, rtol=1e-6)
                            and np.allclose(test, inst.test_features, atol=1e-5, rtol=1e-6)
                            and np.allclose(proxy_msg.weights, inst.proxy_weights)
                            and (proxy_msg.test_start_row, proxy_msg.test_start_col) == inst.test_start)
                # inference through the node
                ireq = InferReward.Request()
                ireq.training_map = train_msg
                ireq.start_row, ireq.start_col = (int(v) for v in inst.train_start)
                ireq.horizon = inst.train_horizon
                ireq.proxy_weights = [float(v) for v in inst.proxy_weights]
                if inst.classifier is not None:
                    ireq.proxy_map = proxy_train_msg
                ireq.beta, ireq.method = float(args.beta), method
                ireq.num_samples, ireq.seed, ireq.prior_sigma = args.num_samples, seed, float(args.prior_sigma)
                ires = call_service(node, infer, ireq, timeout=600)
                if not ires.success:
                    print(f"[via-ros] /ird/infer failed: {ires.message}", file=sys.stderr)
                    disagreements += 1
                    continue
                samples = np.asarray(ires.posterior.samples, dtype=np.float64).reshape(-1, inst.num_features)
                reference = lavaland.proxy_feature_expectations(inst) / (inst.train_horizon + 1)
                test_mdp = GridMDP(test, inst.test_start, inst.test_horizon)
                proxy_test = inst.proxy_test_features.astype(np.float32).astype(np.float64)
                proxy_test_mdp = GridMDP(proxy_test, inst.test_start, inst.test_horizon)
                checks = {
                    "literal": (conv.feature_grid_to_msg(inst.proxy_test_features, inst.proxy_feature_names),
                                inst.proxy_weights[None], "literal", "none", proxy_test_mdp),
                    f"ird_{method}": (test_msg, samples, ex.MAIN_GRANULARITY, ex.MAIN_BASELINE, test_mdp),
                }
                spec = ex.TrialSpec(condition, seed, **dict(settings, z_methods=(method,), factorial=False))
                direct_trial = {r.planner: r for r in ex.run_trial(spec)}
                for label, (grid, weights, mode, baseline, mdp_) in checks.items():
                    preq = PlanPath.Request()
                    preq.map = grid
                    preq.start_row, preq.start_col = (int(v) for v in inst.test_start)
                    preq.horizon, preq.mode, preq.baseline, preq.label = inst.test_horizon, mode, baseline, label
                    preq.weights = [float(v) for v in np.ravel(weights)]
                    preq.reference_features = [float(v) for v in reference] if baseline == "training_features" else []
                    pres = call_service(node, plan, preq, timeout=300)
                    if not pres.success:
                        print(f"[via-ros] /ird/plan ({label}) failed: {pres.message}", file=sys.stderr)
                        disagreements += 1
                        continue
                    ros_cells = tuple(zip((int(r) for r in pres.rows), (int(c) for c in pres.cols)))
                    direct = planning.plan_path(mdp_, weights, mode, baseline,
                                                reference if baseline == "training_features" else None)
                    same = ros_cells == tuple(direct.cells)
                    out_ros = (lavaland.touches_lava(inst.test_labels, ros_cells),
                               lavaland.reaches_target(inst.test_labels, ros_cells),
                               lavaland.true_return(inst.test_labels, ros_cells))
                    d = direct_trial[label]
                    ok = same and world_ok
                    disagreements += not ok
                    print(f"[via-ros] {condition} seed {seed} {label}: world {'agrees' if world_ok else 'DIFFERS'}, "
                          f"cells {'agree' if same else 'DISAGREE'} (lava {out_ros[0]}, target {out_ros[1]}, "
                          f"return {out_ros[2]:.2f}); posterior r_hat {ires.posterior.r_hat_max:.3f}; "
                          f"direct run_trial outcome {'same' if (d.touched_lava, d.reached_target) == out_ros[:2] else 'differs'} "
                          f"(lava {d.touched_lava}, target {d.reached_target})")
            node.destroy_node()
    finally:
        graph.stop()
        tmp.cleanup()
    print(f"[via-ros] {'all agree' if disagreements == 0 else f'{disagreements} disagreement(s)'}")
    return 0 if disagreements == 0 else 1


# --------------------------------------------------------------------------- main


def build_parser() -> argparse.ArgumentParser:
    """The flags; the TrialSpec flags default to None (resolved by :func:`resolve_spec_flags`)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--trials", type=int, default=None, help="trials per condition (default 100; 3 with --via-ros)")
    p.add_argument("--out", type=Path, default=ROOT / "out" / "experiments")
    p.add_argument("--seed", type=int, default=0, help="base seed: trial i uses instance seed SEED + i")
    _parallel.add_arguments(p)
    p.add_argument("--via-ros", action="store_true")
    p.add_argument("--world", type=Path, default=None, metavar="FILE",
                   help="run the trials on this world file (seeds vary the sampler only)")
    p.add_argument("--conditions", nargs="+", default=list(CONDITIONS), choices=CONDITIONS)
    p.add_argument("--z-methods", nargs="+", default=list(ex.Z_METHODS), choices=ex.Z_METHODS)
    p.add_argument("--no-factorial", action="store_true", help="main experiment only")
    p.add_argument("--quick", action="store_true",
                   help="the small setting for a fast look (ird_core.experiments.QUICK); explicit flags override it")
    _parallel.add_trial_arguments(p, argparse.Namespace(**{f: None for f in SPEC_FLAGS}))
    p.add_argument("--num-proxy-samples", type=int, default=None)
    p.add_argument("--factorial-samples", type=int, default=None,
                   help="posterior samples of every factorial plan, per-step and trajectory alike (the first N)")
    p.add_argument("--traj-work-limit", type=int, default=None,
                   help="label expansions per exact trajectory plan (deterministic; ~4e5 per second here)")
    p.add_argument("--z-sampler", nargs="+", action="append", default=[], metavar="ARG",
                   help="METHOD FIELD=VALUE ...: that Z-approximation's own sampler settings "
                        f"(fields {', '.join(Z_SAMPLER_INTS + Z_SAMPLER_REALS)})")
    return p


def resolve_spec_flags(args) -> None:
    """Fill the TrialSpec flags left unset: from --quick's setting, else TrialSpec's defaults."""
    defaults = ex.TrialSpec("side_effects", 0)
    args.explicit = {field for field in SPEC_FLAGS if getattr(args, field) is not None}
    for field in SPEC_FLAGS:
        if getattr(args, field) is None:
            setattr(args, field, ex.QUICK[field] if args.quick and field in ex.QUICK else getattr(defaults, field))


#: The sampler flags shared by both Z-approximations.
SHARED_SAMPLER_FLAGS = ("num_chains", "warmup", "thin", "max_leapfrog")


def _quick_samplers(args) -> dict:
    """Both methods on the shared sampler flags (fixed length) with --quick, as the small setting
    was run, or when one of those flags is given: it then means both methods' setting."""
    shared = args.quick or bool(set(SHARED_SAMPLER_FLAGS) & getattr(args, "explicit", set()))
    return {"sample_z_sampler": None, "maxent_z_sampler": None} if shared else {}


def z_samplers(args) -> dict:
    """``{"<method>_sampler": SamplerSettings}`` from --z-sampler (ValueError naming the bad item)."""
    names, reals = list(Z_SAMPLER_INTS), list(Z_SAMPLER_REALS)
    out = _quick_samplers(args)
    base = ex.TrialSpec("side_effects", 0, **{f: getattr(args, f) for f in SPEC_FLAGS}, **out)
    for method, *items in args.z_sampler:
        if method not in ex.Z_METHODS:
            raise ValueError(f"--z-sampler: method must be one of {ex.Z_METHODS}, got {method!r}")
        values = {}
        for item in items:
            key, _, value = item.partition("=")
            if key in reals:
                try:
                    values[key] = float(value)
                except ValueError:
                    raise ValueError(f"--z-sampler {method}: expected {key}=NUMBER, got {item!r}") from None
                continue
            if key not in names or not value.lstrip("-").isdigit():
                raise ValueError(f"--z-sampler {method}: expected FIELD=INTEGER with FIELD in {names} "
                                 f"(or FIELD=NUMBER with FIELD in {reals}), got {item!r}")
            values[key] = int(value)
        out[f"{method}_sampler"] = dataclasses.replace(base.sampler(method), **values)
    return out


def spec_settings(args) -> dict:
    return dict(**{f: getattr(args, f) for f in SPEC_FLAGS}, z_methods=tuple(args.z_methods),
                factorial=not args.no_factorial, **z_samplers(args))


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    resolve_spec_flags(args)
    try:
        settings = spec_settings(args)
        ex.TrialSpec("side_effects", 0, **settings)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    conditions = list(args.conditions)
    if args.world is not None:
        from ird_core.worlds.world_file import load_world

        if args.via_ros:
            print("--world: not supported with --via-ros (use launch_graph.py --world FILE)", file=sys.stderr)
            return 2
        try:
            load_world(args.world)
        except ValueError as exc:
            print(f"--world: {exc}", file=sys.stderr)
            return 2
        conditions = [FILE_CONDITION]
        settings["world"] = str(args.world.resolve())
    if args.via_ros:
        return run_via_ros(args, settings)
    trials = 100 if args.trials is None else args.trials
    if trials < 1:
        print("--trials must be >= 1", file=sys.stderr)
        return 2
    specs = ex.make_specs(conditions, trials, args.seed, **settings)
    args.out.mkdir(parents=True, exist_ok=True)
    command = "python scripts/run_experiments.py " + " ".join(sys.argv[1:] if argv is None else argv)
    print(f"{len(specs)} trials ({trials} per condition x {len(conditions)} conditions), "
          f"{_parallel.describe(args.workers, args.scheduler)}", file=sys.stderr)
    t0 = time.monotonic()
    results = _flatten(_parallel.parallel_map(ex.run_trial, specs, args.workers, args.scheduler))
    wall = time.monotonic() - t0
    summaries = ex.aggregate(results)
    write_trials_csv(args.out / "trials.csv", results)
    write_results_csv(args.out / "results.csv", summaries)
    traj = [r for r in results if r.granularity == "trajectory"]
    note = (f"Per-step and trajectory plans both use the same first {args.factorial_samples} of the "
            f"{args.num_samples} posterior samples (the main IRD planner uses all {args.num_samples}). "
            f"Trajectory plans: exact solver, at most {args.traj_work_limit:,} label expansions per plan; "
            f"{sum(r.fallback for r in traj)} of {len(traj)} trajectory plans hit the limit and fell back to the "
            f"per-step plan of the same samples (column `fallbacks`).") if traj else ""
    effective = ex.TrialSpec(conditions[0], 0, **settings)  # each method's sampler, defaults included
    shown = dict(settings, **{f"{z}_sampler": effective.sampler(z) for z in ex.Z_METHODS}, trials=trials,
                 seed=args.seed, workers=args.workers, scheduler=args.scheduler)
    write_markdown(args.out / "results.md", summaries, shown, wall, command, note)
    figures = plot_figures(args.out, summaries)
    (args.out / "run.json").write_text(json.dumps({"command": command, "wall_seconds": wall, "settings": shown,
                                                   "figures": [f.name for f in figures]}, indent=2, default=str))
    print(markdown_table(summaries, "main"))
    print("\n".join(claim_check(summaries)))
    print(f"outputs in {args.out}")
    print(f"Wall time: {wall:.1f} s ({wall / 60:.1f} min) for {len(specs)} trials, "
          f"{_parallel.describe(args.workers, args.scheduler)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
