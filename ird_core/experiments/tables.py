"""How both experiments' reports write numbers: csv cells, percentages and paths.

Invariants: a csv float has 6 significant digits (``nan`` for NaN), a bool is ``0`` / ``1``; a
markdown percentage is rounded to a whole percent; a path's cells are ``"row,col row,col ..."``.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from typing import Iterable, Mapping, Sequence

__all__ = ["format_cell", "write_csv", "percent", "number", "cells_text", "write_run_json"]


def format_cell(value: object) -> str:
    """A csv cell: bools as ``0`` / ``1``, floats with 6 significant digits, the rest as ``str``."""
    if isinstance(value, bool):
        return str(int(value))
    if isinstance(value, float):
        return "nan" if math.isnan(value) else f"{value:.6g}"
    return str(value)


def write_csv(path: Path, columns: Sequence[str], rows: Iterable[Mapping[str, object]]) -> None:
    """A csv file with a header of ``columns`` and one line per row (:func:`format_cell`)."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for row in rows:
            w.writerow([format_cell(row[c]) for c in columns])


def percent(x: float) -> str:
    """A fraction as a whole percentage (``nan`` for NaN)."""
    return "nan" if math.isnan(x) else f"{100 * x:.0f}"


def number(x: float, digits: int = 2) -> str:
    """A number with ``digits`` decimals (``nan`` for NaN)."""
    return "nan" if math.isnan(x) else f"{x:.{digits}f}"


def cells_text(cells: Iterable[tuple[int, int]]) -> str:
    """A path's cells as one csv cell, ``"row,col row,col ..."``."""
    return " ".join(f"{a},{b}" for a, b in cells)


def write_run_json(path: Path, command: str, wall: float, settings: Mapping[str, object],
                   figures: Sequence[Path], code: str) -> None:
    """``run.json``: the command, wall time, settings (as strings where not JSON), figure names
    and the code that ran (:mod:`ird_core.experiments.provenance`)."""
    path.write_text(json.dumps({"command": command, "wall_seconds": wall, "settings": settings,
                                "figures": [f.name for f in figures], "code": code}, indent=2, default=str))

