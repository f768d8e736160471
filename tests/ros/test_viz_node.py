"""The viz node in-process (issue 43): every callback guarded, a stamp before the epoch shown as 0
rather than ending the node, Rob's /rob/status on its own channel, and a new world forgetting the
previous world's posterior and question. The callbacks get messages directly (no DDS timing)."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any, Iterator

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter

from ird_msgs.msg import RobStatus
from ird_ros import conversions as conv
from ird_ros.graph import names
from ird_ros.runtime.guard import GuardedNode, unguarded_callbacks

NAMES = ["dirt", "grass", "target", "lava"]


@pytest.fixture
def viz(ros_ctx: Any) -> Iterator[Any]:
    from ird_ros.nodes.viz import VizNode

    from ird_ros.runtime.lifecycle import start_up

    node = VizNode(context=ros_ctx, parameter_overrides=[Parameter("port", value=0)])
    assert start_up(node), node.transition_error  # configure and activate, as autostart does
    try:
        yield node
    finally:
        node.destroy_node()


def _callback(node: Any, topic: str) -> Any:
    """The callback rclpy calls for ``topic`` (the guarded wrapper)."""
    (sub,) = [s for s in node.subscriptions if s.topic_name == topic]
    return sub.callback


def _terrain(sec: int, nanosec: int = 0) -> Any:
    classes = np.array([[0, 1, 2], [3, 0, 0]], dtype=np.uint8)
    return conv.terrain_grid_to_msg(classes, NAMES, stamp=Time(sec=sec, nanosec=nanosec))


def _odom(sec: int, x: float = 0.5, y: float = 0.5) -> Odometry:
    msg = Odometry()
    msg.header.stamp = Time(sec=sec, nanosec=0)
    msg.header.frame_id = "map"
    msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
    msg.pose.pose.orientation.w = 1.0
    return msg


def _posterior(sec: int) -> Any:
    post = SimpleNamespace(samples=np.ones((3, 4)), method="maxent_z", beta=10.0, acceptance_rate=0.5, r_hat_max=1.0,
                           ess_min=10.0, prior_sigma=1.0, num_chains=1, seed=0, converged=True)
    return conv.posterior_to_msg(post, feature_names=NAMES, proxy_weights=np.zeros(4), stamp=Time(sec=sec))


def _status(step: int, row: int, col: int, *, done: bool = False, stopped: bool = False, lava: bool = False,
            target: bool = False, plan_sec: int = 100) -> RobStatus:
    msg = RobStatus(row=row, col=col, terrain="dirt", step=step, horizon=4, done=done, stopped=stopped,
                    touched_lava=lava, reached_target=target, true_return=-1.0, plan_label="literal")
    msg.header.stamp = Time(sec=plan_sec + step)
    msg.plan_stamp = Time(sec=plan_sec)
    return msg


def test_every_callback_is_guarded_and_a_raising_one_leaves_the_node_serving(viz: Any) -> None:
    assert isinstance(viz, GuardedNode)
    assert unguarded_callbacks(viz) == []

    def broken(*_args: Any, **_kwargs: Any) -> None:
        raise RuntimeError("a bug in the view")

    viz.view.show_rob = broken
    assert _callback(viz, names.TOPIC_ODOM)(_odom(1)) is None  # logged, not raised into the executor


def test_a_stamp_before_the_epoch_neither_ends_the_node_nor_loses_the_message(viz: Any) -> None:
    """``stamp.sec = -1`` on /world/terrain and /odom: shown (stamp 0), the node keeps going."""
    _callback(viz, names.TOPIC_TERRAIN)(_terrain(-1))
    assert viz.view.latest("terrain") is not None and viz.terrain is not None
    viz._on_odom(_odom(-1))  # the unguarded method itself: no exception
    assert viz.view.latest("rob") is not None and viz.view.latest("trail") is not None
    _callback(viz, names.TOPIC_TERRAIN)(_terrain(5))  # and the next world is shown
    assert viz.terrain_ns == 5_000_000_000


def test_rob_status_has_a_channel_saying_driving_stopped_or_done_and_what_he_reached(viz: Any) -> None:
    on_status = _callback(viz, names.TOPIC_ROB_STATUS)
    on_status(_status(0, 0, 0))
    state = viz.view.latest("rob_status")
    assert state["state"] == "driving" and state["outcome"] == "stayed put" and state["cell"] == [0, 0]
    on_status(_status(4, 0, 0, done=True))
    assert viz.view.latest("rob_status")["state"] == "done"
    assert viz.view.latest("rob_status")["outcome"] == "stayed put"  # never left the start
    on_status(_status(0, 0, 0, plan_sec=200))
    on_status(_status(1, 0, 1, plan_sec=200))
    on_status(_status(2, 0, 1, stopped=True, done=True, plan_sec=200))
    state = viz.view.latest("rob_status")
    assert state["state"] == "stopped" and state["outcome"] == "moved"
    on_status(_status(0, 1, 1, plan_sec=300))
    on_status(_status(1, 1, 0, lava=True, done=True, plan_sec=300))
    assert viz.view.latest("rob_status")["outcome"] == "touched lava"


def test_a_new_world_clears_the_previous_posterior_and_question(viz: Any) -> None:
    _callback(viz, names.TOPIC_TERRAIN)(_terrain(10))
    _callback(viz, names.TOPIC_POSTERIOR)(_posterior(20))
    assert viz.view.latest("posterior")["num_samples"] == 3
    _callback(viz, names.TOPIC_TERRAIN)(_terrain(30))  # a new world
    shown = viz.view.latest("posterior")
    assert shown["num_samples"] == 0 and shown["terrains"] == {} and "new world" in shown["note"]
    _callback(viz, names.TOPIC_POSTERIOR)(_posterior(20))  # late: the previous world's
    assert viz.view.latest("posterior")["num_samples"] == 0
    _callback(viz, names.TOPIC_POSTERIOR)(_posterior(40))
    assert viz.view.latest("posterior")["num_samples"] == 3
