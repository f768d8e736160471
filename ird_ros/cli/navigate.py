"""``ird navigate``: send a NavigateIrd goal to ``/ird/navigate``, print its feedback and result.

    ird navigate                                   # infer (MaxEnt-Z), plan per step, drive Rob
    ird navigate --mode literal                    # the proxy taken at its word
    ird navigate --method "" --risk-measure cvar --risk-level 0.25   # the current posterior, CVaR
    ird navigate --queries 2                       # ask the designer twice first (a designer must run)

Prints one ``feedback:`` line per new feedback (stage, Rob's cell, progress, the posterior), then
``result: STATUS ...`` with Rob's lava, target and true return and the cells he drove. Ctrl-C
cancels the goal (Rob stops where he is), prints how it ended and exits 130; a second Ctrl-C
leaves at once. Exit status: 0 SUCCEEDED; 2 a goal with a bad field (one line naming it: ``bad
goal: beta: ...`` before anything is sent, by the navigator's own checks within the message's
ranges; ``goal rejected: queries: ...`` when the navigator's parameters refuse it); 1 otherwise (ABORTED, CANCELED by someone else, a goal already active, no
graph). The goal's fields and their defaults are the action's (``msgs_config/ird_msgs/action``).
"""

from __future__ import annotations

import argparse
from typing import Any

from ird_core.vocabulary import BASELINES, METHODS, MODES, RISK_MEASURES
from ird_ros.arg_types import seconds
from ird_ros.cli.common import (
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    CliError,
    add_domain_options,
    client,
    no_graph,
    say,
)
from ird_ros.graph import names

__all__ = ["add_parser", "run", "goal_from_args", "feedback_line", "result_lines"]


def add_parser(verbs: Any) -> None:
    parser = verbs.add_parser("navigate", help="send Rob a navigation goal (/ird/navigate) and follow it",
                              description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 1)[1],
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    goal = parser.add_argument_group("the goal (NavigateIrd.Goal; 0 and \"\" mean the navigator's defaults)")
    goal.add_argument("--method", default="maxent_z", choices=("", *METHODS),
                      help="posterior approximation; \"\" = the current /ird/posterior (default maxent_z)")
    goal.add_argument("--beta", type=float, default=0.0, help="designer rationality in [0, 1000] (default 0)")
    goal.add_argument("--num-samples", type=int, default=0, metavar="K", help="posterior samples (default 0)")
    goal.add_argument("--seed", type=int, default=0, help="seed of the sampler and the questions (default 0)")
    goal.add_argument("--mode", default="per_step", choices=MODES, help="planner granularity (default per_step)")
    goal.add_argument("--baseline", default="training_features", choices=BASELINES,
                      help="reward baseline (default training_features)")
    goal.add_argument("--risk-measure", default="", choices=("", *RISK_MEASURES),
                      help="risk measure over the samples (default \"\": the planner's)")
    goal.add_argument("--risk-level", type=float, default=0.0,
                      help="cvar's alpha in (0, 1] or mean_sd's lambda in [0, 100] (default 0)")
    goal.add_argument("--queries", type=int, default=0, help="designer questions before driving (default 0)")
    goal.add_argument("--label", default="ird_cli", help="the plan's label in PlanInfo and Rob's status")
    parser.add_argument("--no-feedback", action="store_true", help="print only the result")
    parser.add_argument("--result-timeout", type=seconds, default=600.0, metavar="S",
                        help="seconds for the whole goal before giving up with exit 1 (default 600)")
    add_domain_options(parser)
    parser.set_defaults(run=run)


def goal_from_args(args: argparse.Namespace) -> Any:
    """The :class:`~ird_ros.client.NavigationGoal` of the options."""
    from ird_ros.client import NavigationGoal

    return NavigationGoal(method=args.method, beta=args.beta, num_samples=args.num_samples, seed=args.seed,
                          mode=args.mode, baseline=args.baseline, risk_measure=args.risk_measure,
                          risk_level=args.risk_level, queries=args.queries, label=args.label)


def feedback_line(feedback: Any) -> str:
    """One printed line of a :class:`~ird_ros.client.NavigationFeedback`."""
    cell = "" if feedback.pose_cell is None else f", cell ({feedback.pose_cell[0]},{feedback.pose_cell[1]})"
    summary = f", posterior {feedback.posterior_summary}" if feedback.posterior_summary else ""
    return f"feedback: {feedback.stage}{cell}, progress {feedback.progress:.2f}{summary}"


def _flag(value: bool | None) -> str:
    return "-" if value is None else str(value)


def result_lines(result: Any) -> list[str]:
    """The printed lines of a :class:`~ird_ros.client.NavigationResult`: status and outcome, cells."""
    status = result.status.name
    head = f"result: {status}" + ("" if status == "SUCCEEDED" else f" ({result.message})")
    if status == "REJECTED":
        return [head]
    ret = "-" if result.true_return is None else f"{result.true_return:.2f}"
    lines = [f"{head}: lava {_flag(result.touched_lava)}, target {_flag(result.reached_target)}, "
             f"true return {ret}, {len(result.cells)} cells"]
    if len(result.cells):
        lines.append("cells: " + " ".join(f"({r},{c})" for r, c in result.cells))
    return lines


def _exit_status(result: Any) -> int:
    if result.status.name == "SUCCEEDED":
        return EXIT_OK
    if result.status.name == "REJECTED" and result.field:
        raise CliError(f"goal rejected: {result.message}", EXIT_USAGE)
    return EXIT_FAILED


def check_goal_options(args: argparse.Namespace) -> None:
    """The goal's fields checked as the navigator checks them (``ird_ros.jobs.navigation.check_goal``)
    against the message's own bounds (the navigator's limits are its parameters, checked there):
    ``CliError`` (exit 2) naming the field before the command looks for a graph."""
    from ird_ros.jobs.navigation import GoalLimits, check_goal

    int32_max = 2**31 - 1
    try:
        check_goal(method=args.method, beta=args.beta, num_samples=args.num_samples, seed=args.seed, mode=args.mode,
                   baseline=args.baseline, risk_measure=args.risk_measure, risk_level=args.risk_level,
                   queries=args.queries, label=args.label,
                   limits=GoalLimits(max_queries=int32_max, max_num_samples=int32_max))
    except ValueError as exc:  # the bounds are the message's here, not the navigator's parameters
        text = str(exc).replace(f"max_num_samples={int32_max}", str(int32_max))
        raise CliError(f"bad goal: {text.replace(f'max_queries={int32_max}', str(int32_max))}", EXIT_USAGE) from None


def run(args: argparse.Namespace) -> int:
    from ird_ros.client import ClientTimeout, GraphNotFound

    check_goal_options(args)
    goal = goal_from_args(args)
    last: list[str] = []

    def on_feedback(feedback: Any) -> None:
        line = feedback_line(feedback)
        if not args.no_feedback and (not last or line != last[-1]):
            print(line, flush=True)
            last[:] = [line]

    with client(args, "navigate") as ird:
        try:
            handle = ird.navigate_async(goal, on_feedback=on_feedback, timeout=args.timeout)
        except GraphNotFound:
            raise no_graph(ird.domain_id, f"no navigator serving {names.ACTION_NAVIGATE} within "
                                          f"{args.timeout:g} s") from None
        print(f"goal sent to {names.ACTION_NAVIGATE}: method {goal.method or 'current posterior'}, mode {goal.mode}, "
              f"seed {goal.seed}, label {goal.label}", flush=True)
        try:
            result = handle.result(timeout=args.result_timeout)
        except ClientTimeout:
            handle.cancel(timeout=args.timeout)  # a goal this command gave up on does not drive on
            raise
        except KeyboardInterrupt:
            say("ird navigate: Ctrl-C: canceling the goal (Ctrl-C again to leave at once)")
            handle.cancel(timeout=args.timeout)
            result = handle.result(timeout=args.timeout)
            for line in result_lines(result):
                print(line, flush=True)
            return EXIT_INTERRUPTED
        for line in result_lines(result):
            print(line, flush=True)
    return _exit_status(result)
