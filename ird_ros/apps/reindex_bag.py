"""Rebuild a bag whose recorder was killed (the ``ros2 bag reindex`` of this project), no ROS.

    ird-reindex-bag BAG [--check] [--force] [--discard-original]

BAG is a rosbag2 folder with one MCAP file, as written by ``ird_ros.nodes.recorder`` (or the
``.mcap`` file in it). A bag that was closed properly is left alone. Otherwise every complete
record of the MCAP is read (up to the first cut-off or damaged one) and the bag is rewritten
in place (``ird_ros.bags.repair.reindex``): a complete MCAP (chunk indexes, summary, footer)
and a ``metadata.yaml`` with the exact message counts, time span, types and QoS. The original
file is kept as ``<name>.mcap.orig`` unless ``--discard-original``.

Exit status: 0 done (or complete), 1 ``--check`` found a bag to rebuild, 2 not a bag.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ird_ros.bags.repair import ReindexResult, bag_state, reindex

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    """The bag and what to do with it."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("bag", type=Path, help="rosbag2 folder (or its .mcap file)")
    parser.add_argument("--check", action="store_true", help="only report; exit 1 if a rebuild is needed")
    parser.add_argument("--force", action="store_true", help="rebuild even a complete bag")
    parser.add_argument("--discard-original", action="store_true", help="do not keep <name>.mcap.orig")
    return parser


def _print_result(bag: Path, result: ReindexResult) -> None:
    if not result.rebuilt:
        print(f"{bag}: complete, nothing to do (--force rebuilds it anyway)")
        return
    total = sum(result.counts.values())
    print(f"{bag}: rebuilt ({result.state}): {total} messages on {len(result.counts)} topics")
    for topic, count in sorted(result.counts.items()):
        print(f"  {topic}  {count}")
    if result.stop_reason:
        print(f"  read up to: {result.stop_reason}; {result.dropped_bytes} trailing bytes dropped")
    if result.original is not None:
        print(f"  original kept as {result.original}")


def main(argv: list[str] | None = None) -> int:
    """Check or rebuild one bag; exit status as the module says."""
    args = build_parser().parse_args(argv)
    bag = args.bag
    try:
        if args.check:
            state = bag_state(bag)
            print(f"{bag}: {state}")
            return 0 if state == "complete" else 1
        result = reindex(bag, force=args.force, keep_original=not args.discard_original)
    except (ValueError, OSError) as exc:
        print(f"reindex_bag: {exc}", file=sys.stderr)
        return 2
    _print_result(bag, result)
    return 0
