"""ird_core must stay a pure numpy/scipy/matplotlib library: importing it and every one
of its submodules must work when ROS is unavailable.

A subprocess gets a PYTHONPATH whose first entry holds poisoned ``rclpy``, ``ird_msgs``,
``ird_ros`` and message packages (importing any of them raises ImportError), imports
``ird_core`` and every submodule found by pkgutil, and reports what got loaded.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
POISONED = (
    "rclpy", "ird_msgs", "ird_ros", "rosbags", "rosidl_runtime_py", "rosidl_parser",
    "std_msgs", "nav_msgs", "geometry_msgs", "builtin_interfaces", "sensor_msgs",
)

PROBE = """
import importlib, json, pkgutil, sys
import ird_core
imported = ["ird_core"]
def fail(name):
    raise
for info in pkgutil.walk_packages(ird_core.__path__, "ird_core.", onerror=fail):
    importlib.import_module(info.name)
    imported.append(info.name)
poisoned = set(sys.argv[1].split(","))
loaded = sorted(m for m in sys.modules if m.split(".")[0] in poisoned)
print(json.dumps({"imported": imported, "loaded": loaded, "file": ird_core.__file__}))
"""


def test_ird_core_imports_without_ros(tmp_path: Path) -> None:
    poison = tmp_path / "poison"
    for name in POISONED:
        pkg = poison / name
        pkg.mkdir(parents=True)
        (pkg / "__init__.py").write_text(
            f"raise ImportError('{name} is poisoned: ird_core must not import ROS code')\n"
        )
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(poison), str(ROOT)])
    env["MPLBACKEND"] = "Agg"
    result = subprocess.run(
        [sys.executable, "-c", PROBE, ",".join(POISONED)],
        cwd=ROOT, env=env, capture_output=True, text=True, timeout=120,
    )
    assert result.returncode == 0, f"importing ird_core without ROS failed:\n{result.stderr}"
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert Path(report["file"]).resolve().parent == ROOT / "ird_core"
    assert report["loaded"] == [], f"ird_core pulled in ROS modules: {report['loaded']}"

    # Meaningful as ird_core grows: every module file in the package was imported.
    on_disk = {
        "ird_core." + ".".join(p.relative_to(ROOT / "ird_core").with_suffix("").parts)
        for p in (ROOT / "ird_core").rglob("*.py")
        if p.name != "__init__.py" and "__pycache__" not in p.parts
    }
    assert on_disk <= set(report["imported"]), f"not imported: {sorted(on_disk - set(report['imported']))}"


def test_poison_really_blocks_rclpy(tmp_path: Path) -> None:
    """The poisoning above works: with it, `import rclpy` fails."""
    pkg = tmp_path / "rclpy"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("raise ImportError('poisoned')\n")
    env = dict(os.environ, PYTHONPATH=str(tmp_path))
    result = subprocess.run(
        [sys.executable, "-c", "import rclpy"], cwd=ROOT, env=env, capture_output=True, text=True, timeout=60
    )
    assert result.returncode != 0
    assert "poisoned" in result.stderr


def _module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imported(tree: ast.AST, name: str, is_package: bool, modules: set[str]) -> set[str]:
    """Modules ``tree`` imports anywhere (functions too; not under ``if TYPE_CHECKING``)."""
    found: set[str] = set()

    def visit(node: ast.AST) -> None:
        if isinstance(node, ast.If) and getattr(node.test, "id", getattr(node.test, "attr", "")) == "TYPE_CHECKING":
            for child in node.orelse:
                visit(child)
            return
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                package = name.split(".") if is_package else name.split(".")[:-1]
                base = ".".join(package[: len(package) - node.level + 1] + ([base] if base else []))
            for alias in node.names:
                full = f"{base}.{alias.name}"
                found.add(full if full in modules else base)
        for child in ast.iter_child_nodes(node):
            visit(child)

    visit(tree)
    return found


def _import_graph(packages: tuple[str, ...]) -> dict[str, set[str]]:
    """Module -> the project modules its imports run: the module itself and every package
    ``__init__`` above it, except the importer's own packages."""
    files = {_module_name(p): p for pkg in packages for p in (ROOT / pkg).rglob("*.py") if "__pycache__" not in p.parts}
    graph: dict[str, set[str]] = {}
    for name, path in files.items():
        own = {".".join(name.split(".")[:i]) for i in range(1, name.count(".") + 2)}
        edges: set[str] = set()
        for target in _imported(ast.parse(path.read_text()), name, path.name == "__init__.py", set(files)):
            parts = target.split(".")
            edges.update(anc for anc in (".".join(parts[:i]) for i in range(1, len(parts) + 1))
                         if anc in files and anc not in own)
        graph[name] = edges
    return graph


def test_no_import_cycles() -> None:
    """No module of ird_core or ird_ros imports, directly or through others (imports inside
    functions included), a module that imports it back."""
    graph = _import_graph(("ird_core", "ird_ros"))
    for start in graph:
        seen: set[str] = set()
        todo = list(graph[start])
        while todo:
            module = todo.pop()
            assert module != start, f"{start} is in an import cycle"
            if module not in seen:
                seen.add(module)
                todo.extend(graph[module])
