"""The Lavaland experiments' command line with the graph: ``ird_core.experiments.cli`` plus
``--via-ros`` (docs/spec.md section 5).

    ird-experiments [ird_core.experiments.cli's flags] [--via-ros]

Without ``--via-ros`` this is exactly :func:`ird_core.experiments.cli.main` (same parser, same
trials, same report). With it, ``ird_ros.apps.experiments_via_ros.run_via_ros`` runs a few
trials through the graph's services instead (it imports ROS only when it runs).

BLAS is pinned to one thread per process before numpy loads (the pool's workers already use
every core; ``ird_core.experiments.parallel.BLAS_THREAD_VARIABLES``): this module is the entry
point, and ``ird_ros`` and ``ird_ros.apps`` load no numpy.
"""

from __future__ import annotations

import os

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")

import argparse  # noqa: E402
import sys  # noqa: E402

from ird_core.experiments import cli  # noqa: E402
from ird_core.experiments.trials import TrialSpec  # noqa: E402
from ird_ros.apps import experiments_via_ros  # noqa: E402

__all__ = ["VIA_ROS_EPILOG", "build_parser", "main"]

VIA_ROS_EPILOG = f"""
--via-ros: instead, run a few trials (--trials, default {experiments_via_ros.DEFAULT_TRIALS} here) through the
ROS graph's services (/world/generate, /ird/infer, /ird/plan) and compare the planned cells with
direct library calls; exit status 1 on any disagreement. Not with --world (use launch_graph.py
--world FILE).
"""


def build_parser() -> argparse.ArgumentParser:
    """:func:`ird_core.experiments.cli.build_parser` plus ``--via-ros``."""
    parser = cli.build_parser()
    parser.add_argument("--via-ros", action="store_true", help=f"run a few trials (default "
                        f"{experiments_via_ros.DEFAULT_TRIALS}) through the graph's services")
    parser.epilog = (parser.epilog or "") + VIA_ROS_EPILOG
    return parser


def _refuse_unhonoured(args: argparse.Namespace) -> None:
    """``ValueError`` naming the first model flag given away from its default: ``--via-ros``
    runs the graph as its parameters set it (the params file; ``launch_graph.py`` for the
    hypothesis space and training worlds), so such a flag would be silently ignored."""
    defaults = TrialSpec("side_effects", 0)
    for field in cli.MODEL_FLAGS:
        value = getattr(args, field, None)
        if value is not None and value != getattr(defaults, field):
            raise ValueError(f"--{field.replace('_', '-')}: not supported with --via-ros (the graph's parameters "
                             f"decide it: msgs_config/params/graph.yaml, launch_graph.py)")


def main(argv: list[str] | None = None) -> int:
    """The experiments, through the graph with ``--via-ros``; exit status 0, 1 (a --via-ros
    disagreement) or 2 (a bad argument)."""
    args = build_parser().parse_args(argv)
    if args.report_only and not args.via_ros:
        return cli.rewrite_report(args.out, args.merge)
    try:
        if args.report_only:
            raise ValueError("--report-only: not with --via-ros (it runs nothing)")
        settings = cli.trial_settings(args)
        if args.via_ros and args.world is not None:
            raise ValueError("--world: not supported with --via-ros (use launch_graph.py --world FILE)")
        if args.via_ros:
            _refuse_unhonoured(args)
        conditions = cli.world_conditions(args, settings)
    except ValueError as exc:
        print(exc, file=sys.stderr)
        return 2
    if args.via_ros:
        return experiments_via_ros.run_via_ros(args, settings)
    return cli.run_experiment(args, settings, conditions, cli.command_line(argv))
