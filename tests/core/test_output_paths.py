"""ird_core.output_paths: the checks create nothing and name the path in the way."""

from __future__ import annotations

from pathlib import Path

import pytest

from ird_core.output_paths import file_problem, folder_problem, make_output_folder


def test_a_folder_can_be_made_under_folders_and_not_under_a_file(tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    assert folder_problem(tmp_path) == folder_problem(tmp_path / "new" / "deeper") == ""
    assert folder_problem(blocker) == folder_problem(blocker / "x" / "y") == f"{blocker} is not a folder"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a_file"]  # nothing was made


def test_a_file_can_be_written_unless_a_folder_or_a_file_is_in_the_way(tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    assert file_problem(blocker) == file_problem(tmp_path / "new" / "rows.csv") == ""
    assert file_problem(tmp_path) == f"{tmp_path} is a folder, not a file"
    assert file_problem(blocker / "rows.csv") == f"{blocker} is not a folder"
    assert blocker.read_text() == "kept" and not (tmp_path / "new").exists()


def test_make_output_folder_makes_it_or_names_the_option(tmp_path: Path) -> None:
    make_output_folder(tmp_path / "a" / "b")
    make_output_folder(tmp_path / "a" / "b")  # already there: fine
    assert (tmp_path / "a" / "b").is_dir()
    (tmp_path / "f").write_text("kept")
    with pytest.raises(ValueError, match=f"^--plots: cannot make the folder {tmp_path / 'f' / 'x'}: "):
        make_output_folder(tmp_path / "f" / "x", "--plots")
    assert (tmp_path / "f").read_text() == "kept"
