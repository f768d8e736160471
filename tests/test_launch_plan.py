"""ird_ros.launch.plan: the launch plan is decided before any process starts (no ROS, no processes).

Properties: the start order follows the node list and each node's ``after``, with the recorder
last; every command line carries the params file (the given one, else the default) and the
spec's own arguments; the respawn set is the union of the argument and the params file's
``launcher`` section, whose settings also give the delay and the retry limit; the recorder gets
its folder and topics and is never respawned; bad arguments are refused, naming what is wrong.
"""

from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest
import yaml

from ird_ros.graph import DEFAULT_NODES, NODES, NODES_BY_NAME, NodeSpec, names
from ird_ros.launch import (
    LAUNCHER_DEFAULTS,
    RECORDER,
    LaunchError,
    OutputMode,
    default_params_file,
    plan_launch,
)

ROOT = Path(__file__).resolve().parents[1]


def _params(tmp_path: Path, **sections: dict[str, Any]) -> Path:
    """The graph's params file with ``sections`` (``{node: ros__parameters}``) merged in."""
    data = yaml.safe_load(default_params_file().read_text())
    for node, params in sections.items():
        data.setdefault(node, {}).setdefault("ros__parameters", {}).update(params)
    path = tmp_path / "graph.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_default_plan_starts_the_default_nodes_in_table_order_with_the_default_params_file() -> None:
    plan = plan_launch(python="/usr/bin/python3")
    assert plan.names == list(DEFAULT_NODES)
    assert plan.params_file == ROOT / "msgs_config" / "params" / "graph.yaml"
    for node in plan.nodes:
        # managed (lifecycle) nodes: the launcher configures and activates them
        assert node.argv == ("/usr/bin/python3", "-m", node.spec.module, "--ros-args",
                             "--params-file", str(plan.params_file), "-p", "autostart:=false")
        assert not node.respawn and node.wait_ready_topics
    assert plan.managed == set(plan.names)
    assert not plan.has_recorder and plan.record_dir is None and plan.recorded_topics == ()
    assert plan.output is OutputMode.PREFIX and plan.cwd == ROOT and plan.notes == ()
    assert (plan.respawn_delay, plan.respawn_max_retries) == (1.0, LAUNCHER_DEFAULTS["respawn_max_retries"])


def test_start_order_puts_each_node_after_the_launched_nodes_it_needs() -> None:
    plan = plan_launch(nodes=["rob", "perception", "inference", "world"])
    assert plan.names == ["rob", "inference", "world", "perception"]
    # a dependency that is not launched does not hold a node back, and its topics are not awaited
    plan = plan_launch(nodes=["perception", "rob"])
    assert plan.names == ["perception", "rob"]
    assert plan.skipped_ready_topics == {"perception"}
    assert plan.notes == ("perception needs world (not launched): not waiting for "
                          + ", ".join(NODES_BY_NAME["perception"].ready_topics),)
    looped = [NodeSpec("a", "m.a", after=("b",)), NodeSpec("b", "m.b", after=("a",))]
    with pytest.raises(LaunchError, match="wait for each other"):
        plan_launch(specs=looped)


def test_scripts_and_ros_args_of_a_spec_end_up_on_its_command_line(tmp_path: Path) -> None:
    params = _params(tmp_path)
    specs = [replace(s, script="/x/standin.py", ros_args=("-r", f"__node:={s.name}")) for s in NODES]
    plan = plan_launch(specs=specs, nodes=["world"], params=params, python="py")
    assert plan.params_file == params
    assert plan.nodes[0].argv == ("py", "/x/standin.py", "--ros-args", "--params-file", str(params),
                                  "-r", "__node:=world")


def test_respawn_merges_the_argument_with_the_params_file(tmp_path: Path) -> None:
    params = _params(tmp_path, launcher={"respawn": ["world"], "respawn_delay": 0.25, "respawn_max_retries": 2})
    plan = plan_launch(params=params, respawn=["rob"])
    assert plan.respawned == {"world", "rob"}
    assert [n.name for n in plan.nodes if n.respawn] == ["world", "rob"]
    assert (plan.respawn_delay, plan.respawn_max_retries) == (0.25, 2)
    assert {(s.name, s.respawn, s.respawn_delay, s.respawn_max_retries) for s in plan.process_specs()
            if s.respawn} == {("world", True, 0.25, 2), ("rob", True, 0.25, 2)}
    # the arguments win over the file
    plan = plan_launch(params=params, respawn_delay=0.0, respawn_max_retries=-1)
    assert (plan.respawn_delay, plan.respawn_max_retries) == (0.0, -1)
    with pytest.raises(LaunchError, match="respawn names"):
        plan_launch(params=params, nodes=["rob"])


def test_recorder_comes_last_with_its_folder_and_topics_and_is_never_respawned(tmp_path: Path) -> None:
    bag = tmp_path / "bag"
    plan = plan_launch(nodes=["world", "rob"], record_dir=bag, record_topics=[names.TOPIC_PROXY, names.TOPIC_ODOM],
                       respawn=["rob", RECORDER])
    recorder = plan.nodes[-1]
    assert plan.names == ["world", "rob", RECORDER] and plan.has_recorder and plan.record_dir == bag
    assert recorder.argv[:3] == (sys.executable, "-m", "ird_ros.nodes.recorder")
    assert recorder.argv[-4:] == ("-p", f"output_dir:={bag}", "-p", f"topics:=[{names.TOPIC_PROXY},{names.TOPIC_ODOM}]")
    assert not recorder.respawn and plan.respawned == {"rob"}
    assert plan.notes == ("the recorder is never respawned (its bag folder exists after the first start)",)
    assert plan.recorded_topics == tuple(sorted([names.TOPIC_PROXY, names.TOPIC_ODOM]))


def test_recorded_topics_default_to_the_params_file(tmp_path: Path) -> None:
    params = _params(tmp_path, recorder={"topics": [names.TOPIC_TERRAIN, names.TOPIC_PLAN]})
    plan = plan_launch(nodes=["world"], params=params, record_dir=tmp_path / "bag")
    assert plan.record_topics == (names.TOPIC_TERRAIN, names.TOPIC_PLAN)
    assert plan.nodes[-1].argv[-2:] == ("-p", f"topics:=[{names.TOPIC_TERRAIN},{names.TOPIC_PLAN}]")
    assert plan.recorded_topics == (names.TOPIC_TERRAIN,)  # /plan: the planner is not launched
    # no topics anywhere: everything the launched nodes publish, minus the excluded topics
    everything = _params(tmp_path, recorder={"topics": [""], "exclude_topics": [names.TOPIC_PROXY]})
    plan = plan_launch(nodes=["world"], params=everything, record_dir=tmp_path / "bag2")
    assert "topics:=" not in " ".join(plan.nodes[-1].argv)
    assert plan.recorded_topics == tuple(sorted(set(NODES_BY_NAME["world"].publishes) - {names.TOPIC_PROXY}))


def test_environment_sets_domain_logs_transport_and_this_checkout(tmp_path: Path) -> None:
    plan = plan_launch(env={"PATH": "/bin", "PYTHONPATH": "/elsewhere", "ROS_DOMAIN_ID": "7"})
    assert plan.domain.fixed_id(plan.base_env) == 7
    env = plan.environment(12, tmp_path)
    assert env["ROS_DOMAIN_ID"] == "12" and env["ROS_LOG_DIR"] == str(tmp_path)
    assert env["PYTHONUNBUFFERED"] == "1" and env["PATH"] == "/bin"
    assert env["PYTHONPATH"].split(":") == [str(ROOT), "/elsewhere"]
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    assert plan_launch(domain_id=3).domain.fixed_id({"ROS_DOMAIN_ID": "7"}) == 3
    with pytest.raises(LaunchError, match="ROS_DOMAIN_ID"):
        plan_launch(env={"ROS_DOMAIN_ID": "200"}).domain.fixed_id({"ROS_DOMAIN_ID": "200"})


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"output": "loud"}, ValueError, "output must be prefix, quiet or files"),
        ({"private_domain": True, "domain_id": 3}, ValueError, "either domain_id or private_domain"),
        ({"domain_id": 102}, ValueError, "domain_id"),
        ({"respawn_delay": -1.0}, ValueError, "respawn_delay"),
        ({"respawn_max_retries": -2}, ValueError, "respawn_max_retries"),
        ({"params": "/no/such/graph.yaml"}, LaunchError, "params file"),
        ({"nodes": ["world", "nope"]}, LaunchError, "unknown node"),
        ({"nodes": ["world", "world"]}, LaunchError, "duplicates"),
        ({"env": {"IRD_DDS_NETWORK": "maybe"}}, ValueError, "IRD_DDS_NETWORK"),
    ],
)
def test_bad_arguments_are_refused_naming_what_is_wrong(kwargs: dict[str, Any], error: type, match: str) -> None:
    with pytest.raises(error, match=match):
        plan_launch(**kwargs)


def test_an_existing_record_dir_is_refused(tmp_path: Path) -> None:
    with pytest.raises(LaunchError, match="already exists"):
        plan_launch(record_dir=tmp_path)


def test_a_record_or_log_dir_under_a_file_is_refused_before_any_node_starts(tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    with pytest.raises(LaunchError, match=f"^record dir {blocker / 'bag'}: {blocker} is not a folder$"):
        plan_launch(record_dir=blocker / "bag")
    for log_dir in (blocker, blocker / "logs"):
        with pytest.raises(LaunchError, match=f"^log dir {log_dir}: {blocker} is not a folder$"):
            plan_launch(log_dir=log_dir)
    assert plan_launch(record_dir=tmp_path / "new" / "bag", log_dir=tmp_path / "logs").log_dir == tmp_path / "logs"
    assert blocker.read_text() == "kept" and not (tmp_path / "new").exists()  # planning makes no folder
