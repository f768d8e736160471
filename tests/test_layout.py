"""The package layout's rules, read from the source (AST, no imports executed):

- no import cycle among the project's modules, counting imports inside functions and under
  ``TYPE_CHECKING`` (a cycle hidden in a function is still a cycle);
- ``ird_core`` never imports ROS (``ird_ros``, ``rclpy``, ``ird_msgs``) and its worlds never import
  the posterior, the planners, the designer or the experiments (docs/spec.md: worlds describe maps,
  proxies and the true reward; algorithms read them);
- production code (``ird_core``, ``ird_ros``, ``scripts``) never imports ``ird_ros.testing``;
- no module is longer than 450 lines unless its docstring says why (a line starting with
  ``Longer than 450 lines:``).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("ird_core", "ird_ros")
MAX_LINES = 450


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _imports(path: Path, name: str, known: set[str]) -> set[str]:
    """The project modules ``path`` imports anywhere in its body (``from a import b`` counts as
    ``a.b`` when that is a module, else ``a``)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    is_package = path.name == "__init__.py"
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")
                base = base if is_package else base[:-1]
                base = base[: len(base) - (node.level - 1)]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module or ""
            for alias in node.names:
                sub = f"{module}.{alias.name}"
                out.add(sub if sub in known else module)
    return out


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    known = set(modules)
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        deps = set()
        for target in _imports(path, name, known):
            # importing a.b.c also imports the packages a and a.b
            parts = target.split(".")
            deps.update(".".join(parts[:i]) for i in range(1, len(parts) + 1))
        graph[name] = {d for d in deps if d in known and d != name and not name.startswith(d + ".")}
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_the_cycle_finder_finds_a_cycle() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles() -> None:
    assert _cycles(_graph()) == []


def _all_imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            out.add(node.module)
            out.update(f"{node.module}.{alias.name}" for alias in node.names)
    return out


def _offenders(folder: str, forbidden: tuple[str, ...]) -> list[str]:
    hits = []
    for path in sorted((ROOT / folder).rglob("*.py")):
        for module in _all_imports(path):
            if any(module == f or module.startswith(f + ".") for f in forbidden):
                hits.append(f"{path.relative_to(ROOT)} imports {module}")
    return hits


def test_core_imports_no_ros() -> None:
    assert _offenders("ird_core", ("ird_ros", "rclpy", "ird_msgs", "rosbags")) == []


@pytest.mark.parametrize("layer", ["posterior", "planning", "hypothesis", "designer", "experiments", "mcmc"])
def test_worlds_import_no_algorithm(layer: str) -> None:
    assert _offenders("ird_core/worlds", (f"ird_core.{layer}",)) == []


@pytest.mark.parametrize("folder", ["ird_core", "ird_ros", "scripts"])
def test_production_code_does_not_import_the_test_helpers(folder: str) -> None:
    hits = [h for h in _offenders(folder, ("ird_ros.testing",)) if not h.startswith("ird_ros/testing")]
    assert hits == []


def test_modules_are_short_or_say_why() -> None:
    long = []
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            text = path.read_text(encoding="utf-8")
            if text.count("\n") > MAX_LINES and "Longer than 450 lines:" not in (ast.get_docstring(ast.parse(text)) or ""):
                long.append(f"{path.relative_to(ROOT)} ({text.count(chr(10))} lines)")
    assert long == []


@pytest.mark.parametrize("layer", ["designer", "experiments"])
def test_hypothesis_spaces_import_no_experiment(layer: str) -> None:
    """The world node builds its hypothesis space from ``ird_core.hypothesis``: it must not pull
    in the experiments (or the designer) to do so."""
    assert _offenders("ird_core/hypothesis", (f"ird_core.{layer}",)) == []
