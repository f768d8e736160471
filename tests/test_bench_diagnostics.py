"""scripts/bench_diagnostics.py without arviz-stats: the table, the pass rule, the missing-dependency exit,
and the whole timing path with a stand-in for arviz-stats' array interface (our own diagnostics)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from ird_core.mcmc import diagnostics

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "bench_diagnostics.py"


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("bench_diagnostics", SCRIPT)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class OursAsArvizStats:
    """Stands in for ``arviz_stats.base.array_stats`` (same call signature, our numbers)."""

    @staticmethod
    def rhat(ary, chain_axis, draw_axis, method):
        assert (chain_axis, draw_axis, method) == (0, 1, "rank")
        return diagnostics.rank_normalized_r_hat(ary)

    @staticmethod
    def ess(ary, chain_axis, draw_axis, method):
        assert (chain_axis, draw_axis, method) == (0, 1, "bulk")
        return diagnostics.bulk_effective_sample_size(ary)


def test_missing_arviz_stats_prints_the_install_command_and_exits_2(bench, monkeypatch, capsys) -> None:
    monkeypatch.setitem(sys.modules, "arviz_stats", None)  # import raises ImportError
    monkeypatch.setitem(sys.modules, "arviz_stats.base", None)
    assert bench.load_arviz_stats() is None
    assert bench.main([]) == 2
    assert "pip install arviz-stats==0.8.0" in capsys.readouterr().out


def test_format_table_rows_ratios_and_differences(bench) -> None:
    rows = [dict(C=4, N=16, d=50, ours_min=0.002, ours_med=0.003, azs_min=0.06, azs_med=0.09, dr=2.2e-16, dess=0.77),
            dict(C=8, N=1024, d=4, ours_min=0.016, ours_med=0.017, azs_min=0.021, azs_med=0.0238, dr=0.0, dess=1.4e-4)]
    lines = bench.format_table(rows).splitlines()
    assert lines[0].split()[:3] == ["C", "N", "d"] and set(lines[1]) == {"-"}
    assert lines[2].split() == ["4", "16", "50", "|", "2.00", "3.00", "|", "60.00", "90.00", "|", "30.0", "30.0",
                                "|", "2.2e-16", "7.7e-01"]
    assert lines[3].split()[9:12] == ["|", "1.3", "1.4"]
    assert lines[-1].startswith("ms per check") and len(lines) == 5


def test_first_pass_needs_r_hat_ess_and_no_nan(bench) -> None:
    ok, bad_r = (np.array([1.01, 1.04]), np.array([40.0, 33.0])), (np.array([1.01, 1.06]), np.array([40.0, 40.0]))
    low_ess, nan_ess = (np.array([1.0, 1.0]), np.array([40.0, 31.0])), (np.array([1.0, 1.0]), np.array([40.0, np.nan]))
    assert bench.first_pass([(32, bad_r), (48, low_ess), (64, nan_ess), (80, ok), (96, ok)]) == 80
    assert bench.first_pass([(32, bad_r)]) is None


def test_timing_path_with_a_stand_in(bench, monkeypatch, capsys) -> None:
    monkeypatch.setattr(bench, "load_arviz_stats", lambda: OursAsArvizStats)
    monkeypatch.setattr(bench, "CHAINS", (4,))
    monkeypatch.setattr(bench, "DRAWS", (16, 64))
    monkeypatch.setattr(bench, "DIMS", (3,))
    assert bench.main(["--repeats", "2"]) == 0
    out = capsys.readouterr().out.splitlines()
    rows = [line.split() for line in out if "|" in line and line.split()[0] == "4"]
    assert [r[:3] for r in rows] == [["4", "16", "3"], ["4", "64", "3"]]
    assert all(r[-2:] == ["0.0e+00", "0.0e+00"] for r in rows)  # the same numbers on both sides
    assert out[-1] == "arviz-stats bit-identical over repeated calls: True"


def test_time_interleaved_times_every_function_every_repeat(bench) -> None:
    calls: list[str] = []
    funcs = [lambda x: calls.append("a"), lambda x: calls.append("b")]
    times = bench.time_interleaved(funcs, np.zeros((2, 8, 1)), 3)
    assert [len(t) for t in times] == [3, 3] and all(s >= 0 for t in times for s in t)
    assert calls == ["a", "b", "a", "b", "b", "a", "a", "b"]  # warm-up, then alternating order
