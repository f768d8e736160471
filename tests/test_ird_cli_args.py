"""The ``ird`` command without a graph: ``ird --help`` and every ``ird VERB --help`` work; bad input
is one line on stderr naming it, exit 2, no traceback; the graph view hides what ``ros2`` hides
and knows when the records are complete; messages print as YAML with arrays cut; the navigation
lines say what the result says. Against a running graph: tests/ros/test_ird_cli.py (a base name of
its own: pytest imports test modules by their base name)."""

from __future__ import annotations

import math
import types
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from ird_ros.cli import discovery, graph, navigate
from ird_ros.cli.main import build_parser, main
from ird_ros.graph import NODES_BY_NAME, names

ROOT = Path(__file__).resolve().parents[1]
VERBS = ("graph", "echo", "navigate", "infer")


def _one_error_line(capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    err = capsys.readouterr().err
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert "Traceback" not in err and all(n in lines[0] for n in needles), err
    return lines[0]


def test_ird_help_lists_every_verb(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    out = capsys.readouterr().out
    assert info.value.code == 0 and out.startswith("usage: ird ")
    for verb in VERBS:
        assert f"    {verb} " in out, verb
    assert "--domain-id" in out and "ROS_DOMAIN_ID" in out


@pytest.mark.parametrize("verb", VERBS)
def test_every_verb_prints_its_help(verb: str, capsys: pytest.CaptureFixture[str]) -> None:
    if verb == "infer":  # ird-infer's own parser, under the ird command's name
        assert main([verb, "--help"]) == 0
    else:
        with pytest.raises(SystemExit) as info:
            main([verb, "--help"])
        assert info.value.code == 0
    out = capsys.readouterr().out
    assert f"usage: ird {verb}" in out and "--domain-id" in out


def test_every_option_has_help_text() -> None:
    verbs = next(a for a in build_parser()._actions if a.dest == "verb")
    for name, parser in verbs.choices.items():
        if name == "infer":
            continue
        undocumented = [a.option_strings for a in parser._actions if a.option_strings and not a.help]
        assert undocumented == [], name


@pytest.mark.parametrize("argv,needles", [
    (["fly"], ("invalid choice: 'fly'",)),
    ([], ("VERB",)),
    (["navigate", "--mode", "sideways"], ("--mode", "sideways")),
    (["navigate", "--beta", "high"], ("--beta", "high")),
    (["echo"], ("topic",)),
    (["echo", "/world/proxy", "-n", "0"], ("-n", "at least 1")),
    (["echo", "/world/proxy", "--once", "-n", "2"], ("not allowed with",)),
    (["echo", "/world/proxy", "--truncate-length", "-3"], ("--truncate-length",)),
    (["graph", "--domain-id", "250"], ("--domain-id", "250", "0..101")),
    (["graph", "edges"], ("edges",)),
    (["graph", "--timeout", "0"], ("--timeout",)),
    (["graph", "--spin-time", "-1"], ("--spin-time",)),
    (["infer", "--domain-id", "x"], ("--domain-id", "'x'")),
])
def test_bad_arguments_are_one_line_naming_them_exit_2(argv: list[str], needles: tuple[str, ...],
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    line = _one_error_line(capsys, *needles)
    assert line.startswith("ird")


@pytest.mark.parametrize("argv,needles", [
    (["--beta", "nan"], ("bad goal: beta", "nan")),
    (["--beta", "2000"], ("bad goal: beta", "[0, 1000]")),
    (["--num-samples", "-1"], ("bad goal: num_samples", "[0, 2147483647]", "-1")),
    (["--seed", "-1"], ("bad goal: seed", "-1")),
    (["--risk-measure", "cvar", "--risk-level", "2"], ("bad goal: risk_level", "(0, 1]")),
    (["--queries", "-2"], ("bad goal: queries", "-2")),
    (["--label", "x" * 300], ("bad goal: label", "300 characters exceed 256")),
    (["--mode", "trajectory", "--risk-measure", "mean_sd", "--risk-level", "1"], ("bad goal: risk_measure",)),
])
def test_a_goal_the_navigator_would_refuse_is_refused_before_looking_for_a_graph(
        argv: list[str], needles: tuple[str, ...], capsys: pytest.CaptureFixture[str]) -> None:
    """Checked by the navigator's own check_goal: exit 2 at once, where a search for a graph came first."""
    assert main(["navigate", *argv, "--timeout", "30"]) == 2
    line = _one_error_line(capsys, "ird navigate: ", *needles)
    assert "navigator" not in line


def test_result_timeout_must_be_seconds(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["navigate", "--result-timeout", "0"])
    assert info.value.code == 2
    _one_error_line(capsys, "--result-timeout", "expected seconds > 0")

def test_a_bad_ros_domain_id_in_the_environment_is_named(monkeypatch: pytest.MonkeyPatch,
                                                         capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.setenv("ROS_DOMAIN_ID", "250")
    assert main(["graph"]) == 2
    _one_error_line(capsys, "ird graph:", "ROS_DOMAIN_ID", "250")


def test_an_invalid_topic_name_is_named(capsys: pytest.CaptureFixture[str]) -> None:
    pytest.importorskip("rclpy")
    assert main(["echo", "/world/pro xy", "--domain-id", "3"]) == 2
    _one_error_line(capsys, "ird echo:", "'/world/pro xy'", "not a valid topic name")


def test_the_console_script_is_installed() -> None:
    script = Path(sys.executable).parent / "ird"
    assert script.is_file(), "re-run: bash scripts/bootstrap.sh (or pip install -e . --no-deps --no-build-isolation)"
    run = subprocess.run([str(script), "--help"], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0 and run.stdout.startswith("usage: ird "), run.stderr
    assert 'ird = "ird_ros.cli.main:main"' in (ROOT / "pyproject.toml").read_text(encoding="utf-8")


# --- the graph view -------------------------------------------------------------------------------

def _world_view(*, with_proxy: bool = True) -> discovery.GraphView:
    spec = NODES_BY_NAME[names.NODE_WORLD]
    topics = [(t, (names.TOPIC_TYPES[t],)) for t in spec.publishes if with_proxy or t != names.TOPIC_PROXY]
    topics += [("/rosout", ("rcl_interfaces/msg/Log",)), ("/ird/navigate/_action/status", ("x/msg/S",))]
    services = [(names.SRV_GENERATE, ("ird_msgs/srv/GenerateWorld",)),
                ("/world/get_parameters", ("rcl_interfaces/srv/GetParameters",)),
                ("/_ird_graph_1/get_parameters", ("rcl_interfaces/srv/GetParameters",)),
                ("/odd/get_parameters", ("my/srv/Mine",))]
    return discovery.GraphView(("/_ird_graph_1", "/world"), tuple(sorted(topics)), tuple(sorted(services)), ())


def test_the_view_hides_hidden_names_and_ros_infrastructure() -> None:
    view = _world_view()
    shown = view.shown()
    assert shown.nodes == ("/world",)
    assert {n for n, _ in shown.topics} == set(NODES_BY_NAME[names.NODE_WORLD].publishes)
    # a node's standard services go; a service of that name under no node stays
    assert [n for n, _ in shown.services] == ["/odd/get_parameters", names.SRV_GENERATE]
    assert view.shown(everything=True) == view


def test_the_records_say_when_a_node_is_not_fully_seen() -> None:
    assert discovery.missing_from_records(_world_view()) == []
    assert discovery.missing_from_records(_world_view(with_proxy=False)) == [f"/world: topic {names.TOPIC_PROXY}"]
    navigator = discovery.GraphView(("/navigator",), (), (), ())  # what it reads, then its action
    reads = NODES_BY_NAME[names.NODE_NAVIGATOR].subscribes
    assert discovery.missing_from_records(navigator) == [*(f"/navigator: topic {t}" for t in reads),
                                                         f"/navigator: action {names.ACTION_NAVIGATE}"]


def test_a_topic_a_node_reads_waits_for_its_publisher_in_the_default_graph() -> None:
    """Perception seen, the world not yet: what perception reads from the world has no publisher."""
    spec = NODES_BY_NAME[names.NODE_PERCEPTION]
    topics = tuple((t, (names.TOPIC_TYPES[t],)) for t in (*spec.publishes, *spec.subscribes))
    alone = discovery.GraphView(("/perception",), topics, (), (), frozenset(spec.publishes))
    assert discovery.missing_from_records(alone) == [f"/perception reads {t}: no publisher yet"
                                                     for t in spec.subscribes]
    with_world = discovery.GraphView(("/perception",), topics, (), (), frozenset(t for t, _ in topics))
    assert discovery.missing_from_records(with_world) == []


def _settled(monkeypatch: pytest.MonkeyPatch, view: discovery.GraphView, quiet_for: float) -> tuple[bool, list[str]]:
    """Whether ``settle``'s rule calls ``view`` complete after ``quiet_for`` s without change, and
    what it says is missing."""
    monkeypatch.setattr(discovery, "snapshot", lambda _node: view)
    node = types.SimpleNamespace(get_publishers_info_by_topic=lambda _t: [],
                                 get_subscriptions_info_by_topic=lambda _t: [])
    state = discovery._Settling("/_ird_echo_1", 0.5, ())
    state.done(node)  # the first look: the view changed now
    state.changed_at -= quiet_for
    return state.done(node), state.missing(node)


def test_a_launched_graph_is_not_complete_while_only_the_launchers_own_nodes_are_seen(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """CI: `ird echo` found the launcher's ping node first and, 0.5 s later, called the graph empty."""
    for helper in names.LAUNCHER_NODES:
        view = discovery.GraphView(("/_ird_echo_1", f"/{helper}"), (), (), ())
        done, missing = _settled(monkeypatch, view, quiet_for=60.0)
        assert not done and missing == ["the launched nodes (only the launcher's own nodes are in the graph)"]
    with_world = _world_view()
    with_world = replace(with_world, nodes=(*with_world.nodes, "/launcher_ping"))
    assert _settled(monkeypatch, with_world, quiet_for=0.6) == (True, [])


def test_a_view_without_nodes_of_the_records_needs_a_longer_quiet(monkeypatch: pytest.MonkeyPatch) -> None:
    foreign = discovery.GraphView(("/_ird_echo_1", "/turtlesim"), (("/turtle1/pose", ("turtlesim/msg/Pose",)),),
                                  (), ())
    assert _settled(monkeypatch, foreign, quiet_for=1.0) == (False, [])
    assert _settled(monkeypatch, foreign, quiet_for=discovery.FOREIGN_QUIET + 0.1) == (True, [])
    assert _settled(monkeypatch, _world_view(), quiet_for=0.6) == (True, [])  # a node of the records: 0.5 s
    alone = discovery.GraphView(("/_ird_echo_1",), (), (), ())
    assert _settled(monkeypatch, alone, quiet_for=60.0) == (False, [])


def test_expected_names_are_nodes_topics_services_or_actions() -> None:
    view = _world_view()
    assert discovery.missing_names(view, ["world", "/world/proxy", names.SRV_GENERATE]) == []
    assert discovery.missing_names(view, ["navigator", "/world/proxy", "/ird/navigate"]) == ["navigator",
                                                                                            "/ird/navigate"]


def test_graph_renders_sections_and_single_sections() -> None:
    view = _world_view().shown()
    lines = graph.render(view)
    assert lines[0] == "nodes (1):" and lines[1] == "  /world"
    assert f"  {names.TOPIC_PROXY} [ird_msgs/msg/ProxyReward]" in lines and "actions (0):" in lines
    assert graph.render(view, "nodes") == ["/world"]
    assert graph.render(view, "services") == ["/odd/get_parameters", names.SRV_GENERATE]
    assert graph.render(view, "services", show_types=True)[1] == f"{names.SRV_GENERATE} [ird_msgs/srv/GenerateWorld]"
    # managed nodes show their lifecycle state
    assert graph.render(view, "nodes", states={"/world": "active"}) == ["/world  active"]
    assert graph.render(view, states={"/world": "inactive"})[1] == "  /world  inactive"


def test_lifecycle_services_are_infrastructure() -> None:
    nodes = {"/world"}
    assert discovery.is_infrastructure("/world/change_state", nodes)
    assert discovery.is_infrastructure("/world/get_state", nodes)
    assert discovery.is_infrastructure("/world/transition_event", nodes)
    assert not discovery.is_infrastructure(names.SRV_GENERATE, nodes)


# --- messages and navigation lines ----------------------------------------------------------------

def test_a_message_prints_as_yaml_with_long_arrays_cut() -> None:
    pytest.importorskip("nav_msgs")
    import yaml
    from nav_msgs.msg import OccupancyGrid

    from ird_ros.cli import messages

    grid = OccupancyGrid()
    grid.header.frame_id, grid.info.width = "map", 300
    grid.data = [i % 100 for i in range(300)]
    text = messages.to_yaml(grid, truncate=5)
    loaded = yaml.safe_load(text)
    assert loaded["header"] == {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "map"}
    assert loaded["info"]["width"] == 300 and loaded["data"] == [0, 1, 2, 3, 4, "..."]
    assert yaml.safe_load(messages.to_yaml(grid, truncate=0))["data"] == list(grid.data)
    assert yaml.safe_load(messages.to_yaml(grid, no_arr=True))["data"] == "<sequence of 300 values>"
    assert messages.to_yaml(grid.info.width) == "300"


def test_fields_are_checked_against_the_type() -> None:
    pytest.importorskip("nav_msgs")
    from nav_msgs.msg import Path as PathMsg

    from ird_ros.cli import messages

    messages.check_field(PathMsg, "header.stamp.sec", "nav_msgs/msg/Path")
    with pytest.raises(ValueError, match=r"nav_msgs/msg/Path.header has no field 'nope' \(its fields: stamp"):
        messages.check_field(PathMsg, "header.nope", "nav_msgs/msg/Path")
    with pytest.raises(ValueError, match="header.frame_id is not a message"):
        messages.check_field(PathMsg, "header.frame_id.x", "nav_msgs/msg/Path")
    with pytest.raises(ValueError, match="not installed"):
        messages.message_class("no_such_msgs/msg/Nothing")


def test_navigation_lines_say_what_the_result_says() -> None:
    from ird_ros.client import NavigationFeedback, NavigationResult, NavigationStatus

    fb = NavigationFeedback("driving", (2, 3), 0.25, "maxent_z, 40 samples, R-hat 1.01")
    assert navigate.feedback_line(fb) == ("feedback: driving, cell (2,3), progress 0.25, "
                                          "posterior maxent_z, 40 samples, R-hat 1.01")
    assert navigate.feedback_line(NavigationFeedback("inferring", None, 0.0, "")) == \
        "feedback: inferring, progress 0.00"
    cells = np.array([[0, 0], [0, 1]], dtype=np.int64)
    done = NavigationResult(NavigationStatus.SUCCEEDED, "goal succeeded", "", cells, False, True, 8.2, 1.5)
    assert navigate.result_lines(done) == ["result: SUCCEEDED: lava False, target True, true return 8.20, 2 cells",
                                           "cells: (0,0) (0,1)"]
    stopped = NavigationResult(NavigationStatus.CANCELED, "canceled", "", cells[:1], None, None, None, math.nan)
    assert navigate.result_lines(stopped)[0] == "result: CANCELED (canceled): lava -, target -, true return -, 1 cells"
    rejected = NavigationResult.rejected("beta: must be in [0, 1000], got 5000", "beta")
    assert navigate.result_lines(rejected) == ["result: REJECTED (beta: must be in [0, 1000], got 5000)"]
