r"""Run the Lavaland experiments (IRD paper Figure 4 and the appendix factorial).

    ird-experiments [--quick] [--trials N] [--out DIR] [--seed S]
        [--workers W] [--scheduler tcp://HOST:PORT] [--conditions C ...]
        [--size N] [--horizon T] [--obs-dim D] [--num-samples K] [--beta B] ...
        [--factorial-samples N] [--traj-work-limit N] [--z-sampler METHOD FIELD=VALUE ...]

(``scripts/run_experiments.py`` is the same program.) With no flags: the paper's scale, 15x15
maps, T = 30, 50-d observations, 100 paired trials per condition, both Z-approximations, 1000
Sample-Z proxies and the full factorial. --quick: the small setting for a fast look (8x8,
T = 12, 10-d, 64 samples from 4 chains, warm-up 50, thin 4, at most 16 leapfrog steps, 100
Sample-Z proxies, factorial on 10 samples; ird_core.experiments.QUICK); flags given with --quick
override it. --z-sampler sample_z num_chains=8 warmup=200 gives one Z-approximation its own
sampler settings (the numeric fields of ird_core.experiments.SamplerSettings; the others keep
that method's defaults).

Every condition x planner gets N seeded trials (trial i uses instance seed S + i, paired over
conditions). One trial = one Lavaland instance: the literal plan, the oracle plan (optimal
under the true reward), and per Z-approximation ONE posterior whose samples feed every IRD
planner (ird_core.experiments.run_trial): the main planner on all samples, the factorial's
per-step and trajectory plans on the same first --factorial-samples samples. Locally the
trials run in a process pool (W workers, default = cores); with --scheduler on a Dask
distributed cluster (same trial function; both in ird_core.experiments.parallel, tqdm progress
on stderr). A trial is a pure function of its spec, so the numbers do not depend on W, the
scheduler or completion order: a Dask run reproduces a local run bit for bit.

A local Dask cluster (three shells in the checkout; the workers import ird_core from it):

    .venv/bin/dask scheduler --host 127.0.0.1 --port 8786 --no-dashboard
    PYTHONPATH=$PWD OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 \
        .venv/bin/dask worker tcp://127.0.0.1:8786 --nworkers 2 --nthreads 1 --no-dashboard
    .venv/bin/python scripts/run_experiments.py --scheduler tcp://127.0.0.1:8786

Outputs in --out (default out/experiments; ird_core.experiments.report): results.csv (one row
per experiment x condition x planner, with the share of the literal-to-oracle return gap each
IRD planner closes and its 95% paired bootstrap interval), trials.csv (one row per trial x
planner), results.md (tables + settings + wall time), figure4_lava.png (lava fraction per
condition: literal / IRD Sample-Z / IRD MaxEnt-Z / oracle, 95% Wilson error bars),
figure4_return.png (mean true return, 95% Student-t error bars), factorial_<z>.png (per
condition, granularity x baseline), run.json. The wall time is printed last.

--world FILE (a world file, e.g. worlds/figure1.yaml): the trials run on the file's instance
instead of Lavaland (condition ``file``; --conditions, --size, --horizon, --obs-dim unused).
The world is fixed, so trial i differs only in its seed SEED + i, which seeds the posterior
sampler and the Sample-Z proxies: N trials measure how the plans vary with the posterior's
randomness on that one map. The posterior is the joint one over every training world of the
file. A bad file: exit status 2 with the loader's message (file, key, value).

Model and planner: --counts optimal|maxent and --temperature T choose the observation model
(ird_core.posterior.ObservationModel: how the proxy's behaviour is counted; default maxent at
T = 0.2, the calibrated designer), and without --prior-sigma the prior follows the temperature,
sigma = 1 / (T * rms training feature norm), 1 / T for one-hot terrains
(ird_core.posterior.calibration); --risk min|cvar|mean_sd with --risk-level choose the main IRD planner's risk measure
(default min). --frontier adds, from every posterior, the per-step plan at every level of
ird_core.experiments.controls.FRONTIER_RISKS; --controls adds the control planners (prior only,
novelty-avoiding, Sample-Z's other counts reading, Sample-Z without its own term). Either writes
frontier.md (the table and the goal check: lava <= 2%, target >= 0.8 x literal, gap closed >= 90%)
and frontier_<condition>.png. --training-worlds K observes the proxy in K training worlds of
the same distribution (the first the one-world trial's, the same proxy in each).

Chunks: --report-only --out DIR rewrites DIR's report from its trials.csv and run.json (nothing
runs); with --merge A B ... it writes into DIR the report of runs A, B, ... made with the same
settings over other seeds or conditions (e.g. one long condition per run), the trials in a single
run's order (ird_core.experiments.chunks). The trials' numbers come from the csv (6 significant
digits), so a merged report agrees with a single run's to that precision.

Exit status: 0 done, 2 a bad argument (the message names it).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path
from typing import Any

from ird_core.experiments import frontier_report, parallel, report
from ird_core.experiments.chunks import load_chunks
from ird_core.experiments.journal import open_journal
from ird_core.experiments.provenance import code_version
from ird_core.hypothesis import DEFAULT_RFF_FEATURES, HYPOTHESES, NOVELTY_VALUES
from ird_core.experiments.summaries import aggregate
from ird_core.planning.sample_scale import SAMPLE_SCALES
from ird_core.experiments.trials import QUICK, Z_METHODS, SamplerSettings, TrialResult, TrialSpec, make_specs, run_trial
from ird_core.output_paths import make_output_folder
from ird_core.vocabulary import PROXY_COUNTS, RISK_MEASURES
from ird_core.worlds.lavaland import CONDITIONS, FILE_CONDITION
from ird_core.worlds.world_file import load_world_file

__all__ = ["SPEC_FLAGS", "SHARED_SAMPLER_FLAGS", "DEFAULT_TRIALS", "build_parser", "resolve_spec_flags",
           "z_samplers", "spec_settings", "trial_settings", "world_conditions", "run_local", "run_dask",
           "run_experiment", "rewrite_report", "main"]

#: TrialSpec fields set by a flag of the same name (dashes for underscores); --quick's fields among them.
SPEC_FLAGS: tuple[str, ...] = (
    "size", "horizon", "obs_dim", "num_samples", "beta", "prior_sigma", "num_chains", "warmup", "thin",
    "max_leapfrog", "num_proxy_samples", "factorial_samples", "traj_work_limit")
#: The sampler flags shared by both Z-approximations.
SHARED_SAMPLER_FLAGS: tuple[str, ...] = ("num_chains", "warmup", "thin", "max_leapfrog")
#: --z-sampler's FIELD=VALUE fields: SamplerSettings' integer and real ones.
Z_SAMPLER_INTS = tuple(f.name for f in dataclasses.fields(SamplerSettings) if f.type in ("int", int))
Z_SAMPLER_REALS = tuple(f.name for f in dataclasses.fields(SamplerSettings) if f.type in ("float", float))
#: Trials per condition without --trials.
DEFAULT_TRIALS: int = 100
#: How results.md and run.json name the program.
COMMAND = "python scripts/run_experiments.py"


# --------------------------------------------------------------------------- flags


def build_parser() -> argparse.ArgumentParser:
    """The flags; the TrialSpec flags default to None (resolved by :func:`resolve_spec_flags`)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--trials", type=int, default=None, help=f"trials per condition (default {DEFAULT_TRIALS})")
    p.add_argument("--out", type=Path, default=Path("out") / "experiments",
                   help="output folder, from the working directory (default out/experiments)")
    p.add_argument("--seed", type=int, default=0, help="base seed: trial i uses instance seed SEED + i")
    parallel.add_arguments(p)
    p.add_argument("--world", type=Path, default=None, metavar="FILE",
                   help="run the trials on this world file (seeds vary the sampler only)")
    p.add_argument("--conditions", nargs="+", default=list(CONDITIONS), choices=CONDITIONS)
    p.add_argument("--z-methods", nargs="+", default=list(Z_METHODS), choices=Z_METHODS)
    p.add_argument("--no-factorial", action="store_true", help="no granularity x baseline factorial")
    p.add_argument("--counts", choices=PROXY_COUNTS, default=None,
                   help="the observation model's counts: optimal-path or MaxEnt (docs/modelling.md)")
    p.add_argument("--temperature", type=float, default=None,
                   help="the modelled designer's temperature (default 0.2, the calibrated designer); "
                        "without --prior-sigma the prior follows it: sigma = 1 / (temperature * rms training "
                        "feature norm), 1 / temperature for one-hot terrains")
    p.add_argument("--sample-scale", choices=SAMPLE_SCALES, default=None,
                   help="how the IRD planners scale posterior samples: by their reward range over the training "
                        "maps (training_spread, the default: ird_core.planning.sample_scale) or not at all (none)")
    p.add_argument("--risk", choices=RISK_MEASURES, default=None, help="the main IRD planner's risk measure")
    p.add_argument("--risk-level", type=float, default=None,
                   help="its level: alpha in (0, 1] for cvar, lambda >= 0 for mean_sd")
    p.add_argument("--frontier", action=argparse.BooleanOptionalAction, default=None,
                   help="plan every risk level of the frontier from every posterior (frontier.md, frontier_<c>.png)")
    p.add_argument("--controls", action=argparse.BooleanOptionalAction, default=None,
                   help="the control planners: prior only, novelty-avoiding, the other Sample-Z reading, "
                        "Sample-Z without its own term")
    p.add_argument("--novelty-feature", action=argparse.BooleanOptionalAction, default=None,
                   help="add the hypothesis feature 'novel' (nonzero on test cells unlike every training cell, 0 in "
                        "training; ird_core.hypothesis.novelty) to IRD's posterior and plans")
    p.add_argument("--novelty-value", choices=NOVELTY_VALUES, default=None,
                   help="the novel feature's value on novel cells: the training cells' rms feature norm "
                        "(feature_scale, the default: a novel cell gets the calibrated prior's reward spread) "
                        "or 1 (one, the value before; the committed results say which they used)")
    p.add_argument("--hypothesis", choices=HYPOTHESES, default=None,
                   help="IRD's hypothesis space in the latent conditions: linear in the observations (the paper's, "
                        "default) or rff, random Fourier features of an RBF kernel on them "
                        "(ird_core.hypothesis.rff)")
    p.add_argument("--rff-features", type=int, default=None, metavar="D",
                   help=f"random features of --hypothesis rff (default {DEFAULT_RFF_FEATURES})")
    p.add_argument("--training-worlds", type=int, default=None, metavar="K",
                   help="Lavaland training worlds the designer's proxy is observed in (default 1, the paper's; "
                        "the first is the one-world trial's, so runs are paired by seed: "
                        "ird_core.worlds.training_worlds)")
    p.add_argument("--quick", action="store_true",
                   help="the small setting for a fast look (ird_core.experiments.QUICK); explicit flags override it")
    parallel.add_trial_arguments(p, argparse.Namespace(**{f: None for f in SPEC_FLAGS}))
    p.add_argument("--num-proxy-samples", type=int, default=None)
    p.add_argument("--factorial-samples", type=int, default=None,
                   help="posterior samples of every factorial plan, per-step and trajectory alike (the first N)")
    p.add_argument("--traj-work-limit", type=int, default=None,
                   help="label expansions per exact trajectory plan (deterministic, unlike a time limit)")
    p.add_argument("--z-sampler", nargs="+", action="append", default=[], metavar="ARG",
                   help="METHOD FIELD=VALUE ...: that Z-approximation's own sampler settings "
                        f"(fields {', '.join(Z_SAMPLER_INTS + Z_SAMPLER_REALS)})")
    p.add_argument("--report-only", action="store_true",
                   help="run nothing: rewrite the report in --out from its trials.csv and run.json")
    p.add_argument("--merge", nargs="+", type=Path, default=None, metavar="DIR",
                   help="with --report-only: the report of the runs in DIR... (chunks of other seeds or "
                        "conditions with the same settings, e.g. one condition per run) written into --out")
    return p


def resolve_spec_flags(args: argparse.Namespace) -> None:
    """Fill the TrialSpec flags left unset: from --quick's setting, else TrialSpec's defaults."""
    defaults = TrialSpec("side_effects", 0)
    args.explicit = {field for field in SPEC_FLAGS if getattr(args, field) is not None}
    for field in SPEC_FLAGS:
        if getattr(args, field) is None:
            setattr(args, field, QUICK[field] if args.quick and field in QUICK else getattr(defaults, field))


def _quick_samplers(args: argparse.Namespace) -> dict[str, None]:
    """Both methods on the shared sampler flags (fixed length) with --quick, as the small setting
    was run, or when one of those flags is given: it then means both methods' setting."""
    shared = args.quick or bool(set(SHARED_SAMPLER_FLAGS) & getattr(args, "explicit", set()))
    return {"sample_z_sampler": None, "maxent_z_sampler": None} if shared else {}


def _sampler_values(method: str, items: list[str]) -> dict[str, int | float]:
    """--z-sampler's ``FIELD=VALUE`` items of one method (ValueError naming the bad item)."""
    names, reals = list(Z_SAMPLER_INTS), list(Z_SAMPLER_REALS)
    values: dict[str, int | float] = {}
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
    return values


def z_samplers(args: argparse.Namespace) -> dict[str, SamplerSettings | None]:
    """``{"<method>_sampler": SamplerSettings}`` from --z-sampler (ValueError naming the bad item)."""
    out: dict[str, SamplerSettings | None] = dict(_quick_samplers(args))
    base = TrialSpec("side_effects", 0, **{f: getattr(args, f) for f in SPEC_FLAGS}, **out)
    for method, *items in args.z_sampler:
        if method not in Z_METHODS:
            raise ValueError(f"--z-sampler: method must be one of {Z_METHODS}, got {method!r}")
        out[f"{method}_sampler"] = dataclasses.replace(base.sampler(method), **_sampler_values(method, items))
    return out


#: TrialSpec fields set by an optional flag of the same name (None: the TrialSpec default).
MODEL_FLAGS: tuple[str, ...] = ("counts", "temperature", "sample_scale", "risk", "risk_level", "frontier", "controls",
                               "novelty_feature", "novelty_value", "hypothesis", "rff_features", "training_worlds")


def spec_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The TrialSpec keywords of the (resolved) flags."""
    model = {f: getattr(args, f) for f in MODEL_FLAGS if getattr(args, f, None) is not None}
    return dict(**{f: getattr(args, f) for f in SPEC_FLAGS}, z_methods=tuple(args.z_methods),
                factorial=not args.no_factorial, **model, **z_samplers(args))


def trial_settings(args: argparse.Namespace) -> dict[str, Any]:
    """The flags' TrialSpec keywords, resolved and validated (ValueError naming the bad flag)."""
    resolve_spec_flags(args)
    settings = spec_settings(args)
    TrialSpec("side_effects", 0, **settings)
    return settings


def world_conditions(args: argparse.Namespace, settings: dict[str, Any]) -> list[str]:
    """The run's conditions: --conditions, or with --world the file's (whose resolved path is
    then set in ``settings["world"]``). ValueError ``--world: ...`` if the file does not load."""
    if args.world is None:
        return list(args.conditions)
    try:
        loaded = load_world_file(args.world)
    except ValueError as exc:
        raise ValueError(f"--world: {exc}") from None
    for line in loaded.warnings:
        print(f"warning: {line}", file=sys.stderr)
    settings["world"] = str(args.world.resolve())
    return [FILE_CONDITION]


# --------------------------------------------------------------------------- running


def _flatten(per_trial: list[list[TrialResult]]) -> list[TrialResult]:
    return [r for rs in per_trial for r in rs]


def run_local(specs: list[TrialSpec], workers: int, progress: Any = None) -> list[TrialResult]:
    """Run specs in a process pool; results in spec order."""
    return _flatten(parallel.map_local(run_trial, specs, workers, progress))


def run_dask(specs: list[TrialSpec], client: Any, progress: Any = None) -> list[TrialResult]:
    """Run specs on a Dask distributed client; results in spec order."""
    return _flatten(parallel.map_dask(run_trial, specs, client, progress))


def _shown_settings(args: argparse.Namespace, settings: dict[str, Any], conditions: list[str],
                    trials: int) -> dict[str, Any]:
    """The settings the report states: each method's effective sampler (defaults included), the
    novel feature's value when the feature is on, and the run's trials, seed, workers and scheduler."""
    effective = TrialSpec(conditions[0], 0, **settings)
    novelty = {"novelty_value": effective.novelty_value} if effective.novelty_feature else {}
    return dict(settings, **novelty, **{f"{z}_sampler": effective.sampler(z) for z in Z_METHODS}, trials=trials,
                seed=args.seed, workers=args.workers, scheduler=args.scheduler)


def run_experiment(args: argparse.Namespace, settings: dict[str, Any], conditions: list[str], command: str) -> int:
    """Run the trials of ``conditions`` with ``settings``, write the report into ``args.out``
    and print Figure 4's table, the claim check and the wall time. Exit status 0, 2 on bad --trials
    or --seed."""
    trials = DEFAULT_TRIALS if args.trials is None else args.trials
    if trials < 1:
        print("--trials must be >= 1", file=sys.stderr)
        return 2
    try:
        specs = make_specs(conditions, trials, args.seed, **settings)
        make_output_folder(args.out)
    except ValueError as exc:  # a seed the trials cannot use, or an --out no report can be written to
        print(exc, file=sys.stderr)
        return 2
    where = parallel.describe(args.workers, args.scheduler)
    print(f"{len(specs)} trials ({trials} per condition x {len(conditions)} conditions), {where}", file=sys.stderr)
    code = code_version()  # before any trial: the code that runs them
    journal, resumed = open_journal(args.out, code, specs)
    t0 = time.monotonic()
    results = _flatten(parallel.parallel_map(run_trial, specs, args.workers, args.scheduler, journal=journal))
    wall = time.monotonic() - t0
    summaries = aggregate(results)
    shown = _shown_settings(args, settings, conditions, trials)
    run = report.RunRecord(command, wall, dict(shown, resumed_trials=resumed) if resumed else shown, code)
    report.write_report(args.out, results, summaries, run)
    frontier_report.write_frontier(args.out, summaries, run)
    journal.close()
    print(report.markdown_table(summaries, "main"))
    print("\n".join(report.claim_check(summaries)))
    print(f"outputs in {args.out}")
    print(f"Wall time: {wall:.1f} s ({wall / 60:.1f} min) for {len(specs)} trials, {where}")
    return 0


def rewrite_report(out: Path, chunks: "list[Path] | None" = None) -> int:
    """Rewrite the report in ``out`` from ``trials.csv`` and ``run.json`` of ``out`` or of each
    chunk directory (:mod:`ird_core.experiments.chunks`), its trials in a single run's order
    (conditions in the paper's order, then seeds), and print Figure 4's table. Exit status 0, 2
    when a file cannot be read or the chunks do not fit together."""
    try:
        merged, results = load_chunks(out, chunks, "trials.csv", report.read_trials_csv,
                                      lambda r: (r.experiment, r.condition, r.seed, r.planner), lambda r: r.seed)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    results.sort(key=lambda r: (report.ORDER.index(r.condition), r.seed))  # stable: a trial's rows keep their order
    summaries = aggregate(results)
    run = report.RunRecord(merged.command, merged.wall, merged.settings, merged.code)
    try:
        make_output_folder(out)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    report.write_report(out, results, summaries, run)
    frontier_report.write_frontier(out, summaries, run)
    print(report.markdown_table(summaries, "main"))
    print(f"report rewritten in {out}")
    return 0


def command_line(argv: list[str] | None) -> str:
    """The command as results.md records it."""
    return f"{COMMAND} " + " ".join(sys.argv[1:] if argv is None else argv)


def main(argv: list[str] | None = None) -> int:
    """The experiments without ROS (``ird_ros.apps.experiments`` adds ``--via-ros``)."""
    args = build_parser().parse_args(argv)
    if args.report_only:
        return rewrite_report(args.out, args.merge)
    try:
        settings = trial_settings(args)
        conditions = world_conditions(args, settings)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    return run_experiment(args, settings, conditions, command_line(argv))
