"""``ird infer``: call ``/ird/infer`` once and print the posterior: ``ird-infer``
(``ird_ros.apps.call_inference``) under the ``ird`` command, with its options and output.

    ird infer                          # a small generated map
    ird infer --from-world             # the world node's training worlds and proxy
    ird infer --domain-id 85 --method sample_z --num-samples 100 --risk cvar --risk-level 0.25

``--domain-id N`` is this verb's own (it sets ``ROS_DOMAIN_ID`` for the client); every other
argument is ``ird-infer``'s, parsed by its own parser (``ird infer --help`` lists them).
"""

from __future__ import annotations

import contextlib
import os
import sys
from typing import Any, Iterator

from ird_ros.cli.common import EXIT_USAGE, CliParser, add_domain_options, resolve_domain

__all__ = ["add_parser", "run", "HELP"]

HELP = "call /ird/infer once and print the posterior (ird-infer)"


def add_parser(verbs: Any) -> None:
    """Listed in ``ird --help``; ``ird_ros.cli.main`` hands the arguments after ``infer`` to :func:`run`."""
    verbs.add_parser("infer", help=HELP, add_help=False)


@contextlib.contextmanager
def _environment(domain: int, prog: str) -> Iterator[None]:
    """``ROS_DOMAIN_ID`` = ``domain`` and ``sys.argv[0]`` = ``prog`` (``ird-infer``'s parser names
    itself after it) while ``ird-infer`` runs."""
    saved_domain, saved_argv = os.environ.get("ROS_DOMAIN_ID"), list(sys.argv)
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    sys.argv[:1] = [prog]
    try:
        yield
    finally:
        sys.argv[:] = saved_argv
        if saved_domain is None:
            os.environ.pop("ROS_DOMAIN_ID", None)
        else:
            os.environ["ROS_DOMAIN_ID"] = saved_domain


def run(argv: list[str]) -> int:
    """``ird infer ARGS``: ``--domain-id`` here, the rest to ``call_inference.main``; its exit status."""
    from ird_ros.apps import call_inference

    own = CliParser(prog="ird infer", add_help=False, allow_abbrev=False)
    add_domain_options(own, timeout=None)
    args, rest = own.parse_known_args(argv)
    if any(a in ("-h", "--help") for a in rest):
        print(f"ird infer: {HELP}; also takes --domain-id N (default: ROS_DOMAIN_ID, else 0).\n", flush=True)
    with _environment(resolve_domain(args), "ird infer"):
        try:
            return int(call_inference.main(rest) or 0)
        except SystemExit as exc:  # its parser: --help (0) or a bad argument (2, printed)
            return exc.code if isinstance(exc.code, int) else EXIT_USAGE
