"""Summarise a recorded IRD bag and plot Rob's missions, without ROS.

    ird-analyze-bag BAG [--out DIR] [--json FILE] [--msg-root DIR ...] [--no-plots]

BAG is a rosbag2 folder (MCAP or SQLite storage; or the .mcap file in it) as written by ``ird_ros.nodes.recorder``
(``ird-launch --record BAG``). Only the ``rosbags`` library is needed (plus numpy and
matplotlib for the plots): the ``ird_msgs`` types are read from the repository's
``msgs_config/ird_msgs/msg/*.msg`` (``--msg-root`` adds other folders of ``<pkg>/msg/*.msg``).

Prints:
  - per topic: type, message count, first and last log time (s since the bag's first
    message), mean rate, QoS durability;
  - per mission (one executed plan, see ird_ros.bags.missions): label, plan moves and
    length, executed length (odometry), steps, how it ended (done, cancelled: stopped before
    the plan's end, running), touched lava, reached target, what Rob did (touched lava,
    reached the target, stayed put, moved N cells) and the true return (from the mission's
    final /rob/status);
  - per plan label: runs, lava and target fractions, mean true return;
  - per question to the designer (/ird/queries): query id, strategy, information gain,
    options, answer, who answered, answers in the evidence after it.
Writes into --out (default: BAG_analysis next to the bag) trajectories_<i>.png (Rob's
odometry and plans over the ground-truth /world/terrain; none for a bag without missions, which
says so), true_return.png, posterior.png and
query_rounds.png (each question's options on the map); with --json, the whole report as JSON.
Exit status 1 if the bag can't be read; 2 if --out or --json cannot be written (checked
before the bag is read); 3 if the bag was read but a plot could not be drawn
(the report is printed, the other plots written, the failure named as a plotting one).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from ird_core.output_paths import file_problem, folder_problem
from ird_ros.bags.analysis import analyze
from ird_ros.bags.rounds import rounds_table
from ird_ros.bags.storage import REPO_MSG_ROOT, make_typestore
from ird_ros.graph import names

__all__ = ["build_parser", "print_report", "no_mission_line", "main"]


def _fmt(value: float | None, spec: str = ".3f") -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return format(value, spec)


def _print_topics(report: dict[str, Any]) -> None:
    topics = report["topics"]
    print(f"Bag: {report['bag']}")
    total = sum(t["count"] for t in topics)
    print(f"  {len(topics)} topics, {total} messages, {report['duration_s']:.3f} s")
    print()
    w = max([len("topic")] + [len(t["topic"]) for t in topics])
    wt = max([len("type")] + [len(t["type"]) for t in topics])
    print(f"{'topic':<{w}}  {'type':<{wt}}  {'count':>6}  {'first[s]':>9}  {'last[s]':>9}  {'rate[Hz]':>9}  durability")
    for t in topics:
        print(f"{t['topic']:<{w}}  {t['type']:<{wt}}  {t['count']:>6}  {_fmt(t['first_s']):>9}  "
              f"{_fmt(t['last_s']):>9}  {_fmt(t['rate_hz'], '.2f'):>9}  {t['durability']}")
    print()


def no_mission_line(report: dict[str, Any]) -> str:
    """What a bag without missions lacks, and how to record one."""
    counts = {t["topic"]: t["count"] for t in report["topics"]}
    held = ", ".join(f"{topic} {counts.get(topic, 0)}" for topic in (names.TOPIC_PLAN, names.TOPIC_ROB_STATUS))
    return (f"Missions: none: no mission in this bag, Rob drove no plan ({held} messages) "
            "(run the graph with --mission, or drive Rob with a client); no trajectories plot written")


def _print_missions(report: dict[str, Any]) -> None:
    missions = report["missions"]
    if not missions:
        print(no_mission_line(report))
        return
    wl = max([len("label")] + [len(m["label"]) for m in missions])
    print("Missions:")
    print(f"{'#':>3}  {'label':<{wl}}  {'start[s]':>8}  {'plan T':>6}  {'plan[m]':>8}  {'odom[m]':>8}  "
          f"{'steps':>9}  {'end':>9}  {'lava':>5}  {'target':>6}  {'true return':>11}  outcome")
    for m in missions:
        print(f"{m['index']:>3}  {m['label']:<{wl}}  {m['start_s']:>8.3f}  {m['plan_moves']:>6}  "
              f"{_fmt(m['plan_length_m'], '.2f'):>8}  {_fmt(m['executed_length_m'], '.2f'):>8}  "
              f"{m['steps']:>4}/{m['horizon']:<4}  {m['end']:>9}  {str(m['touched_lava']):>5}  "
              f"{str(m['reached_target']):>6}  {_fmt(m['true_return']):>11}  {m['outcome']}")
    print()
    print("Per label:")
    for label, s in report["labels"].items():
        print(f"  {label}: {s['runs']} run(s), lava {s['lava_fraction']:.2f}, "
              f"target {s['target_fraction']:.2f}, mean true return {_fmt(s['mean_true_return'])}")


def print_report(report: dict[str, Any]) -> None:
    """The report of ``ird_ros.bags.analysis.analyze`` as text: topics, missions, questions, plots."""
    _print_topics(report)
    _print_missions(report)
    if report.get("query_rounds"):
        print()
        print("Questions to the designer:")
        print(rounds_table(report["query_rounds"]))
    if report["plots"]:
        print()
        print("Plots:")
        for p in report["plots"]:
            print(f"  {p}")


def build_parser() -> argparse.ArgumentParser:
    """The bag and the report's destinations."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("bag", type=Path, help="rosbag2 folder (or its .mcap file)")
    parser.add_argument("--out", type=Path, default=None, help="folder for the PNG plots (default: BAG_analysis)")
    parser.add_argument("--json", type=Path, default=None, help="also write the report as JSON here")
    parser.add_argument("--msg-root", type=Path, action="append", default=[],
                        help="extra folder of <pkg>/msg/*.msg definitions (repeatable)")
    parser.add_argument("--no-plots", action="store_true", help="print the summary only")
    return parser


def _not_a_bag(bag: Path) -> str:
    """Why ``bag`` is no rosbag2 folder ("" when it has a metadata.yaml to read)."""
    if not bag.exists():
        return "does not exist"
    if not bag.is_dir():
        return "is not a folder (BAG is the rosbag2 folder, or the .mcap file in it)"
    if not (bag / "metadata.yaml").is_file():
        return ("is not a readable rosbag2 folder (no metadata.yaml; was the recorder stopped with SIGKILL? "
                "ird-reindex-bag rebuilds it)")
    return ""

def main(argv: list[str] | None = None) -> int:
    """Analyse, print and (with --json) save the report; exit status 0, 1 if the bag can't be read,
    2 if --out or --json cannot be written (checked first), 3 if a plot could not be drawn."""
    args = build_parser().parse_args(argv)
    if args.bag.is_file() and args.bag.suffix == ".mcap":
        args.bag = args.bag.parent  # the bag's MCAP file: its folder is the bag
    problem = _not_a_bag(args.bag)
    if problem:
        print(f"error: {args.bag} {problem}", file=sys.stderr)
        return 1
    out = None if args.no_plots else (args.out or args.bag.parent / f"{args.bag.name}_analysis")
    for option, problem in (("--out", out and folder_problem(out)), ("--json", args.json and file_problem(args.json))):
        if problem:  # before reading the bag: the report would be lost at the end
            print(f"error: {option}: {problem}", file=sys.stderr)
            return 2
    try:
        report = analyze(args.bag, out, make_typestore([REPO_MSG_ROOT, *args.msg_root]))
    except Exception as exc:  # a corrupt bag: say what and where
        print(f"error: cannot read {args.bag}: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    print_report(report)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)  # file_problem found that it can be made
        args.json.write_text(json.dumps(report, indent=2, default=float), encoding="utf-8")
    if report["plot_errors"]:
        print(f"error: {len(report['plot_errors'])} plot(s) could not be drawn (the bag was read; the fault is "
              "in the plotting, not in the bag):", file=sys.stderr)
        for line in report["plot_errors"]:
            print(f"  {line}", file=sys.stderr)
        return 3
    return 0
