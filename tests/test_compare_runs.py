"""Runs side by side (ird_core.experiments.compare_runs, scripts/compare_runs.py): each run placed
by its recorded setting (the TrialSpec default when it records none), the numbers drawn are the
results.csv numbers, the goal check per point, and bad arguments refused by name before
anything is drawn."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from ird_core.experiments import compare_runs
from ird_core.experiments.report import write_results_csv
from ird_core.experiments.summaries import CellSummary
from ird_core.experiments.tables import write_run_json


def _summary(condition: str, planner: str, lava: float, target: float, gap: float) -> CellSummary:
    return CellSummary("main", condition, planner, "", "", "", 50, lava, max(lava - 0.05, 0), lava + 0.05,
                       target, max(target - 0.1, 0), target + 0.1, 1.0, 0.5, 1.5, gap, gap - 0.05,
                       min(gap + 0.05, 1.0), 0, 1.0, 1.01, 0)


def _run(folder: Path, settings: dict, ird: dict[str, tuple[float, float, float]]) -> Path:
    folder.mkdir(parents=True)
    rows = []
    for condition, (lava, target, gap) in ird.items():
        rows += [_summary(condition, "literal", 0.5, 0.5, math.nan),
                 _summary(condition, "ird_maxent_z", lava, target, gap)]
    write_results_csv(folder / "results.csv", rows)
    write_run_json(folder / "run.json", "test", 1.0, settings, [], "git test")
    return folder


@pytest.fixture
def runs(tmp_path) -> list[Path]:
    return [_run(tmp_path / "one", {"size": 15}, {"latent_raw": (0.05, 0.2, 0.8), "latent_classifier": (0.0, 0.1, 0.9)}),
            _run(tmp_path / "three", {"training_worlds": 3}, {"latent_raw": (0.02, 0.6, 0.94)}),
            _run(tmp_path / "three_novel", {"training_worlds": 3, "novelty_feature": True},
                 {"latent_raw": (0.0, 0.45, 0.95)})]


def test_runs_are_placed_by_their_setting_and_a_missing_one_is_the_default(runs) -> None:
    points = compare_runs.load_runs(runs, "training_worlds", "novelty_feature")
    placed = {(p.condition, p.x, p.series): p.ird.target_fraction for p in points}
    assert placed == {("latent_raw", 1.0, "novelty_feature = False"): 0.2,
                      ("latent_classifier", 1.0, "novelty_feature = False"): 0.1,
                      ("latent_raw", 3.0, "novelty_feature = False"): 0.6,
                      ("latent_raw", 3.0, "novelty_feature = True"): 0.45}
    only = compare_runs.load_runs(runs, "training_worlds", conditions=["latent_classifier"])
    assert [(p.condition, p.series) for p in only] == [("latent_classifier", "IRD")]


def test_the_figure_draws_the_csv_numbers(runs) -> None:
    points = compare_runs.load_runs(runs, "training_worlds", "novelty_feature", conditions=["latent_raw"])
    fig = compare_runs.comparison_figure(points, "training_worlds")
    lava_ax, target_ax = fig.axes[0], fig.axes[1]
    drawn = [(tuple(line.get_xdata()), tuple(line.get_ydata())) for line in lava_ax.lines if line.get_marker() == "o"]
    assert drawn == [((1.0, 3.0), (0.05, 0.02)), ((3.0,), (0.0,))]  # per series, in x order
    bars = [line for line in target_ax.lines if line.get_linestyle() == "--"]
    np.testing.assert_allclose(bars[0].get_ydata(), [0.4, 0.4])  # 0.8 x the literal's 0.5


def test_the_goal_check_names_what_misses(runs) -> None:
    lines = compare_runs.summary_lines(compare_runs.load_runs(runs, "training_worlds", "novelty_feature"),
                                       "training_worlds")
    assert any(line.startswith("novelty_feature = False, training_worlds = 3, 50 trials: latent_raw")
               and line.endswith("PASS") for line in lines)
    assert any("training_worlds = 1" in line and "lava 5% > 2%" in line and "target 20% < 40.0%" in line
               for line in lines)
    assert any("novelty_feature = True" in line and "PASS" in line for line in lines)


def test_the_command_writes_the_figure_and_prints_the_check(runs, tmp_path, capsys) -> None:
    out = tmp_path / "new" / "cmp.png"
    assert compare_runs.main([*map(str, runs), "--series", "novelty_feature", "--out", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "MISS" in capsys.readouterr().out


@pytest.mark.parametrize("extra, message", [
    (["--x", "colour"], "x: 'colour' is not a trial setting"),
    (["--x", "hypothesis"], "x: 'hypothesis' is 'linear'"),
    (["--series", "flavour"], "series: 'flavour' is not a trial setting"),
    (["--planner", "ird_sample_z"], "planner: no run has 'ird_sample_z'"),
    (["--conditions", "lava_world"], "conditions: unknown ['lava_world']"),
])
def test_a_bad_argument_is_refused_by_name(runs, tmp_path, capsys, extra, message) -> None:
    out = tmp_path / "cmp.png"
    with pytest.raises(SystemExit) as stop:
        compare_runs.main([*map(str, runs), *extra, "--out", str(out)])
    assert stop.value.code == 2 and message in capsys.readouterr().err and not out.exists()


def test_a_folder_that_is_not_a_run_a_clash_and_a_bad_out_are_refused(runs, tmp_path, capsys) -> None:
    cases = [([str(tmp_path)], "not a run folder (no results.csv"),
             ([str(runs[1]), str(runs[1])], "merge such runs first"),
             ([str(runs[0]), "--out", str(tmp_path)], "--out: "),
             ]
    for args, message in cases:
        with pytest.raises(SystemExit) as stop:
            compare_runs.main([*args, "--out", str(tmp_path / "x.png")] if "--out" not in args else args)
        assert stop.value.code == 2 and message in capsys.readouterr().err, message


@pytest.mark.parametrize("damage", ["run.json", "settings", "results.csv"])
def test_a_damaged_run_is_refused_naming_its_folder(runs, tmp_path, capsys, damage) -> None:
    folder = runs[1]
    if damage == "run.json":
        (folder / "run.json").write_text("{not json")
    elif damage == "settings":
        (folder / "run.json").write_text('{"settings": [1, 2]}')
    else:
        (folder / "results.csv").write_text("experiment,condition\nmain,latent_raw,extra\n")
    with pytest.raises(SystemExit) as stop:
        compare_runs.main([*map(str, runs), "--out", str(tmp_path / "x.png")])
    assert stop.value.code == 2 and f"{folder}: " in capsys.readouterr().err


def test_a_target_just_under_the_bar_shows_the_bar_unrounded(tmp_path) -> None:
    """7 of 50 against 0.8 x 9 of 50: 14% < 14.4%, which whole percents would print as 14% < 14%."""
    folder = _run(tmp_path / "close", {}, {"latent_classifier": (0.0, 0.14, 0.95)})
    (folder / "results.csv").write_text((folder / "results.csv").read_text().replace(
        "literal,,,,50,0.5,0.45,0.55,0.5,", "literal,,,,50,0.5,0.45,0.55,0.18,"))
    line, = compare_runs.summary_lines(compare_runs.load_runs([folder], "training_worlds"), "training_worlds")
    assert "target 14% < 14.4% (0.8 x literal's 18%)" in line
