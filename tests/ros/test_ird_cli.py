"""The ``ird`` command (its installed console script) against a real graph over DDS: the default graph
launched in a private domain, attached with ``--domain-id`` as a second shell would (the test's own
ROS_DOMAIN_ID is another domain).

- ``ird graph`` lists every node, topic, service and the action with their types, hides what ``ros2``
  hides (action internals, parameter services, its own node) unless ``--all``;
- ``ird echo`` prints the message an ``IrdClient`` receives, one field with ``--field``, exactly N with
  ``-n N``; an unknown topic or field is one line naming it, exit 2; Ctrl-C ends it with 130;
- ``ird navigate`` prints feedback in every stage and the result the ground truth gives for the cells
  driven; Ctrl-C cancels the goal (Rob reports a stop) and exits 130; a bad field is exit 2;
- ``ird infer`` prints the posterior of ird-infer's request;
- an empty domain: exit 1 naming it. No output ever holds a traceback.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
from pathlib import Path
from typing import Any, Iterator

import pytest
import yaml

from ird_core.worlds import evaluation, lavaland
from ird_ros.graph import DEFAULT_NODES, NODES_BY_NAME, names
from ird_ros.graph.domains import lease_domain
from ird_ros.testing import NodeProcess

ROOT = Path(__file__).resolve().parents[2]
IRD = Path(sys.executable).parent / "ird"
SIZE, HORIZON, OBS_DIM, SEED = 6, 8, 6, 4
CELL = re.compile(r"\((\d+),(\d+)\)")


@pytest.fixture(scope="module")
def graph(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Any]:
    from ird_ros.launch import GraphLauncher

    assert IRD.is_file(), "the ird console script is missing: bash scripts/bootstrap.sh"
    tmp = tmp_path_factory.mktemp("ird_cli")
    params = yaml.safe_load((ROOT / "msgs_config/params/graph.yaml").read_text())
    params["world"]["ros__parameters"].update(condition="latent_raw", seed=SEED, height=SIZE, width=SIZE,
                                              horizon=HORIZON, obs_dim=OBS_DIM)
    params["rob"]["ros__parameters"]["rate_hz"] = 2.0  # 8 moves in 4 s: time to press Ctrl-C mid-drive
    params_file = tmp / "graph.yaml"
    params_file.write_text(yaml.safe_dump(params))
    with GraphLauncher(params=params_file, private_domain=True, output="quiet", log_dir=tmp / "logs") as launched:
        launched.wait_ready(timeout=120)
        yield launched


@pytest.fixture(scope="module")
def ird(graph: Any) -> Iterator[Any]:
    from ird_ros.client import IrdClient

    with IrdClient(graph.domain_id, node_name="ird_cli_test") as client:
        client.watch_rob(timeout=60)
        yield client


def _run(graph: Any, *argv: str, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """``ird VERB --domain-id <the graph's> ARGS``, to its end; never a traceback."""
    verb, *rest = argv
    done = subprocess.run([str(IRD), verb, "--domain-id", str(graph.domain_id), *rest], capture_output=True,
                          text=True, cwd=ROOT, timeout=timeout)
    assert "Traceback" not in done.stdout + done.stderr, done.stdout + done.stderr
    assert f"ROS_DOMAIN_ID={graph.domain_id}" in done.stdout + done.stderr  # the banner: the domain it joined
    return done


def _start(graph: Any, *argv: str) -> NodeProcess:
    verb, *rest = argv
    argv_ = [str(IRD), verb, "--domain-id", str(graph.domain_id), *rest]
    return NodeProcess(argv_, dict(os.environ), ROOT, f"ird_{verb}")


def _sections(out: str) -> dict[str, list[str]]:
    sections: dict[str, list[str]] = {}
    current = ""
    for line in out.splitlines():
        if not line.startswith("  "):
            current = line.split(" (")[0]
            sections[current] = []
        else:
            sections[current].append(line.strip())
    return sections


# --- ird graph -----------------------------------------------------------------------------------

#: DDS never says it has shown every process: what a test must see, it names (``--wait-for``);
#: the rest (each node's topics, services and action) follows from the graph's records.
EVERY_NODE = ("--wait-for", ",".join(DEFAULT_NODES))


def test_graph_lists_every_node_topic_service_and_the_action(graph: Any) -> None:
    done = _run(graph, "graph", *EVERY_NODE)
    assert done.returncode == 0, done.stderr
    sections = _sections(done.stdout)
    assert set(sections) == {"nodes", "topics", "services", "actions"}, done.stdout
    # each managed node with its lifecycle state (the launcher activated them all)
    assert {(f"/{n}", "active") for n in DEFAULT_NODES} <= {tuple(line.split()) for line in sections["nodes"]}
    assert not [n for n in sections["nodes"] if "/_" in n]  # no hidden node: not the CLI's own
    published = {t for n in DEFAULT_NODES for t in NODES_BY_NAME[n].publishes}
    for topic in published:
        assert f"{topic} [{names.TOPIC_TYPES[topic]}]" in sections["topics"], topic
    for service, srv_type in names.SERVICE_TYPES.items():
        assert f"{service} [{srv_type}]" in sections["services"], service
    assert sections["actions"] == [f"{names.ACTION_NAVIGATE} [{names.ACTION_TYPES[names.ACTION_NAVIGATE]}]"]
    for hidden in ("/_action/", "describe_parameters", "/rosout", "/parameter_events"):
        assert hidden not in done.stdout, hidden


def test_graph_sections_are_lists_and_all_shows_what_is_hidden(graph: Any) -> None:
    topics = _run(graph, "graph", "topics", *EVERY_NODE)
    assert topics.returncode == 0, topics.stderr
    subscribed = {t for n in DEFAULT_NODES for t in NODES_BY_NAME[n].subscribes}
    published = {t for n in DEFAULT_NODES for t in NODES_BY_NAME[n].publishes}
    assert set(topics.stdout.split()) == published | subscribed
    services = _run(graph, "graph", "services", "--all", *EVERY_NODE)
    listed = services.stdout.split()
    assert "/world/describe_parameters" in listed and f"{names.ACTION_NAVIGATE}/_action/send_goal" in listed
    assert set(names.SERVICE_TYPES) <= set(listed)


def test_graph_wait_for_names_what_did_not_come(graph: Any) -> None:
    done = _run(graph, "graph", "--wait-for", f"{names.NODE_DESIGNER},/no/such/name", "--timeout", "3")
    assert done.returncode == 1 and done.stdout == ""
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith(f"ird graph: --wait-for: not in the graph of ROS_DOMAIN_ID={graph.domain_id} after 3 s: ")
    assert last.endswith(f" after 3 s: {names.NODE_DESIGNER}, /no/such/name")  # the designer is off by default


# --- ird echo ------------------------------------------------------------------------------------

def test_echo_once_prints_the_message_the_graph_holds(graph: Any, ird: Any) -> None:
    proxy = ird.proxy(timeout=60)
    done = _run(graph, "echo", names.TOPIC_PROXY, "--once")
    assert done.returncode == 0, done.stderr
    text, end = done.stdout.rsplit("---\n", 1)
    assert end == "" and "---" not in text  # one message
    printed = yaml.safe_load(text)
    assert printed["condition"] == proxy.condition and printed["seed"] == proxy.seed
    assert printed["feature_names"] == list(proxy.feature_names)
    assert printed["weights"] == pytest.approx(list(proxy.weights))
    assert (printed["test_start_row"], printed["test_start_col"]) == (proxy.test_start_row, proxy.test_start_col)


def test_echo_n_prints_exactly_n_messages_of_one_field(graph: Any, ird: Any) -> None:
    """The first is the latched proxy; the second comes from a world this test generates after it."""
    current = ird.proxy(timeout=60).seed
    proc = _start(graph, "echo", "world/proxy", "-n", "2", "--field", "seed")
    try:
        proc.wait_for_output("---", timeout=120)
        assert ird.generate_world("", current + 3).ok
        ird.world(seed=current + 3, timeout=60)  # this client has it too (the next tests read it)
        assert proc.proc.wait(timeout=120) == 0, proc.describe()
    finally:
        proc.stop()
    # stdout and stderr come merged: the banner, "reading ...", maybe a Fast DDS log line; the rest is
    # each message's field and its separator
    out = [line for line in proc.output().splitlines() if line == "---" or line.isdigit()]
    assert out == [str(current), "---", str(current + 3), "---"], proc.describe()


def test_echo_finds_the_type_of_a_topic_outside_the_records(graph: Any) -> None:
    """/rosout (every node's log, transient local): type and QoS from the graph, not from the records."""
    done = _run(graph, "echo", "/rosout", "--once", "--field", "name")
    assert done.returncode == 0, done.stderr
    assert "ird echo: reading /rosout [rcl_interfaces/msg/Log]" in done.stderr.splitlines()
    (name, end) = done.stdout.splitlines()
    assert end == "---" and name.split(".")[0] in {*DEFAULT_NODES, "launcher", "launcher_ping"}, done.stdout


def test_echo_refuses_an_unknown_topic_or_field_in_one_line(graph: Any) -> None:
    unknown = _run(graph, "echo", "/no/such/topic", "--once")
    assert unknown.returncode == 2 and unknown.stdout == ""
    (line,) = unknown.stderr.strip().splitlines()[-1:]
    assert line.startswith("ird echo: unknown topic /no/such/topic") and names.TOPIC_PROXY in line
    field = _run(graph, "echo", names.TOPIC_PROXY, "--field", "header.nosuch")
    assert field.returncode == 2 and field.stdout == ""
    last = field.stderr.strip().splitlines()[-1]
    assert last.startswith("ird echo: /world/proxy: field 'header.nosuch'") and "'nosuch'" in last


def test_ctrl_c_ends_echo_with_130(graph: Any) -> None:
    proc = _start(graph, "echo", names.TOPIC_ROB_STATUS)  # Rob is idle: no status comes
    try:
        reading = f"ird echo: reading {names.TOPIC_ROB_STATUS} [{names.TOPIC_TYPES[names.TOPIC_ROB_STATUS]}]"
        proc.wait_for_output(reading, timeout=120)
        proc.proc.send_signal(signal.SIGINT)
        code = proc.proc.wait(timeout=60)
    finally:
        proc.stop()
    out = proc.output()
    assert code == 130 and "Traceback" not in out, out
    assert "ird echo: interrupted" in out.splitlines()


def test_every_verb_spins_one_executor_for_its_lifetime(graph: Any) -> None:
    """The verbs' client node belongs to one executor from before their first wait to their end,
    which every wait spins (a temporary executor per wait could be half-built by a Ctrl-C)."""
    import argparse

    from rclpy.executors import SingleThreadedExecutor

    from ird_ros.cli.common import client

    with client(argparse.Namespace(domain_id=graph.domain_id), "test") as ird:
        executor = ird.node.executor
        assert isinstance(executor, SingleThreadedExecutor)
        ird.wait_ready(timeout=60)
        ird.spin_until(lambda: (names.NODE_WORLD, "/") in ird.node.get_node_names_and_namespaces(),
                       timeout=60, what="the world node")
        assert ird.node.executor is executor  # the waits spun it and left the node on it


# --- ird navigate --------------------------------------------------------------------------------

def _instance(ird: Any) -> Any:
    proxy = ird.proxy(timeout=60)
    return lavaland.make_instance(proxy.condition, int(proxy.seed), size=SIZE, horizon=HORIZON, obs_dim=OBS_DIM)


def _cells(out: str) -> list[tuple[int, int]]:
    line = next(x for x in out.splitlines() if x.startswith("cells: "))
    return [(int(r), int(c)) for r, c in CELL.findall(line)]


def test_navigate_prints_feedback_and_the_judged_result(graph: Any, ird: Any) -> None:
    inst = _instance(ird)
    done = _run(graph, "navigate", "--beta", "5", "--num-samples", "40", "--seed", "11", "--label", "cli_test")
    assert done.returncode == 0, done.stdout + done.stderr
    lines = done.stdout.splitlines()
    stages = {x.split(",")[0].removeprefix("feedback: ") for x in lines if x.startswith("feedback: ")}
    assert {"inferring", "planning", "driving"} <= stages, done.stdout
    cells = _cells(done.stdout)
    assert len(cells) == inst.test_horizon + 1 and cells[0] == tuple(inst.test_start)
    outcome = evaluation.evaluate_path(inst.test_labels, cells)
    result = next(x for x in lines if x.startswith("result: "))
    assert result == (f"result: SUCCEEDED: lava {outcome.touched_lava}, target {outcome.reached_target}, "
                      f"true return {outcome.true_return:.2f}, {len(cells)} cells")


def test_ctrl_c_cancels_the_goal_and_exits_130(graph: Any, ird: Any) -> None:
    statuses = ird.received(names.TOPIC_ROB_STATUS)
    since = len(statuses)
    proc = _start(graph, "navigate", "--beta", "5", "--num-samples", "40", "--seed", "12", "--label", "cli_cancel")
    try:
        proc.wait_for_output("feedback: driving, cell", timeout=300)
        proc.proc.send_signal(signal.SIGINT)
        code = proc.proc.wait(timeout=120)
    finally:
        proc.stop()
    out = proc.output()
    assert code == 130 and "Traceback" not in out, out
    assert "result: CANCELED" in out, out
    cells = _cells(out)
    assert 1 <= len(cells) < HORIZON + 1
    # the cancel reached the navigator: Rob reports the drive stopped where the result says
    ird.spin_until(lambda: any(s.stopped and s.plan_label.startswith("cli_cancel") for s in statuses[since:]),
                   timeout=60, what="Rob's stopped status")
    final = next(s for s in statuses[since:] if s.stopped and s.plan_label.startswith("cli_cancel"))
    assert (final.row, final.col) == cells[-1]


def test_navigate_refuses_a_bad_field_in_one_line(graph: Any) -> None:
    """A field only the navigator can judge (its max_queries parameter, 5 in the graph's params)
    is sent and rejected there (a field out of the message's own range never leaves the client:
    tests/test_ird_cli_args.py)."""
    done = _run(graph, "navigate", "--queries", "6")
    assert done.returncode == 2, done.stdout + done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith("ird navigate: goal rejected: queries") and "max_queries=5" in last, last


# --- ird infer -----------------------------------------------------------------------------------

def test_infer_prints_the_posterior_of_its_request(graph: Any) -> None:
    done = _run(graph, "infer", "--beta", "5", "--num-samples", "40")
    assert done.returncode == 0, done.stdout + done.stderr
    rows = {x.split()[0]: x.split()[1:] for x in done.stdout.splitlines()
            if x.split() and x.split()[0] in ("dirt", "grass", "target")}
    # ird-infer's generated request: the designer's proxy (0.1, -0.2, 1.0) on dirt, grass, target
    assert {k: float(v[0]) for k, v in rows.items()} == {"dirt": 0.1, "grass": -0.2, "target": 1.0}
    assert "maxent_z, beta=5" in done.stdout and "acceptance" in done.stdout


# --- no graph ------------------------------------------------------------------------------------

@pytest.mark.parametrize("argv", [["graph"], ["echo", "/world/proxy"], ["navigate"]])
def test_an_empty_domain_is_exit_1_naming_it(argv: list[str]) -> None:
    with lease_domain() as empty:
        done = subprocess.run([str(IRD), *argv, "--domain-id", str(empty.domain_id), "--timeout", "2"],
                              capture_output=True, text=True, cwd=ROOT, timeout=120)
    assert done.returncode == 1 and done.stdout == "", done.stdout + done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith(f"ird {argv[0]}: ") and f"ROS_DOMAIN_ID={empty.domain_id}" in last
    assert "Traceback" not in done.stderr
