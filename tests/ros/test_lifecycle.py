"""Managed (lifecycle) nodes over real DDS: transitions, what an inactive node does not do,
read-only and run-time parameters, and the launcher as lifecycle manager.

The world node runs on its own with ``autostart:=false`` (as the launcher starts it) and a test
client drives it through ``/world/change_state``. Nothing sleeps: every wait is a service answer,
a received message or a launcher event, each with a deadline.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import Any, Iterator

import pytest

from ird_ros.bags import storage
from ird_ros.cli import discovery
from ird_ros.cli.graph import lifecycle_states
from ird_ros.graph import NODES_BY_NAME, names
from ird_ros.graph.domains import DomainLease
from ird_ros.launch import GraphLauncher, LaunchError
from ird_ros.testing import NodeProcess, spawn_node_process
from ird_ros.waits import call_service, spin_until, wait_for_publishers

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
SMALL = ("-p", "height:=5", "-p", "width:=6", "-p", "horizon:=6", "-p", "obs_dim:=8")


@pytest.fixture(scope="module")
def world(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    argv = ["-m", "ird_ros.nodes.world", "--ros-args", "--params-file", PARAMS, "-p", "autostart:=false",
            "-p", "condition:=side_effects", "-p", "seed:=1", *SMALL]
    with spawn_node_process(argv, domain=ros_domain, name="world", ready_text="world unconfigured") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()


class World:
    """The test's clients of the world node: lifecycle, parameters, /world/generate, /world/proxy."""

    def __init__(self, node: Any, proc: NodeProcess) -> None:
        from lifecycle_msgs.srv import ChangeState, GetState
        from rcl_interfaces.srv import SetParameters

        from ird_msgs.msg import ProxyReward
        from ird_msgs.srv import GenerateWorld

        self.node, self.proc = node, proc
        self.get_state = node.create_client(GetState, "/world/get_state")
        self.change_state = node.create_client(ChangeState, "/world/change_state")
        self.set_parameters = node.create_client(SetParameters, "/world/set_parameters")
        self.generate = node.create_client(GenerateWorld, names.SRV_GENERATE)
        self.proxies: list[Any] = []
        self.sub = node.create_subscription(ProxyReward, names.TOPIC_PROXY, self.proxies.append, names.latched_qos())

    def call(self, client: Any, request: Any) -> Any:
        return call_service(self.node, client, request, timeout=30.0, processes=[self.proc])

    def state(self) -> str:
        from lifecycle_msgs.srv import GetState

        return str(self.call(self.get_state, GetState.Request()).current_state.label)

    def transition(self, transition_id: int) -> bool:
        from lifecycle_msgs.msg import Transition
        from lifecycle_msgs.srv import ChangeState

        return bool(self.call(self.change_state, ChangeState.Request(transition=Transition(id=transition_id))).success)

    def set(self, name: str, value: Any) -> Any:
        from rcl_interfaces.srv import SetParameters
        from rclpy.parameter import Parameter

        return self.call(self.set_parameters, SetParameters.Request(
            parameters=[Parameter(name, value=value).to_parameter_msg()])).results[0]

    def try_generate(self, seed: int) -> Any:
        from ird_msgs.srv import GenerateWorld

        return self.call(self.generate, GenerateWorld.Request(condition="", seed=seed))

    def wait_proxies(self, count: int) -> None:
        spin_until(self.node, lambda: len(self.proxies) >= count, timeout=30.0, what=f"{count} /world/proxy",
                   processes=[self.proc])


def test_world_lifecycle_transitions_over_dds(world: NodeProcess, ros_node: Any) -> None:
    from lifecycle_msgs.msg import Transition

    w = World(ros_node, world)
    assert w.state() == "unconfigured"
    assert w.transition(Transition.TRANSITION_CONFIGURE) and w.state() == "inactive"

    # inactive: the service answers that it is not served, nothing is published
    refused = w.try_generate(seed=7)
    assert not refused.success and "inactive" in refused.message and names.SRV_GENERATE in refused.message
    wait_for_publishers(ros_node, w.sub, timeout=30.0, processes=[world])  # the publisher exists (configured)

    assert w.transition(Transition.TRANSITION_ACTIVATE) and w.state() == "active"
    w.wait_proxies(1)
    # One writer delivers in order: a message published while inactive would have come first.
    assert len(w.proxies) == 1 and w.proxies[0].seed == 1

    # read-only: refused with rclpy's reason; run-time: a new seed publishes that world
    result = w.set("height", 9)
    assert not result.successful and "read-only" in result.reason
    result = w.set("condition", "no_such_condition")
    assert not result.successful and "condition" in result.reason
    assert w.set("seed", 4).successful
    w.wait_proxies(2)
    assert w.proxies[-1].seed == 4 and w.proxies[-1].condition == "side_effects"
    done = w.try_generate(seed=5)
    assert done.success, done.message

    assert w.transition(Transition.TRANSITION_DEACTIVATE) and w.state() == "inactive"
    assert not w.try_generate(seed=6).success
    assert w.transition(Transition.TRANSITION_CLEANUP) and w.state() == "unconfigured"
    # configurable again, from the parameters as they are now (seed 5, set by /world/generate)
    assert w.transition(Transition.TRANSITION_CONFIGURE) and w.transition(Transition.TRANSITION_ACTIVATE)
    w.wait_proxies(4)
    assert w.proxies[-1].seed == 5
    assert w.transition(Transition.TRANSITION_DEACTIVATE) and w.transition(Transition.TRANSITION_CLEANUP)
    assert w.transition(Transition.TRANSITION_UNCONFIGURED_SHUTDOWN) and w.state() == "finalized"


def test_configure_failure_names_the_node_and_the_reason(tmp_path: Path) -> None:
    spec = replace(NODES_BY_NAME["world"], ros_args=("-p", "condition:=no_such_condition", *SMALL))
    with GraphLauncher(nodes=["world"], specs=[spec], private_domain=True, output="quiet", echo=lambda _t: None) as graph:
        with pytest.raises(LaunchError) as err:
            graph.wait_ready(timeout=60)
        text = str(err.value)
        assert "world" in text and "configure failed" in text and "parameter condition: must be one of" in text
        assert graph.state("world").value == "starting"  # up, unconfigured, until the launcher stops it
    assert graph.stop() == {"world": 0}


def test_launcher_configures_and_activates_recorder_first(tmp_path: Path) -> None:
    from lifecycle_msgs.srv import GetState

    from ird_ros.graph.domains import ros_context

    specs = [replace(NODES_BY_NAME[n], ros_args=SMALL if n == "world" else ()) for n in ("world", "perception", "rob")]
    bag = tmp_path / "bag"
    with GraphLauncher(nodes=["world", "perception", "rob"], specs=specs, record_dir=bag, private_domain=True,
                       output="quiet", echo=lambda _t: None) as graph:
        graph.wait_ready(timeout=120)
        ready = {ev.node: ev.index for ev in graph.events() if ev.kind == "ready"}
        assert all(ready["recorder"] < ready[n] for n in ("world", "perception", "rob")), ready
        assert ready["world"] < ready["perception"]  # perception (after: world) is activated after it
        with ros_context(graph.domain_id) as ctx:
            import rclpy

            node = rclpy.create_node("lifecycle_check", context=ctx)
            try:
                # a second shell's view (ird graph): each managed node with its state
                wanted = [f"/{n}/get_state" for n in ("world", "perception", "rob", "recorder")]
                def seen() -> bool:
                    view = discovery.snapshot(node)
                    return (set(wanted) <= {n for n, _t in view.services}
                            and {w.rsplit("/", 1)[0] for w in wanted} <= set(view.nodes))

                spin_until(node, seen, timeout=30.0, what="the managed nodes and their lifecycle services")
                states = lifecycle_states(node, discovery.snapshot(node), timeout=10.0)
                assert {n: states.get(n) for n in ("/world", "/perception", "/rob", "/recorder")} == dict.fromkeys(
                    ("/world", "/perception", "/rob", "/recorder"), "active"), states
                assert all(call_service(node, node.create_client(GetState, service), GetState.Request())
                           .current_state.label == "active" for service in wanted)
            finally:
                node.destroy_node()
    counts = {t.topic: t.count for t in storage.summarize(bag)}
    assert counts.get(names.TOPIC_PROXY, 0) == 1 and counts.get(names.TOPIC_TERRAIN_FEATURES, 0) == 1, counts


def test_a_destroyed_managed_node_leaves_the_graph_while_its_object_lives(ros_ctx: Any, ros_node: Any) -> None:
    """``destroy_node`` takes a managed node out of the graph at once, though a reference to the
    Python object remains (pytest keeps fixture values): rclpy's lifecycle state machine held the
    rcl node until garbage collection, so the node, its lifecycle services and its participant
    outlived the test and polluted the next test that leased the same domain ID."""
    from ird_ros.nodes.world import WorldNode
    from ird_ros.runtime.lifecycle import TransitionCallbackReturn

    # a namespace of its own: the module's world process is in this domain too
    kept = WorldNode(context=ros_ctx, namespace="/leak_check", parameter_overrides=_small_world_parameters())
    assert kept.trigger_configure() == TransitionCallbackReturn.SUCCESS, kept.transition_error
    own = ("world", "/leak_check")
    lifecycle = {f"/leak_check/world/{s}" for s in ("change_state", "get_state", "get_available_states",
                                                     "get_available_transitions", "get_transition_graph")}
    assert own in ros_node.get_node_names_and_namespaces()  # the same context: its graph is local
    assert lifecycle <= {s for s, _ in ros_node.get_service_names_and_types()}
    kept.destroy_node()
    assert own not in ros_node.get_node_names_and_namespaces()
    # the lifecycle services went with the state machine (rclpy keeps every node's
    # get_type_description endpoint after destroy_node, plain nodes' too: not checked)
    assert not lifecycle & {s for s, _ in ros_node.get_service_names_and_types()}
    assert kept is not None  # still referenced here


def _small_world_parameters() -> list[Any]:
    from rclpy.parameter import Parameter

    return [Parameter("height", value=5), Parameter("width", value=5), Parameter("horizon", value=4),
            Parameter("condition", value="side_effects")]
