"""Start the IRD ROS graph (one process per node), wait until it is ready, supervise it.

    .venv/bin/python scripts/launch_graph.py [--nodes world,perception,...] [--params FILE] [--world FILE]
        [--record DIR] [--domain-id N | --private-domain] [--respawn NODE,...]
        [--timeout S] [--run-for S] [--output prefix|quiet|files] [--log-dir DIR] [--dds-network]
        [--mission [N] [--mission-then-exit]] [--viz [--viz-port PORT]]

Prints each node's output as ``[node] line`` (``--output prefix``, the default), then a
status table (node, pid, state, ready after X s) once every node is ready, and reports a
node that dies (exit code or signal) and its restart when it is in --respawn (or in the
params file's ``launcher: ros__parameters: respawn: [...]``); a node that keeps dying is
given up after --respawn-max-retries restarts. Ctrl-C (SIGINT) or SIGTERM stops everything
within 5 s: SIGINT, then SIGTERM, then SIGKILL to each node's process group; the recorder
(--record) is stopped last, so the bag is complete. Children are also told to stop (SIGTERM,
via PR_SET_PDEATHSIG) if this launcher is killed with SIGKILL.

--private-domain leases a free ROS_DOMAIN_ID in 0..101 and sets a private ROS_LOG_DIR; the
chosen id is printed (``[launcher] ROS_DOMAIN_ID=N (this graph)``, then the line a second shell
runs to attach: ``export ROS_DOMAIN_ID=N; source scripts/lib/ros_env.sh && ird_ros_env``). Without it,
--domain-id or the inherited ROS_DOMAIN_ID (default 0) is used; either must be in 0..101
(higher IDs put the DDS ports into Linux's ephemeral port range).

DDS transport: loopback only by default (the nodes and the launcher load
msgs_config/dds/fastdds_localhost.xml, so no socket binds outside 127.0.0.0/8 and nothing
off this machine can reach the graph). --dds-network (or IRD_DDS_NETWORK=1) is for a graph
spread over several machines: no profile, ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET. A
FASTRTPS_DEFAULT_PROFILES_FILE of your own is kept (see ird_ros/graph/domains.py).

--world FILE (a world file, e.g. worlds/figure1.yaml): the world node publishes it instead of
a generated Lavaland and perception takes its classifier from it (both get ``-p
world_file:=FILE`` after the params file). The file is loaded here first, with every check the
services would apply later (sizes, horizons, yaw; ``ird_core.worlds.world_file``): a bad file is
reported (file, key, value) with exit status 2 before any node starts, and what loads but looks
wrong (a start on a terrain no training world shows) is printed as a ``[launcher] warning:`` line.

--hypothesis rff, --rff-features D, --novelty-feature: IRD's hypothesis space (default: the
params file's, the paper's linear space): the world node then also publishes
/world/hypothesis/{train,test}_features and poses /ird/infer in that space
(``ird_core.hypothesis``; docs/spec.md section 6). --training-worlds K: a generated Lavaland
has K training worlds, the proxy observed in each (``ird_core.worlds.training_worlds``).

--mission [N] (N = 1 without a number): once the graph is ready, a client sends Rob navigation
goals through the navigator's action /ird/navigate: for each seed 0..N-1 it generates that seed's
world (/world/generate; with --world the file's world stays and the seed seeds the sampler), then
the literal goal and the IRD goal (MaxEnt-Z posterior, per-step risk-averse plan), each driven to
the end, one printed line per goal (``[mission] seed 0 ird: SUCCEEDED, lava False, ...``; see
ird_ros/apps/mission.py). The graph then keeps running (--run-for counts from there) so a
recorder (--record) holds the missions for analyze_bag.py; --mission-then-exit stops it instead,
with exit status 0 if every goal succeeded, else 1. --viz adds the viz node (a live view over the
Foxglove protocol) when this checkout has it; --viz-port PORT picks its port (default: the params
file's, 8766; 0 = any free port) and the launcher prints the live view's URL once the graph is
ready (``[launcher] live view: ws://127.0.0.1:PORT``). A port in use stops the viz node at
start-up with a message naming --viz-port (a second graph with --viz needs another port).

Exit status: 0 after a requested stop (signal or --run-for, also during the start-up checks);
1 if the graph could not start, did not become ready within --timeout (what is missing is
printed) or every node died; 2 for bad arguments or a bad --world file. See
ird_ros/launch/launcher.py for how readiness is decided.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import threading
import time
from pathlib import Path

from ird_core.hypothesis import DEFAULT_RFF_FEATURES, HYPOTHESES, HypothesisSpace
from ird_core.worlds.training_worlds import MAX_TRAINING_WORLDS, check_training_worlds
from ird_core.worlds.world_file import load_world_file
from ird_ros.arg_types import seconds, seconds_or_zero
from ird_ros.graph import DEFAULT_NODES, NODES, NODES_BY_NAME, NodeSpec, names
from ird_ros.graph.domains import DDS_NETWORK_VAR, domain_banner
from ird_ros.launch import GraphLauncher, LaunchError, OutputMode
from ird_ros.launch.plan import with_viz_port
from ird_ros.nodes.world import with_generated_training_worlds, with_hypothesis, with_world_file

__all__ = ["main", "build_parser"]


class _StopRequested(BaseException):
    """Raised by the SIGINT/SIGTERM handler to leave the wait for the graph."""


class _StopSignals:
    """SIGINT and SIGTERM raise ``_StopRequested`` once, and not after ``stopping`` is set.

    SIGINT is set explicitly: a launcher started with ``&`` from a non-interactive shell has it ignored.
    """

    def __init__(self) -> None:
        self.received: str | None = None
        self.stopping = False
        signal.signal(signal.SIGINT, self._handle)
        signal.signal(signal.SIGTERM, self._handle)

    def _handle(self, signum: int, _frame: object) -> None:
        if self.stopping:
            return
        self.stopping = True
        self.received = signal.Signals(signum).name
        raise _StopRequested()


def _csv(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def build_parser() -> argparse.ArgumentParser:
    """The command line (every option documented in ``--help``)."""
    first, rest = __doc__.split("\n\n", 1)  # the usage line once (description), the rest as epilog
    parser = argparse.ArgumentParser(description=first, formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog=rest)
    parser.add_argument("--nodes", type=_csv, default=None, help=f"comma-separated (default: {','.join(DEFAULT_NODES)})")
    parser.add_argument("--world", type=Path, default=None, metavar="FILE",
                        help="world file (YAML) the world node publishes instead of generating Lavaland")
    parser.add_argument("--hypothesis", choices=HYPOTHESES, default=None,
                        help="IRD's hypothesis space (default: the params file's, linear)")
    parser.add_argument("--rff-features", type=int, default=None, metavar="D",
                        help=f"random Fourier features of --hypothesis rff (default {DEFAULT_RFF_FEATURES})")
    parser.add_argument("--novelty-feature", action="store_true",
                        help="add the hypothesis feature 'novel' (zero in training)")
    parser.add_argument("--training-worlds", type=int, default=None, metavar="K",
                        help=f"training worlds of a generated Lavaland, 1..{MAX_TRAINING_WORLDS} (default: the params "
                             "file's, 1; ird_core.worlds.training_worlds)")
    parser.add_argument("--params", type=Path, default=None, help="ROS params file (default: msgs_config/params/graph.yaml)")
    parser.add_argument("--record", type=Path, default=None, metavar="DIR", help="record a bag (MCAP) into this new folder")
    parser.add_argument("--record-topics", type=_csv, default=None, help="topics to record (default: params file, else all)")
    dom = parser.add_mutually_exclusive_group()
    dom.add_argument("--domain-id", type=int, default=None, help="ROS domain of the graph, 0..101")
    dom.add_argument("--private-domain", action="store_true",
                     help="lease a free ROS domain in 0..101 (printed as ROS_DOMAIN_ID=N) with a private ROS_LOG_DIR")
    parser.add_argument("--respawn", type=_csv, default=[], help="nodes to restart when they die")
    parser.add_argument("--respawn-delay", type=float, default=None, help="seconds before a restart (default: params file, else 1.0)")
    parser.add_argument("--respawn-max-retries", type=int, default=None, metavar="N",
                        help="restarts of one node before giving up on it, -1 for no limit (default: params file, else 5)")
    parser.add_argument("--timeout", type=seconds, default=90.0, help="seconds to wait for readiness (default 90)")
    parser.add_argument("--run-for", type=seconds_or_zero, default=None, help="stop after this many seconds of being ready")
    parser.add_argument("--output", choices=[m.value for m in OutputMode], default=OutputMode.PREFIX.value,
                        help="nodes' output: prefix (printed as [node] line), quiet (shown on errors), "
                             "files (<log-dir>/<node>.log)")
    parser.add_argument("--log-dir", type=Path, default=None, help="ROS_LOG_DIR of the nodes (and logs for --output files)")
    parser.add_argument("--dds-network", action="store_true",
                        help="DDS on every interface, for multi-machine use (default: loopback only)")
    parser.add_argument("--node-table", default=None, metavar="MODULE:ATTR",
                        help="another node table (a list of ird_ros.graph.NodeSpec), e.g. for tests' stand-ins")
    parser.add_argument("--viz", action="store_true",
                        help="also start the viz node (live view over the Foxglove protocol), if the node table has it")
    parser.add_argument("--viz-port", type=int, default=None, metavar="PORT",
                        help="the live view's port (default: the params file's, 8766; 0 = any free port, printed); "
                             "with --viz or viz in --nodes")
    mission = parser.add_argument_group("mission (navigation goals once the graph is ready)")
    mission.add_argument("--mission", type=int, nargs="?", const=1, default=None, metavar="N",
                         help="for seeds 0..N-1 (N = 1 if omitted): generate the seed's world and send Rob the "
                              "literal and the IRD goal through /ird/navigate; then keep running")
    mission.add_argument("--mission-then-exit", action="store_true",
                         help="with --mission: stop the graph after the goals (exit 0 if all succeeded, else 1)")
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    _check_mission_args(parser, args)
    signals = _StopSignals()
    if args.dds_network:
        os.environ[DDS_NETWORK_VAR] = "1"
    try:
        graph = _make_launcher(args)
    except (LaunchError, ValueError) as exc:
        _error(str(exc))
        return 2
    except _StopRequested:  # while loading --world: nothing was started
        print(f"[launcher] {signals.received} received: stopping", flush=True)
        return 0
    return _run(graph, args, signals)


def _check_mission_args(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """``--mission`` needs N >= 1 and the world and navigator nodes; ``--viz`` adds viz when it exists."""
    if args.mission_then_exit and args.mission is None:
        parser.error("--mission-then-exit: only with --mission")
    if args.mission is not None and args.mission < 1:
        parser.error(f"--mission: N must be >= 1, got {args.mission}")
    if args.mission is not None and args.nodes is not None and not {"world", "navigator"} <= set(args.nodes):
        parser.error("--mission: needs the world and navigator nodes in --nodes")
    if args.viz and "viz" not in NODES_BY_NAME:
        print("[launcher] --viz: this checkout has no viz node; starting without it", flush=True)
    elif args.viz and "viz" not in (args.nodes or ()):
        args.nodes = [*(args.nodes if args.nodes is not None else DEFAULT_NODES), "viz"]
    if args.viz_port is not None:
        if "viz" not in (args.nodes or ()):
            parser.error("--viz-port: only with --viz (or viz in --nodes)")
        if not 0 <= args.viz_port <= 65535:
            parser.error(f"--viz-port: must be in 0..65535 (0 = any free port), got {args.viz_port}")


def _make_launcher(args: argparse.Namespace) -> GraphLauncher:
    """The launcher the options ask for; ``ValueError`` or ``LaunchError`` for bad ones."""
    return GraphLauncher(
        specs=_node_table(args), nodes=args.nodes, params=args.params, record_dir=args.record,
        record_topics=args.record_topics, domain_id=args.domain_id, private_domain=args.private_domain,
        respawn=args.respawn, respawn_delay=args.respawn_delay, respawn_max_retries=args.respawn_max_retries,
        output=args.output, log_dir=args.log_dir)


def _node_table(args: argparse.Namespace) -> list[NodeSpec] | None:
    """``--node-table`` (default: the graph's), with ``--world``'s file, which is checked first."""
    specs: list[NodeSpec] | None = None
    if args.node_table:
        module, _, attr = args.node_table.partition(":")
        specs = list(getattr(importlib.import_module(module), attr or "SPECS"))
    if args.viz_port is not None:
        specs = with_viz_port(specs, args.viz_port)
    if args.hypothesis is not None or args.rff_features is not None or args.novelty_feature:
        try:
            space = HypothesisSpace(args.hypothesis or "linear", DEFAULT_RFF_FEATURES if args.rff_features is None
                                    else args.rff_features, args.novelty_feature)
        except ValueError as exc:
            raise ValueError(f"--rff-features: {exc}") from None  # the one field argparse leaves unchecked
        specs = with_hypothesis(specs if specs is not None else NODES, space)
    if args.training_worlds is not None:
        try:
            check_training_worlds(args.training_worlds)
        except ValueError as exc:
            raise ValueError(f"--training-worlds: {exc}") from None
        specs = with_generated_training_worlds(specs if specs is not None else NODES, args.training_worlds)
    if args.world is None:
        return specs
    try:
        loaded = load_world_file(args.world)
    except ValueError as exc:
        raise ValueError(f"--world: {exc}") from None
    for warning in loaded.warnings:
        print(f"[launcher] warning: --world: {warning}", file=sys.stderr, flush=True)
    return with_world_file(specs if specs is not None else NODES, args.world)


def _run(graph: GraphLauncher, args: argparse.Namespace, signals: _StopSignals) -> int:
    """Start the graph, wait for it, supervise it until a stop; always stop it. The exit status."""
    t_start = time.monotonic()
    try:
        code = _start_and_wait(graph, args.timeout, t_start)
        if code:
            return code
        if "viz" in graph.pids():
            _print_live_view(graph)
        if args.mission is not None:
            code = _mission(graph, args)
            if args.mission_then_exit:
                return code
        return _supervise(graph, args.run_for)
    except _StopRequested:
        print(f"[launcher] {signals.received} received: stopping", flush=True)
        return 0
    finally:
        signals.stopping = True  # a later signal is ignored: the stop below is under way
        codes = graph.stop()
        print(f"[launcher] stopped {len(codes)} process(es) in {graph.stop_duration or 0.0:.2f} s", flush=True)
        print(graph.status_table(), flush=True)


def _start_and_wait(graph: GraphLauncher, timeout: float, t_start: float) -> int:
    """Start the graph and wait until it is ready: 0, or 1 (the error printed)."""
    try:
        graph.start()
    except LaunchError as exc:
        _error(str(exc))
        return 1
    domain, attach = domain_banner(graph.domain_id).splitlines()
    print(f"[launcher] {domain} ROS_LOG_DIR={graph.env['ROS_LOG_DIR']}\n[launcher] {attach}", flush=True)
    for name, pid in graph.pids().items():
        print(f"[launcher] started {name} pid {pid}", flush=True)
    try:
        graph.wait_ready(timeout)
    except LaunchError as exc:
        _error(str(exc))
        print(graph.status_table(), flush=True)
        return 1
    # the table first: a line "graph ready after" means everything above it is out
    print(graph.status_table(), flush=True)
    print(f"[launcher] graph ready after {time.monotonic() - t_start:.2f} s", flush=True)
    return 0


def _print_live_view(graph: GraphLauncher) -> None:
    """The viz node's URL (the bound port, also for --viz-port 0), from its latched /viz/status."""
    import json

    from ird_ros.client import ClientTimeout, IrdClient

    try:
        with IrdClient(graph.domain_id, node_name=names.NODE_LAUNCHER_VIZ_STATUS) as ird:
            status = json.loads(ird.latest(names.TOPIC_VIZ_STATUS, timeout=30).data)
    except (ClientTimeout, ValueError, KeyError) as exc:
        _error(f"--viz: could not read /viz/status ({exc})")
        return
    print(f"[launcher] live view: {status['url']} (Foxglove or Lichtblick: open connection, Foxglove WebSocket)",
          flush=True)


def _mission(graph: GraphLauncher, args: argparse.Namespace) -> int:
    """``--mission``: the navigation goals (``ird_ros.apps.mission``); 0 if every goal succeeded, else 1."""
    from ird_ros.apps.mission import run_mission
    from ird_ros.client import ClientTimeout

    try:
        return run_mission(graph.domain_id, range(args.mission), generate=args.world is None,
                           echo=lambda line: print(line, flush=True))
    except ClientTimeout as exc:
        _error(f"--mission: {exc}")
        return 1


def _supervise(graph: GraphLauncher, run_for: float | None) -> int:
    """Wait until every node has exited (1) or ``run_for`` seconds passed (0)."""
    wake = threading.Event()
    end = None if run_for is None else time.monotonic() + run_for
    while True:
        if graph.all_exited():
            print("[launcher] every node has exited", file=sys.stderr, flush=True)
            return 1
        if end is not None and time.monotonic() >= end:
            print(f"[launcher] --run-for {run_for:g} s elapsed", flush=True)
            return 0
        wake.wait(0.2)


def _error(text: str) -> None:
    print(f"[launcher] error: {text}", file=sys.stderr, flush=True)
