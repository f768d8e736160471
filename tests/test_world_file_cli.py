"""A bad world file at the programs' doors: ``launch_graph.py``, ``demo.py`` and
``run_experiments.py`` with ``--world`` exit 2 naming the file and the key, with no traceback and
before any node starts; the world file's limits are within the nodes' limits; a node that dies
while the graph starts is reported with its last output also when its output goes to files."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from ird_core.worlds import file_values

ROOT = Path(__file__).resolve().parents[1]
WORLD = ROOT / "worlds" / "figure1.yaml"
PARAMS = yaml.safe_load((ROOT / "msgs_config" / "params" / "graph.yaml").read_text())


def _node_limit(node: str, name: str) -> list[float]:
    """The node's parameter ``name``: its default and the graph's params file's value."""
    import importlib

    param = importlib.import_module(f"ird_ros.nodes.{node}").PARAMETERS[name]
    values = [param.default]
    if name in PARAMS.get(node, {}).get("ros__parameters", {}):
        values.append(PARAMS[node]["ros__parameters"][name])
    return values


def test_world_file_limits_do_not_exceed_the_nodes_limits() -> None:
    """A world that loads is one every service accepts with the shipped settings."""
    for node in ("planner", "inference"):
        assert all(file_values.MAX_HORIZON <= v for v in _node_limit(node, "max_horizon"))
        assert all(file_values.MAX_MAP_VALUES <= v for v in _node_limit(node, "max_map_values"))
    assert all(file_values.MAX_PLAN_WORK <= v for v in _node_limit("planner", "max_plan_work"))
    from ird_ros.nodes.world import PARAMETERS as WORLD_PARAMS

    for side in ("height", "width"):
        assert file_values.MAX_MAP_SIDE <= WORLD_PARAMS[side].max_value
    assert file_values.MAX_SEED <= WORLD_PARAMS["seed"].max_value
    low, high = file_values.RESOLUTION_RANGE
    assert WORLD_PARAMS["resolution"].min_value <= low and high <= WORLD_PARAMS["resolution"].max_value
    assert file_values.MAX_MAP_SIDE ** 2 <= file_values.MAX_MAP_VALUES  # the side limit admits a square map


def _bad_world(tmp_path: Path, kind: str) -> tuple[Path, str]:
    """A bad world file of ``kind`` and the ``<file>: <key>`` its error must start with."""
    doc = yaml.safe_load(WORLD.read_text())
    for image in ("figure1_train.png", "figure1_test.png"):
        (tmp_path / image).write_bytes((WORLD.parent / image).read_bytes())
    path = tmp_path / "bad.yaml"
    if kind == "png":
        path = tmp_path / "figure1_train.png"
        return path, f"{path}: (file): is a PNG image"
    if kind == "yaw":
        doc["origin"] = [0.0, 0.0, 1.5]
        key = "origin"
    elif kind == "horizon":
        doc["test_world"]["horizon"] = 1_000_000_000
        key = "test_world.horizon"
    elif kind == "laughs":
        doc["proxy"] = "LAUGHS"
        key = "proxy["
    elif kind == "misspelled":
        doc["training_worlds"][0]["horizn"] = 3
        key = "training_worlds[0].horizn"
    text = yaml.safe_dump(doc, sort_keys=False)
    path.write_text(text.replace("LAUGHS", "[&a [x, x, x, x, x, x, x, x], " + ", ".join(
        f"&{chr(98 + i)} [" + ", ".join([f"*{chr(97 + i)}"] * 8) + "]" for i in range(9)) + "]"))
    return path, f"{path}: {key}"


def _run(argv: list[str], tmp_path: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    # the timeout is a safety net for a hang, not a speed requirement
    return subprocess.run([sys.executable, *argv], capture_output=True, text=True, env=env, cwd=tmp_path,
                          timeout=600)


PROGRAMS = {
    "launch_graph": lambda world, out: [str(ROOT / "scripts" / "launch_graph.py"), "--world", str(world),
                                        "--private-domain"],
    "demo": lambda world, out: [str(ROOT / "scripts" / "demo.py"), "--world", str(world), "--no-survey",
                                "--out", str(out)],
    "run_experiments": lambda world, out: [str(ROOT / "scripts" / "run_experiments.py"), "--world", str(world),
                                           "--trials", "1", "--out", str(out)],
}
CASES = [("launch_graph", kind) for kind in ("png", "yaw", "horizon", "laughs", "misspelled")] + [
    (program, kind) for program in ("demo", "run_experiments") for kind in ("png", "yaw", "laughs")]


@pytest.mark.parametrize("program, kind", CASES)
def test_bad_world_exits_2_naming_file_and_key(tmp_path: Path, program: str, kind: str) -> None:
    world, expected = _bad_world(tmp_path, kind)
    run = _run(PROGRAMS[program](world, tmp_path / "out"), tmp_path)
    assert run.returncode == 2, (run.stdout, run.stderr)
    assert expected in run.stderr, run.stderr
    assert "Traceback" not in run.stderr + run.stdout, run.stderr
    assert "started" not in run.stdout and not (tmp_path / "out").exists()  # nothing ran, nothing written


def test_launch_graph_prints_the_world_files_warnings(tmp_path: Path) -> None:
    """A test start on lava (a terrain no training map shows) loads with a warning line; the
    graph itself is then refused for an unknown node, so nothing starts."""
    doc = yaml.safe_load(WORLD.read_text())
    for image in ("figure1_train.png", "figure1_test.png"):
        (tmp_path / image).write_bytes((WORLD.parent / image).read_bytes())
    from ird_core.worlds import world_file

    inst = world_file.load_world(WORLD)
    lava = [int(v) for v in next(iter(zip(*(inst.test_labels == 3).nonzero())))]
    doc["test_world"]["start"] = lava
    path = tmp_path / "lava_start.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    run = _run([str(ROOT / "scripts" / "launch_graph.py"), "--world", str(path), "--nodes", "no_such_node"], tmp_path)
    assert f"[launcher] warning: --world: {path}: test_world.start: {lava} is on lava" in run.stderr, run.stderr
    assert run.returncode == 2 and "unknown node" in run.stderr and "Traceback" not in run.stderr


def test_demo_prints_the_world_files_warnings(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from ird_ros.apps import demo

    doc = yaml.safe_load(WORLD.read_text())
    for image in ("figure1_train.png", "figure1_test.png"):
        (tmp_path / image).write_bytes((WORLD.parent / image).read_bytes())
    doc["test_world"]["start"] = [int(v) for v in doc["training_worlds"][0]["start"]]
    path = tmp_path / "seen.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    demo.mission_spec(demo.parse_args(["--world", str(path)]))
    assert "warning" not in capsys.readouterr().err  # a start on a terrain the training map shows
    from ird_core.worlds import world_file

    labels = world_file.load_world(WORLD).test_labels
    doc["test_world"]["start"] = [int(v) for v in next(iter(zip(*(labels == 3).nonzero())))]
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    spec, scene = demo.mission_spec(demo.parse_args(["--world", str(path)]))
    assert scene == "figure1" and spec.world == str(path.resolve())
    err = capsys.readouterr().err
    assert err.startswith(f"[demo] warning: --world: {path}: test_world.start:") and "is on lava" in err


def test_a_node_that_fails_to_configure_is_reported_with_its_reason_in_files_mode(tmp_path: Path) -> None:
    """The demo's launcher writes the nodes' output to files: the report of a node whose configure
    transition failed still carries the reason it logged (here the world node's refusal of a bad
    world file, given to it directly, past the launchers' own check)."""
    from ird_ros.graph import NODES_BY_NAME
    from ird_ros.launch import GraphLauncher, LaunchError

    bad, _ = _bad_world(tmp_path, "horizon")
    spec = dataclasses.replace(NODES_BY_NAME["world"], ros_args=("-p", f"world_file:={bad}"))
    with GraphLauncher(specs=[spec], nodes=["world"], private_domain=True, output="files",
                       log_dir=tmp_path / "logs") as graph, pytest.raises(LaunchError) as info:
        graph.wait_ready(timeout=300)
    report = str(info.value)
    assert "world (pid" in report and "configure failed:" in report, report
    after = report.split("configure failed:", 1)[1]
    assert f"{bad}: test_world.horizon: must be an integer in [1, 1000]" in after, report
