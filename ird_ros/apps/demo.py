"""The demo mission: Rob, a proxy reward, and lava the designer never saw.

Starts the whole ROS 2 graph (world, perception, inference, planner, rob, navigator, recorder;
``--viz`` adds the live view) in one ROS domain: the ``ROS_DOMAIN_ID`` this process got (demo.sh's
lease, kept by ``ird_ros_env``, or one you exported), else a private lease; it prints that one id
and the line a second shell runs to attach. Then, as an ordinary client of the graph:

1. reads the designer's proxy reward the world publishes;
2. sends the navigator (action ``/ird/navigate``) the literal goal: the navigator calls
   ``/ird/infer`` (IRD posterior over the true reward given the proxy, on the world's request) and
   plans with the proxy taken at its word;
3. sends the IRD goal: a plan risk-averse over that posterior's samples;
4. Rob drives each plan on the test map to the end; the action's results say how it went;
5. stops the graph (the recorder closes the bag), and writes a picture: the training map, the
   test map with both paths, and the posterior's risk map.

It also measures, directly with ``ird_core`` and the same settings, how often over 20 seeds the
literal plan and the IRD plan touch lava, so the one mission shown is put in context.

With ``--queries N`` the designer node joins the graph and, after the IRD plan, the demo asks
``N`` questions: each round calls ``/ird/query`` (options on the test map Rob is about to
drive), waits for the designer's answer on ``/ird/queries`` (``--designer simulated``: the
simulated designer node answers with the true rewards; ``--designer web``: a person answers on
the page whose URL is printed, with no time limit), takes the re-sampled posterior and its risk
map, asks ``/ird/plan`` for a new IRD plan and lets Rob drive it. It prints a table of every
plan (information gain, answer, lava, target, gold, true return) and draws ``rounds.png``: the
plans before and after each answer with the options asked, and the risk maps. Ctrl-C stops the
graph cleanly (the bag is closed) at any point.

    bash scripts/demo.sh [--condition latent_raw] [--seed 3] [--out out/demo]
    bash scripts/demo.sh --queries 3 [--condition pot_of_gold] [--designer web]
    bash scripts/demo.sh --world worlds/figure1.yaml [--queries 2]

With ``--world FILE`` the graph runs the world file (``ird_core.worlds.world_file``) instead of a
generated Lavaland: the world node and perception load it, ``/ird/infer`` gets every training
world of the file (the world's ``/world/infer_request``), ``--condition`` is unused and
``--seed`` seeds the sampler and the designer only; the survey then repeats the mission's
planners on the same file over sampler seeds 0-19.

The mission (docs/spec.md sections 3-7) talks to the graph only through
``ird_ros.client.IrdClient``; its rounds of questions are drawn by ``ird_ros.apps.demo_rounds``.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime as dt
import itertools
import json
import math
import multiprocessing
import multiprocessing.pool
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any

import yaml

from ird_core import posterior
from ird_core.designer.queries import STRATEGIES
from ird_core.experiments import MAIN_BASELINE, MAIN_GRANULARITY, QUICK, TrialSpec, run_trial, trial_instance
from ird_core.output_paths import make_output_folder
from ird_core.render import save_mission_figure
from ird_core.worlds import lavaland
from ird_core.worlds.lavaland import LavalandInstance
from ird_ros.apps.demo_mission import Mission, Results
from ird_ros.apps.demo_rounds import outcome_text, rounds_table, save_rounds_figure
from ird_ros.resources import graph_params

#: The demo's default seed: the first one, and (with the default settings) one of the seeds 0-19 on
#: which the literal plan walks into lava, the failure the paper is about (Section 1). The demo
#: prints the survey over those 20 seeds so this one mission is not mistaken for the average.
DEFAULT_SEED = 0
SURVEY_SEEDS = tuple(range(20))
#: Query rounds: 2 options (the exact best pair), info_gain; each round costs a proposal
#: (candidates = the distinct plans of the posterior samples), a re-sampling and Rob's drive.
DEFAULT_NUM_OPTIONS = 2
#: The simulated designer answers by the Boltzmann rule on the options' true returns.
DEFAULT_DESIGNER_BETA = 1.0


def build_parser() -> argparse.ArgumentParser:
    """The demo's options (``scripts/demo.sh --help`` prints the same list without a venv)."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--condition", default="latent_raw", choices=lavaland.ALL_CONDITIONS,
                   help="the Lavaland condition (default latent_raw)")
    p.add_argument("--world", type=Path, default=None, metavar="FILE",
                   help="a world file (worlds/*.yaml) instead of a generated Lavaland")
    p.add_argument("--seed", type=int, default=DEFAULT_SEED, help="world seed (maps, proxy; also the designer's)")
    p.add_argument("--method", default="maxent_z", choices=posterior.METHODS,
                   help="the IRD posterior's approximation (default maxent_z)")
    p.add_argument("--beta", type=float, default=None, help="designer rationality (default: the experiments')")
    p.add_argument("--num-samples", type=int, default=None, help="posterior samples (default: the experiments')")
    p.add_argument("--rate", type=float, default=10.0, help="Rob's speed, cells per second")
    p.add_argument("--out", default=str(Path("out") / "demo"),
                   help="output folder, from the working directory (a run folder is made inside)")
    p.add_argument("--no-survey", action="store_true", help="skip the 20-seed survey")
    p.add_argument("--viz", action="store_true",
                   help="also start the viz node (live view over the Foxglove protocol; its ws:// URL is printed)")
    p.add_argument("--viz-port", type=int, default=None, metavar="PORT",
                   help="with --viz: the live view's port (0 = any free port; without it 8766, the params file's)")
    q = p.add_argument_group("questions to the designer (after the IRD plan)")
    q.add_argument("--queries", type=int, default=0, help="rounds of questions (0 = none: the plain mission)")
    q.add_argument("--designer", default="simulated", choices=("simulated", "web"),
                   help="who answers: the simulated designer node, or a person on the web page")
    q.add_argument("--num-options", type=int, default=DEFAULT_NUM_OPTIONS, help="paths per question")
    q.add_argument("--strategy", default="evoi", choices=STRATEGIES, help="how the options are chosen")
    q.add_argument("--designer-beta", type=float, default=DEFAULT_DESIGNER_BETA,
                   help="simulated designer's rationality on the options' true returns")
    q.add_argument("--port", type=int, default=8765, help="web designer's port on 127.0.0.1")
    return p


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = build_parser()
    args = p.parse_args(argv)
    if args.queries < 0:
        p.error(f"--queries: must be >= 0, got {args.queries}")
    if args.designer == "web" and not args.queries:
        p.error("--designer web: the designer only answers questions; add --queries N")
    if args.num_options < 2:
        p.error(f"--num-options: must be >= 2, got {args.num_options}")
    if not 1 <= args.port <= 65535:
        p.error(f"--port: must be in 1..65535, got {args.port}")
    if args.viz_port is not None and not (args.viz and 0 <= args.viz_port <= 65535):
        p.error(f"--viz-port: needs --viz and a port in 0..65535 (0 = any free port), got {args.viz_port}")
    from ird_ros.nodes.rob import PARAMETERS as ROB  # the rob node's own range, checked before it starts
    rate = ROB["rate_hz"]
    if not (math.isfinite(args.rate) and rate.min_value <= args.rate <= rate.max_value):
        p.error(f"--rate: must be in {rate.min_value:g}..{rate.max_value:g} cells per second, got {args.rate}")
    if not (math.isfinite(args.designer_beta) and args.designer_beta >= 0):
        p.error(f"--designer-beta: must be a finite number >= 0, got {args.designer_beta}")
    return args


# --------------------------------------------------------------------------- set-up


@dataclasses.dataclass(frozen=True)
class Setup:
    """The mission's settings: the trial spec the graph is configured with, the instance the world
    node builds from it (its ground truth judges gold), the scene's name and the run folder."""

    spec: TrialSpec
    inst: LavalandInstance
    scene: str
    run_dir: Path
    params: Path


def write_params(run_dir: Path, args: argparse.Namespace, spec: TrialSpec) -> Path:
    """The graph's parameter file with the experiments' world and sampler settings."""
    params = yaml.safe_load(graph_params().read_text())
    world = params["world"]["ros__parameters"]
    world.update(condition=args.condition, seed=args.seed, height=spec.size, width=spec.size,
                 horizon=spec.horizon, obs_dim=spec.obs_dim)
    params["inference"]["ros__parameters"].update(
        num_chains=spec.num_chains, warmup=spec.warmup, thin=spec.thin,
        num_proxy_samples=spec.num_proxy_samples,
        time_budget=0.0)  # no wall-clock stop: the iteration cap bounds the run, so the numbers do not depend on load
    if args.world is not None:
        for node in ("world", "perception"):
            params[node]["ros__parameters"]["world_file"] = str(args.world.resolve())
    params["rob"]["ros__parameters"]["rate_hz"] = float(args.rate)
    params["designer"]["ros__parameters"].update(mode=args.designer, beta=float(args.designer_beta),
                                                 seed=int(args.seed), port=int(args.port))
    path = run_dir / "graph.yaml"
    path.write_text(yaml.safe_dump(params, sort_keys=False))
    return path


def mission_spec(args: argparse.Namespace) -> tuple[TrialSpec, str]:
    """The trial spec of the demo world (the experiments' small setting) and the scene's name.

    ``--world`` is loaded here with every check the graph's services apply (before any node
    starts): ``ValueError`` ``--world: <file>: <key>: ...`` if it does not load; its warnings
    are printed as ``[demo] warning:`` lines on stderr."""
    base = TrialSpec(condition=args.condition, seed=args.seed, **QUICK)
    beta = args.beta if args.beta is not None else base.beta
    num_samples = args.num_samples if args.num_samples is not None else base.num_samples
    spec = dataclasses.replace(base, beta=beta, num_samples=num_samples, z_methods=(args.method,), factorial=False)
    if args.world is None:
        return spec, args.condition
    from ird_core.worlds.world_file import load_world_file

    try:
        loaded = load_world_file(args.world)
    except ValueError as exc:
        raise ValueError(f"--world: {exc}") from None
    for warning in loaded.warnings:
        print(f"[demo] warning: --world: {warning}", file=sys.stderr, flush=True)
    return dataclasses.replace(spec, condition=lavaland.FILE_CONDITION, world=str(args.world.resolve())), loaded.name


def make_run_dir(out: str | Path, now: dt.datetime | None = None) -> Path:
    """A new folder ``run-<time>`` in ``out`` (a relative ``out`` is taken from the working
    directory); ``run-<time>-2``, ``-3``, ... when demos started in the same second took the name.
    ``ValueError`` naming ``--out`` when no folder can be made there."""
    base = Path(out).resolve()
    make_output_folder(base, "--out")
    stamp = (now or dt.datetime.now()).strftime("run-%Y%m%d-%H%M%S")
    for n in itertools.count(1):
        run_dir = base / (stamp if n == 1 else f"{stamp}-{n}")
        with contextlib.suppress(FileExistsError):
            run_dir.mkdir()  # atomic: of two demos, one gets each name
            return run_dir
    raise AssertionError("unreachable")


def prepare(args: argparse.Namespace, spec: TrialSpec, scene: str) -> Setup:
    """The run folder with the graph's parameter file; the world node's instance (its ground truth)."""
    inst = trial_instance(spec)  # the world node builds (or loads) the same instance
    run_dir = make_run_dir(args.out)
    return Setup(spec, inst, scene, run_dir, write_params(run_dir, args, spec))


def print_header(args: argparse.Namespace, setup: Setup) -> None:
    spec = setup.spec
    print(f"IRD demo: {'world file' if args.world else 'condition'} {setup.scene}, seed {args.seed}, {args.method}, "
          f"beta {spec.beta}, {spec.num_samples} samples, IRD planner {MAIN_GRANULARITY}/{MAIN_BASELINE}\n"
          f"output: {setup.run_dir}", flush=True)
    if args.queries:
        print(f"then {args.queries} question(s) to the {args.designer} designer: {args.num_options} options "
              f"({args.strategy})" + (f", designer beta {args.designer_beta}" if args.designer == "simulated" else ""),
              flush=True)
    print(flush=True)


# --------------------------------------------------------------------------- the survey


def survey(spec: TrialSpec) -> dict[str, tuple[int, int]]:
    """Seeds on which each planner touches lava and reaches a target, straight from ird_core
    (runs beside the graph): ``{planner: (lava seeds, target seeds)}``."""
    counts: dict[str, tuple[int, int]] = {}
    for seed in SURVEY_SEEDS:
        for result in run_trial(dataclasses.replace(spec, seed=seed)):
            lava, target = counts.get(result.planner, (0, 0))
            counts[result.planner] = (lava + int(result.touched_lava), target + int(result.reached_target))
    return counts


class Survey:
    """The 20-seed survey in one worker process that ignores Ctrl-C (the demo ends it itself)."""

    def __init__(self, spec: TrialSpec | None) -> None:
        self._pool: multiprocessing.pool.Pool | None = None
        self._job: Any = None
        if spec is not None:
            self._pool = multiprocessing.Pool(1, initializer=signal.signal, initargs=(signal.SIGINT, signal.SIG_IGN))
            self._job = self._pool.apply_async(survey, (spec,))

    def cancel(self) -> None:
        if self._pool is not None:
            self._pool.terminate()
            self._pool = None

    def report(self, scene: str, method: str) -> None:
        """Wait for the survey and print it (nothing if it was skipped or cancelled)."""
        if self._pool is None:
            return
        counts = self._job.get()
        n = len(SURVEY_SEEDS)
        (lit_lava, lit_target), (ird_lava, ird_target) = counts["literal"], counts["ird_" + method]
        print(f"\nOver seeds {SURVEY_SEEDS[0]}-{SURVEY_SEEDS[-1]} ({scene}, same settings, ird_core "
              f"directly): literal touches lava on {lit_lava}/{n} and reaches a target on {lit_target}/{n}; "
              f"IRD touches lava on {ird_lava}/{n} and reaches a target on {ird_target}/{n}.")
        self._pool.close()
        self._pool.join()
        self._pool = None


# --------------------------------------------------------------------------- the graph


def web_url(output: str, port: int) -> str:
    """The page's URL from the designer's log line ``designer web page at URL`` (else 127.0.0.1:port)."""
    marker = "designer web page at "
    lines = [line for line in output.splitlines() if marker in line]
    return lines[-1].split(marker, 1)[1].split()[0] if lines else f"http://127.0.0.1:{port}/"


def print_live_view(ird: Any) -> None:
    """The viz node's ``ws://`` URL, from its latched status (JSON with ``url``)."""
    from ird_ros.graph import names

    status = json.loads(ird.latest(names.TOPIC_VIZ_STATUS, timeout=60).data)
    print(f"live view (Foxglove protocol): {status['url']}  (open it in Foxglove or Lichtblick)\n", flush=True)


def graph_nodes(args: argparse.Namespace) -> list[str] | None:
    """The demo's nodes: the default ones, the designer with ``--queries``, viz with ``--viz`` (when
    the node table has it); None: the defaults."""
    from ird_ros.graph import DEFAULT_NODES, NODES_BY_NAME

    extra = (["designer"] if args.queries else []) + (["viz"] if args.viz and "viz" in NODES_BY_NAME else [])
    return [*DEFAULT_NODES, *extra] if extra else None


def print_domain(graph: Any, args: argparse.Namespace) -> None:
    """The one domain of the graph with the line to attach a second shell (a note if --viz has no node)."""
    from ird_ros.graph.domains import domain_banner

    print(domain_banner(graph.domain_id), flush=True)
    if args.viz and "viz" not in graph.pids():
        print("[demo] --viz: this checkout has no viz node; running without the live view", flush=True)


def run_graph(args: argparse.Namespace, setup: Setup, results: Results) -> None:
    """Start the graph, run the mission as its client, stop the graph (the bag is closed).

    Raises ``LaunchError`` (a node never got ready) and lets Ctrl-C through."""
    from ird_ros.client import IrdClient
    from ird_ros.launch import GraphLauncher

    # the domain this shell exported (demo.sh's, kept by ird_ros_env), else a private lease: one id
    from ird_ros.launch.plan import with_viz_port

    specs = with_viz_port(None, args.viz_port) if args.viz and args.viz_port is not None else None
    with GraphLauncher(nodes=graph_nodes(args), specs=specs, params=setup.params, record_dir=setup.run_dir / "bag",
                       private_domain=not os.environ.get("ROS_DOMAIN_ID"), output="files",
                       log_dir=setup.run_dir / "logs") as graph:
        print_domain(graph, args)
        ready = graph.wait_ready(timeout=120)
        print(graph.status_table(), flush=True)
        print(f"graph ready in {max(ready.values()):.1f} s (domain {graph.domain_id})\n", flush=True)
        if args.queries and args.designer == "web":
            print(f"designer web page: {web_url(graph.output('designer', last=200), args.port)}\n"
                  "  (open it in a browser and answer each question; Ctrl-C stops the demo)\n", flush=True)
        with IrdClient(graph.domain_id, node_name="ird_demo") as ird:
            if "viz" in graph.pids():
                print_live_view(ird)
            Mission(ird, args, setup.spec, setup.inst.test_labels, results).run()


# --------------------------------------------------------------------------- the report


def report_mission(args: argparse.Namespace, setup: Setup, results: Results) -> list[Path]:
    """The mission picture and table, and with questions the rounds' table and picture."""
    inst, outcomes, pictures = setup.inst, results.outcomes, []
    if outcomes:
        pictures.append(setup.run_dir / "mission.png")
        save_mission_figure(pictures[-1], inst.train_labels, inst.test_labels,
                            {o.label: o.cells for o in outcomes}, risk_map=results.risk,
                            title=f"{setup.scene}, seed {args.seed}: literal proxy vs IRD",
                            train_start=inst.train_start, test_start=inst.test_start,
                            outcomes={o.label: outcome_text(o) for o in outcomes})
        print("\nMission results (from Rob's /rob/status):")
        print(f"  {'plan':<18} {'touched lava':>12} {'reached target':>15} {'true return':>12}")
        for o in outcomes:
            print(f"  {o.label:<18} {str(o.touched_lava):>12} {str(o.reached_target):>15} {o.true_return:>12.2f}")
    if args.queries and len(outcomes) == 2:
        literal, before = outcomes
        print(f"\nQuestions to the {args.designer} designer ({len(results.rounds)} answered; Rob's /rob/status, "
              "gold from the world's terrain):")
        print(rounds_table(literal, before, results.rounds))
        pictures.append(setup.run_dir / "rounds.png")
        save_rounds_figure(pictures[-1], inst.test_labels, inst.test_start, literal, before, results.spread,
                           results.rounds,
                           title=f"{setup.scene}, seed {args.seed}: IRD plan before and after each "
                                 f"answer of the {args.designer} designer")
    return pictures


def report_bag(setup: Setup) -> None:
    """The topics the recorder's bag holds, and its plots."""
    from ird_ros.bags.analysis import analyze

    bag_dir = setup.run_dir / "bag"
    if bag_dir.is_dir():
        summary = analyze(bag_dir, out_dir=setup.run_dir / "bag_plots")
        recorded = sorted((t["topic"], t["count"]) for t in summary["topics"])
        print(f"\nBag {bag_dir}: " + ", ".join(f"{topic} {count}" for topic, count in recorded))


# --------------------------------------------------------------------------- main


STOPPED_LINE = "[demo] stopped by Ctrl-C"


def main(argv: list[str] | None = None) -> int:
    """The mission: set up, start the survey, run the graph and its client, report. Exit code 0,
    1 if the graph did not start, 2 for an unreadable ``--world`` or an unusable ``--out``, 130
    after Ctrl-C (wherever it comes: one line, never a traceback; the graph and the survey are
    stopped first)."""
    try:
        return _main(argv)
    except KeyboardInterrupt:
        print(f"\n{STOPPED_LINE}", file=sys.stderr, flush=True)
        return 130


def _main(argv: list[str] | None) -> int:
    args = parse_args(argv)
    try:
        spec, scene = mission_spec(args)
    except ValueError as exc:
        print(f"[demo] {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # while loading --world: nothing was started
        print(f"\n{STOPPED_LINE}", file=sys.stderr)
        return 130
    try:
        setup = prepare(args, spec, scene)
    except ValueError as exc:  # nothing was started
        print(f"[demo] {exc}", file=sys.stderr)
        return 2
    t_start = time.monotonic()
    print_header(args, setup)
    background = Survey(None if args.no_survey else spec)
    try:
        return _run(args, setup, scene, background, t_start)
    finally:
        background.cancel()  # after Ctrl-C or an error; a no-op once the survey was reported


def _run(args: argparse.Namespace, setup: Setup, scene: str, background: Survey, t_start: float) -> int:
    from rclpy.executors import ExternalShutdownException  # after --help: works before the venv is complete

    from ird_ros.launch import LaunchError

    results = Results()
    interrupted = False
    try:
        run_graph(args, setup, results)
    except LaunchError as exc:  # a node that never got ready: its log says why
        print(f"\n[demo] the graph did not start: {exc}\nnode logs: {setup.run_dir / 'logs'}", flush=True)
        background.cancel()
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        interrupted = True
        print(f"\n{STOPPED_LINE}: the graph was stopped and the bag closed.", flush=True)
        background.cancel()
    pictures = report_mission(args, setup, results)
    report_bag(setup)
    background.report(scene, args.method)
    print("\n" + "\n".join(f"picture: {p}" for p in pictures))
    print(f"bag:     {setup.run_dir / 'bag'}\ntotal time {time.monotonic() - t_start:.0f} s")
    return 130 if interrupted else 0


if __name__ == "__main__":
    sys.exit(main())
