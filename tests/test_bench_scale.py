"""scripts/bench_scale.py and ird_core.experiments.scale_timing: a timing samples the trial's own
posterior to the requested ESS, the tables' ratios and verdicts, bad arguments named."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import importlib.util
from pathlib import Path

import pytest

from ird_core.experiments import trials
from ird_core.experiments.scale_timing import TIMING_COLUMNS, ScaleTiming, time_trial

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "bench_scale.py"
TINY = trials.TrialSpec("side_effects", 3, size=6, horizon=8, num_proxy_samples=50)


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_scale", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def row(size: int, method: str, evidence: float, sample: float, plan: float, converged: bool = True) -> ScaleTiming:
    return ScaleTiming("latent_raw", 0, size, 2 * size - 8 if size > 15 else 30, method, 50, evidence, sample, plan,
                       0.01, 1.02, 450.0, 300, 1200, converged, "converged")


def test_timing_runs_until_the_requested_ess_and_samples_the_trials_posterior() -> None:
    timing = time_trial(TINY, "maxent_z", min_ess=300.0, max_iterations=2000)
    assert timing.converged and timing.ess_min >= 300.0 and timing.r_hat_max <= trials.RUN_UNTIL_R_HAT
    assert timing.dim == 4 and timing.size == 6 and timing.horizon == 8
    assert timing.posterior_seconds == timing.evidence_seconds + timing.sample_seconds
    # The trials' stopping rule (ESS >= 32) is met earlier on the same chains: same seeds, fewer draws.
    trial = trials.trial_posterior(TINY, trials.trial_instance(TINY), "maxent_z")
    assert trial.iterations <= timing.iterations
    again = time_trial(TINY, "maxent_z", min_ess=300.0, max_iterations=2000)
    fields = ("r_hat_max", "ess_min", "iterations", "evaluations")
    assert [getattr(again, f) for f in fields] == [getattr(timing, f) for f in fields]


def test_timing_reports_a_capped_run_as_not_converged() -> None:
    timing = time_trial(TINY, "maxent_z", min_ess=10**6, max_iterations=40)
    assert not timing.converged and timing.iterations <= 64


@pytest.mark.parametrize("kwargs, field", [(dict(method="nuts"), "method"), (dict(min_ess=float("nan")), "min_ess"),
                                           (dict(max_iterations=0), "max_iterations")])
def test_bad_arguments_name_the_field(kwargs: dict, field: str) -> None:
    arguments = dict(method="maxent_z") | kwargs
    with pytest.raises(ValueError, match=field):
        time_trial(TINY, **arguments)


def test_sizes_parse_and_bad_ones_name_the_flag(bench) -> None:
    assert bench.parse_size("64:120") == (64, 120)
    for bad in ("64", "64:x", "2:10", "16:0"):
        with pytest.raises(argparse.ArgumentTypeError, match="--sizes"):
            bench.parse_size(bad)


def test_medians_are_relative_to_the_first_size_of_each_method(bench) -> None:
    rows = [row(15, "maxent_z", 0.1, 0.9, 0.01), row(15, "maxent_z", 0.1, 1.9, 0.03),
            row(64, "maxent_z", 0.5, 7.5, 0.2), row(64, "maxent_z", 0.5, 9.5, 0.2, converged=False),
            row(15, "sample_z", 1.0, 3.0, 0.02), row(64, "sample_z", 70.0, 130.0, 0.1)]
    lines = bench.format_medians(rows).splitlines()
    cells = [line.split() for line in lines[2:]]
    assert cells[0][5:7] == ["1.50", "1.0x"] and cells[1][5:7] == ["9.00", "6.0x"]
    assert cells[1][8:10] == ["0.200", "10.0x"] and cells[1][-1] == "1/2"
    assert cells[3][5:7] == ["200.00", "50.0x"]
    verdicts = bench.goal_lines(rows)
    assert len(verdicts) == 2 and "sample_z" in verdicts[0] and "MISSED (worst 200.0 s)" in verdicts[0]
    # The MaxEnt-Z posterior of 10.0 s would meet the time, but one run did not converge.
    assert "maxent_z" in verdicts[1] and "<= 10 s: MISSED" in verdicts[1] and "plan <= 1 s: met" in verdicts[1]
    met = [dataclasses.replace(r, converged=True) for r in rows if r.method == "maxent_z"]
    assert "<= 10 s: met (worst 10.0 s)" in bench.goal_lines(met)[0]


def test_main_prints_the_tables_and_writes_every_row(bench, tmp_path, capsys) -> None:
    out = tmp_path / "timing.csv"
    code = bench.main(["--sizes", "6:8", "7:10", "--seeds", "0", "--condition", "side_effects",
                       "--min-ess", "100", "--out", str(out)])
    assert code == 0
    text = capsys.readouterr().out
    assert "x ref" in text and "6x6" in text and "7x7" in text and "goal" not in text
    with open(out, newline="") as handle:
        table = list(csv.reader(handle))
    assert tuple(table[0]) == TIMING_COLUMNS and len(table) == 3
    assert [r[TIMING_COLUMNS.index("size")] for r in table[1:]] == ["6", "7"]


def test_an_interrupted_run_prints_and_writes_the_runs_it_measured(bench, tmp_path, capsys, monkeypatch) -> None:
    measured = iter([row(6, "maxent_z", 0.1, 0.2, 0.01)])

    def one_then_interrupt(spec, method, min_ess, max_iterations):
        if spec.num_proxy_samples == 10:  # the warm-up call on the tiny map
            return row(6, method, 0.0, 0.0, 0.0)
        try:
            return next(measured)
        except StopIteration:
            raise KeyboardInterrupt from None

    monkeypatch.setattr(bench, "time_trial", one_then_interrupt)
    out = tmp_path / "timing.csv"
    assert bench.main(["--sizes", "6:8", "7:10", "--seeds", "0", "--out", str(out)]) == 0
    captured = capsys.readouterr()
    assert "interrupted: 1 of 2 runs measured" in captured.err and "x ref" in captured.out
    with open(out, newline="") as handle:
        assert len(list(csv.reader(handle))) == 2  # the header and the one run
    measured = iter([])
    assert bench.main(["--sizes", "6:8", "--seeds", "0"]) == 130  # nothing measured: nothing to print


@pytest.mark.parametrize("argv, message", [
    (["--seeds", "0", "-1"], "seed must be a non-negative int, got -1"),
    (["--out", "{tmp}"], "--out: {tmp} is a folder, not a file"),
    (["--out", "{tmp}/a_file/rows.csv"], "--out: {tmp}/a_file is not a folder"),
])
def test_bad_arguments_are_refused_before_any_run(bench, tmp_path, capsys, monkeypatch, argv, message) -> None:
    (tmp_path / "a_file").write_text("kept")
    monkeypatch.setattr(bench, "time_trial", lambda *a: pytest.fail("a run started"))
    with pytest.raises(SystemExit) as stop:
        bench.main(["--sizes", "6:8", *[a.format(tmp=tmp_path) for a in argv]])
    assert stop.value.code == 2 and message.format(tmp=tmp_path) in capsys.readouterr().err
    assert (tmp_path / "a_file").read_text() == "kept"
