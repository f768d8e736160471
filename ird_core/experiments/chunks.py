"""One report from several runs ("chunks") of the same experiment: runs with equal settings over
disjoint trials, e.g. seeds 0-49 and 50-99, or one condition per machine or per day.

Invariants: chunks are merged only when every setting but :data:`CHUNK_KEYS` is equal and no
trial key (condition, seed, planner, ...) occurs in two of them; the merged settings give the
number of distinct seeds as ``trials``, the seeds' range and chunk count as ``seed`` and the sum
of the chunks' ``resumed_trials`` (trials an interrupted chunk kept from its journal: how the
chunk was run, not what it ran) when any has one; the merged command joins the chunks' commands
with ``" && "``, and the merged wall time is the sum of theirs. Each chunk is a report directory
with its ``run.json``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Hashable, Iterable, Mapping, Sequence, TypeVar

from ird_core.experiments.provenance import NOT_RECORDED, merged_code

__all__ = ["CHUNK_KEYS", "MergedRun", "read_run", "merge_runs", "load_chunks"]

T = TypeVar("T")

#: Settings that may differ between the chunks of one report.
CHUNK_KEYS: tuple[str, ...] = ("trials", "seed", "workers", "scheduler", "resumed_trials")


@dataclass(frozen=True)
class MergedRun:
    """How the merged report states its run: the command, the wall time (s), the settings and the
    code that ran (``provenance.merged_code`` of the chunks')."""

    command: str
    wall: float
    settings: dict[str, Any]
    code: str


def read_run(source: Path) -> dict[str, Any]:
    """A report's ``run.json``, its settings' lists as the tuples the run held (``OSError`` /
    ``ValueError`` / ``KeyError`` if missing or malformed)."""
    run = json.loads((source / "run.json").read_text())
    missing = [key for key in ("command", "wall_seconds", "settings") if key not in run]
    if missing:
        raise KeyError(f"run.json lacks {', '.join(missing)}")
    run["settings"] = {k: tuple(v) if isinstance(v, list) else v for k, v in dict(run["settings"]).items()}
    return run


def merge_runs(runs: Sequence[Mapping[str, Any]], keys: Sequence[Hashable], seeds: Iterable[int]) -> MergedRun:
    """The run of the chunks ``runs`` (their ``run.json``), given every result's trial key and seed.

    Raises:
        ValueError: ``"no trials to report"``, ``"the chunks' settings differ"`` or ``"the
            chunks share seeds"`` (a trial key occurs twice).
    """
    distinct = sorted(set(seeds))
    if not distinct:
        raise ValueError("no trials to report")
    fixed = [{k: v for k, v in run["settings"].items() if k not in CHUNK_KEYS} for run in runs]
    if any(f != fixed[0] for f in fixed):
        raise ValueError("the chunks' settings differ")
    if len(keys) != len(set(keys)):
        raise ValueError("the chunks share seeds")
    settings = dict(runs[0]["settings"])
    command = runs[0]["command"]
    if len(runs) > 1:
        settings.update(trials=len(distinct), seed=f"{distinct[0]}..{distinct[-1]} in {len(runs)} chunks")
        settings.pop("resumed_trials", None)
        resumed = sum(int(run["settings"].get("resumed_trials") or 0) for run in runs)
        if resumed:
            settings["resumed_trials"] = resumed
        command = " && ".join(run["command"] for run in runs)
    return MergedRun(command, sum(float(run["wall_seconds"]) for run in runs), settings,
                     merged_code(str(run.get("code", NOT_RECORDED)) for run in runs))


def load_chunks(out: Path, chunks: "Sequence[Path] | None", trials_name: str,
                read_trials: Callable[[Path], list[T]], trial_key: Callable[[T], Hashable],
                seed: Callable[[T], int]) -> tuple[MergedRun, list[T]]:
    """The merged run and the results, in chunk order, of each chunk directory (or of ``out``
    alone): its ``run.json`` and its ``trials_name`` file, read by ``read_trials``.

    Raises:
        ValueError: ``"--report-only: cannot read DIR: ..."``, or the :func:`merge_runs` refusal
            prefixed by ``--merge`` (``--report-only`` without chunks).
    """
    runs: list[dict[str, Any]] = []
    results: list[T] = []
    for source in chunks or [out]:
        try:
            runs.append(read_run(source))
            results += read_trials(source / trials_name)
        except (OSError, ValueError, KeyError) as exc:
            raise ValueError(f"--report-only: cannot read {source}: {exc}") from None
    try:
        merged = merge_runs(runs, [trial_key(r) for r in results], (seed(r) for r in results))
    except ValueError as exc:
        raise ValueError(f"{'--merge' if chunks else '--report-only'}: {exc}") from None
    return merged, results
