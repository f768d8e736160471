"""The README and the docs pages say true things:

- every code block marked ``python runnable`` runs as it is, alone, in an empty folder, and prints
  exactly the ``text output`` block that follows it (if one does), with the reference numerics
  (``REFERENCE_NUMERICS``: the same on every x86-64 machine with AVX2, whatever its load);
- every repository path they name (a Markdown link or image, or a path like ``scripts/demo.sh``
  in the text or a code block) exists.

Pages that a run writes (``docs/results/``) and the build output are not read.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted([ROOT / "README.md", *(p for p in (ROOT / "docs").rglob("*.md")
                                      if not p.relative_to(ROOT / "docs").parts[0] in ("_build", "results"))])

FENCE = re.compile(r"^```([^\n`]*)\n(.*?)^```[ \t]*$", re.S | re.M)
LINK = re.compile(r"\]\(([^)\s]+)\)")
# A path from the repository root: one of its top-level folders, then at least one more part.
REPO_PATH = re.compile(r"(?<![\w./$~-])((?:\.ci|docs|ird_core|ird_ros|scripts|tests|msgs_config|worlds)/[\w./-]*[\w/])")
TOP_FILES = re.compile(r"(?<![\w./-])(README\.md|CHANGELOG\.md|requirements(?:-docs)?\.txt|pyproject\.toml)(?![\w-])")
# Named outputs (written by a run or a build, not committed) and placeholders.
NOT_FILES = ("docs/_build", "__pycache__", "worlds/exported")

# The pages' printed numbers come from seeded runs with deterministic bounds (no wall-clock
# budget decides them), but MCMC amplifies the last bits of floating-point arithmetic, and
# OpenBLAS and numpy pick their kernels by CPU: an AVX-512 machine prints other R-hats (and
# another designer's answer) than an AVX2 one. So the blocks run with OpenBLAS's Haswell (AVX2)
# kernels, numpy's AVX2 loops and one BLAS thread, which every x86-64 machine since 2013 has
# (docs/library.md says so where it prints them).
REFERENCE_NUMERICS = {
    "OPENBLAS_CORETYPE": "Haswell",
    "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR",
    "OPENBLAS_NUM_THREADS": "1",
}


def run_block(code: str, cwd: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    """Run one runnable block as a reader would (a fresh interpreter in ``cwd``), with the
    reference numerics."""
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True,
                          timeout=timeout, env={**os.environ, **REFERENCE_NUMERICS})


def runnable_blocks(text: str) -> list[tuple[str, str | None]]:
    """``(code, expected output or None)`` for every ``python runnable`` block of ``text``: the
    expected output is the next fenced block when its info string is ``text output``."""
    blocks = [(m.group(1).strip(), m.group(2)) for m in FENCE.finditer(text)]
    out = []
    for i, (info, body) in enumerate(blocks):
        if info == "python runnable":
            following = blocks[i + 1] if i + 1 < len(blocks) else None
            out.append((body, following[1] if following and following[0] == "text output" else None))
    return out


def named_paths(text: str, page: Path) -> set[Path]:
    """The repository files and folders ``text`` (the content of ``page``) names."""
    out: set[Path] = set()
    for target in LINK.findall(text):
        if re.match(r"^[a-z]+:", target) or target.startswith("#"):
            continue
        out.add((page.parent / target.split("#")[0]).resolve())
    for match in REPO_PATH.finditer(text):
        path = match.group(1).rstrip(".")
        if any(marker in path for marker in NOT_FILES) or text[match.end():match.end() + 1] in "*<{[":
            continue
        out.add((ROOT / path).resolve())
    out.update((ROOT / name).resolve() for name in TOP_FILES.findall(text))
    return out


def missing_paths(text: str, page: Path) -> list[str]:
    return sorted(str(p.relative_to(ROOT)) if p.is_relative_to(ROOT) else str(p)
                  for p in named_paths(text, page) if not p.exists())


def test_the_checks_can_fail(tmp_path: Path) -> None:
    text = ("See `scripts/no_such_script.py`, [a page](no_such_page.md#x), ![a picture](docs/nope.png)\n"
            "and `scripts/demo.sh`, [the spec](docs/spec.md), `requirements-docs.txt`.\n"
            "```python runnable\nprint(1)\n```\n\n```text output\n1\n```\n```python\nnot run\n```\n")
    assert missing_paths(text, ROOT / "README.md") == ["docs/nope.png", "no_such_page.md",
                                                       "scripts/no_such_script.py"]
    assert runnable_blocks(text) == [("print(1)\n", "1\n")]


def test_there_is_something_to_check() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert runnable_blocks(readme), "the README has no python runnable block"
    assert len(named_paths(readme, ROOT / "README.md")) > 20
    assert len(readme.splitlines()) <= 200, "the README is a front page: at most 200 lines"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_named_path_exists(page: Path) -> None:
    assert missing_paths(page.read_text(encoding="utf-8"), page) == []


RUNNABLE = [(page, i, code, output) for page in PAGES
            for i, (code, output) in enumerate(runnable_blocks(page.read_text(encoding="utf-8")))]


@pytest.mark.slow
@pytest.mark.parametrize("page, index, code, output", RUNNABLE,
                         ids=[f"{p.relative_to(ROOT)}#{i}" for p, i, _, _ in RUNNABLE])
def test_runnable_block_runs_and_prints_what_the_page_says(page: Path, index: int, code: str, output: str | None,
                                                           tmp_path: Path) -> None:
    done = run_block(code, tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    if output is not None:
        assert done.stdout.rstrip("\n").splitlines() == output.rstrip("\n").splitlines()
