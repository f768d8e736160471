"""``pip install .`` gives a working install (issue 44):

- pyproject.toml declares every third-party package that ``ird_core`` and ``ird_ros`` import
  (read from the source, checked against what those declarations pull in, transitively): what
  ``ird_core`` imports at module level in its dependencies, the rest in an extra;
- a wheel built from the checkout, installed with ``--no-deps`` beside the project venv's
  packages, runs its entry points from a folder outside the checkout (``ird-export-world``,
  ``ird-launch --help`` and a one-node graph), importing the installed copy (never the checkout),
  finds its DDS profile, parameter file and web page as package data, and writes nothing into
  the installed package.
"""

from __future__ import annotations

import ast
import functools
import importlib.metadata as metadata
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from packaging.requirements import Requirement

ROOT = Path(__file__).resolve().parents[1]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
PROJECT_MODULES = {"ird_core", "ird_ros", "__future__"}
# Imported, but not from a distribution that pyproject.toml can name, with the reason.
NOT_DECLARED = {
    "ird_msgs": "the project's interfaces, built from msgs_config/ird_msgs by cmake (scripts/bootstrap.sh)",
    "compression": "Python 3.14's standard zstd module, tried before backports.zstd (ird_ros.bags.mcap_scan)",
    "lz4": "read only for lz4-compressed bags, which rosbags never writes; a clear error without it",
}


def _norm(name: str) -> str:
    return re.sub(r"[-_.]+", "-", name).lower()


def _closure(requirements: list[str]) -> set[str]:
    """The normalised names of ``requirements`` and of everything they require, as installed."""
    todo = [Requirement(r) for r in requirements]
    seen: set[str] = set()
    while todo:
        req = todo.pop()
        if req.marker is not None and not req.marker.evaluate({"extra": ""}):
            continue
        name = _norm(req.name)
        if name in seen:
            continue
        seen.add(name)
        try:
            todo.extend(Requirement(r) for r in metadata.requires(req.name) or [])
        except metadata.PackageNotFoundError:
            pass  # declared but not installed here: the import check below says whether it matters
    return seen


def _imports(package: str) -> dict[str, tuple[str, bool]]:
    """``{top-level module: (a file importing it, imported at module level outside try)}`` for
    the third-party imports of ``package``."""
    out: dict[str, tuple[str, bool]] = {}
    for path in sorted((ROOT / package).rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        guarded: set[int] = set()
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Try)):
                guarded.update(id(n) for n in ast.walk(node) if n is not node or isinstance(node, ast.Try))
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top in sys.stdlib_module_names or top in PROJECT_MODULES:
                    continue
                required = id(node) not in guarded
                if top not in out or (required and not out[top][1]):
                    out[top] = (str(path.relative_to(ROOT)), required)
    return out


@functools.cache
def _distributions() -> dict[str, list[str]]:
    return metadata.packages_distributions()  # reads every installed distribution's file list: once


def _providers(module: str) -> set[str]:
    return {_norm(d) for d in _distributions().get(module, [])}


def test_every_import_is_declared() -> None:
    core = _closure(PYPROJECT["project"]["dependencies"])
    extras = PYPROJECT["project"]["optional-dependencies"]
    everything = _closure(PYPROJECT["project"]["dependencies"] + [r for reqs in extras.values() for r in reqs])
    missing = []
    for package in ("ird_core", "ird_ros"):
        for module, (where, required) in sorted(_imports(package).items()):
            if module in NOT_DECLARED:
                continue
            providers = _providers(module)
            assert providers, f"{module} (imported by {where}) is not installed in this venv"
            # ird_core's module-level imports must come with a plain `pip install ird`.
            declared = core if package == "ird_core" and required else everything
            if not providers & declared:
                missing.append(f"{module} ({where}; from {sorted(providers)})")
    assert missing == [], "imported but not declared in pyproject.toml: " + ", ".join(missing)


def test_the_import_check_can_fail() -> None:
    assert "numpy" in _imports("ird_core") and _imports("ird_core")["numpy"][1]
    assert not _providers("numpy") & _closure(["PyYAML>=6"])
    assert "pillow" in _closure(["matplotlib"])  # transitive requirements count


def _copy_source(dst: Path) -> Path:
    """What a wheel is built from (pyproject.toml, README.md, the packages, msgs_config)."""
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", "build", "*.egg-info")
    for name in ("ird_core", "ird_ros", "msgs_config"):
        shutil.copytree(ROOT / name, dst / name, symlinks=True, ignore=ignore)
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(ROOT / name, dst / name)
    return dst


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts}


@pytest.mark.slow
def test_the_built_wheel_runs_from_any_folder(tmp_path: Path) -> None:
    src = _copy_source(tmp_path / "src")
    dist, target, elsewhere = tmp_path / "dist", tmp_path / "installed", tmp_path / "elsewhere"
    elsewhere.mkdir()
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "--no-input"]
    subprocess.run([*pip, "wheel", "--no-deps", "--no-build-isolation", "-w", str(dist), str(src)],
                   check=True, capture_output=True, text=True, timeout=300)
    (wheel,) = dist.glob("ird-*.whl")
    subprocess.run([*pip, "install", "--no-deps", "--no-compile", "--target", str(target), str(wheel)],
                   check=True, capture_output=True, text=True, timeout=300)
    shipped = _files(target)
    for data in ("ird_ros/msgs_config/dds/fastdds_localhost.xml", "ird_ros/msgs_config/params/graph.yaml",
                 "ird_ros/msgs_config/ird_msgs/msg/RewardPosterior.msg", "ird_ros/web/static/index.html"):
        assert data in shipped, f"{data} is not in the wheel"
    assert not (target / "ird_ros" / "msgs_config").is_symlink()

    # The installed copy, beside the project venv's packages (whose editable ird it shadows).
    env = {**os.environ, "PYTHONPATH": str(target), "PYTHONDONTWRITEBYTECODE": "1"}

    def run(*argv: str, verbose: bool = False) -> subprocess.CompletedProcess:
        return subprocess.run(list(argv), cwd=elsewhere, capture_output=True, text=True, timeout=300,
                              env={**env, "PYTHONVERBOSE": "1"} if verbose else env)

    exported = run(str(target / "bin" / "ird-export-world"), "--condition", "latent_raw", "--size", "6",
                   "--horizon", "8", verbose=True)
    assert exported.returncode == 0, exported.stderr[-3000:]
    written = elsewhere / exported.stdout.strip().splitlines()[-1]  # relative: the working directory
    assert written.parent == elsewhere / "worlds" / "exported" and written.is_file(), written
    loaded = re.findall(r"code object from '?([^'\s]+/ird_core/__init__\.py)", exported.stderr)
    assert loaded and all(Path(p).is_relative_to(target) for p in loaded), loaded

    launch = run(str(target / "bin" / "ird-launch"), "--help")
    assert launch.returncode == 0 and "--params" in launch.stdout, launch.stderr[-3000:]
    # A real graph of one node, with the installed params file and DDS profile (its children get
    # the installed copy on their PYTHONPATH).
    graph = run(str(target / "bin" / "ird-launch"), "--nodes", "world", "--private-domain", "--run-for", "1",
                "--timeout", "120")
    assert graph.returncode == 0 and "graph ready" in graph.stdout, (graph.stdout + graph.stderr)[-3000:]

    probe = run(sys.executable, "-c", "import ird_core, ird_ros.resources as r, ird_ros.graph.domains as d, "
                "ird_ros.launch as l, ird_ros.web.server as w\n"
                "for p in (ird_core.__file__, r.dds_profile(), d.DDS_PROFILE, r.graph_params(), "
                "l.default_params_file(), w.WEB_DIR / 'index.html', r.msg_root() / 'ird_msgs'): print(p)")
    assert probe.returncode == 0, probe.stderr[-3000:]
    for line in probe.stdout.splitlines():
        assert Path(line).is_relative_to(target.resolve()) and Path(line).exists(), line
    assert _files(target) == shipped, "a run wrote into the installed package"
