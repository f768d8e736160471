"""An interrupted experiment resumes where it stopped: each finished trial's result is kept on disk
the moment it arrives (:class:`Journal`), and a rerun of the same command reuses it.

A trial is a pure function of its spec and of the code (:mod:`ird_core.experiments.provenance`),
so a kept result stands for a fresh one only for the same spec under the same code. The journal
therefore keys each result by a hash of its spec's ``repr`` (the specs are frozen dataclasses of
numbers and strings: equal ``repr``, equal trial) and records the code line it was made under. It
is used only when that line names a clean commit (``git <commit>``): a tree with uncommitted
changes has a line that does not identify its code, so such a run neither reads nor writes a
journal; a journal made under another commit is discarded, never mixed in. A report made from
reused trials is the one the uninterrupted run writes, bit for bit, except its wall time, which
counts this run only (``resumed_trials`` in the report's settings says how many came from the
journal).

Files: ``<out>/journal/CODE`` (the code line) and one pickle per finished trial, written to a
temporary name and renamed, so a kill leaves whole files only; an unreadable file counts as not
finished. The folder is removed once the report is written.
"""

from __future__ import annotations

import hashlib
import os
import pickle
import shutil
import sys
from pathlib import Path
from typing import Any

__all__ = ["Journal", "JOURNAL_DIR", "MISSING", "open_journal"]

#: The journal's folder under a run's output folder.
JOURNAL_DIR: str = "journal"

#: What :meth:`Journal.load` returns for a trial not yet finished.
MISSING: Any = object()


def _resumable(code: str) -> bool:
    return code.startswith("git ") and " " not in code[4:]


class Journal:
    """Finished trials of one run on disk (module docstring). ``enabled`` is False for code that a
    code line does not identify; then nothing is read or written."""

    def __init__(self, out: Path, code: str) -> None:
        self.folder = Path(out) / JOURNAL_DIR
        self.code = code
        self.enabled = _resumable(code)
        self.discarded = ""  # the code line of a journal thrown away at open, if any
        if not self.enabled:
            return
        marker = self.folder / "CODE"
        if self.folder.exists():
            previous = marker.read_text().strip() if marker.exists() else "unknown"
            if previous != code:
                self.discarded = previous
                shutil.rmtree(self.folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        marker.write_text(code + "\n")

    @staticmethod
    def key(item: Any) -> str:
        """The file name of ``item``'s result: a hash of its ``repr``."""
        return hashlib.sha256(repr(item).encode("utf-8")).hexdigest()[:40]

    def load(self, item: Any) -> Any:
        """``item``'s kept result, or :data:`MISSING`."""
        if not self.enabled:
            return MISSING
        path = self.folder / f"{self.key(item)}.pkl"
        try:
            with path.open("rb") as handle:
                kept_item, result = pickle.load(handle)
        except (OSError, EOFError, pickle.UnpicklingError, ValueError, TypeError, AttributeError):
            return MISSING
        return result if repr(kept_item) == repr(item) else MISSING

    def record(self, item: Any, result: Any) -> None:
        """Keep ``item``'s result (atomically: a temporary file renamed into place)."""
        if not self.enabled:
            return
        path = self.folder / f"{self.key(item)}.pkl"
        tmp = path.with_suffix(".tmp")
        with tmp.open("wb") as handle:
            pickle.dump((item, result), handle, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, path)

    def close(self) -> None:
        """Remove the journal (the run's report is written)."""
        if self.enabled:
            shutil.rmtree(self.folder, ignore_errors=True)


def open_journal(out: Path, code: str, specs: "list[Any]") -> "tuple[Journal, int]":
    """The run's journal in ``out`` and how many of ``specs`` it already holds; says on stderr
    what it found (kept trials, a discarded journal, or why the run cannot resume)."""
    journal = Journal(out, code)
    if not journal.enabled:
        print(f"journal: off ({code}: an interrupted run will start again)", file=sys.stderr)
        return journal, 0
    if journal.discarded:
        print(f"journal: {journal.folder} held trials of {journal.discarded}, not of this code: discarded",
              file=sys.stderr)
    resumed = sum(journal.load(spec) is not MISSING for spec in specs)
    if resumed:
        print(f"journal: resuming, {resumed} of {len(specs)} trials already done ({journal.folder})", file=sys.stderr)
    return journal, resumed
