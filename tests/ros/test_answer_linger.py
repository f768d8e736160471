"""A stopping node keeps its participant for a moment after its last answer
(``ird_ros.runtime.node_main.linger_after_answer``, ``GuardedNode.last_answer``).

Properties:

- ``last_answer`` is set when one of the node's own services has its answer ready, a failure
  answer included, and not by rclpy's parameter services (a launcher's liveness pings must not
  delay every stop);
- the linger waits until exactly ``linger`` seconds after the last answer, and not at all for a
  node without answers, without ``last_answer``, or whose last answer is older.

The end-to-end property (a node that answers and then exits delivers its answer) is
``tests/ros/test_shutdown_signals.py``.
"""

from __future__ import annotations

import time
from types import SimpleNamespace
from typing import Any

from rcl_interfaces.srv import GetParameters
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from std_srvs.srv import Trigger

from ird_ros.runtime.guard import GuardedNode
from ird_ros.runtime.node_main import ANSWER_LINGER, linger_after_answer
from ird_ros.waits import call_service


class _Answering(GuardedNode):
    def __init__(self, context: Any) -> None:
        super().__init__("linger_answering_node", context=context)
        self.declare_parameter("answer", 42)
        self.create_service(Trigger, "/linger/ok", self._ok)
        self.create_service(Trigger, "/linger/raises", self._raises)

    def _ok(self, req: Any, resp: Any) -> Any:
        resp.success = True
        return resp

    def _raises(self, req: Any, resp: Any) -> Any:
        raise ZeroDivisionError("a bug")


def test_last_answer_marks_the_nodes_own_answers_only(ros_ctx: Any) -> None:
    server = _Answering(ros_ctx)
    client_node = Node("linger_client_node", context=ros_ctx)
    executor = SingleThreadedExecutor(context=ros_ctx)
    executor.add_node(server)
    executor.add_node(client_node)
    try:
        assert server.last_answer is None
        parameters = client_node.create_client(GetParameters, "/linger_answering_node/get_parameters")
        got = call_service(client_node, parameters, GetParameters.Request(names=["answer"]), timeout=30.0,
                           executor=executor)
        assert got.values[0].integer_value == 42
        assert server.last_answer is None, "a parameter request counted as an answer"
        for name in ("/linger/ok", "/linger/raises"):
            before = time.monotonic()
            client = client_node.create_client(Trigger, name)
            answer = call_service(client_node, client, Trigger.Request(), timeout=30.0, executor=executor)
            assert answer.success is (name == "/linger/ok"), answer
            assert server.last_answer is not None and before <= server.last_answer <= time.monotonic(), name
    finally:
        executor.shutdown()
        client_node.destroy_node()
        server.destroy_node()


def test_the_linger_ends_exactly_linger_seconds_after_the_last_answer() -> None:
    linger = 0.3
    node = SimpleNamespace(last_answer=time.monotonic() - 0.1)
    waited = linger_after_answer(node, linger)
    assert 0.0 < waited <= linger - 0.1
    assert time.monotonic() >= node.last_answer + linger


def test_no_linger_without_a_recent_answer() -> None:
    now = time.monotonic()
    for node in (SimpleNamespace(last_answer=None), SimpleNamespace(), SimpleNamespace(last_answer=now - 2.0)):
        assert linger_after_answer(node, 1.0) == 0.0
    assert ANSWER_LINGER == 1.0  # the value docs/limits.md states
