"""Where a program writes: checked before its work starts, so a run never fails at its end.

Invariants: ``folder_problem`` and ``file_problem`` create nothing and return "" exactly when the
folder (or the file) could be made or written there; otherwise a sentence naming the path that
stands in the way (a file where a folder must go, a folder where the file must go, a folder the
process cannot write into). ``make_output_folder`` creates the folder or raises ``ValueError``
naming the option it came from; the experiments call it before their first trial.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["folder_problem", "file_problem", "make_output_folder"]


def _nearest_existing(path: Path) -> Path:
    """``path`` or its nearest ancestor that exists (the root always does)."""
    return next(p for p in (path, *path.absolute().parents) if p.exists())


def folder_problem(path: Path) -> str:
    """Why no folder can be made (or used) at ``path``: "" when it can."""
    existing = _nearest_existing(Path(path))
    if not existing.is_dir():
        return f"{existing} is not a folder"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"cannot write into {existing}"
    return ""


def file_problem(path: Path) -> str:
    """Why the file ``path`` could not be written (made, or replaced): "" when it can."""
    path = Path(path)
    if path.is_dir():
        return f"{path} is a folder, not a file"
    if path.exists():
        return "" if os.access(path, os.W_OK) else f"cannot write {path}"
    return folder_problem(path.parent)


def make_output_folder(out: Path, option: str = "--out") -> None:
    """Create the folder ``out`` (parents included); ``ValueError`` naming ``option`` and the path
    in the way when it cannot be made or written into."""
    try:
        Path(out).mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ValueError(f"{option}: cannot make the folder {out}: {exc.strerror or exc}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise ValueError(f"{option}: cannot write into the folder {out}")
