"""The entry points' command lines, without ROS running: every program's ``--help`` works and
documents each option, ``demo.sh --help`` prints its usage on a machine without a venv (no
bootstrap, no domain lease), ``ird_ros_env`` keeps an exported ROS_DOMAIN_ID, and the banner
every entry point prints names one domain and the line a second shell runs to attach to it."""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
from pathlib import Path
from typing import Callable

import pytest

from ird_core.experiments import posterior_terrain
from ird_ros.apps import analyze_bag, call_inference, demo, experiments, launch_graph, reindex_bag
from ird_ros.graph.domains import domain_banner

ROOT = Path(__file__).resolve().parents[1]

MAINS: dict[str, Callable[[list[str]], int]] = {
    "demo": demo.main, "launch_graph": launch_graph.main, "call_inference": call_inference.main,
    "analyze_bag": analyze_bag.main, "reindex_bag": reindex_bag.main, "experiments": experiments.main,
}


def _options(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in parser._actions if a.option_strings and a.dest != "help"]


@pytest.mark.parametrize("name", sorted(MAINS))
def test_every_entry_point_prints_help(name: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        MAINS[name](["--help"])
    assert info.value.code == 0
    assert "usage:" in capsys.readouterr().out


@pytest.mark.parametrize("parser", [launch_graph.build_parser(), demo.build_parser(),
                                    analyze_bag.build_parser()], ids=["launch_graph", "demo", "analyze_bag"])
def test_every_option_has_help_text(parser: argparse.ArgumentParser) -> None:
    undocumented = [a.option_strings[0] for a in _options(parser) if not a.help or a.help == argparse.SUPPRESS]
    assert undocumented == []


def test_launch_graph_help_documents_the_mission_and_the_attach_line() -> None:
    text = launch_graph.build_parser().format_help()
    for option in ("--mission", "--mission-then-exit", "--viz", "--private-domain", "--record"):
        assert option in text
    assert "/ird/navigate" in text and "analyze_bag.py" in text
    assert "source scripts/lib/ros_env.sh && ird_ros_env" in text


@pytest.mark.parametrize("argv,message", [
    (["--timeout", "-5"], "argument --timeout: expected seconds > 0, got '-5'"),
    (["--timeout", "0"], "argument --timeout: expected seconds > 0, got '0'"),
    (["--run-for", "nan"], "argument --run-for: expected seconds >= 0, got 'nan'"),
    (["--run-for", "-1"], "argument --run-for: expected seconds >= 0, got '-1'"),
    (["--mission-then-exit"], "only with --mission"),
    (["--mission", "0"], "N must be >= 1"),
    (["--mission", "--nodes", "world,inference"], "needs the world and navigator nodes"),
])
def test_launch_graph_refuses_bad_options_before_starting_a_node(argv: list[str], message: str,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """Refused before any node starts (a negative --timeout started the graph to report it "not
    ready after -5 s"; --run-for nan never stopped it)."""
    with pytest.raises(SystemExit) as info:
        launch_graph.main(argv)
    assert info.value.code == 2 and message in capsys.readouterr().err


@pytest.mark.parametrize("argv,message", [
    (["--seed", "-1"], "argument --seed: expected an integer in [0, 4294967295], got '-1'"),
    (["--num-samples", "0"], "argument --num-samples: expected an integer in [1, 4294967295], got '0'"),
    (["--beta", "nan"], "argument --beta: expected a finite number >= 0, got 'nan'"),
    (["--timeout", "-1"], "argument --timeout: expected a finite number > 0, got '-1'"),
    (["--designer-temperature", "0.0001"],
     "argument --designer-temperature: expected 0 or a number in [0.001, 1000], got '0.0001'"),
    (["--risk-level", "inf"], "argument --risk-level: expected a finite number >= 0, got 'inf'"),
])
def test_call_inference_refuses_a_bad_option_before_looking_for_a_graph(
        argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Refused by the parser (status 2), before the client node exists: a negative seed was a
    numpy traceback, a negative timeout a search "within -1 s", NaN ones searched forever."""
    with pytest.raises(SystemExit) as info:
        call_inference.parse_args(argv)
    assert info.value.code == 2 and message in capsys.readouterr().err
    args = call_inference.parse_args(["--designer-temperature", "0", "--seed", "4294967295"])
    assert (args.designer_temperature, args.seed) == (0.0, 4294967295)


@pytest.mark.parametrize("argv,message", [(["--seed", "-3"], "seed must be a non-negative int, got -3"),
                                          (["--beta", "nan"], "beta: expected a finite number >= 0, got nan"),
                                          (["--samples", "0"], "samples: expected an integer >= 1, got 0")])
def test_plot_posterior_terrain_refuses_a_bad_argument_before_sampling(
        tmp_path: Path, argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        posterior_terrain.main([str(tmp_path / "out.png"), *argv])
    assert info.value.code == 2 and message in capsys.readouterr().err
    assert not (tmp_path / "out.png").exists()


def test_plot_posterior_terrain_refuses_an_output_it_cannot_write_before_sampling(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    for output, message in ((tmp_path, f"output: {tmp_path} is a folder, not a file"),
                            (blocker / "p.png", f"output: {blocker} is not a folder")):
        with pytest.raises(SystemExit) as info:  # exits before the sampler: no seconds of MCMC first
            posterior_terrain.main([str(output), "--samples", "4"])
        assert info.value.code == 2 and message in capsys.readouterr().err
    assert blocker.read_text() == "kept"


@pytest.mark.parametrize("argv,message", [
    (["--rate", "0"], "--rate: must be in 0.01..1000 cells per second, got 0.0"),
    (["--rate", "nan"], "--rate: must be in 0.01..1000 cells per second, got nan"),
    (["--designer-beta", "inf"], "--designer-beta: must be a finite number >= 0, got inf"),
])
def test_demo_refuses_a_bad_rate_or_designer_beta_before_the_graph_starts(
        argv: list[str], message: str, capsys: pytest.CaptureFixture[str]) -> None:
    """``--rate 0`` started the graph for the rob node to refuse its ``rate_hz``; the range is the
    node's own declaration."""
    with pytest.raises(SystemExit) as info:
        demo.parse_args(argv)
    assert info.value.code == 2 and message in capsys.readouterr().err
    assert demo.parse_args(["--rate", "0.01"]).rate == 0.01


def test_launch_graph_hypothesis_options_reach_the_world_node_only() -> None:
    parser = launch_graph.build_parser()
    assert launch_graph._node_table(parser.parse_args([])) is None  # the params file's space
    specs = launch_graph._node_table(parser.parse_args(["--hypothesis", "rff", "--rff-features", "40",
                                                        "--novelty-feature"]))
    by_name = {s.name: s for s in specs}
    assert by_name["world"].ros_args[-8:] == ("-p", "hypothesis:=rff", "-p", "rff_features:=40",
                                              "-p", "novelty_feature:=true", "-p", "novelty_value:=feature_scale")
    assert all("hypothesis:=rff" not in s.ros_args for name, s in by_name.items() if name != "world")
    only_novel = {s.name: s for s in launch_graph._node_table(parser.parse_args(["--novelty-feature"]))}["world"]
    assert "hypothesis:=linear" in only_novel.ros_args and "novelty_feature:=true" in only_novel.ros_args


def test_launch_graph_training_worlds_reach_the_world_node_only(capsys: pytest.CaptureFixture[str]) -> None:
    parser = launch_graph.build_parser()
    by_name = {s.name: s for s in launch_graph._node_table(parser.parse_args(["--training-worlds", "3"]))}
    assert by_name["world"].ros_args[-2:] == ("-p", "training_worlds:=3")
    assert all("training_worlds:=3" not in s.ros_args for name, s in by_name.items() if name != "world")
    for bad in ("0", "17"):
        assert launch_graph.main(["--training-worlds", bad]) == 2
        assert "--training-worlds: training_worlds must be an integer in [1, 16]" in capsys.readouterr().err


def test_launch_graph_refuses_a_bad_rff_count(capsys: pytest.CaptureFixture[str]) -> None:
    assert launch_graph.main(["--hypothesis", "rff", "--rff-features", "0"]) == 2
    assert "--rff-features: rff_features" in capsys.readouterr().err
    with pytest.raises(SystemExit) as info:
        launch_graph.main(["--hypothesis", "quadratic"])
    assert info.value.code == 2 and "--hypothesis" in capsys.readouterr().err


def test_launch_graph_mission_takes_an_optional_count() -> None:
    parser = launch_graph.build_parser()
    assert parser.parse_args([]).mission is None
    assert parser.parse_args(["--mission"]).mission == 1
    assert parser.parse_args(["--mission", "3", "--mission-then-exit"]).mission == 3


def test_demo_sh_help_needs_no_venv_and_lists_every_demo_option(tmp_path: Path) -> None:
    """demo.sh alone in a fresh tree: no bootstrap.sh, no .venv, no ros_env.sh to lease a domain."""
    (tmp_path / "scripts").mkdir()
    shutil.copy(ROOT / "scripts" / "demo.sh", tmp_path / "scripts" / "demo.sh")
    env = {"PATH": os.environ.get("PATH", "/usr/bin:/bin"), "HOME": str(tmp_path),
           "IRD_DOMAIN_LOCK_DIR": str(tmp_path / "locks")}
    for flag in ("--help", "-h"):
        run = subprocess.run(["bash", str(tmp_path / "scripts" / "demo.sh"), "--seed", "3", flag],
                             capture_output=True, text=True, env=env, timeout=30)
        assert run.returncode == 0, run.stderr
        assert run.stdout.startswith("usage: bash scripts/demo.sh") and run.stderr == ""
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scripts"]  # nothing set up, nothing leased
    for action in _options(demo.build_parser()):
        assert all(opt in run.stdout for opt in action.option_strings), action.option_strings


def _bash(script: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["bash", "-c", script], capture_output=True, text=True, cwd=ROOT, env=env, timeout=30)


def test_ird_ros_env_keeps_an_exported_domain_id(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k not in ("ROS_DOMAIN_ID", "ROS_LOG_DIR")}
    env["IRD_DOMAIN_LOCK_DIR"] = str(tmp_path / "locks")
    kept = _bash("export ROS_DOMAIN_ID=85; source scripts/lib/ros_env.sh && ird_ros_env && "
                 "echo \"id=$ROS_DOMAIN_ID\" && env | grep '^ROS_DOMAIN_ID='", env)
    assert kept.returncode == 0, kept.stderr
    assert kept.stdout.split() == ["id=85", "ROS_DOMAIN_ID=85"]
    assert not (tmp_path / "locks").exists()  # nothing leased
    # set in the shell but not exported: kept and exported, so the shell's children see it too
    unexported = _bash("ROS_DOMAIN_ID=7; source scripts/lib/ros_env.sh && ird_ros_env && "
                       "env | grep '^ROS_DOMAIN_ID='", env)
    assert unexported.stdout.split() == ["ROS_DOMAIN_ID=7"], unexported.stderr
    refused = _bash("export ROS_DOMAIN_ID=250; source scripts/lib/ros_env.sh && ird_ros_env", env)
    assert refused.returncode == 1 and "0..101" in refused.stderr and "250" in refused.stderr


def test_domain_banner_names_one_domain_and_the_attach_line() -> None:
    lines = domain_banner(85).splitlines()
    assert lines == ["ROS_DOMAIN_ID=85 (this graph)",
                     "attach a second shell: export ROS_DOMAIN_ID=85; source scripts/lib/ros_env.sh && ird_ros_env"]
    assert domain_banner(3, "searched for the graph").startswith("ROS_DOMAIN_ID=3 (searched for the graph)\n")


def test_thin_scripts_print_help() -> None:
    for script in ("launch_graph.py", "call_inference.py", "analyze_bag.py", "demo.py"):
        run = subprocess.run([sys.executable, str(ROOT / "scripts" / script), "--help"], capture_output=True,
                             text=True, cwd=ROOT, timeout=60)
        assert run.returncode == 0 and "usage:" in run.stdout, (script, run.stderr)
