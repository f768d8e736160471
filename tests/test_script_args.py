"""The shell entry points parse their arguments before doing anything: ``--help`` prints a usage
and starts, builds or sets up nothing; relative paths are the caller's (issue 43)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _tree(tmp_path: Path, *scripts: str) -> Path:
    """A fresh tree holding only ``scripts`` (no bootstrap.sh, no .venv: nothing can be set up)."""
    tree = tmp_path / "tree"
    (tree / "scripts").mkdir(parents=True)
    for script in scripts:
        shutil.copy(ROOT / "scripts" / script, tree / "scripts" / script)
    return tree


def _env(tmp_path: Path) -> dict[str, str]:
    return {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": str(tmp_path)}


@pytest.mark.parametrize("script", ["stress_ros_tests.sh", "build_docs.sh"])
@pytest.mark.parametrize("flag", ["--help", "-h"])
def test_help_prints_usage_and_does_nothing_else(tmp_path: Path, script: str, flag: str) -> None:
    tree = _tree(tmp_path, script)
    caller = tmp_path / "caller"
    caller.mkdir()
    run = subprocess.run(["bash", str(tree / "scripts" / script), flag], capture_output=True, text=True,
                         cwd=caller, env=_env(tmp_path), timeout=30)
    assert run.returncode == 0 and run.stderr == "", run.stderr
    assert run.stdout.startswith(f"usage: bash scripts/{script}")
    assert "[stress]" not in run.stdout and "[docs]" not in run.stdout
    assert sorted(p.name for p in tree.iterdir()) == ["scripts"] and list(caller.iterdir()) == []


@pytest.mark.parametrize("argv, message", [
    (["abc"], "RUNS must be a positive whole number, got 'abc'"),
    (["0"], "RUNS must be a positive whole number, got '0'"),
])
def test_stress_refuses_a_bad_run_count(tmp_path: Path, argv: list[str], message: str) -> None:
    tree = _tree(tmp_path, "stress_ros_tests.sh")
    run = subprocess.run(["bash", str(tree / "scripts" / "stress_ros_tests.sh"), *argv], capture_output=True,
                         text=True, env=_env(tmp_path), timeout=30)
    assert run.returncode == 2 and message in run.stderr and run.stdout == ""


def test_build_docs_refuses_an_unknown_option(tmp_path: Path) -> None:
    tree = _tree(tmp_path, "build_docs.sh")
    run = subprocess.run(["bash", str(tree / "scripts" / "build_docs.sh"), "--out"], capture_output=True,
                         text=True, cwd=tmp_path, env=_env(tmp_path), timeout=30)
    assert run.returncode == 2 and "unknown option '--out'" in run.stderr
    assert not (tmp_path / "--out").exists()


def test_demo_sh_runs_the_demo_from_the_callers_directory(tmp_path: Path) -> None:
    """``--world rel.yaml`` and ``--out rel`` name files of the caller's directory: demo.sh must not
    change directory before the demo resolves them (stand-ins for the bootstrap, the ROS
    environment and the venv's python record what the demo would get)."""
    tree = _tree(tmp_path, "demo.sh")
    (tree / "scripts" / "bootstrap.sh").write_text("exit 0\n")
    (tree / "scripts" / "lib").mkdir()
    (tree / "scripts" / "lib" / "ros_env.sh").write_text("ird_ros_env() { :; }\n")
    python = tree / ".venv" / "bin" / "python"
    python.parent.mkdir(parents=True)
    python.write_text('#!/usr/bin/env bash\necho "cwd=$PWD"\necho "args=$*"\n')
    python.chmod(0o755)
    caller = tmp_path / "caller"
    caller.mkdir()
    run = subprocess.run(["bash", str(tree / "scripts" / "demo.sh"), "--world", "mine.yaml", "--out", "runs"],
                         capture_output=True, text=True, cwd=caller, env=_env(tmp_path), timeout=30)
    assert run.returncode == 0, run.stderr
    assert run.stdout.splitlines() == [f"cwd={caller}", f"args={tree}/scripts/demo.py --world mine.yaml --out runs"]


def test_demo_sh_help_states_the_parsers_choices_and_defaults() -> None:
    """Every ``{choices}`` and ``(default X)`` that demo.sh's usage states is the parser's."""
    from ird_ros.apps import demo

    usage = subprocess.run(["bash", str(ROOT / "scripts" / "demo.sh"), "--help"], capture_output=True, text=True,
                           timeout=30).stdout
    blocks = re.split(r"\n  (?=-)", usage.split("options:", 1)[1])  # one block per option
    by_option = {}
    for block in filter(str.strip, blocks):
        first = block.strip().split()[0].rstrip(",")
        by_option[first] = " ".join(block.split())
    checked = 0
    for action in demo.build_parser()._actions:
        text = next((by_option[o] for o in action.option_strings if o in by_option), None)
        assert text is not None, f"{action.option_strings} missing from demo.sh --help"
        if action.choices:
            assert "{" + ",".join(map(str, action.choices)) + "}" in text, (action.option_strings, text)
            checked += 1
        stated = re.search(r"\(default ([^);]+)\)|; default ([^)]+)\)", text)
        if stated and "experiments" not in text:
            value = (stated.group(1) or stated.group(2)).strip()
            assert value in {str(action.default), f"{action.default:g}" if isinstance(action.default, float) else ""} \
                or str(action.default).endswith(value), (action.option_strings, value, action.default)
            checked += 1
    assert checked >= 8
