"""``IrdClient``: one typed client of a running IRD graph (docs/spec.md section 6).

In the spirit of nav2_simple_commander's ``BasicNavigator``: a node of its own in one ROS domain
whose methods read like a mission::

    with IrdClient() as ird:                       # ROS_DOMAIN_ID from the environment
        ird.wait_ready(timeout=60)                 # every service of the graph discovered
        ird.watch_rob()                            # /rob/status is a stream: subscribe first
        proxy = ird.proxy()
        posterior = ird.infer(infer_request(...)).unwrap()
        plan = ird.plan(plan_request(...)).unwrap()
        drive = ird.wait_for_rob(plan)
        result = ird.navigate(NavigationGoal(mode="per_step"))   # or all of it: the NavigateIrd action

Invariants:

- Every service call returns a :class:`~ird_ros.client.results.CallResult` (status DONE, BUSY,
  REFUSED or FAILED, the decoded payload, the field a refusal names, the raw response); a
  refusal is an answer, never an exception.
- Every wait spins this client's node (``ird_ros.waits``, no sleeps). A wait that runs out
  raises :class:`ClientTimeout`, or :class:`GraphNotFound` when nothing in the domain offers the
  service or publishes the topic; both name the ROS_DOMAIN_ID searched and how to change it.
- A call never waits past its timeout, and a request whose server drops out of the graph while it is
  pending (a node stopped, frozen or starved for the DDS lease, 20 s) is resent when the server is back
  (``/ird/infer``: the same request gives the same answer) or, if no answer comes within ``lost_grace``
  s of its return, ends FAILED saying so (:mod:`ird_ros.client.pending`): DDS drops such a request.
- Service clients use the deep service QoS (``ird_ros.runtime.offload.service_qos``), so a burst
  of requests is answered in full; a request is sent only once its server is discovered (a request
  sent earlier is dropped without an error).
- Topics are read with the graph's QoS (``ird_ros.graph.names.qos_for``): latched topics give the
  latest message even to a late subscriber; ``/rob/status`` is volatile, so :meth:`watch_rob` must
  precede the plan whose drive :meth:`wait_for_rob` waits for.

rclpy and the message packages are imported when a client is made, not when this module is.
"""

from __future__ import annotations

import contextlib
import importlib
import os
from typing import TYPE_CHECKING, Any, Callable, Iterable, Sequence, TypeVar

import numpy as np

from ird_ros import conversions as conv
from ird_ros.client.navigation import (
    NavigationFeedback,
    NavigationGoal,
    NavigationHandle,
    NavigationResult,
    make_action_client,
    send_goal,
)
from ird_ros.client.pending import LOST_GRACE, RESEND_SAFE, PendingCall
from ird_ros.client.results import (
    CallResult,
    Plan,
    Query,
    RobDrive,
    WorldMessages,
)
from ird_ros.graph import names
from ird_ros.graph.domains import check_domain_id, ros_context
from ird_ros.runtime.offload import service_qos
from ird_ros.stamps import stamp_key
from ird_ros.waits import WatchedProcess, spin_until

if TYPE_CHECKING:
    from ird_msgs.msg import ProxyReward, QueryRecord
    from ird_msgs.srv import InferReward, PlanPath, ProposeQuery

__all__ = ["IrdClient", "PendingCall", "ClientTimeout", "GraphNotFound", "ALL_SERVICES", "domain_hint"]

T = TypeVar("T")

ALL_SERVICES: tuple[str, ...] = tuple(names.SERVICE_TYPES)
"""Every service of the full graph (world, inference, planner, rob)."""

#: Reader depth of the stream topics (/rob/status, /odom): a whole drive queues while the
#: caller is not spinning.
STREAM_READER_DEPTH = 100

_WORLD_TOPICS = (names.TOPIC_TRAIN_FEATURES, names.TOPIC_TEST_FEATURES, names.TOPIC_TRAIN_PROXY_FEATURES,
                 names.TOPIC_PROXY)


class ClientTimeout(TimeoutError):
    """A wait of :class:`IrdClient` ran out; the message names the domain searched."""


class GraphNotFound(ClientTimeout):
    """Nothing in the domain offers the service (or publishes the topic) waited for."""


def domain_hint(domain_id: int) -> str:
    """The sentence every client timeout ends with: the domain searched and how to pick another."""
    return (f"(searched ROS_DOMAIN_ID={domain_id}; if the graph runs in another domain, set it with "
            f"`export ROS_DOMAIN_ID=N` before starting this client)")


def default_domain_id() -> int:
    """``ROS_DOMAIN_ID`` from the environment (ROS's default 0 when unset)."""
    return check_domain_id(os.environ.get("ROS_DOMAIN_ID") or 0, "ROS_DOMAIN_ID")


def _interface(type_name: str) -> Any:
    """The Python class of ``package/msg/Name`` or ``package/srv/Name``."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


def _decode_posterior(response: Any) -> conv.PosteriorData:
    return conv.posterior_from_msg(response.posterior, field="response.posterior")


def _decode_plan(response: Any) -> Plan:
    cells = tuple((int(r), int(c)) for r, c in zip(response.rows, response.cols))
    return Plan(cells, float(response.objective), response.path.header.stamp)


class IrdClient:
    """A client node of the IRD graph in one ROS domain (see the module docstring).

    Args:
        domain_id: the domain to join (default ``ROS_DOMAIN_ID``, else 0); ignored with ``context``.
        node_name: the client node's name.
        context: an initialised rclpy context to create the node in (the caller shuts it down);
            default: a context of the client's own, shut down by :meth:`close`.
        executor: an executor to add the node to and to spin in every wait (several clients
            spun together); default: the node's own temporary executor per wait.
        processes: helper processes a wait gives up on when one exits (tests).
    """

    def __init__(self, domain_id: int | None = None, *, node_name: str = "ird_client", context: Any = None,
                 executor: Any = None, processes: Sequence[WatchedProcess] = ()) -> None:
        import rclpy

        self._stack = contextlib.ExitStack()
        if context is None:
            domain = default_domain_id() if domain_id is None else check_domain_id(domain_id)
            context = self._stack.enter_context(ros_context(domain))
        try:
            self.domain_id = int(context.get_domain_id())
            self.node = rclpy.create_node(node_name, context=context)
        except BaseException:
            self._stack.close()
            raise
        self._executor = executor
        if executor is not None:
            executor.add_node(self.node)
        self.processes = list(processes)
        self._services: dict[str, Any] = {}
        self._subscriptions: dict[str, Any] = {}
        self._received: dict[str, list[Any]] = {}
        self._navigate: Any = None  # the /ird/navigate action client, made on first use

    # ------------------------------------------------------------------ lifetime

    def close(self) -> None:
        """Destroy the node (and shut down the client's own context)."""
        if self._executor is not None:
            self._executor.remove_node(self.node)
        if self._navigate is not None:
            self._navigate.destroy()
        self.node.destroy_node()
        self._stack.close()

    def __enter__(self) -> "IrdClient":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ------------------------------------------------------------------ waits

    def spin_until(self, condition: Callable[[], bool], *, timeout: float, what: str) -> None:
        """Spin until ``condition()``; :class:`ClientTimeout` naming ``what`` after ``timeout`` s."""
        try:
            spin_until(self.node, condition, timeout=timeout, what=what, executor=self._executor,
                       processes=self.processes)
        except TimeoutError as exc:
            raise ClientTimeout(f"{exc}\n{domain_hint(self.domain_id)}") from None

    def _discover(self, found: Callable[[], bool], missing: Callable[[], str], timeout: float) -> None:
        try:
            spin_until(self.node, found, timeout=timeout, what="discovery", executor=self._executor,
                       processes=self.processes)
        except TimeoutError as exc:
            raise GraphNotFound(f"{missing()} not found within {timeout:g} s {domain_hint(self.domain_id)}"
                                f"\n{exc}") from None

    def is_ready(self, service: str) -> bool:
        """Whether ``service`` is discovered now (its client is made on first use; no spinning)."""
        return bool(self._client(service).service_is_ready())

    def wait_ready(self, timeout: float = 60.0, *, services: Iterable[str] = ALL_SERVICES) -> None:
        """Wait until every service in ``services`` is discovered (:class:`GraphNotFound` names the rest)."""
        clients = [self._client(service) for service in services]

        def missing() -> str:
            return "service(s) " + ", ".join(c.srv_name for c in clients if not c.service_is_ready())

        self._discover(lambda: all(c.service_is_ready() for c in clients), missing, timeout)

    # ------------------------------------------------------------------ topics

    def subscribe(self, *topics: str) -> None:
        """Start collecting ``topics`` (each once; the graph's QoS): before a stream's first message,
        or to count the messages of a topic from now on."""
        for topic in topics:
            if topic in self._subscriptions:
                continue
            received: list[Any] = []
            qos = names.qos_for(topic)
            if names.TOPIC_QOS[topic] == names.STREAM:
                qos = names.stream_qos(STREAM_READER_DEPTH)
            self._subscriptions[topic] = self.node.create_subscription(
                _interface(names.TOPIC_TYPES[topic]), topic, received.append, qos)
            self._received[topic] = received

    def received(self, topic: str) -> list[Any]:
        """Every message of ``topic`` received so far (subscribing now if needed); grows as the node spins."""
        self.subscribe(topic)
        return self._received[topic]

    def latest(self, topic: str, *, after: int = 0, timeout: float = 60.0) -> Any:
        """The latest message of ``topic`` once more than ``after`` were received.

        :class:`GraphNotFound` if nobody publishes ``topic`` in the domain, else :class:`ClientTimeout`.
        """
        received = self.received(topic)
        subscription = self._subscriptions[topic]
        try:
            spin_until(self.node, lambda: len(received) > after, timeout=timeout, what=f"a message on {topic}",
                       executor=self._executor, processes=self.processes)
        except TimeoutError as exc:
            kind = GraphNotFound if subscription.get_publisher_count() == 0 else ClientTimeout
            raise kind(f"{exc}\n{domain_hint(self.domain_id)}") from None
        return received[-1]

    def proxy(self, *, timeout: float = 60.0) -> "ProxyReward":
        """The designer's proxy reward (``/world/proxy``, an ``ird_msgs/ProxyReward``)."""
        return self.latest(names.TOPIC_PROXY, timeout=timeout)

    def world_infer_request(self, *, timeout: float = 60.0) -> "InferReward.Request":
        """The ``/ird/infer`` request the world poses (every training world of a world file)."""
        return self.latest(names.TOPIC_INFER_REQUEST, timeout=timeout)

    def risk_map(self, *, after: int = 0, timeout: float = 30.0) -> np.ndarray:
        """The planner's (H, W) risk map (0..100) once more than ``after`` were received."""
        msg = self.latest(names.TOPIC_RISK_MAP, after=after, timeout=timeout)
        return conv.occupancy_grid_from_msg(msg, field=names.TOPIC_RISK_MAP)

    def world(self, *, condition: str | None = None, seed: int | None = None,
              other_than: WorldMessages | None = None, timeout: float = 60.0) -> WorldMessages:
        """The latest complete generation of the world node (every map and the proxy of one stamp),
        waiting until it has ``condition`` and ``seed`` (if given) and is not ``other_than``."""
        self.subscribe(*_WORLD_TOPICS)
        found: list[WorldMessages] = []

        def complete() -> bool:
            msgs = [self._received[t][-1] if self._received[t] else None for t in _WORLD_TOPICS]
            if any(m is None for m in msgs) or len({stamp_key(m.header.stamp) for m in msgs}) != 1:
                return False
            world = WorldMessages(*msgs)
            if (condition is not None and world.proxy.condition != condition) or (
                    seed is not None and world.proxy.seed != seed) or (
                    other_than is not None and world.stamp == other_than.stamp):
                return False
            found.append(world)
            return True

        described = " ".join(f"{k} {v}" for k, v in (("condition", condition), ("seed", seed)) if v is not None)
        self.spin_until(complete, timeout=timeout, what=f"a complete world {described}".rstrip())
        return found[-1]

    # ------------------------------------------------------------------ services

    def _client(self, service: str) -> Any:
        if service not in self._services:
            srv_type = _interface(names.SERVICE_TYPES[service])
            self._services[service] = self.node.create_client(srv_type, service, qos_profile=service_qos())
        return self._services[service]

    def call_async(self, service: str, request: Any, *, decode: Callable[[Any], T] | None = None,
                   timeout: float = 60.0, resend: bool | None = None,
                   lost_grace: float = LOST_GRACE) -> PendingCall[T]:
        """Send ``request`` once ``service`` is discovered (within ``timeout``); answer later.

        ``resend`` (default: ``service`` in ``RESEND_SAFE``) sends it again when its server drops out
        and comes back; else the call ends FAILED ``lost_grace`` s after the return without an answer."""
        client = self._client(service)
        self._discover(client.service_is_ready, lambda: f"service {service}", timeout)
        return PendingCall(service, client, request, decode,
                           resend=service in RESEND_SAFE if resend is None else resend, lost_grace=lost_grace)

    def wait(self, pending: PendingCall[T], *, timeout: float) -> CallResult[T]:
        """Spin until ``pending`` ends; :class:`ClientTimeout` naming the service, the timeout and the
        domain (and whether its server dropped out meanwhile) after ``timeout`` s."""
        try:
            self.spin_until(pending.done, timeout=timeout, what=f"the answer of {pending.service}")
        except ClientTimeout as exc:
            raise ClientTimeout(f"{exc}{pending.drop_note()}") from None
        return pending.result()

    def call(self, service: str, request: Any, *, decode: Callable[[Any], T] | None = None,
             timeout: float = 120.0, resend: bool | None = None, lost_grace: float = LOST_GRACE) -> CallResult[T]:
        """Call ``service`` and wait for the answer (``timeout`` for discovery and again for the answer);
        ``decode`` makes the payload of a DONE answer (default: the raw response); ``resend`` and
        ``lost_grace`` as :meth:`call_async`."""
        pending = self.call_async(service, request, decode=decode, timeout=timeout, resend=resend,
                                  lost_grace=lost_grace)
        return self.wait(pending, timeout=timeout)

    def generate_world(self, condition: str = "", seed: int = 0, *, timeout: float = 120.0) -> CallResult[str]:
        """``/world/generate``: a new Lavaland world (docs/spec.md section 5); the value is the node's
        description of it. The maps follow on the latched topics (:meth:`world`)."""
        from ird_msgs.srv import GenerateWorld

        request = GenerateWorld.Request(condition=condition, seed=int(seed))
        return self.call(names.SRV_GENERATE, request, decode=lambda r: str(r.message), timeout=timeout)

    def infer_async(self, request: "InferReward.Request", *, timeout: float = 60.0) -> PendingCall[conv.PosteriorData]:
        """``/ird/infer`` without waiting for the answer (bursts)."""
        return self.call_async(names.SRV_INFER, request, decode=_decode_posterior, timeout=timeout)

    def infer(self, request: "InferReward.Request", *, timeout: float = 300.0) -> CallResult[conv.PosteriorData]:
        """``/ird/infer``: the IRD posterior (docs/spec.md section 3), samples as (K, d) numpy; the
        observation model is the request's (``infer_request(..., proxy_counts=,
        designer_temperature=)``) and the posterior says which it used (``proxy_counts``,
        ``designer_temperature``)."""
        return self.call(names.SRV_INFER, request, decode=_decode_posterior, timeout=timeout)

    def plan_async(self, request: "PlanPath.Request", *, timeout: float = 60.0) -> PendingCall[Plan]:
        """``/ird/plan`` without waiting for the answer."""
        return self.call_async(names.SRV_PLAN, request, decode=_decode_plan, timeout=timeout)

    def plan(self, request: "PlanPath.Request", *, timeout: float = 300.0) -> CallResult[Plan]:
        """``/ird/plan``: a literal or risk-averse path (docs/spec.md section 4); Rob drives it. The
        risk measure is the request's (``plan_request(..., risk=, risk_level=)``); the raw
        response (``result.response.risk`` / ``risk_level``) says which the plan used."""
        return self.call(names.SRV_PLAN, request, decode=_decode_plan, timeout=timeout)

    def propose_query(self, request: "ProposeQuery.Request", *, kind: str | None = None,
                      timeout: float = 300.0) -> CallResult[Query]:
        """``/ird/query``: a question to the designer (docs/spec.md section 7). ``kind`` (when given)
        sets ``request.kind``: "paths" (the options are read as cells on the request's map, or, an
        empty map, on the latest ``/world/test_features``) or "proxies" (each offered proxy's plan,
        read on the latest ``/world/train_features``; the weights are ``result.response.option_proxies``)."""
        if kind is not None:
            request.kind = str(kind)
        proxies = request.kind == "proxies"
        topic = names.TOPIC_TRAIN_FEATURES if proxies else names.TOPIC_TEST_FEATURES
        if proxies or not request.map.layers:
            self.subscribe(topic)

        def decode(response: Any) -> Query:
            grid = request.map if request.map.layers and not proxies else self.latest(topic, timeout=timeout)
            return self._decode_query(response, grid)

        return self.call(names.SRV_QUERY, request, decode=decode, timeout=timeout)

    @staticmethod
    def _decode_query(response: Any, grid_msg: Any) -> Query:
        info = grid_msg.info
        origin = (float(info.origin.position.x), float(info.origin.position.y))
        options = tuple(np.array(conv.path_to_cells(p, resolution=float(info.resolution), origin=origin),
                                 dtype=np.int64) for p in response.options)
        names_ = tuple(response.feature_names)
        features = np.asarray(response.option_features, dtype=np.float64).reshape(len(options), len(names_))
        return Query(int(response.query_id), options, names_, features, float(response.information_gain))

    def answer_async(self, query_id: int, chosen: int, *, beta: float = 0.0, answered_by: str = "client",
                     timeout: float = 60.0) -> PendingCall[conv.PosteriorData]:
        """``/ird/answer`` without waiting for the answer."""
        from ird_msgs.srv import AnswerQuery

        request = AnswerQuery.Request(query_id=int(query_id), chosen=int(chosen), beta=float(beta),
                                      answered_by=answered_by)
        return self.call_async(names.SRV_ANSWER, request, decode=_decode_posterior, timeout=timeout)

    def answer(self, query_id: int, chosen: int, *, beta: float = 0.0, answered_by: str = "client",
               timeout: float = 300.0) -> CallResult[conv.PosteriorData]:
        """``/ird/answer``: option ``chosen`` of query ``query_id``; the value is the re-sampled
        posterior given every answer so far (docs/spec.md section 7). ``beta`` 0 = the node's."""
        pending = self.answer_async(query_id, chosen, beta=beta, answered_by=answered_by, timeout=timeout)
        return self.wait(pending, timeout=timeout)

    # ------------------------------------------------------------------ Rob and the designer

    def watch_rob(self, *, timeout: float = 60.0) -> None:
        """Collect ``/rob/status`` from now on and wait until Rob's publisher is matched (the
        stream is volatile: statuses published before the match are lost)."""
        self.subscribe(names.TOPIC_ROB_STATUS)
        subscription = self._subscriptions[names.TOPIC_ROB_STATUS]
        self._discover(lambda: subscription.get_publisher_count() >= 1,
                       lambda: f"Rob's {names.TOPIC_ROB_STATUS} publisher", timeout)

    def wait_for_rob(self, plan: Plan, *, timeout: float = 120.0, label: str = "the") -> RobDrive:
        """Wait until Rob reports ``plan`` done; his statuses for it (needs :meth:`watch_rob` first)."""
        if names.TOPIC_ROB_STATUS not in self._subscriptions:
            raise RuntimeError("wait_for_rob: call watch_rob() before asking for the plan")
        statuses = self._received[names.TOPIC_ROB_STATUS]
        key = stamp_key(plan.stamp)

        def finals() -> list[Any]:
            return [s for s in statuses if s.done and stamp_key(s.plan_stamp) == key]

        self.spin_until(lambda: bool(finals()), timeout=timeout, what=f"Rob finishing {label} plan")
        return RobDrive(tuple(s for s in statuses if stamp_key(s.plan_stamp) == key), finals()[-1])

    def wait_for_answer(self, query_id: int, *, timeout: float = 300.0) -> "QueryRecord":
        """The ``answered`` record of query ``query_id`` on ``/ird/queries`` (an ``ird_msgs/QueryRecord``)."""
        records = self.received(names.TOPIC_QUERIES)

        def answered() -> list[Any]:
            return [r for r in records if r.event == "answered" and int(r.query_id) == int(query_id)]

        self.spin_until(lambda: bool(answered()), timeout=timeout, what=f"the answer to query {query_id}")
        return answered()[0]

    def posterior_of(self, record: "QueryRecord", *, timeout: float = 60.0) -> conv.PosteriorData:
        """The posterior published on ``/ird/posterior`` with ``record``'s stamp (the re-sampling of an answer)."""
        posteriors = self.received(names.TOPIC_POSTERIOR)
        key = stamp_key(record.header.stamp)

        def matching() -> list[Any]:
            return [p for p in posteriors if stamp_key(p.header.stamp) == key]

        self.spin_until(lambda: bool(matching()), timeout=timeout,
                        what=f"the posterior of the answer to query {record.query_id}")
        return conv.posterior_from_msg(matching()[0], field=names.TOPIC_POSTERIOR)

    # ------------------------------------------------------------------ navigation (NavigateIrd)

    def navigate_async(self, goal: NavigationGoal, *, on_feedback: Callable[[NavigationFeedback], None] | None = None,
                       timeout: float = 60.0) -> NavigationHandle:
        """Send ``goal`` to ``/ird/navigate`` once its server is discovered (within ``timeout``);
        ``done()``, ``cancel()``, ``result(timeout)`` later (:mod:`ird_ros.client.navigation`)."""
        if self._navigate is None:
            self._navigate = make_action_client(self.node)
        self._discover(self._navigate.server_is_ready, lambda: f"action {names.ACTION_NAVIGATE}", timeout)
        return send_goal(self._navigate, self.spin_until, goal, on_feedback)

    def navigate(self, goal: NavigationGoal, *, on_feedback: Callable[[NavigationFeedback], None] | None = None,
                 timeout: float = 600.0) -> NavigationResult:
        """Run a navigation goal (infer, ask, plan, drive) and return how it ended: SUCCEEDED, CANCELED,
        ABORTED or REJECTED (the field named); :class:`ClientTimeout` after ``timeout`` s."""
        return self.navigate_async(goal, on_feedback=on_feedback).result(timeout)
