"""Which code produced a result: the checkout's commit, and every uncommitted change to the code
that computes results, as one line that every report states (``run.json``'s ``code``, the
``Code:`` line of ``results.md`` and ``active.md``).

A trial is a pure function of its spec *and of the code*: a result made from uncommitted code
cannot be reproduced from any commit, and nothing else in a report would show it. So the line is
read when a run starts (:func:`code_version`), before any trial, and a merged report lists each
chunk's line when they differ (:func:`merged_code`).

The code that computes results is the ``ird_core`` package and ``scripts/``
(:data:`RESULT_CODE`). Outside a git checkout (an installed package) the line says so.
"""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Iterable

__all__ = ["RESULT_CODE", "NOT_RECORDED", "code_version", "merged_code"]

#: The checkout's paths whose changes can change a result.
RESULT_CODE: tuple[str, ...] = ("ird_core", "scripts")

#: The ``code`` of a ``run.json`` written before runs recorded it.
NOT_RECORDED: str = "not recorded"

#: At most this many changed files are named (then "and N more").
_NAMED_CHANGES: int = 6

_ROOT = Path(__file__).resolve().parents[2]


def _git(root: Path, *args: str) -> str:
    """``git -C root args`` 's standard output (``OSError`` / ``SubprocessError`` when git is
    missing or ``root`` is not a checkout)."""
    return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=30,
                          check=True).stdout


def code_version(root: "Path | None" = None) -> str:
    """``"git <commit>"``, ``"git <commit> with uncommitted changes to a, b"`` (tracked files
    changed and untracked files added under :data:`RESULT_CODE`), or ``"not a git checkout
    (<root>)"``; ``root``: the checkout (default: the one this module is in)."""
    root = _ROOT if root is None else Path(root)
    try:
        commit = _git(root, "rev-parse", "--short=12", "HEAD").strip()
        status = _git(root, "status", "--porcelain", "--untracked-files=all", "--", *RESULT_CODE)
    except (OSError, subprocess.SubprocessError):
        return f"not a git checkout ({root})"
    changed = sorted({line[3:].strip() for line in status.splitlines() if line.strip()})
    if not changed:
        return f"git {commit}"
    named = ", ".join(changed[:_NAMED_CHANGES])
    more = f" and {len(changed) - _NAMED_CHANGES} more" if len(changed) > _NAMED_CHANGES else ""
    return f"git {commit} with uncommitted changes to {named}{more}"


def merged_code(lines: Iterable[str]) -> str:
    """The code line of a report merged from chunks: their one line when they agree, else each
    distinct line in first-seen order, joined by ``" | "`` (a missing line is :data:`NOT_RECORDED`)."""
    distinct = list(dict.fromkeys(line or NOT_RECORDED for line in lines))
    return " | ".join(distinct) if distinct else NOT_RECORDED
