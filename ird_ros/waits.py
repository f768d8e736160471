"""Waiting on the ROS graph from a client: discovery, service calls, messages (no sleeps).

Every wait spins the caller's node (``spin_once`` with a short timeout wakes up on any ROS
event) until a condition holds or a deadline passes, and then raises ``TimeoutError`` that
includes the output of the helper processes it was given. ``ird_ros.client.IrdClient`` is built
on these waits; tests use them directly for nodes of their own.

rclpy is imported lazily, so importing this module costs nothing without ROS.
"""

from __future__ import annotations

import time
from typing import Any, Callable, Protocol, Sequence

__all__ = [
    "WatchedProcess",
    "spin_until",
    "wait_for_subscribers",
    "wait_for_publishers",
    "wait_for_service",
    "wait_for_node",
    "call_service",
    "receive_messages",
]


class WatchedProcess(Protocol):
    """A helper process a wait gives up on when it exits (the tests' node processes)."""

    name: str

    def alive(self) -> bool: ...

    def describe(self) -> str: ...


def spin_until(
    node: Any,
    condition: Callable[[], bool],
    *,
    timeout: float,
    what: str = "condition",
    executor: Any = None,
    processes: Sequence[WatchedProcess] = (),
) -> None:
    """Spin until ``condition()`` is true.

    Spins ``executor`` if given, else the executor ``node`` belongs to, else a temporary
    single-threaded executor in the node's context. Raises ``TimeoutError`` naming
    ``what`` (with the output of ``processes``) after ``timeout`` seconds, or as soon as
    one of ``processes`` has exited.
    """
    from rclpy.executors import SingleThreadedExecutor

    temporary = None
    if executor is None:
        executor = node.executor
    if executor is None:
        executor = temporary = SingleThreadedExecutor(context=node.context)
        temporary.add_node(node)
    try:
        deadline = time.monotonic() + timeout
        while not condition():
            for proc in processes:
                if not proc.alive():
                    raise TimeoutError(f"waiting for {what}: {proc.name} exited\n{proc.describe()}")
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                details = "\n".join(p.describe() for p in processes)
                raise TimeoutError(f"timed out after {timeout} s waiting for {what}\n{details}")
            executor.spin_once(timeout_sec=min(0.05, remaining))
    finally:
        if temporary is not None:
            node.executor = None  # detaches the node from the temporary executor
            temporary.shutdown()


def wait_for_subscribers(node: Any, publisher: Any, count: int = 1, *, timeout: float = 20.0, **kw: Any) -> None:
    """Wait until ``publisher`` has matched at least ``count`` subscriptions."""
    spin_until(
        node,
        lambda: publisher.get_subscription_count() >= count,
        timeout=timeout,
        what=f"{count} subscriber(s) on {publisher.topic_name}",
        **kw,
    )


def wait_for_publishers(node: Any, subscription: Any, count: int = 1, *, timeout: float = 20.0, **kw: Any) -> None:
    """Wait until ``subscription`` has matched at least ``count`` publishers."""
    spin_until(
        node,
        lambda: subscription.get_publisher_count() >= count,
        timeout=timeout,
        what=f"{count} publisher(s) on {subscription.topic_name}",
        **kw,
    )


def wait_for_service(node: Any, client: Any, *, timeout: float = 20.0, **kw: Any) -> None:
    """Wait until the server of ``client`` is discovered."""
    spin_until(node, client.service_is_ready, timeout=timeout, what=f"service {client.srv_name}", **kw)


def wait_for_node(node: Any, name: str, namespace: str = "/", *, timeout: float = 20.0, **kw: Any) -> None:
    """Wait until a node called ``namespace/name`` is in the graph."""
    spin_until(
        node,
        lambda: (name, namespace) in node.get_node_names_and_namespaces(),
        timeout=timeout,
        what=f"node {namespace.rstrip('/')}/{name}",
        **kw,
    )


def call_service(node: Any, client: Any, request: Any, *, timeout: float = 30.0, **kw: Any) -> Any:
    """Wait for the server, call it, and spin until the response arrives; return the response.

    Waiting first matters: a request sent before discovery matched client and server is
    dropped without an error, and the call would hang until ``timeout``.
    """
    wait_for_service(node, client, timeout=timeout, **kw)
    future = client.call_async(request)
    spin_until(node, future.done, timeout=timeout, what=f"response of {client.srv_name}", **kw)
    return future.result()


def receive_messages(
    node: Any,
    msg_type: Any,
    topic: str,
    *,
    count: int = 1,
    qos: Any = None,
    timeout: float = 20.0,
    raw: bool = False,
    **kw: Any,
) -> list[Any]:
    """Subscribe to ``topic`` and spin until ``count`` messages arrived; return them.

    ``qos`` defaults to reliable, transient local, depth 10 (which also receives what was
    published before the subscription matched, from transient-local publishers).
    """
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

    if qos is None:
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    received: list[Any] = []
    sub = node.create_subscription(msg_type, topic, received.append, qos, raw=raw)
    try:
        spin_until(node, lambda: len(received) >= count, timeout=timeout, what=f"{count} message(s) on {topic}", **kw)
    finally:
        node.destroy_subscription(sub)
    return received
