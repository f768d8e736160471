"""--viz-port (issue 43): the launcher's and the demo's option for the live view's port, and the
launcher's --help printing its first paragraph once. No ROS: the parsers and the launch plan."""

from __future__ import annotations

import pytest

from ird_ros.apps import demo, launch_graph
from ird_ros.graph import NODES
from ird_ros.launch.plan import with_viz_port


def test_launcher_help_prints_its_first_paragraph_once() -> None:
    text = launch_graph.build_parser().format_help()
    first = launch_graph.__doc__.split("\n\n")[0].strip()
    assert text.count(first) == 1, text[:600]
    assert "--viz-port PORT" in text


def test_with_viz_port_sets_the_viz_nodes_port_only() -> None:
    specs = {s.name: s for s in with_viz_port(None, 0)}
    assert specs["viz"].ros_args[-2:] == ("-p", "port:=0")
    assert all(specs[s.name].ros_args == s.ros_args for s in NODES if s.name != "viz")
    with pytest.raises(ValueError, match=r"^--viz-port: must be in 0\.\.65535"):
        with_viz_port(None, 70000)


def test_launcher_viz_port_needs_the_viz_node_and_a_port(capsys: pytest.CaptureFixture[str]) -> None:
    parser = launch_graph.build_parser()
    args = parser.parse_args(["--viz", "--viz-port", "0"])
    launch_graph._check_mission_args(parser, args)
    assert "viz" in args.nodes and args.viz_port == 0
    for argv, text in ((["--viz-port", "9000"], "--viz-port: only with --viz"),
                       (["--viz", "--viz-port", "-1"], "--viz-port: must be in 0..65535")):
        bad = parser.parse_args(argv)
        with pytest.raises(SystemExit):
            launch_graph._check_mission_args(parser, bad)
        assert text in capsys.readouterr().err


def test_demo_passes_viz_port_through(capsys: pytest.CaptureFixture[str]) -> None:
    assert demo.parse_args(["--viz", "--viz-port", "0"]).viz_port == 0
    assert demo.parse_args([]).viz_port is None
    with pytest.raises(SystemExit):
        demo.parse_args(["--viz-port", "9000"])
    assert "--viz-port: needs --viz" in capsys.readouterr().err
