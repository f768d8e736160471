"""The navigator node: serves the ``NavigateIrd`` action on ``/ird/navigate`` (like Nav2's bt_navigator).

Run: ``python -m ird_ros.nodes.navigator --ros-args --params-file msgs_config/params/graph.yaml``

A goal runs, in order (feedback ``stage`` names the step):

1. ``inferring``: ``/ird/infer`` with the world's latched ``/world/infer_request`` as the base
   (``method``, ``beta``, ``num_samples``, ``seed`` from the goal; 0 = the navigator's
   ``default_beta`` / ``default_num_samples``); or, with ``method`` "", the latest
   ``/ird/posterior`` (no inference; none received yet: rejected naming ``method``).
2. ``asking`` (``queries`` > 0): ``/ird/query`` (seed = goal seed + i), then the designer's answer
   on ``/ird/queries`` (a designer node must run; none within ``answer_timeout`` s: aborted saying
   so) and the re-sampled posterior of that answer on ``/ird/posterior``. The questions are asked
   before Rob drives, so the one plan he drives uses every answer.
3. ``planning``: ``/ird/plan`` from ``/world/proxy``'s test start and horizon with the goal's
   ``mode``, ``baseline``, ``risk_measure`` (as ``risk``; "" = the planner's default) and
   ``risk_level``, and the posterior's samples as explicit weights (the proxy for ``literal``);
   the planner publishes ``/plan`` and Rob starts driving it.
4. ``driving``: Rob's ``/rob/status`` for that plan's stamp (feedback: his cell and pose,
   ``progress`` = fraction of the plan driven) until ``done``; no status for ``rob_timeout`` s:
   aborted. Rob's first status of a NEWER plan (another client's ``/ird/plan``, or the planner's
   ``replan_on_posterior``, replaced ours on ``/plan``) aborts the goal at once, saying so, with
   the label and stamp of the plan Rob drives now (:class:`ird_ros.jobs.navigation.DriveTracker`).

The result: the driven cells (start first), ``touched_lava`` / ``reached_target`` / ``true_return``
by :func:`ird_ros.jobs.navigation.judge` on ``/world/terrain`` and ``/world/proxy``'s true rewards
(``judged`` false when either is missing), the plan's objective.

Choices (docs/spec.md section 6):

- One goal at a time: a goal that arrives while one is active is REJECTED by the action protocol
  (no pre-emption); the client reports it as rejected because a goal is active.
- A goal with a bad field (:func:`ird_ros.jobs.navigation.check_goal`: ``method`` not a ZMethod
  nor "", ``beta`` / ``num_samples`` out of range, ``mode`` / ``baseline`` unknown, ``risk_measure``
  / ``risk_level`` that the planner would refuse (unknown measure, a level out of its range,
  ``mean_sd`` with ``trajectory``), ``queries`` < 0 or > ``max_queries``, ``label`` longer than
  ``ird_core.checks.MAX_TEXT_LENGTH``) is accepted and finished at once, before any work, with
  result status ``rejected`` and the field in ``field`` (protocol status ABORTED: the protocol's
  rejection carries no reason). So is a goal that a later service would refuse only after the
  inference (:func:`ird_ros.jobs.navigation.check_goal_work`): ``num_samples`` past what the
  planner's ``max_plan_work`` (or, with ``queries``, the inference node's ``max_query_work``)
  allows on the world's test map, or a ``risk_level`` that the planner's default measure refuses.
  The limits are read from the planner's and the inference node's parameter services at the
  goal's start. The action server's callbacks run in ``ird_ros.runtime.guard``'s guard: an unexpected exception rejects the goal (or the cancel) or
  aborts it, and the node keeps serving.
- Cancel: the goal stops waiting; while Rob drives (or once a plan asked for before the cancel is
  out and Rob reported its first cell), ``/rob/stop`` stops him where he is (his last status says
  ``stopped``) and the result is ``canceled`` with the cells driven so far (none before driving).
  A service request the cancel stopped waiting for (``/ird/infer``, ``/ird/query``) cannot be
  withdrawn (ROS services have no cancel) and still occupies the inference node until answered,
  so the navigator keeps at most one request per service outstanding: the next goal's request
  waits for that answer first (or, being the same request, takes that answer as its own). N
  cancelled goals thus hold at most one of the inference node's ``max_pending`` places, not N.
- Bursts: the action's goal, cancel and result services have the deep service QoS on both ends
  (``ird_ros.runtime.guard.action_qos``); a goal while one is active and any cancel are answered at
  once, so every request of a burst is answered.

The goal is a coroutine on the node's single-threaded executor (``run_node``): every service
call and wait is awaited, never blocking, so subscriptions, cancel requests and parameter services
keep being served; the action server and the clients are in one reentrant callback group.

Longer than 450 lines: one goal's whole life (pre-flight limits, inference, questions, plan,
drive, cancel, the outstanding requests a cancel leaves) runs in this node's callbacks; the
decisions that need no ROS are in ``ird_ros.jobs.navigation``.
"""

from __future__ import annotations

import copy
import math
from collections import deque
from typing import Any

from rcl_interfaces.srv import GetParameters
from rclpy.action import CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.parameter import parameter_value_to_python
from rclpy.task import Future
from std_srvs.srv import Trigger

from ird_core.planning.risk_measures import MIN_RISK
from ird_msgs.action import NavigateIrd
from ird_msgs.msg import ProxyReward, QueryRecord, RewardPosterior, RobStatus, TerrainGrid
from ird_msgs.srv import InferReward, PlanPath, ProposeQuery
from ird_ros import conversions as conv
from ird_ros.graph import names
from ird_ros.jobs.navigation import (
    CheckedGoal,
    DownstreamLimits,
    DriveTracker,
    GoalLimits,
    NavigationStatus,
    Stage,
    check_goal,
    check_goal_work,
    judge,
    posterior_summary,
)
from ird_ros.jobs.planning import request_risk
from ird_ros.runtime.guard import MAX_MESSAGE, guarded_action_server
from ird_ros.runtime.node_main import exit_process, run_node
from ird_ros.runtime.lifecycle import ManagedNode
from ird_ros.runtime.node_params import Param, runtime_except
from ird_ros.runtime.offload import service_qos
from ird_ros.stamps import stamp_key

__all__ = ["NavigatorNode", "PARAMETERS", "main"]

PARAMETERS: dict[str, Param] = {
    "default_beta": Param(5.0, "Designer rationality of a goal with beta 0", min_value=0.001, max_value=1000.0),
    "default_num_samples": Param(40, "Posterior samples of a goal with num_samples 0", min_value=1),
    "max_num_samples": Param(100000, "Largest num_samples a goal may ask for", min_value=1),
    "max_queries": Param(5, "Largest number of designer questions a goal may ask for", min_value=0,
                         max_value=1000),
    "answer_timeout": Param(120.0, "Seconds to wait for the designer's answer to a question (a designer node "
                                   "must run); past it the goal is aborted", min_value=0.1),
    "service_timeout": Param(10.0, "Seconds to wait for a service (/ird/infer, /ird/query, /ird/plan, /rob/stop) "
                                   "to be discovered, and for a latched input", min_value=0.1),
    "call_timeout": Param(600.0, "Seconds to wait for the answer of /ird/infer, /ird/query or /ird/plan",
                          min_value=0.1),
    "rob_timeout": Param(30.0, "Seconds without a status from Rob while he drives the plan after which the "
                               "goal is aborted", min_value=0.1),
}
PARAMETERS = runtime_except(PARAMETERS, ())  # all of them: each goal reads them when it starts

_STATUS_BUFFER = 1000  # recent /rob/status messages kept: Rob may report before /ird/plan answers

#: The parameter services the navigator reads the downstream limits from (relative names: the
#: nodes share the navigator's namespace).
_PLANNER_PARAMETERS = f"{names.NODE_PLANNER}/get_parameters"
_INFERENCE_PARAMETERS = f"{names.NODE_INFERENCE}/get_parameters"
_GOAL_FIELDS = frozenset(NavigateIrd.Goal.get_fields_and_field_types())


class _Stop(Exception):
    """Ends a goal early: the result status and message (and the field of a rejection)."""

    def __init__(self, status: NavigationStatus, message: str, field: str = "") -> None:
        if len(message) > MAX_MESSAGE:  # a goal may echo a huge field back
            message = f"{message[:MAX_MESSAGE]}... ({len(message)} characters)"
        super().__init__(message)
        self.status, self.message, self.field = status, message, field[:MAX_MESSAGE]


class NavigatorNode(ManagedNode):
    """The navigator (managed): accepts goals only while active (deactivating cancels the running
    goal); its limits and timeouts may change at run time (the next goal uses them)."""

    PARAMETERS = PARAMETERS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_NAVIGATOR, **kwargs)

    def apply_parameters(self, p: dict[str, Any], changed: set[str]) -> None:
        self.limits = GoalLimits(max_queries=p["max_queries"], max_num_samples=p["max_num_samples"],
                                 default_beta=p["default_beta"], default_num_samples=p["default_num_samples"])
        self.answer_timeout, self.service_timeout = p["answer_timeout"], p["service_timeout"]
        self.call_timeout, self.rob_timeout = p["call_timeout"], p["rob_timeout"]

    def configure(self, p: dict[str, Any]) -> None:
        self.apply_parameters(p, set(p))
        self.infer_request: InferReward.Request | None = None
        self.proxy: ProxyReward | None = None
        self.terrain: conv.TerrainGridData | None = None
        self.posteriors: deque[RewardPosterior] = deque(maxlen=32)
        self.answers: dict[int, QueryRecord] = {}
        self._statuses: deque[RobStatus] = deque(maxlen=_STATUS_BUFFER)
        self._busy = False
        self._cancel = False  # the active goal's cancel was requested (and not yet handled)
        self._events: list[Future] = []  # woken by every input and by a cancel request
        self._tracker: DriveTracker | None = None
        self._in_flight: tuple[str, Any] | None = None  # the latest service call: (service, future)
        # per service, the (request, future) of a call a cancel stopped waiting for, until answered
        self._orphans: dict[str, tuple[Any, Any]] = {}
        self._goal_handle: Any = None
        self._summary = ""
        latched = names.latched_qos()
        self.create_subscription(InferReward.Request, names.TOPIC_INFER_REQUEST, self._on_infer_request, latched)
        self.create_subscription(ProxyReward, names.TOPIC_PROXY, self._on_proxy, latched)
        self.create_subscription(TerrainGrid, names.TOPIC_TERRAIN, self._on_terrain, latched)
        self.create_subscription(RewardPosterior, names.TOPIC_POSTERIOR, self._on_posterior, latched)
        self.create_subscription(QueryRecord, names.TOPIC_QUERIES, self._on_query_record, names.history_qos())
        self._status_sub = self.create_subscription(RobStatus, names.TOPIC_ROB_STATUS, self._on_status,
                                                    names.stream_qos(100))
        group = ReentrantCallbackGroup()
        self._service_clients = {service: self.create_client(srv, service, qos_profile=service_qos(), callback_group=group)
                         for service, srv in ((names.SRV_INFER, InferReward), (names.SRV_QUERY, ProposeQuery),
                                              (names.SRV_PLAN, PlanPath), (names.SRV_ROB_STOP, Trigger),
                                              (_PLANNER_PARAMETERS, GetParameters),
                                              (_INFERENCE_PARAMETERS, GetParameters))}
        self._server = guarded_action_server(self, NavigateIrd, names.ACTION_NAVIGATE, execute_callback=self._execute,
                                             goal_callback=self._on_goal, cancel_callback=self._on_cancel,
                                             callback_group=group)

    def deactivate(self) -> None:
        if self._busy:  # the running goal ends as if cancelled (Rob stops)
            self._cancel = True
            self._wake()

    # ------------------------------------------------------------------ inputs

    def _wake(self) -> None:
        events, self._events = self._events, []
        for event in events:
            if not event.done():
                event.set_result(True)

    def _on_infer_request(self, msg: InferReward.Request) -> None:
        self.infer_request = msg
        self._wake()

    def _on_proxy(self, msg: ProxyReward) -> None:
        self.proxy = msg
        self._wake()

    def _on_terrain(self, msg: TerrainGrid) -> None:
        try:
            self.terrain = conv.terrain_grid_from_msg(msg, field=names.TOPIC_TERRAIN)
        except ValueError as exc:
            self.get_logger().error(f"ignoring bad terrain: {exc}")
        self._wake()

    def _on_posterior(self, msg: RewardPosterior) -> None:
        self.posteriors.append(msg)
        self._wake()

    def _on_query_record(self, msg: QueryRecord) -> None:
        if msg.event == "answered":
            self.answers[int(msg.query_id)] = msg
            self._wake()

    def _on_status(self, msg: RobStatus) -> None:
        self._statuses.append(msg)
        if self._feed(msg):
            self._wake()

    def _feed(self, msg: RobStatus) -> bool:
        tracker = self._tracker
        if tracker is not None and tracker.other_plan(stamp_key(msg.plan_stamp), msg.plan_label):
            return True  # a newer plan replaced ours: the drive loop ends at once
        if tracker is None or not tracker.feed(stamp_key(msg.plan_stamp), msg.step, msg.row, msg.col, msg.done,
                                               msg.stopped, msg):
            return False
        self._feedback(Stage.DRIVING, tracker)
        return True

    # ------------------------------------------------------------------ waiting

    async def _wait(self, condition: Any, timeout: float) -> bool:
        """Await until ``condition()`` (re-checked on every input) or the goal's cancel request:
        True if ``condition()`` holds; ``_Stop(CANCELED)`` on cancel; False after ``timeout`` s."""
        expired = [False]

        def expire() -> None:
            expired[0] = True
            self._wake()

        timer = None
        try:
            while True:
                if self._cancel:
                    raise _Stop(NavigationStatus.CANCELED, "canceled")
                if condition():
                    return True
                if expired[0]:
                    return False
                event = Future()
                self._events.append(event)
                if timer is None:
                    timer = self.create_timer(timeout, expire)
                await event
        finally:
            if timer is not None:
                self.destroy_timer(timer)

    async def _call(self, service: str, request: Any) -> Any:
        """The response of ``service`` (``_Stop(ABORTED)`` if undiscovered, unanswered or failed)."""
        client = self._service_clients[service]
        if not await self._wait(client.service_is_ready, self.service_timeout):
            raise _Stop(NavigationStatus.ABORTED, f"{service}: not available within {self.service_timeout:g} s "
                                                  f"(is its node running?)")
        future = await self._settle_orphan(service, request)
        if future is None:
            future = client.call_async(request)
            future.add_done_callback(lambda _f: self._wake())
        self._in_flight = (service, future)
        try:
            answered = await self._wait(future.done, self.call_timeout)
        except _Stop:  # canceled: the request stays with its server until answered (module doc)
            if not future.done():
                self._orphans[service] = (request, future)
            raise
        if not answered:
            client.remove_pending_request(future)  # a late answer is dropped, not kept forever
            raise _Stop(NavigationStatus.ABORTED, f"{service}: no answer within {self.call_timeout:g} s")
        response = future.result()
        if hasattr(response, "success") and not response.success and service != names.SRV_ROB_STOP:
            raise _Stop(NavigationStatus.ABORTED, f"{service} failed: {response.message}")
        return response

    async def _settle_orphan(self, service: str, request: Any) -> Any:
        """Before a request to ``service``: the pending future of a canceled goal's identical request
        (its answer is this request's), else None once a canceled goal's different request to it is
        answered (waited for, up to ``call_timeout``): at most one request per service outstanding."""
        orphan = self._orphans.get(service)
        if orphan is None:
            return None
        old_request, future = orphan
        if future.done():
            del self._orphans[service]
            return None
        if old_request == request:
            del self._orphans[service]
            self.get_logger().info(f"{service}: a canceled goal's identical request is still pending: its "
                                   f"answer is this goal's")
            return future
        self.get_logger().info(f"{service}: waiting for the answer to a canceled goal's request before sending "
                               f"this goal's (one request per service at a time)")
        if not await self._wait(future.done, self.call_timeout):  # a cancel now keeps the orphan
            self._service_clients[service].remove_pending_request(future)
        self._orphans.pop(service, None)
        return None

    async def _remote_parameters(self, service: str, wanted: tuple[str, ...]) -> dict[str, Any]:
        """The values of ``wanted`` parameters from a node's ``get_parameters`` service (None: unset)."""
        response = await self._call(service, GetParameters.Request(names=list(wanted)))
        values = [parameter_value_to_python(v) for v in response.values]
        return dict(zip(wanted, values)) if len(values) == len(wanted) else {}

    @staticmethod
    def _number(value: Any) -> Any:
        return value if isinstance(value, (int, float)) and not isinstance(value, bool) else None

    async def _preflight(self, goal: CheckedGoal, proxy: ProxyReward) -> None:
        """Refuse a goal that the planner or /ird/query would refuse only after the inference
        (:func:`check_goal_work` with their parameters), before any work starts."""
        planner = await self._remote_parameters(_PLANNER_PARAMETERS, ("max_plan_work", "max_horizon", "risk", "risk_level"))
        inference: dict[str, Any] = {}
        num_features = 0
        if goal.queries > 0 and not goal.uses_current_posterior:
            inference = await self._remote_parameters(_INFERENCE_PARAMETERS, ("max_query_work",))
            base = await self._latched("infer_request", names.TOPIC_INFER_REQUEST)
            num_features = len(base.training_map.layers)
        default_risk = None
        try:
            if planner.get("risk") is not None and planner.get("risk_level") is not None:
                default_risk = request_risk(str(planner["risk"]), float(planner["risk_level"]), MIN_RISK)
        except ValueError:  # a planner with such parameters does not start; leave the check to it
            default_risk = None
        if self.terrain is None:  # latched with the proxy; without it the sizes are left to the services
            await self._wait(lambda: self.terrain is not None, self.service_timeout)
        terrain = self.terrain
        sized = terrain is not None
        height, width = terrain.classes.shape[:2] if terrain is not None else (0, 0)
        number = self._number
        limits = DownstreamLimits(
            max_plan_work=number(planner.get("max_plan_work")) if sized else None,
            max_horizon=number(planner.get("max_horizon")), default_risk=default_risk,
            max_query_work=number(inference.get("max_query_work")) if sized else None)
        try:
            check_goal_work(goal, horizon=int(proxy.test_horizon), height=int(height), width=int(width),
                            num_features=num_features, limits=limits)
        except ValueError as exc:
            field = str(exc).split(":", 1)[0]
            if field in _GOAL_FIELDS:
                raise _Stop(NavigationStatus.REJECTED, str(exc), field) from None
            raise _Stop(NavigationStatus.ABORTED, str(exc)) from None

    async def _latched(self, attribute: str, topic: str) -> Any:
        if not await self._wait(lambda: getattr(self, attribute) is not None, self.service_timeout):
            raise _Stop(NavigationStatus.ABORTED, f"{topic}: nothing received within {self.service_timeout:g} s "
                                                  f"(is the world node running?)")
        return getattr(self, attribute)

    # ------------------------------------------------------------------ action callbacks

    def _on_goal(self, _goal: NavigateIrd.Goal) -> GoalResponse:
        if not self.is_active:
            self.get_logger().warning(f"goal rejected: the navigator is {self.lifecycle_state}, not active",
                                      throttle_duration_sec=1.0)
            return GoalResponse.REJECT
        if self._busy:  # answered at once; a burst logs one line a second, not one per goal
            self.get_logger().warning("goal rejected: a goal is active (one goal at a time)", throttle_duration_sec=1.0)
            return GoalResponse.REJECT
        self._busy = True
        return GoalResponse.ACCEPT

    def _on_cancel(self, _goal_handle: Any) -> CancelResponse:
        self.get_logger().info("cancel requested", throttle_duration_sec=1.0)
        self._cancel = True
        self._wake()
        return CancelResponse.ACCEPT

    def _feedback(self, stage: Stage, tracker: DriveTracker | None = None) -> None:
        handle = self._goal_handle
        if handle is None or not handle.is_active:
            return
        msg = NavigateIrd.Feedback(stage=str(stage), posterior_summary=self._summary)
        if tracker is not None and tracker.cell is not None:
            msg.has_pose, (msg.row, msg.col) = True, tracker.cell
            msg.progress = tracker.progress
            msg.pose.header = conv.make_header(conv.now_stamp(self))
            if self.terrain is not None:
                x, y = conv.cell_center(tracker.cell[0], tracker.cell[1], self.terrain.resolution,
                                        self.terrain.origin)
                msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
        handle.publish_feedback(msg)

    async def _execute(self, goal_handle: Any) -> NavigateIrd.Result:
        self._goal_handle, self._tracker, self._summary, self._cancel = goal_handle, None, "", False
        self._in_flight = None
        request = goal_handle.request
        result = NavigateIrd.Result(objective=math.nan, true_return=math.nan)
        try:
            try:
                goal = check_goal(method=request.method, beta=request.beta, num_samples=request.num_samples,
                                  seed=request.seed, mode=request.mode, baseline=request.baseline,
                                  risk_measure=request.risk_measure, risk_level=request.risk_level,
                                  queries=request.queries, label=request.label, limits=self.limits)
            except ValueError as exc:
                raise _Stop(NavigationStatus.REJECTED, str(exc), str(exc).split(":", 1)[0]) from None
            await self._navigate(goal, result)
            result.status, result.message = str(NavigationStatus.SUCCEEDED), "reached the end of the plan"
            goal_handle.succeed()
        except _Stop as stop:
            if stop.status is NavigationStatus.CANCELED:
                await self._stop_rob()
                goal_handle.canceled()
            else:
                goal_handle.abort()
            result.status, result.message, result.field = str(stop.status), stop.message, stop.field
        except Exception as exc:  # noqa: BLE001 - a bug must end the goal, not the node
            self.get_logger().error(f"goal failed: {type(exc).__name__}: {exc}")
            goal_handle.abort()
            result.status, result.message = str(NavigationStatus.ABORTED), f"internal error: {exc}"
        finally:
            self._finish(result)
            self._goal_handle, self._tracker, self._busy, self._cancel = None, None, False, False
        self.get_logger().info(f"goal {result.status}: {result.message}")
        return result

    def _finish(self, result: NavigateIrd.Result) -> None:
        """Fill the driven cells and their judgement from the tracker."""
        tracker = self._tracker
        if tracker is None:
            return
        cells = tracker.cells
        result.rows, result.cols = [r for r, _ in cells], [c for _, c in cells]
        proxy = self.proxy
        if cells and self.terrain is not None and proxy is not None:
            verdict = judge(cells, self.terrain.classes, self.terrain.class_names,
                            dict(zip(proxy.terrain_names, proxy.true_terrain_rewards)))
            result.judged = True
            result.touched_lava, result.reached_target = verdict.touched_lava, verdict.reached_target
            result.true_return = verdict.true_return

    async def _stop_rob(self) -> None:
        """Stop Rob where he is and take his final (stopped) status, if he drives (or is about to
        drive) our plan: a plan asked for before the cancel is published anyway, so its answer is
        awaited; Rob is stopped once he reported the plan's first cell (before that he may not have
        received it, and would drive it after the stop)."""
        self._cancel = False  # the waits below must not end on the cancel request itself
        try:
            if self._tracker is None and self._in_flight is not None and self._in_flight[0] == names.SRV_PLAN:
                future = self._in_flight[1]
                if await self._wait(future.done, self.call_timeout) and future.result().success:
                    self._track(future.result())
            tracker = self._tracker
            if tracker is None or tracker.over:  # finished, stopped, or driving someone else's plan
                return
            await self._wait(lambda: tracker.over or tracker.last_step >= 0, self.rob_timeout)
            if tracker.over:
                return
            response = await self._call(names.SRV_ROB_STOP, Trigger.Request())
            self.get_logger().info(f"Rob: {response.message}")
            await self._wait(lambda: tracker.over, self.service_timeout)
        except _Stop as exc:
            self.get_logger().error(f"could not stop Rob: {exc.message}")

    # ------------------------------------------------------------------ the goal

    async def _navigate(self, goal: CheckedGoal, result: NavigateIrd.Result) -> None:
        proxy = await self._latched("proxy", names.TOPIC_PROXY)
        if goal.uses_current_posterior and not self.posteriors:
            raise self._no_posterior()
        await self._preflight(goal, proxy)
        samples = await self._posterior(goal)
        for i in range(goal.queries):
            samples = await self._ask(goal, proxy, i)
        self._feedback(Stage.PLANNING)
        if self._status_sub.get_publisher_count() == 0:
            raise _Stop(NavigationStatus.ABORTED, f"{names.TOPIC_ROB_STATUS}: Rob is not running")
        request = PlanPath.Request(start_row=proxy.test_start_row, start_col=proxy.test_start_col,
                                   horizon=proxy.test_horizon, mode=str(goal.mode), baseline=str(goal.baseline),
                                   label=goal.label, risk=str(goal.risk_measure or ""), risk_level=goal.risk_level)
        if goal.mode != "literal":
            request.weights = samples
        plan = await self._call(names.SRV_PLAN, request)
        result.objective = float(plan.objective)
        tracker = self._track(plan)
        self._feedback(Stage.DRIVING, tracker)
        while not tracker.over:
            step = tracker.last_step
            if not await self._wait(lambda: tracker.over or tracker.last_step != step, self.rob_timeout):
                raise _Stop(NavigationStatus.ABORTED, f"{names.TOPIC_ROB_STATUS}: no status from Rob for "
                                                      f"{self.rob_timeout:g} s while driving")
        if tracker.replaced_by is not None:
            (sec, nanosec), label = tracker.replaced_by
            driven = f"after {tracker.last_step} of {tracker.horizon} moves" if tracker.last_step >= 0 else \
                "before his first move"
            raise _Stop(NavigationStatus.ABORTED, f"{names.TOPIC_PLAN}: another plan replaced this goal's {driven}: "
                                                  f"Rob now drives plan '{label or '(no label yet)'}' (stamp "
                                                  f"{sec}.{nanosec:09d}), published by another client's "
                                                  f"{names.SRV_PLAN} (or the planner's replan_on_posterior); this "
                                                  f"goal's plan was abandoned")
        if tracker.stopped:
            raise _Stop(NavigationStatus.ABORTED, "Rob was stopped (/rob/stop) before the end of the plan")

    def _track(self, plan: PlanPath.Response) -> DriveTracker:
        """Follow Rob's drive of ``plan`` (the statuses he sent before /ird/plan answered included)."""
        cells = tuple((int(r), int(c)) for r, c in zip(plan.rows, plan.cols))
        tracker = self._tracker = DriveTracker(stamp_key(plan.path.header.stamp), cells)
        for status in list(self._statuses):
            self._feed(status)
        return tracker

    def _summarise(self, msg: RewardPosterior, answers: int = 0) -> list[float]:
        posterior = conv.posterior_from_msg(msg, field=names.TOPIC_POSTERIOR)
        self._summary = posterior_summary(str(posterior.method), len(posterior.samples), posterior.r_hat_max,
                                          posterior.converged, answers)
        return [float(v) for v in posterior.samples.ravel()]

    @staticmethod
    def _no_posterior() -> _Stop:
        return _Stop(NavigationStatus.REJECTED, f"method: '' uses the current posterior, but none was received on "
                                                f"{names.TOPIC_POSTERIOR} (infer first)", "method")

    async def _posterior(self, goal: CheckedGoal) -> list[float]:
        """Step 1: the posterior's samples (K*d values), inferred or the current one."""
        if goal.uses_current_posterior:
            if not self.posteriors:
                raise self._no_posterior()
            samples = self._summarise(self.posteriors[-1])
            self._feedback(Stage.INFERRING)
            return samples
        self._feedback(Stage.INFERRING)
        request = copy.deepcopy(await self._latched("infer_request", names.TOPIC_INFER_REQUEST))
        request.method, request.beta = str(goal.method), goal.beta
        request.num_samples, request.seed = goal.num_samples, goal.seed
        response = await self._call(names.SRV_INFER, request)
        samples = self._summarise(response.posterior)
        self._feedback(Stage.INFERRING)
        return samples

    async def _ask(self, goal: CheckedGoal, proxy: ProxyReward, i: int) -> list[float]:
        """Step 2, question ``i``: propose, wait for the designer's answer and its posterior."""
        self._feedback(Stage.ASKING)
        request = ProposeQuery.Request(start_row=proxy.test_start_row, start_col=proxy.test_start_col,
                                       seed=(goal.seed + i) % 2**32)
        query_id = int((await self._call(names.SRV_QUERY, request)).query_id)
        if not await self._wait(lambda: query_id in self.answers, self.answer_timeout):
            raise _Stop(NavigationStatus.ABORTED, f"queries: no answer to question {i + 1} (query {query_id}) "
                                                  f"within answer_timeout={self.answer_timeout:g} s; is a designer "
                                                  f"node running (launch_graph.py --nodes ...,designer)?")
        key = stamp_key(self.answers[query_id].header.stamp)

        def matching() -> list[RewardPosterior]:
            return [p for p in self.posteriors if stamp_key(p.header.stamp) == key]

        if not await self._wait(lambda: bool(matching()), self.service_timeout):
            raise _Stop(NavigationStatus.ABORTED, f"{names.TOPIC_POSTERIOR}: the posterior of the answer to query "
                                                  f"{query_id} did not arrive")
        samples = self._summarise(matching()[-1], i + 1)
        self._feedback(Stage.ASKING)
        return samples


def main(args: list[str] | None = None) -> int:
    return run_node(NavigatorNode, args)


if __name__ == "__main__":
    exit_process(main())
