"""ird_core must stay a pure numpy/scipy/matplotlib library: importing it and every one
of its submodules must work when ROS is unavailable.

A subprocess gets a PYTHONPATH whose first entry holds poisoned ``rclpy``, ``ird_msgs``,
``ird_ros`` and message packages (importing any of them raises ImportError), imports
``ird_core`` and every submodule found by pkgutil, and reports what got loaded.
"""

from __future__ import annotations

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
