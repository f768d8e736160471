#!/usr/bin/env python3
"""Start the IRD ROS graph (one process per node), wait until it is ready, supervise it.

    .venv/bin/python scripts/launch_graph.py [--nodes world,perception,...] [--params FILE] [--world FILE]
        [--record DIR] [--domain-id N | --private-domain] [--respawn NODE,...]
        [--timeout S] [--run-for S] [--output prefix|quiet|files] [--log-dir DIR] [--dds-network]

Prints each node's output as ``[node] line`` (``--output prefix``, the default), then a
status table (node, pid, state, ready after X s) once every node is ready, and reports a
node that dies (exit code or signal) and its restart when it is in --respawn (or in the
params file's ``launcher: ros__parameters: respawn: [...]``). Ctrl-C (SIGINT) or SIGTERM
stops everything within 5 s: SIGINT, then SIGTERM, then SIGKILL to each node's process
group; the recorder (--record) is stopped last, so the bag is complete. Children are also
told to stop (SIGTERM, via PR_SET_PDEATHSIG) if this launcher is killed with SIGKILL.

--private-domain leases a free ROS_DOMAIN_ID in 0..101 and sets a private ROS_LOG_DIR; the
chosen id is printed (``[launcher] ROS_DOMAIN_ID=N``) for clients to use. Without it,
--domain-id or the inherited ROS_DOMAIN_ID (default 0) is used; either must be in 0..101
(higher IDs put the DDS ports into Linux's ephemeral port range).

DDS transport: loopback only by default (the nodes and the launcher load
msgs_config/dds/fastdds_localhost.xml, so no socket binds outside 127.0.0.0/8 and nothing
off this machine can reach the graph). --dds-network (or IRD_DDS_NETWORK=1) is for a graph
spread over several machines: no profile, ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET. A
FASTRTPS_DEFAULT_PROFILES_FILE of your own is kept (see ird_ros/domains.py).

--world FILE (a world file, e.g. worlds/figure1.yaml): the world node publishes it instead of
a generated Lavaland and perception takes its classifier from it (both get ``-p
world_file:=FILE`` after the params file). The file is loaded here first: a bad file is
reported (file, key, value) with exit status 2 before any node starts.

Exit status: 0 after a requested stop (signal or --run-for); 1 if the graph could not start,
did not become ready within --timeout (what is missing is printed) or every node died; 2 for
bad arguments. See ird_ros/launcher.py for how readiness is decided.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout

from ird_ros.graph.domains import DDS_NETWORK_VAR  # noqa: E402
from ird_ros.launch.launcher import GraphLauncher, LaunchError, graph_specs  # noqa: E402


class _StopRequested(BaseException):
    pass


def _csv(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def main(argv: list[str] | None = None) -> int:
    names = [s.name for s in graph_specs()]
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    parser.add_argument("--nodes", type=_csv, default=None, help=f"comma-separated (default: {','.join(names)})")
    parser.add_argument("--world", type=Path, default=None, metavar="FILE",
                        help="world file (YAML) the world node publishes instead of generating Lavaland")
    parser.add_argument("--params", type=Path, default=None, help="ROS params file (default: msgs_config/params/graph.yaml)")
    parser.add_argument("--record", type=Path, default=None, metavar="DIR", help="record a bag (MCAP) into this new folder")
    parser.add_argument("--record-topics", type=_csv, default=None, help="topics to record (default: params file, else all)")
    dom = parser.add_mutually_exclusive_group()
    dom.add_argument("--domain-id", type=int, default=None, help="ROS domain of the graph, 0..101")
    dom.add_argument("--private-domain", action="store_true")
    parser.add_argument("--respawn", type=_csv, default=[], help="nodes to restart when they die")
    parser.add_argument("--respawn-delay", type=float, default=None, help="seconds before a restart (default 1.0)")
    parser.add_argument("--timeout", type=float, default=90.0, help="seconds to wait for readiness (default 90)")
    parser.add_argument("--run-for", type=float, default=None, help="stop after this many seconds of being ready")
    parser.add_argument("--output", choices=["prefix", "quiet", "files"], default="prefix")
    parser.add_argument("--log-dir", type=Path, default=None, help="ROS_LOG_DIR of the nodes (and logs for --output files)")
    parser.add_argument("--dds-network", action="store_true",
                        help="DDS on every interface, for multi-machine use (default: loopback only)")
    parser.add_argument("--node-table", default=None, metavar="MODULE:ATTR",
                        help="another node table (a list of ird_ros.launch.launcher.LaunchSpec), e.g. for tests' stand-ins")
    args = parser.parse_args(argv)

    # Ctrl-C / SIGTERM: stop the graph. Restore SIGINT explicitly: a launcher started with `&`
    # from a non-interactive shell has it ignored.
    state = {"stopping": False, "signal": None}

    def on_signal(signum: int, _frame: object) -> None:
        if state["stopping"]:
            return
        state["stopping"] = True
        state["signal"] = signal.Signals(signum).name
        raise _StopRequested()

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)

    if args.dds_network:
        os.environ[DDS_NETWORK_VAR] = "1"
    specs = None
    if args.node_table:
        import importlib

        module, _, attr = args.node_table.partition(":")
        specs = getattr(importlib.import_module(module), attr or "SPECS")
    if args.world is not None:
        from ird_core.worlds.world_file import load_world_file
        from ird_ros.nodes.world import with_world_file

        try:
            load_world_file(args.world)
        except ValueError as exc:
            print(f"[launcher] error: --world: {exc}", file=sys.stderr, flush=True)
            return 2
        specs = with_world_file(specs if specs is not None else graph_specs(optional=True), args.world)
    try:
        graph = GraphLauncher(
            specs=specs, nodes=args.nodes, params=args.params, record_dir=args.record, record_topics=args.record_topics,
            domain_id=args.domain_id, private_domain=args.private_domain, respawn=args.respawn,
            respawn_delay=args.respawn_delay, output=args.output, log_dir=args.log_dir,
        )
    except (LaunchError, ValueError) as exc:
        print(f"[launcher] error: {exc}", file=sys.stderr, flush=True)
        return 2

    code = 0
    t_start = time.monotonic()
    try:
        try:
            graph.start()
        except LaunchError as exc:
            print(f"[launcher] error: {exc}", file=sys.stderr, flush=True)
            code = 1
            return code
        print(f"[launcher] ROS_DOMAIN_ID={graph.domain_id} ROS_LOG_DIR={graph.env['ROS_LOG_DIR']}", flush=True)
        for name, pid in graph.pids().items():
            print(f"[launcher] started {name} pid {pid}", flush=True)
        try:
            graph.wait_ready(args.timeout)
        except LaunchError as exc:
            print(f"[launcher] error: {exc}", file=sys.stderr, flush=True)
            print(graph.status_table(), flush=True)
            code = 1
            return code
        # the table first: a line "graph ready after" means everything above it is out
        print(graph.status_table(), flush=True)
        print(f"[launcher] graph ready after {time.monotonic() - t_start:.2f} s", flush=True)
        wake = threading.Event()
        end = None if args.run_for is None else time.monotonic() + args.run_for
        while True:
            if graph.all_exited():
                print("[launcher] every node has exited", file=sys.stderr, flush=True)
                code = 1
                break
            if end is not None and time.monotonic() >= end:
                print(f"[launcher] --run-for {args.run_for:g} s elapsed", flush=True)
                break
            wake.wait(0.2)
    except _StopRequested:
        print(f"[launcher] {state['signal']} received: stopping", flush=True)
    finally:
        state["stopping"] = True
        codes = graph.stop()
        print(f"[launcher] stopped {len(codes)} process(es) in {graph.stop_duration or 0.0:.2f} s", flush=True)
        print(graph.status_table(), flush=True)
    return code


if __name__ == "__main__":
    sys.exit(main())
