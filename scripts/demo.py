#!/usr/bin/env python3
"""The demo mission: Rob, a proxy reward, and lava the designer never saw.

Starts the whole ROS 2 graph (world, perception, inference, planner, rob, recorder) in a
private domain, then, as an ordinary client of the graph:

1. reads the designer's proxy reward and the training map the world publishes;
2. calls ``/ird/infer`` (IRD posterior over the true reward given the proxy);
3. asks ``/ird/plan`` for the literal plan (the proxy taken at its word) and the IRD plan
   (risk-averse over the posterior samples);
4. lets Rob execute both plans on the test map and reads his reports on ``/rob/status``;
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
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as dt
import math
import multiprocessing
import signal
import sys
import time
from pathlib import Path

import numpy as np
import yaml

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from _demo_rounds import (  # noqa: E402
    Outcome,
    RoundResult,
    describe_counts,
    rounds_table,
    save_rounds_figure,
    terrain_counts,
)

from ird_core import posterior
from ird_core.designer.queries import STRATEGIES  # noqa: E402
from ird_core.experiments import MAIN_BASELINE, MAIN_GRANULARITY, QUICK, TrialSpec, run_trial, trial_instance  # noqa: E402
from ird_core.render import save_mission_figure  # noqa: E402
from ird_core.worlds import lavaland  # noqa: E402

#: The demo's default seed: the first one, and (with the default settings) one of the 5 of seeds
#: 0-19 on which the literal plan walks into lava, the failure the paper is about. The demo
#: prints the survey over those 20 seeds so this one mission is not mistaken for the average:
#: on most seeds the literal plan is safe, and IRD reaches a target on about half of them.
DEFAULT_SEED = 0
SURVEY_SEEDS = tuple(range(20))
#: Query rounds: 2 options (the exact best pair), info_gain; each round costs about a proposal
#: (candidates = the distinct plans of the posterior samples), a re-sampling and Rob's drive.
DEFAULT_NUM_OPTIONS = 2
#: The simulated designer answers by the Boltzmann rule on the options' true returns.
DEFAULT_DESIGNER_BETA = 1.0


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--condition", default="latent_raw", choices=lavaland.ALL_CONDITIONS)
    p.add_argument("--world", type=Path, default=None, metavar="FILE",
                   help="a world file (worlds/*.yaml) instead of a generated Lavaland")
    p.add_argument("--seed", type=int, default=DEFAULT_SEED, help="world seed (maps, proxy; also the designer's)")
    p.add_argument("--method", default="maxent_z", choices=posterior.METHODS)
    p.add_argument("--beta", type=float, default=None, help="designer rationality (default: the experiments')")
    p.add_argument("--num-samples", type=int, default=None, help="posterior samples (default: the experiments')")
    p.add_argument("--rate", type=float, default=10.0, help="Rob's speed, cells per second")
    p.add_argument("--out", default=str(REPO / "out" / "demo"), help="output folder (a run folder is made inside)")
    p.add_argument("--no-survey", action="store_true", help="skip the 20-seed survey")
    q = p.add_argument_group("questions to the designer (after the IRD plan)")
    q.add_argument("--queries", type=int, default=0, help="rounds of questions (0 = none: the plain mission)")
    q.add_argument("--designer", default="simulated", choices=("simulated", "web"),
                   help="who answers: the simulated designer node, or a person on the web page")
    q.add_argument("--num-options", type=int, default=DEFAULT_NUM_OPTIONS, help="paths per question")
    q.add_argument("--strategy", default="info_gain", choices=STRATEGIES, help="how the options are chosen")
    q.add_argument("--designer-beta", type=float, default=DEFAULT_DESIGNER_BETA,
                   help="simulated designer's rationality on the options' true returns")
    q.add_argument("--port", type=int, default=8765, help="web designer's port on 127.0.0.1")
    args = p.parse_args(argv)
    if args.queries < 0:
        p.error(f"--queries: must be >= 0, got {args.queries}")
    if args.designer == "web" and not args.queries:
        p.error("--designer web: the designer only answers questions; add --queries N")
    if args.num_options < 2:
        p.error(f"--num-options: must be >= 2, got {args.num_options}")
    if not 1 <= args.port <= 65535:
        p.error(f"--port: must be in 1..65535, got {args.port}")
    return args


def write_params(run_dir: Path, args: argparse.Namespace, spec: TrialSpec) -> Path:
    """The graph's parameter file with the experiments' world and sampler settings."""
    params = yaml.safe_load((REPO / "msgs_config" / "params" / "graph.yaml").read_text())
    world = params["world"]["ros__parameters"]
    world.update(condition=args.condition, seed=args.seed, height=spec.size, width=spec.size,
                 horizon=spec.horizon, obs_dim=spec.obs_dim)
    params["inference"]["ros__parameters"].update(
        num_chains=spec.num_chains, warmup=spec.warmup, thin=spec.thin,
        num_proxy_samples=spec.num_proxy_samples)
    if args.world is not None:
        for node in ("world", "perception"):
            params[node]["ros__parameters"]["world_file"] = str(args.world.resolve())
    params["rob"]["ros__parameters"]["rate_hz"] = float(args.rate)
    params["designer"]["ros__parameters"].update(mode=args.designer, beta=float(args.designer_beta),
                                                 seed=int(args.seed), port=int(args.port))
    path = run_dir / "graph.yaml"
    path.write_text(yaml.safe_dump(params, sort_keys=False))
    return path


def survey(spec: TrialSpec) -> dict[str, int]:
    """Seeds on which each planner touches lava, straight from ird_core (runs beside the graph)."""
    counts: dict[str, int] = {}
    for seed in SURVEY_SEEDS:
        for result in run_trial(dataclasses.replace(spec, seed=seed)):
            counts[result.planner] = counts.get(result.planner, 0) + int(result.touched_lava)
    return counts


@dataclasses.dataclass
class Results:
    """What the mission produced so far (filled as it goes, so Ctrl-C keeps what was done)."""

    outcomes: list[Outcome] = dataclasses.field(default_factory=list)
    risk: np.ndarray | None = None
    rounds: list[RoundResult] = dataclasses.field(default_factory=list)


def web_url(output: str, port: int) -> str:
    """The page's URL from the designer's log line ``designer web page at URL`` (else 127.0.0.1:port)."""
    marker = "designer web page at "
    lines = [line for line in output.splitlines() if marker in line]
    return lines[-1].split(marker, 1)[1].split()[0] if lines else f"http://127.0.0.1:{port}/"


def main() -> int:
    args = parse_args()
    # Imported here so `--help` works before the venv is complete.
    import rclpy
    from rclpy.executors import ExternalShutdownException

    from ird_ros.bags.analysis import analyze
    from ird_ros.graph import DEFAULT_NODES
    from ird_ros.graph.domains import ros_context
    from ird_ros.launch.launcher import GraphLauncher, LaunchError

    base = TrialSpec(condition=args.condition, seed=args.seed, **QUICK)  # the demo world: the small setting
    beta = args.beta if args.beta is not None else base.beta
    num_samples = args.num_samples if args.num_samples is not None else base.num_samples
    mode, baseline = MAIN_GRANULARITY, MAIN_BASELINE
    spec = dataclasses.replace(base, beta=beta, num_samples=num_samples, z_methods=(args.method,),
                               factorial=False)
    scene = args.condition
    if args.world is not None:
        from ird_core.worlds.world_file import load_world_file

        try:
            scene = load_world_file(args.world).name
        except ValueError as exc:
            print(f"[demo] --world: {exc}", file=sys.stderr)
            return 2
        spec = dataclasses.replace(spec, condition=lavaland.FILE_CONDITION, world=str(args.world.resolve()))
    # The world node builds (or loads) the same instance: its ground truth, for gold.
    inst = trial_instance(spec)

    run_dir = Path(args.out) / dt.datetime.now().strftime("run-%Y%m%d-%H%M%S")
    run_dir.mkdir(parents=True, exist_ok=False)
    params = write_params(run_dir, args, spec)
    t_start = time.monotonic()
    print(f"IRD demo: {'world file' if args.world else 'condition'} {scene}, seed {args.seed}, {args.method}, beta {beta}, "
          f"{num_samples} samples, IRD planner {mode}/{baseline}\noutput: {run_dir}", flush=True)
    if args.queries:
        print(f"then {args.queries} question(s) to the {args.designer} designer: {args.num_options} options "
              f"({args.strategy})" + (f", designer beta {args.designer_beta}" if args.designer == "simulated" else ""),
              flush=True)
    print(flush=True)

    # The survey's worker ignores Ctrl-C: the demo terminates it itself.
    pool = None if args.no_survey else multiprocessing.Pool(
        1, initializer=signal.signal, initargs=(signal.SIGINT, signal.SIG_IGN))
    survey_job = None if pool is None else pool.apply_async(survey, (spec,))

    results = Results()
    nodes = [*DEFAULT_NODES, "designer"] if args.queries else None
    interrupted = False
    try:
        with GraphLauncher(nodes=nodes, params=params, record_dir=run_dir / "bag", private_domain=True,
                           output="files", log_dir=run_dir / "logs") as graph:
            ready = graph.wait_ready(timeout=120)
            print(graph.status_table(), flush=True)
            print(f"graph ready in {max(ready.values()):.1f} s (domain {graph.domain_id})\n", flush=True)
            if args.queries and args.designer == "web":
                print(f"designer web page: {web_url(graph.output('designer', last=200), args.port)}\n"
                      "  (open it in a browser and answer each question; Ctrl-C stops the demo)\n", flush=True)
            with ros_context(graph.domain_id) as ctx:
                node = rclpy.create_node("ird_demo", context=ctx)
                try:
                    run_mission(node, args, spec, inst.test_labels, results)
                finally:
                    node.destroy_node()
    except LaunchError as exc:  # a node that never got ready: its log says why
        print(f"\n[demo] the graph did not start: {exc}\nnode logs: {run_dir / 'logs'}", flush=True)
        if pool is not None:
            pool.terminate()
        return 1
    except (KeyboardInterrupt, ExternalShutdownException):
        interrupted = True
        print("\n[demo] stopped by Ctrl-C: the graph was stopped and the bag closed.", flush=True)
        if pool is not None:
            pool.terminate()
            pool = None
    bag_dir = run_dir / "bag"

    pictures = []
    outcomes = results.outcomes
    if outcomes:
        pictures.append(run_dir / "mission.png")
        save_mission_figure(pictures[-1], inst.train_labels, inst.test_labels,
                            {o.label: o.cells for o in outcomes}, risk_map=results.risk,
                            title=f"{scene}, seed {args.seed}: literal proxy vs IRD",
                            train_start=inst.train_start, test_start=inst.test_start)
        print("\nMission results (from Rob's /rob/status):")
        print(f"  {'plan':<18} {'touched lava':>12} {'reached target':>15} {'true return':>12}")
        for o in outcomes:
            print(f"  {o.label:<18} {str(o.touched_lava):>12} {str(o.reached_target):>15} {o.true_return:>12.2f}")
    if args.queries and len(outcomes) == 2:
        literal, before = outcomes
        print(f"\nQuestions to the {args.designer} designer ({len(results.rounds)} answered; Rob's /rob/status, "
              "gold from the world's terrain):")
        print(rounds_table(literal, before, results.rounds))
        pictures.append(run_dir / "rounds.png")
        save_rounds_figure(pictures[-1], inst.test_labels, inst.test_start, literal, before, results.risk,
                           results.rounds,
                           title=f"{scene}, seed {args.seed}: IRD plan before and after each "
                                 f"answer of the {args.designer} designer")

    if bag_dir.is_dir():
        summary = analyze(bag_dir, out_dir=run_dir / "bag_plots")
        recorded = sorted((t["topic"], t["count"]) for t in summary["topics"])
        print(f"\nBag {bag_dir}: " + ", ".join(f"{topic} {count}" for topic, count in recorded))

    if survey_job is not None and pool is not None:
        counts = survey_job.get()
        n = len(SURVEY_SEEDS)
        print(f"\nOver seeds {SURVEY_SEEDS[0]}-{SURVEY_SEEDS[-1]} ({scene}, same settings, ird_core "
              f"directly): literal touches lava on {counts['literal']}/{n}, "
              f"IRD on {counts['ird_' + args.method]}/{n}.")
        pool.close()
        pool.join()
    print("\n" + "\n".join(f"picture: {p}" for p in pictures))
    print(f"bag:     {bag_dir}\ntotal time {time.monotonic() - t_start:.0f} s")
    return 130 if interrupted else 0


class MissionClient:
    """The demo's client of the graph: Rob's status, the world's proxy and test map, the planner."""

    def __init__(self, node, test_labels: np.ndarray) -> None:
        from nav_msgs.msg import OccupancyGrid

        from ird_msgs.msg import FeatureGrid, ProxyReward, RobStatus
        from ird_msgs.srv import PlanPath
        from ird_ros.client.waits import receive_messages, wait_for_publishers
        from ird_ros.graph import names

        self.node, self.test_labels = node, test_labels
        # Rob's status is a volatile stream: subscribe and wait for the match before any plan exists.
        self.status: list = []
        status_sub = node.create_subscription(RobStatus, names.TOPIC_ROB_STATUS, self.status.append, 100)
        wait_for_publishers(node, status_sub, timeout=60)
        self.proxy = receive_messages(node, ProxyReward, names.TOPIC_PROXY, timeout=60)[-1]
        self.train = receive_messages(node, FeatureGrid, names.TOPIC_TRAIN_FEATURES, timeout=60)[-1]
        self.test = receive_messages(node, FeatureGrid, names.TOPIC_TEST_FEATURES, timeout=60)[-1]
        self.risk_msgs: list = []
        node.create_subscription(OccupancyGrid, names.TOPIC_RISK_MAP, self.risk_msgs.append, names.latched_qos())
        self.planner = node.create_client(PlanPath, names.SRV_PLAN)

    def drive(self, label: str, mode: str, baseline: str, weights: list[float]) -> Outcome:
        """``/ird/plan`` (empty weights: the world's proxy for literal), then wait for Rob to finish it."""
        from ird_msgs.srv import PlanPath
        from ird_ros.client.waits import call_service, spin_until

        req = PlanPath.Request()  # map empty = the latest perceived test map
        proxy = self.proxy
        req.start_row, req.start_col, req.horizon = proxy.test_start_row, proxy.test_start_col, proxy.test_horizon
        req.mode, req.baseline, req.label = mode, baseline, label
        req.weights = weights
        plan = call_service(self.node, self.planner, req, timeout=300)
        if not plan.success:
            raise SystemExit(f"/ird/plan ({label}) failed: {plan.message}")
        stamp = plan.path.header.stamp
        print(f"/ird/plan {label}: objective {plan.objective:.3f}; Rob executes it...", flush=True)

        def finished() -> bool:
            return any(s.done and s.plan_stamp == stamp for s in self.status)

        spin_until(self.node, finished, timeout=120, what=f"Rob finishing the {label} plan")
        final = [s for s in self.status if s.done and s.plan_stamp == stamp][-1]
        cells = list(zip(plan.rows, plan.cols))
        return Outcome(label, cells, plan.objective, final.touched_lava, final.reached_target, final.true_return,
                       lavaland.reaches_gold(self.test_labels, cells))

    def latest_risk(self, after: int = 0, timeout: float = 30.0) -> np.ndarray:
        """The latest /ird/risk_map once more than ``after`` were received."""
        from ird_ros import conversions as conv
        from ird_ros.client.waits import spin_until

        spin_until(self.node, lambda: len(self.risk_msgs) > after, timeout=timeout, what="a new risk map on /ird/risk_map")
        return conv.occupancy_grid_from_msg(self.risk_msgs[-1])


def run_mission(node, args: argparse.Namespace, spec: TrialSpec, test_labels: np.ndarray, results: Results) -> None:
    """The client side of the mission: infer, plan twice, watch Rob; then the rounds of questions."""
    from ird_msgs.msg import FeatureGrid
    from ird_msgs.srv import InferReward
    from ird_ros.client.waits import call_service, receive_messages
    from ird_ros.graph import names
    from ird_ros.nodes.world import TOPIC_INFER_REQUEST

    client = MissionClient(node, test_labels)
    proxy = client.proxy
    if args.world is not None:  # every training world of the file, as the world node poses it
        request = receive_messages(node, InferReward.Request, TOPIC_INFER_REQUEST, timeout=60)[-1]
    else:
        request = InferReward.Request()
        request.training_map = client.train
        request.start_row, request.start_col, request.horizon = proxy.start_row, proxy.start_col, proxy.horizon
        request.proxy_weights = list(proxy.weights)
    if args.condition == "latent_classifier" and args.world is None:  # the proxy is on the classified map
        request.proxy_map = receive_messages(node, FeatureGrid, names.TOPIC_TRAIN_PROXY_FEATURES, timeout=60)[-1]
    request.beta, request.method = float(spec.beta), args.method
    request.num_samples, request.seed = int(spec.num_samples), int(args.seed)
    infer = node.create_client(InferReward, names.SRV_INFER)
    t0 = time.monotonic()
    response = call_service(node, infer, request, timeout=300)
    if not response.success:
        raise SystemExit(f"/ird/infer failed: {response.message}")
    post = response.posterior
    print(f"/ird/infer: {post.num_samples} samples in {time.monotonic() - t0:.1f} s, "
          f"acceptance {post.acceptance_rate:.2f}, R-hat {post.r_hat_max:.3f}, ESS {post.ess_min:.0f}",
          flush=True)

    results.outcomes.append(client.drive("literal", "literal", "none", []))
    results.outcomes.append(client.drive(f"IRD {MAIN_GRANULARITY}", MAIN_GRANULARITY, MAIN_BASELINE,
                                         list(post.samples)))
    results.risk = client.latest_risk()
    if args.queries:
        run_rounds(client, args, results)


def run_rounds(client: MissionClient, args: argparse.Namespace, results: Results) -> None:
    """``args.queries`` rounds: /ird/query, the designer's answer (on /ird/queries) and its
    re-sampled posterior, the planner's new risk map, a new IRD plan that Rob drives."""
    from ird_msgs.msg import QueryRecord, RewardPosterior
    from ird_msgs.srv import ProposeQuery
    from ird_ros import conversions as conv
    from ird_ros.client.waits import call_service, spin_until
    from ird_ros.graph import names

    node, proxy = client.node, client.proxy
    grid = conv.feature_grid_from_msg(client.test, field=names.TOPIC_TEST_FEATURES)
    records: list = []
    posteriors: list = []
    node.create_subscription(QueryRecord, names.TOPIC_QUERIES, records.append, names.history_qos())
    node.create_subscription(RewardPosterior, names.TOPIC_POSTERIOR, posteriors.append, names.latched_qos())
    query = node.create_client(ProposeQuery, names.SRV_QUERY)
    # A person takes as long as they take; the simulated designer answers within a re-sampling.
    answer_timeout = math.inf if args.designer == "web" else 300.0
    t_rounds = time.monotonic()
    for index in range(1, args.queries + 1):
        risk_count = len(client.risk_msgs)
        req = ProposeQuery.Request(start_row=proxy.test_start_row, start_col=proxy.test_start_col, horizon=0,
                                   num_options=args.num_options, strategy=args.strategy,
                                   seed=(args.seed + index) % 2**32)
        t0 = time.monotonic()
        response = call_service(node, query, req, timeout=300)
        if not response.success:
            if response.message.startswith("num_options"):  # every sample plans the same few paths
                print(f"round {index}: nothing left to ask ({response.message})", flush=True)
                break
            raise SystemExit(f"/ird/query failed: {response.message}")
        qid = int(response.query_id)
        options = tuple(np.array(conv.path_to_cells(p, resolution=grid.resolution, origin=grid.origin),
                                 dtype=np.int64) for p in response.options)
        counts = terrain_counts(client.test_labels, options)
        described = "; ".join(f"{k}: {describe_counts(c)}" for k, c in enumerate(counts))
        print(f"round {index}: query {qid} in {time.monotonic() - t0:.1f} s, information gain "
              f"{response.information_gain:.3f} nats; options {described}; waiting for the {args.designer} "
              "designer...", flush=True)

        def answered(qid: int = qid) -> list:
            return [r for r in records if r.event == "answered" and int(r.query_id) == qid]

        spin_until(node, lambda: bool(answered()), timeout=answer_timeout, what=f"the answer to query {qid}")
        record = answered()[0]
        spin_until(node, lambda r=record: any(p.header.stamp == r.header.stamp for p in posteriors), timeout=60,
                   what=f"the posterior of the answer to query {qid}")
        post = next(p for p in posteriors if p.header.stamp == record.header.stamp)
        risk = client.latest_risk(after=risk_count)
        print(f"round {index}: option {record.chosen} chosen by {record.answered_by}; re-sampled posterior "
              f"({post.num_samples} samples, R-hat {post.r_hat_max:.3f}) {time.monotonic() - t0:.1f} s after the "
              "question",
              flush=True)
        plan = client.drive(f"IRD after {index}", MAIN_GRANULARITY, MAIN_BASELINE, list(post.samples))
        results.rounds.append(RoundResult(index, qid, float(response.information_gain), options, int(record.chosen),
                                          str(record.answered_by), plan, counts, risk))
    print(f"{len(results.rounds)} round(s) (question, answer, re-sampling, new plan, Rob's drive) in "
          f"{time.monotonic() - t_rounds:.1f} s", flush=True)


if __name__ == "__main__":
    sys.exit(main())
