"""An interrupted experiment resumes (``ird_core.experiments.journal``): finished trials are kept as
they arrive and not run again, the resumed report equals an uninterrupted run's, a journal of
other code is discarded, code that a code line does not identify keeps none, an unreadable entry
is recomputed, and the journal is gone once the report is written."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import pytest
from test_experiments import TINY_ARGS

from ird_core.experiments import cli, parallel
from ird_core.experiments.journal import JOURNAL_DIR, MISSING, Journal

CLEAN = "git 0123456789ab"


class Stop(RuntimeError):
    """The interruption."""


def _square(x: int) -> int:
    return x * x


def test_an_interrupted_map_resumes_with_the_kept_results(tmp_path: Path) -> None:
    items = list(range(6))
    calls: list[int] = []

    def until_three(x: int) -> int:
        if x == 3:
            raise Stop
        calls.append(x)
        return x * x

    with pytest.raises(Stop):
        parallel.parallel_map(until_three, items, journal=Journal(tmp_path, CLEAN))
    assert calls == [0, 1, 2]
    calls.clear()

    def counted(x: int) -> int:
        calls.append(x)
        return x * x

    journal = Journal(tmp_path, CLEAN)
    assert [journal.load(x) is not MISSING for x in items] == [True, True, True, False, False, False]
    assert parallel.parallel_map(counted, items, journal=journal) == [x * x for x in items]
    assert calls == [3, 4, 5]  # the finished ones were not run again
    journal.close()
    assert not (tmp_path / JOURNAL_DIR).exists()


def test_a_pool_keeps_results_as_they_finish(tmp_path: Path) -> None:
    journal = Journal(tmp_path, CLEAN)
    assert parallel.parallel_map(_square, list(range(5)), workers=2, journal=journal) == [0, 1, 4, 9, 16]
    assert all(Journal(tmp_path, CLEAN).load(x) == x * x for x in range(5))


def test_other_code_discards_the_journal(tmp_path: Path) -> None:
    Journal(tmp_path, CLEAN).record(2, "old")
    assert Journal(tmp_path, CLEAN).load(2) == "old"
    other = Journal(tmp_path, "git ba9876543210")
    assert other.discarded == CLEAN and other.load(2) is MISSING


@pytest.mark.parametrize("code", ["git 0123456789ab with uncommitted changes to ird_core/x.py",
                                  "not a git checkout (/somewhere)"])
def test_unidentified_code_keeps_no_journal(tmp_path: Path, code: str) -> None:
    journal = Journal(tmp_path, code)
    journal.record(1, "x")
    assert not journal.enabled and journal.load(1) is MISSING and not (tmp_path / JOURNAL_DIR).exists()


def test_unreadable_or_foreign_entries_count_as_not_finished(tmp_path: Path) -> None:
    journal = Journal(tmp_path, CLEAN)
    journal.record(7, 49)
    path = tmp_path / JOURNAL_DIR / f"{Journal.key(7)}.pkl"
    path.write_bytes(path.read_bytes()[:10])  # truncated
    assert journal.load(7) is MISSING
    journal.record(8, 64)
    (tmp_path / JOURNAL_DIR / f"{Journal.key(9)}.pkl").write_bytes(path.with_name(f"{Journal.key(8)}.pkl").read_bytes())
    assert journal.load(9) is MISSING  # a file whose item is another one's


def _interrupt_at(monkeypatch: pytest.MonkeyPatch, seed: int, argv: list[str]) -> None:
    """Run ``run_experiments.py argv``, interrupted when it reaches the trial of ``seed``."""
    run_trial = cli.run_trial

    def stop_at_seed(spec: Any) -> Any:
        if spec.seed == seed:
            raise Stop
        return run_trial(spec)

    monkeypatch.setattr(cli, "run_trial", stop_at_seed)
    with pytest.raises(Stop):
        cli.main(argv)
    monkeypatch.setattr(cli, "run_trial", run_trial)


@pytest.mark.timeout(300)
def test_a_resumed_chunk_merges_with_the_others(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """How many trials a chunk kept from its journal is how it ran, not what: the chunks merge,
    and the merged run says how many trials were resumed in all."""
    monkeypatch.setattr(cli, "code_version", lambda: CLEAN)
    args = ["--trials", "2", "--workers", "1", "--conditions", "side_effects", "--no-factorial", *TINY_ARGS]
    _interrupt_at(monkeypatch, 1, [*args, "--out", str(tmp_path / "a")])
    assert cli.main([*args, "--out", str(tmp_path / "a")]) == 0
    assert cli.main([*args, "--seed", "2", "--out", str(tmp_path / "b")]) == 0
    assert cli.main(["--report-only", "--out", str(tmp_path / "ab"), "--merge", str(tmp_path / "a"),
                     str(tmp_path / "b")]) == 0
    settings = json.loads((tmp_path / "ab" / "run.json").read_text())["settings"]
    assert (settings["trials"], settings["resumed_trials"]) == (4, 1)
    assert {row["seed"] for row in _rows(tmp_path / "ab" / "trials.csv")} == {"0", "1", "2", "3"}


def _rows(path: Path) -> list[dict[str, Any]]:
    with path.open() as handle:
        return list(csv.DictReader(handle))


def _untimed(row: dict[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in row.items() if not k.endswith("infer_seconds")}


@pytest.mark.timeout(300)
def test_run_experiments_resumes_and_writes_the_uninterrupted_report(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                     capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setattr(cli, "code_version", lambda: CLEAN)
    args = ["--trials", "3", "--workers", "1", "--conditions", "side_effects", *TINY_ARGS]
    assert cli.main([*args, "--out", str(tmp_path / "whole")]) == 0

    _interrupt_at(monkeypatch, 2, [*args, "--out", str(tmp_path / "resumed")])
    assert len(list((tmp_path / "resumed" / JOURNAL_DIR).glob("*.pkl"))) == 2
    capsys.readouterr()
    assert cli.main([*args, "--out", str(tmp_path / "resumed")]) == 0
    assert "resuming, 2 of 3 trials already done" in capsys.readouterr().err
    assert not (tmp_path / "resumed" / JOURNAL_DIR).exists()
    for table in ("results.csv", "trials.csv"):
        whole, resumed = (_rows(tmp_path / d / table) for d in ("whole", "resumed"))
        assert len(resumed) == len(whole) > 0
        # Inference time is the one measurement that is not a function of the spec.
        assert [_untimed(r) for r in resumed] == [_untimed(r) for r in whole]
    assert "resumed_trials" in (tmp_path / "resumed" / "run.json").read_text()
