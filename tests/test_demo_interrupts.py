"""The demo's run folders and its Ctrl-C (issue 43): two demos started in the same second get two
folders; a Ctrl-C wherever it lands ends the demo with one line and exit code 130, never a
traceback, and the survey's worker is stopped."""

from __future__ import annotations

import datetime as dt
from pathlib import Path
from typing import Any

import pytest

from ird_ros.apps import demo


def test_demos_started_in_the_same_second_get_their_own_folders(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    now = dt.datetime(2025, 1, 2, 3, 4, 5)
    monkeypatch.chdir(tmp_path)
    made = [demo.make_run_dir("out/demo", now) for _ in range(3)]
    assert [p.name for p in made] == ["run-20250102-030405", "run-20250102-030405-2", "run-20250102-030405-3"]
    assert all(p.is_dir() and p.parent == tmp_path / "out" / "demo" for p in made)  # relative to the caller


def test_an_out_where_no_folder_can_be_made_ends_the_demo_before_anything_starts(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    for out in (blocker, blocker / "sub"):
        assert demo.main(["--out", str(out), "--no-survey"]) == 2
        err = capsys.readouterr().err
        assert f"[demo] --out: cannot make the folder {out}: " in err and "Traceback" not in err, err
    assert blocker.read_text() == "kept"

class FakeSurvey:
    cancelled = 0

    def __init__(self, spec: Any) -> None:
        pass

    def cancel(self) -> None:
        FakeSurvey.cancelled += 1

    def report(self, scene: str, method: str) -> None:
        raise KeyboardInterrupt  # Ctrl-C while the demo waits for the survey


def test_ctrl_c_while_waiting_for_the_survey_is_one_line_and_130(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    FakeSurvey.cancelled = 0
    monkeypatch.setattr(demo, "Survey", FakeSurvey)
    monkeypatch.setattr(demo, "run_graph", lambda args, setup, results: None)
    monkeypatch.setattr(demo, "report_mission", lambda args, setup, results: [])
    monkeypatch.setattr(demo, "report_bag", lambda setup: None)
    assert demo.main(["--out", str(tmp_path)]) == 130
    out, err = capsys.readouterr()
    assert err.strip() == demo.STOPPED_LINE and "Traceback" not in out + err
    assert FakeSurvey.cancelled >= 1


def test_ctrl_c_while_the_graph_starts_is_one_line_and_130(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                           capsys: pytest.CaptureFixture[str]) -> None:
    def interrupted(args: Any, setup: Any, results: Any) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(demo, "Survey", FakeSurvey)
    monkeypatch.setattr(demo, "run_graph", interrupted)
    monkeypatch.setattr(demo, "report_bag", lambda setup: None)
    monkeypatch.setattr(FakeSurvey, "report", lambda self, scene, method: None)
    assert demo.main(["--out", str(tmp_path), "--no-survey"]) == 130
    out, err = capsys.readouterr()
    assert "[demo] stopped by Ctrl-C: the graph was stopped and the bag closed." in out
    assert "Traceback" not in out + err
