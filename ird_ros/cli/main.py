"""The ``ird`` command (``pyproject.toml``'s ``ird = "ird_ros.cli.main:main"``): argparse verbs,
one module each, and the exit status every verb shares (``ird_ros.cli`` module docstring).

    ird --help                 # the verbs
    ird VERB --help            # a verb's options
"""

from __future__ import annotations

import argparse
import os
import sys

from ird_ros import cli
from ird_ros.cli import echo, graph, infer, navigate
from ird_ros.cli.common import EXIT_FAILED, EXIT_INTERRUPTED, CliError, CliParser, restore_sigint, say

__all__ = ["build_parser", "main"]

_EPILOG = """\
Every verb joins the ROS domain --domain-id N (default: ROS_DOMAIN_ID, else 0): the one the launcher
printed, e.g. "[launcher] ROS_DOMAIN_ID=85 (this graph)". Exit status: 0 done, 1 no graph or a goal or
call that did not succeed, 2 bad input (one line naming it), 130 Ctrl-C.

  ird-launch --private-domain            # shell 1: the graph; note its ROS_DOMAIN_ID
  ird graph --domain-id 85               # shell 2: what runs there
  ird echo /world/proxy --once --domain-id 85
  ird navigate --domain-id 85
"""


def build_parser() -> argparse.ArgumentParser:
    """The command line: one sub-parser per verb."""
    parser = CliParser(prog="ird", description=(cli.__doc__ or "").split("\n\n")[0],
                       epilog=_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    verbs = parser.add_subparsers(dest="verb", metavar="VERB", required=True, parser_class=CliParser)
    for module in (graph, echo, navigate, infer):
        module.add_parser(verbs)
    return parser


def _run(argv: list[str]) -> int:
    if argv and argv[0] == "infer":  # its arguments are ird-infer's, parsed by its own parser
        return infer.run(argv[1:])
    args = build_parser().parse_args(argv)
    return int(args.run(args))


def _prog(verb: str) -> str:
    return f"ird {verb}" if verb else "ird"


def main(argv: list[str] | None = None) -> int:
    """Run ``ird VERB ...``; the exit status (never a traceback for bad input, a missing graph or Ctrl-C)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    verb = argv[0] if argv and not argv[0].startswith("-") else ""
    restore_sigint()
    try:
        return _run(argv)
    except CliError as exc:
        say(f"{_prog(verb)}: {exc}")
        return exc.code
    except TimeoutError as exc:  # a client wait that ran out (ClientTimeout): it names the domain
        say(f"{_prog(verb)}: {' '.join(str(exc).split())}")
        return EXIT_FAILED
    except KeyboardInterrupt:
        say(f"{_prog(verb)}: interrupted")
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # `ird echo ... | head`: the reader left; stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return 0


if __name__ == "__main__":
    sys.exit(main())
