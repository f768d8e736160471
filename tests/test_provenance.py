"""Which code produced a result (ird_core.experiments.provenance): the commit, every uncommitted
change to ``ird_core`` or ``scripts``, and nothing else; a merged report names each chunk's."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from ird_core.experiments import chunks, cli, provenance


def _git(root: Path, *args: str) -> str:
    return subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, check=True).stdout.strip()


@pytest.fixture
def checkout(tmp_path: Path) -> Path:
    root = tmp_path / "checkout"
    for path in ("ird_core/mod.py", "scripts/run.py", "docs/page.md"):
        (root / path).parent.mkdir(parents=True, exist_ok=True)
        (root / path).write_text("x = 1\n")
    _git(root.parent, "init", "-q", str(root))
    _git(root, "add", ".")
    _git(root, "-c", "user.name=t", "-c", "user.email=t@example.com", "commit", "-q", "-m", "first")
    return root


def test_a_clean_checkout_is_its_commit(checkout: Path) -> None:
    assert provenance.code_version(checkout) == f"git {_git(checkout, 'rev-parse', '--short=12', 'HEAD')}"


def test_changed_and_new_files_under_the_result_code_are_named_and_nothing_else(checkout: Path) -> None:
    commit = _git(checkout, "rev-parse", "--short=12", "HEAD")
    (checkout / "docs/page.md").write_text("changed\n")  # not code that computes results
    assert provenance.code_version(checkout) == f"git {commit}"
    (checkout / "ird_core/mod.py").write_text("x = 2\n")
    (checkout / "scripts/new.py").write_text("y = 1\n")
    assert provenance.code_version(checkout) == (
        f"git {commit} with uncommitted changes to ird_core/mod.py, scripts/new.py")


def test_many_changes_are_counted_past_the_named_ones(checkout: Path) -> None:
    for i in range(9):
        (checkout / f"ird_core/extra_{i}.py").write_text("z = 0\n")
    line = provenance.code_version(checkout)
    assert line.endswith(" and 3 more") and "ird_core/extra_0.py" in line and "extra_8" not in line


def test_outside_a_checkout_the_line_says_so(tmp_path: Path) -> None:
    assert provenance.code_version(tmp_path) == f"not a git checkout ({tmp_path})"


def test_a_merged_report_names_each_distinct_chunk_code_once() -> None:
    assert provenance.merged_code(["git a", "git a"]) == "git a"
    assert provenance.merged_code(["git a", "git b with uncommitted changes to x", "git a"]) == \
        "git a | git b with uncommitted changes to x"
    assert provenance.merged_code(["git a", ""]) == f"git a | {provenance.NOT_RECORDED}"


def test_merged_runs_carry_the_chunks_code_and_old_runs_say_not_recorded() -> None:
    run = {"command": "c", "wall_seconds": 1.0, "settings": {"trials": 1, "seed": 0}}
    merged = chunks.merge_runs([dict(run, code="git a"), dict(run, settings={"trials": 1, "seed": 1})],
                               [("x", 0), ("x", 1)], [0, 1])
    assert merged.code == f"git a | {provenance.NOT_RECORDED}"


def test_a_run_records_the_code_it_started_with(tmp_path: Path) -> None:
    out = tmp_path / "run"
    assert cli.main(["--quick", "--trials", "1", "--conditions", "side_effects", "--z-methods", "maxent_z",
                     "--no-factorial", "--workers", "1", "--out", str(out)]) == 0
    line = provenance.code_version()
    assert json.loads((out / "run.json").read_text())["code"] == line
    assert f"Code: {line}\n" in (out / "results.md").read_text()
    assert cli.main(["--report-only", "--out", str(out)]) == 0  # a rewritten report keeps it
    assert f"Code: {line}\n" in (out / "results.md").read_text()
