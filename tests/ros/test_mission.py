"""``launch_graph.py --mission``: a launched and recorded graph runs navigation goals by itself,
over real DDS in a private domain, and ``analyze_bag.py`` reads the recorded bag as missions; the
launcher prints its one domain with the attach line; a client with no graph in its domain says
which domain it searched, in one paragraph, without a traceback.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path
from typing import Any, Iterator

import pytest
import yaml

from ird_ros.apps import analyze_bag, call_inference
from ird_ros.bags.analysis import analyze
from ird_ros.graph.domains import DomainLease, lease_domain
from ird_ros.testing import NodeProcess

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = ROOT / "scripts" / "launch_graph.py"
SIZE, HORIZON, OBS_DIM = 6, 8, 6


def _small_params(path: Path) -> Path:
    """The graph's params with a small world and a fast Rob (as the end-to-end tests use)."""
    params = yaml.safe_load((ROOT / "msgs_config" / "params" / "graph.yaml").read_text())
    params["world"]["ros__parameters"].update(condition="latent_raw", seed=4, height=SIZE, width=SIZE,
                                              horizon=HORIZON, obs_dim=OBS_DIM)
    params["rob"]["ros__parameters"]["rate_hz"] = 50.0
    path.write_text(yaml.safe_dump(params))
    return path


@pytest.fixture(scope="module")
def mission_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, Any]]:
    """``launch_graph.py --private-domain --record DIR --mission 1 --mission-then-exit``, to its end."""
    tmp = tmp_path_factory.mktemp("mission")
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    argv = [sys.executable, str(SCRIPT), "--private-domain", "--output", "quiet", "--params",
            str(_small_params(tmp / "graph.yaml")), "--record", str(tmp / "bag"), "--mission", "1",
            "--mission-then-exit"]
    proc = NodeProcess(argv, env, ROOT, "launch_graph_mission")
    try:
        proc.wait_for_output("[launcher] stopped ", timeout=600)
        code = proc.proc.wait(timeout=30)
    finally:
        proc.stop()
    yield {"code": code, "out": proc.output(last=2000), "bag": tmp / "bag", "tmp": tmp}


def test_mission_runs_the_goals_and_exits(mission_run: dict[str, Any]) -> None:
    out = mission_run["out"]
    assert mission_run["code"] == 0, out
    lines = out.splitlines()
    for label in ("literal", "ird"):
        line = next((x for x in lines if x.startswith(f"[mission] seed 0 {label}: ")), None)
        assert line is not None and "SUCCEEDED: " in line and "true return" in line, out
    assert "[mission] 1 seed(s): every goal ran to its end: " in out


def test_the_launcher_prints_one_domain_and_the_attach_line(mission_run: dict[str, Any]) -> None:
    lines = mission_run["out"].splitlines()
    ids = {x.split("ROS_DOMAIN_ID=")[1].split()[0].rstrip(";") for x in lines if "ROS_DOMAIN_ID=" in x}
    assert len(ids) == 1, ids
    (domain,) = ids
    assert any(x.startswith(f"[launcher] ROS_DOMAIN_ID={domain} (this graph)") for x in lines)
    attach = [x for x in lines if "attach a second shell" in x]
    assert attach == [f"[launcher] attach a second shell: export ROS_DOMAIN_ID={domain}; "
                      "source scripts/lib/ros_env.sh && ird_ros_env"]


def test_the_recorded_bag_holds_the_missions(mission_run: dict[str, Any], capsys: pytest.CaptureFixture[str]) -> None:
    report = analyze(mission_run["bag"], mission_run["tmp"] / "plots")
    missions = report["missions"]
    assert len(missions) >= 1, report["topics"]
    # Rob's whole path: every step of the plan reported, odometry along it
    assert any(m["done"] and m["steps"] == m["horizon"] >= 1 and m["executed_length_m"] is not None
               for m in missions), missions
    assert {m["label"] for m in missions} <= {"literal", "ird"}
    assert any(Path(p).name.startswith("trajectories_") for p in report["plots"])
    assert analyze_bag.main([str(mission_run["bag"]), "--no-plots"]) == 0
    text = capsys.readouterr().out
    assert "Missions:" in text and "no mission in this bag" not in text


@pytest.fixture
def empty_domain() -> Iterator[DomainLease]:
    with lease_domain() as lease:
        yield lease


def test_call_inference_without_a_graph_says_where_it_looked(empty_domain: DomainLease,
                                                             monkeypatch: pytest.MonkeyPatch,
                                                             capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("ROS_DOMAIN_ID", str(empty_domain.domain_id))
    assert call_inference.main(["--from-world", "--timeout", "1"]) == 1
    captured = capsys.readouterr()
    n = empty_domain.domain_id
    assert captured.out.startswith(f"ROS_DOMAIN_ID={n} (searched for the graph)\n")
    assert f"export ROS_DOMAIN_ID={n}; source scripts/lib/ros_env.sh && ird_ros_env" in captured.out
    err = captured.err.strip()
    assert "\n" not in err and "Traceback" not in err  # one paragraph
    assert f"ROS_DOMAIN_ID={n}" in err and "export ROS_DOMAIN_ID=" in err and "ird_ros_env" in err
