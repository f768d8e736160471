"""The designer node: answers the robot's questions (``/ird/queries`` -> ``/ird/answer``).

Run: ``python -m ird_ros.nodes.designer --ros-args --params-file msgs_config/params/graph.yaml
[-p mode:=web]``; off by default in the launcher (``scripts/launch_graph.py --nodes ...,designer``).

It reads the latched history of ``/ird/queries`` (``names.history_qos()``), so a respawned
designer sees every recent proposal and answers those still open; an answer it already sent
and that is still being re-sampled is not sent twice (an answer from a previous life of the
node is refused by the inference node as "already answered" or "busy" and changes nothing).
Records stamped before the current ``/world/terrain`` belong to a forgotten world and are ignored
(the inference node forgets the evidence with the world).

Two kinds of question (``QueryRecord.kind``): "paths" (options are paths on the test map) and
"proxies" (Active IRD: options are proxy rewards the designer might have written, each shown as
its plan on the TRAINING map). The training map's terrain is not published as such: the node
reads ``/world/train_features`` and ``/world/test_features`` and takes each training cell's
terrain from the test map's feature vectors, or from the Gaussian world's instance made again
(:func:`ird_ros.web.terrain_view.training_classes`); it waits for the training map of the current
generation (same stamp as ``/world/terrain``) before it shows or answers a proxies query.

- ``mode: simulated``: each open query is answered with ``ird_core.designer.queries.SimulatedDesigner
  (beta, seed)`` on the options' TRUE returns (:func:`ird_ros.bags.rounds.option_returns`: the
  ground-truth terrain of ``/world/terrain``, for "proxies" the training map's terrain as
  ``ird_core.designer.proxy_queries.simulated_proxy_answer`` does; the true rewards of ``/world/proxy``),
  ``answered_by: "simulated"``. A ``busy`` refusal is retried after ``retry_period``; any other
  refusal (a forgotten world's query) is final.
- ``mode: web``: ``ird_ros.web.server.WebDesigner`` serves a page on ``host:port`` in its own
  thread; the node forwards proposals, answers, the world, the posterior/risk map and the risk
  measure of the current plan (the latest ``/ird/plan_info`` of this world) to it and
  its clicks come back through ``on_answer(query_id, chosen)``, which calls ``/ird/answer``
  (``answered_by: "web"``) with ``Client.call`` from the web server's thread (the executor keeps
  spinning in the main thread and completes the call). Contract: the dicts of
  :mod:`ird_ros.bags.rounds` (``record_dict``) and :func:`world_dict`, :func:`posterior_dict`,
  :func:`risk_dict` and :func:`plan_dict` here. In a Gaussian-feature world (latent conditions)
  the posterior is shown per terrain, not per observation dimension (:mod:`ird_ros.web.terrain_view`:
  the world's instance is made again from ``/world/proxy`` and ``/world/terrain``). A proxies
  query is drawn on the training map (:func:`world_dict` of it, ``show_train_world``), each option
  with its proxy's weights (``proxy_feature_names``: ``/world/proxy``'s feature names). The page
  names options by letters (so does this node's log, in both modes) and never shows sampler
  statistics after an answer (they are logged); it shows how each drive ended (Rob's final
  ``/rob/status``: plan, lava, target, true return, stopped early; and the navigator's last goal
  status from ``/ird/navigate``'s action status: succeeded, aborted or canceled,
  :func:`mission_dict`); at most ``max_pages`` pages are open at once (one more is refused with a
  message naming the limit); when the node shuts down the page is told the graph stopped.

The node never blocks an executor callback: simulated answers are ``call_async`` with a done
callback. Every callback runs in ``ird_ros.runtime.guard``'s guard: whatever a message raises is
logged, never the end of the node.

Longer than 450 lines: the two modes share every subscription and the decoding of the current
world's records; the page's dicts (``*_dict``) are short functions kept beside the node that fills them.
"""

from __future__ import annotations

import time
from enum import StrEnum
from typing import Any

import numpy as np
from action_msgs.msg import GoalStatus, GoalStatusArray
from nav_msgs.msg import OccupancyGrid

from ird_core.designer.queries import SimulatedDesigner
from ird_core.vocabulary import QueryEvent, QueryKind, values
from ird_msgs.msg import FeatureGrid, PlanInfo, ProxyReward, QueryRecord, RewardPosterior, RobStatus, TerrainGrid
from ird_msgs.srv import AnswerQuery
from ird_ros import conversions as conv
from ird_ros.bags import rounds as qr
from ird_ros.graph import names
from ird_ros.jobs.planning import risk_text
from ird_ros.runtime.node_main import exit_process, run_node
from ird_ros.runtime.lifecycle import ManagedNode
from ird_ros.runtime.node_params import Param, runtime_except
from ird_ros.runtime.offload import BUSY_PREFIX, service_qos
from ird_ros.stamps import stamp_ns, stamp_seconds
from ird_ros.web import terrain_view
from ird_ros.web.page_state import option_letter

__all__ = ["DesignerNode", "DesignerMode", "PARAMETERS", "MODES", "world_dict", "posterior_dict", "risk_dict",
           "plan_dict", "mission_dict", "GOAL_OUTCOMES", "main"]

class DesignerMode(StrEnum):
    """Who answers: the node itself on the true returns, or a person on the web page."""

    SIMULATED = "simulated"
    WEB = "web"


MODES: tuple[str, ...] = values(DesignerMode)

PARAMETERS: dict[str, Param] = {
    "mode": Param(DesignerMode.SIMULATED.value, "simulated: answer every open query itself; web: a person answers on a page",
                  choices=MODES),
    "beta": Param(1.0, "Simulated designer's rationality (Boltzmann beta on the options' true returns)",
                  min_value=0.0),
    "seed": Param(0, "Seed of the simulated designer's choices", min_value=0, max_value=2**32 - 1),
    "host": Param("127.0.0.1", "Web page address (loopback by default)"),
    "port": Param(8765, "Web page port (0 = any free port)", min_value=0, max_value=65535),
    "answer_timeout": Param(120.0, "Seconds an answer may take (re-sampling) before it is given up",
                            min_value=0.1),
    "retry_period": Param(1.0, "Seconds before a simulated answer refused as busy is sent again", min_value=0.01),
    "max_pages": Param(16, "Web pages open at once (WebSockets); one more is refused with a message naming the limit",
                       min_value=1, max_value=1024),
}
PARAMETERS = runtime_except(PARAMETERS, ("mode", "seed", "host", "port", "max_pages"))  # the page's are read-only

#: The navigator's terminal goal states (``action_msgs/GoalStatus``), as the page says them.
GOAL_OUTCOMES = {GoalStatus.STATUS_SUCCEEDED: "succeeded", GoalStatus.STATUS_ABORTED: "aborted",
                 GoalStatus.STATUS_CANCELED: "canceled"}


HISTORY_SETTLE = 0.2
"""Seconds without a new /ird/queries record before open proposals are answered."""


def world_dict(terrain: conv.TerrainGridData, start: tuple[int, int] | None, stamp: float) -> dict[str, Any]:
    """The page's map: ``classes[row][col]`` (row 0 = bottom, 255 unknown), class names, the start
    (Rob's on the test map; the training start on the training map)."""
    h, w = terrain.classes.shape
    return {"height": h, "width": w, "class_names": list(terrain.class_names),
            "classes": terrain.classes.astype(int).tolist(), "start": None if start is None else list(start),
            "stamp": stamp}


def proxy_names(names: Any, p: int) -> list[str]:
    """The p proxy features' names (``/world/proxy``'s when there are p of them, else w1..wp)."""
    names = [str(n) for n in (names or ())]
    return names if len(names) == p else [f"w{i + 1}" for i in range(p)]


def posterior_dict(post: conv.PosteriorData, num_answers: int, stamp: float, *, instance: Any = None,
                   observations: bool = False) -> dict[str, Any]:
    """The page's posterior summary: per-feature mean and standard deviation of the samples; per
    terrain with ``instance`` (a Gaussian world's, :func:`ird_ros.web.terrain_view.terrain_posterior`),
    or per observation dimension said as such with ``observations``."""
    out = {"feature_names": list(post.feature_names), "mean": post.samples.mean(axis=0).tolist(),
           "std": post.samples.std(axis=0).tolist(), "num_samples": int(post.samples.shape[0]),
           "num_answers": int(num_answers), "method": post.method, "converged": bool(post.converged),
           "r_hat_max": float(post.r_hat_max) if np.isfinite(post.r_hat_max) else None, "stamp": stamp}
    if instance is not None:
        out.update(terrain_view.terrain_posterior(post.samples, instance))
    elif observations:
        out.update(terrain_view.observation_note(post.feature_names))
    return out


def risk_dict(costs: np.ndarray, stamp: float, plan: dict[str, Any] | None = None) -> dict[str, Any]:
    """The page's risk map: ``values[row][col]`` in 0..100 (-1 unknown) and ``plan``, what the
    current plan maximised (:func:`plan_dict`, ``None``: no plan of this world yet). The map is the
    samples' reward spread whatever the plan's measure."""
    h, w = costs.shape
    return {"height": h, "width": w, "values": costs.astype(int).tolist(), "stamp": stamp, "plan": plan}


def plan_dict(info: PlanInfo) -> dict[str, Any]:
    """The page's plan line: label, mode, baseline, risk measure and level, and ``text``, e.g.
    ``"per-step CVaR alpha=0.25"`` (:func:`ird_ros.jobs.planning.risk_text`)."""
    level = float(info.risk_level)
    return {"label": info.label, "mode": info.mode, "baseline": info.baseline, "risk": info.risk,
            "risk_level": level if np.isfinite(level) else None,
            "text": risk_text(info.mode, info.risk, level), "stamp": stamp_seconds(info.header.stamp)}


def mission_dict(rob: RobStatus | None, goal: str | None) -> dict[str, Any] | None:
    """The page's line on how the mission ended: Rob's final status (``rob``: plan label, cell, step
    and horizon, lava, target, true return, stopped early) and the navigator's last goal outcome
    (``goal``: "succeeded", "aborted", "canceled"), with ``text`` saying both; None if neither is known."""
    if rob is None and goal is None:
        return None
    parts, out = [], {"goal": goal, "rob": None}
    if rob is not None:
        out["rob"] = {"plan_label": rob.plan_label, "row": int(rob.row), "col": int(rob.col), "step": int(rob.step),
                      "horizon": int(rob.horizon), "touched_lava": bool(rob.touched_lava),
                      "reached_target": bool(rob.reached_target), "true_return": float(rob.true_return),
                      "stopped": bool(rob.stopped), "stamp": stamp_seconds(rob.header.stamp)}
        plan = rob.plan_label or "unlabelled"
        how = (f"stopped plan {plan} at step {rob.step} of {rob.horizon}" if rob.stopped
               else f"finished plan {plan} ({rob.step} steps)")
        parts.append(f"Rob {how}: {'touched lava' if rob.touched_lava else 'no lava'}, "
                     f"{'reached a target' if rob.reached_target else 'no target'}, true return {rob.true_return:.2f}")
    if goal is not None:
        parts.append(f"the navigator's last goal {goal}")
    out["text"] = "; ".join(parts) + "."
    out["text"] = out["text"][0].upper() + out["text"][1:]
    return out


class DesignerNode(ManagedNode):
    """The designer (managed): its web page runs from configure to cleanup; questions are answered
    (simulated or from the page) only while active; ``beta``, ``answer_timeout`` and
    ``retry_period`` may change at run time."""

    PARAMETERS = PARAMETERS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_DESIGNER, **kwargs)

    def apply_parameters(self, p: dict[str, Any], changed: set[str]) -> None:
        self.answer_timeout, self.retry_period = float(p["answer_timeout"]), float(p["retry_period"])
        self.designer.beta = float(p["beta"])
        if "retry_period" in changed:
            self._retry_timer.timer_period_ns = int(self.retry_period * 1e9)

    def configure(self, p: dict[str, Any]) -> None:
        self.mode = DesignerMode(p["mode"])
        self.answer_timeout, self.retry_period = float(p["answer_timeout"]), float(p["retry_period"])
        self.designer = SimulatedDesigner(float(p["beta"]), int(p["seed"]))
        self.records: list[QueryRecord] = []  # every /ird/queries message, in arrival order
        self._events_key: tuple[int, int] | None = None
        self._events: list[qr.QueryRecordData] = []
        self.terrain: conv.TerrainGridData | None = None
        self.terrain_ns = 0  # header stamp (ns) of the world's terrain
        self.grids: dict[str, tuple[int, conv.FeatureGridData]] = {}  # train / test features: (stamp ns, grid)
        self._train_key: tuple[Any, ...] | None = None
        self._train_classes: np.ndarray | None = None
        self.proxy: ProxyReward | None = None
        self.posterior: RewardPosterior | None = None
        self.risk: OccupancyGrid | None = None
        self.plan_info: PlanInfo | None = None
        self.rob_final: RobStatus | None = None  # Rob's last status with done: true
        self.goal_outcome: str | None = None  # the navigator's last terminal goal status
        self._goal_seen: set[bytes] = set()  # goals whose terminal status was shown
        self._instance_key: tuple[Any, ...] | None = None  # what the Gaussian world's instance was made of
        self._instance: Any = None
        self._in_flight: set[tuple[int, int]] = set()  # (query_id, proposal stamp) being answered
        self._done: set[tuple[int, int]] = set()  # answered by us, or refused for good
        self._shown: set[tuple[int, str, int]] = set()  # (query id, event, stamp) forwarded to the page
        self._client = self.create_client(AnswerQuery, names.SRV_ANSWER, qos_profile=service_qos())
        self.web: Any = None
        if self.mode is DesignerMode.WEB:
            from ird_ros.web.server import WebDesigner  # only the web mode needs the HTTP stack

            self.web = WebDesigner(p["host"], int(p["port"]), self._web_answer, logger=self.get_logger(),
                                   max_sockets=int(p["max_pages"]))
            self.web.start()
            self.get_logger().info(f"designer web page at {self.web.url}")
        latched = names.latched_qos()
        self.create_subscription(QueryRecord, names.TOPIC_QUERIES, self._on_record, names.history_qos())
        self.create_subscription(TerrainGrid, names.TOPIC_TERRAIN, self._on_terrain, latched)
        self.create_subscription(ProxyReward, names.TOPIC_PROXY, self._on_proxy, latched)
        for topic in (names.TOPIC_TRAIN_FEATURES, names.TOPIC_TEST_FEATURES):
            self.create_subscription(FeatureGrid, topic, lambda msg, t=topic: self._on_grid(t, msg), latched)
        self.create_subscription(RewardPosterior, names.TOPIC_POSTERIOR, self._on_posterior, latched)
        self.create_subscription(OccupancyGrid, names.TOPIC_RISK_MAP, self._on_risk, latched)
        self.create_subscription(PlanInfo, names.TOPIC_PLAN_INFO, self._on_plan_info, latched)
        if self.web is not None:  # how each drive ended, for the page
            self.create_subscription(RobStatus, names.TOPIC_ROB_STATUS, self._on_rob_status, names.stream_qos())
            from rclpy.qos import qos_profile_action_status_default

            self.create_subscription(GoalStatusArray, f"{names.ACTION_NAVIGATE}/_action/status", self._on_goal_status,
                                     qos_profile_action_status_default)
        self._retry_timer = self.create_timer(self.retry_period, self._update)
        # A (re)started designer receives the whole latched history as one burst: a proposal is
        # judged open only once the burst is in (no record for HISTORY_SETTLE seconds), or an
        # answer recorded right after it would not be seen yet and the query answered again.
        self._last_record = time.monotonic()
        self._settle_timer = self.create_timer(HISTORY_SETTLE, self._update)

    def release(self) -> None:
        if getattr(self, "web", None) is not None:
            self.web.stop("graph stopped: the designer node shut down")
            self.web = None

    # ------------------------------------------------------------------ inputs

    def _on_record(self, msg: QueryRecord) -> None:
        self.records.append(msg)
        self._last_record = time.monotonic()
        self._update()

    def _on_terrain(self, msg: TerrainGrid) -> None:
        try:
            self.terrain = conv.terrain_grid_from_msg(msg, field=names.TOPIC_TERRAIN)
        except ValueError as exc:
            self.get_logger().error(f"ignoring a bad terrain: {exc}")
            return
        self.terrain_ns = stamp_ns(msg.header.stamp)
        self._show_world()
        self._update()

    def _on_grid(self, topic: str, msg: FeatureGrid) -> None:
        try:
            self.grids[topic] = (stamp_ns(msg.header.stamp), conv.feature_grid_from_msg(msg, field=topic))
        except ValueError as exc:
            self.get_logger().error(f"ignoring a bad feature map: {exc}")
            return
        self._show_world()
        self._update()

    def train_map(self) -> tuple[conv.FeatureGridData, np.ndarray] | None:
        """The current world's training map and its classes (:func:`terrain_view.training_classes`),
        or None until both feature maps of the terrain's generation are in."""
        train, test = self.grids.get(names.TOPIC_TRAIN_FEATURES), self.grids.get(names.TOPIC_TEST_FEATURES)
        if self.terrain is None or train is None or test is None or not train[0] == test[0] == self.terrain_ns:
            return None
        instance = None
        if self.proxy is not None and self.proxy.condition in terrain_view.GAUSSIAN_CONDITIONS:
            instance = self._gaussian_instance(train[1].layers)
        key = (self.terrain_ns, instance is not None)
        if key != self._train_key:
            self._train_key = key
            self._train_classes = terrain_view.training_classes(train[1].features, test[1].features,
                                                                self.terrain.classes, instance)
        assert self._train_classes is not None
        return train[1], self._train_classes

    def _on_proxy(self, msg: ProxyReward) -> None:
        self.proxy = msg
        self._show_world()
        self._show_posterior()  # a Gaussian world's terrain rows need the proxy's condition and seed
        self._update()

    def _on_posterior(self, msg: RewardPosterior) -> None:
        self.posterior = msg
        self._show_posterior()

    def _on_risk(self, msg: OccupancyGrid) -> None:
        self.risk = msg
        self._show_posterior()

    def _on_plan_info(self, msg: PlanInfo) -> None:
        self.plan_info = msg
        self._show_posterior()

    def _on_rob_status(self, msg: RobStatus) -> None:
        if msg.done:
            self.rob_final = msg
            self._show_mission()

    def _on_goal_status(self, msg: GoalStatusArray) -> None:
        """The newest goal that reached a terminal state and was not shown yet."""
        ended = [s for s in msg.status_list if s.status in GOAL_OUTCOMES
                 and bytes(s.goal_info.goal_id.uuid) not in self._goal_seen]
        if not ended:
            return
        last = max(ended, key=lambda s: (s.goal_info.stamp.sec, s.goal_info.stamp.nanosec))
        self._goal_seen.update(bytes(s.goal_info.goal_id.uuid) for s in ended)
        self.goal_outcome = GOAL_OUTCOMES[last.status]
        self._show_mission()

    def _show_mission(self) -> None:
        mission = mission_dict(self.rob_final, self.goal_outcome)
        if self.web is not None and mission is not None:
            self.web.show_mission(mission)

    def current_plan(self) -> dict[str, Any] | None:
        """:func:`plan_dict` of the latest plan made in the current world (stamped at or after
        its terrain), else ``None``."""
        info = self.plan_info
        if info is None or self.terrain is None or stamp_ns(info.header.stamp) < self.terrain_ns:
            return None
        return plan_dict(info)

    def events(self) -> list[qr.QueryRecordData]:
        """The decoded records of the current world (needs the terrain's geometry to map poses to
        cells); records stamped before the world's terrain belong to a forgotten world."""
        if self.terrain is None:
            return []
        train = self.train_map()
        key = (len(self.records), self.terrain_ns, train is not None)  # decode on change only
        if self._events_key == key:
            return self._events
        out = []
        for msg in self.records:
            if stamp_ns(msg.header.stamp) < self.terrain_ns:
                continue
            grid: Any = self.terrain
            if msg.kind == QueryKind.PROXIES:  # options are plans on the training map
                if train is None:
                    continue  # decoded once the training map is in
                grid = train[0]
            try:
                out.append(qr.event_from_msg(msg, resolution=grid.resolution, origin=grid.origin,
                                             field=names.TOPIC_QUERIES))
            except ValueError as exc:
                self.get_logger().error(f"ignoring a bad query record: {exc}")
        self._events_key, self._events = key, out
        return out

    def _update(self) -> None:
        if not self.is_active:  # inactive: the page and the questions wait
            return
        events = self.events()
        if self.web is not None:
            new = [ev for ev in events if (ev.query_id, ev.event, ev.stamp_ns) not in self._shown]
            for ev in new:
                shown = qr.record_dict(ev)
                shown["proxy_feature_names"] = proxy_names(None if self.proxy is None else self.proxy.feature_names,
                                                           ev.option_proxies.shape[1])
                (self.web.show_query if ev.event is QueryEvent.PROPOSED else self.web.show_answer)(shown)
                self._shown.add((ev.query_id, ev.event, ev.stamp_ns))
            if any(ev.event is QueryEvent.ANSWERED for ev in new):
                self._show_posterior()  # the posterior may have arrived before its answer's record
        elif self.proxy is not None and time.monotonic() - self._last_record >= HISTORY_SETTLE:
            for proposal in qr.open_queries(events):
                self._answer_simulated(proposal)

    # ------------------------------------------------------------------ simulated mode

    def _answer_simulated(self, proposal: qr.QueryRecordData) -> None:
        key = (proposal.query_id, proposal.stamp_ns)
        if key in self._in_flight or key in self._done or not self._client.service_is_ready():
            return
        assert self.terrain is not None and self.proxy is not None
        classes = self.terrain.classes
        if proposal.kind is QueryKind.PROXIES:  # the true return of each proxy's plan on the TRAINING map
            train = self.train_map()
            if train is None:
                return  # events() decodes a proxies record only with the training map: not reached
            classes = train[1]
        try:
            returns = qr.option_returns(classes, self.terrain.class_names, self.proxy.terrain_names,
                                        self.proxy.true_terrain_rewards, proposal.options)
        except ValueError as exc:
            self.get_logger().error(f"query {proposal.query_id}: cannot judge the options: {exc}")
            self._done.add(key)
            return
        chosen = self.designer.answer(returns)
        request = AnswerQuery.Request(query_id=proposal.query_id, chosen=chosen, beta=0.0,
                                      answered_by=DesignerMode.SIMULATED.value)
        self._in_flight.add(key)
        returns_by_letter = ", ".join(f"{option_letter(k)} {r:.3f}" for k, r in enumerate(returns))
        self.get_logger().info(f"query {proposal.query_id}: {proposal.kind} options, true returns "
                               f"{returns_by_letter}; answering Option {option_letter(chosen)}")
        self._client.call_async(request).add_done_callback(lambda fut, k=key: self._on_answered(k, fut))

    def _on_answered(self, key: tuple[int, int], future: Any) -> None:
        self._in_flight.discard(key)
        response = future.result() if future.exception() is None else None
        if response is None:
            self.get_logger().error(f"query {key[0]}: the answer failed: {future.exception()}")
            return  # retried by the timer
        if response.success:
            self._done.add(key)
        elif response.message.startswith(BUSY_PREFIX):
            self.get_logger().info(f"query {key[0]}: {response.message} (retrying)")
        else:
            self._done.add(key)
            self.get_logger().warning(f"query {key[0]}: answer refused: {response.message}")

    # ------------------------------------------------------------------ web mode

    def _show_world(self) -> None:
        if self.web is None or self.terrain is None:
            return
        start = None if self.proxy is None else (int(self.proxy.test_start_row), int(self.proxy.test_start_col))
        self.web.show_world(world_dict(self.terrain, start, self.terrain_ns / 1e9))
        train = self.train_map()
        if train is not None:
            start = None if self.proxy is None else (int(self.proxy.start_row), int(self.proxy.start_col))
            self.web.show_train_world(world_dict(conv.TerrainGridData(train[1], self.terrain.class_names), start,
                                                 self.terrain_ns / 1e9))

    def _show_posterior(self) -> None:
        if self.web is None or self.posterior is None:
            return
        try:
            post = conv.posterior_from_msg(self.posterior, field=names.TOPIC_POSTERIOR)
            risk = None if self.risk is None else risk_dict(conv.occupancy_grid_from_msg(self.risk),
                                                            stamp_seconds(self.risk.header.stamp), self.current_plan())
        except ValueError as exc:
            self.get_logger().error(f"ignoring a bad posterior or risk map: {exc}")
            return
        # An answer's record carries its posterior's stamp; a posterior without one is /ird/infer's.
        stamp = self.posterior.header.stamp
        num_answers = next((int(r.num_answers) for r in reversed(self.records)
                            if r.event == QueryEvent.ANSWERED and r.header.stamp == stamp), 0)
        gaussian = self.proxy is not None and self.proxy.condition in terrain_view.GAUSSIAN_CONDITIONS
        self.web.show_posterior(posterior_dict(post, num_answers, stamp_seconds(self.posterior.header.stamp),
                                               instance=self._gaussian_instance(post.feature_names) if gaussian
                                               else None, observations=gaussian), risk)

    def _gaussian_instance(self, feature_names: Any) -> Any:
        """The current Gaussian world's Lavaland instance (made again once per world), or None."""
        proxy, terrain = self.proxy, self.terrain
        if proxy is None or terrain is None:
            return None
        start = (int(proxy.test_start_row), int(proxy.test_start_col))
        key = (proxy.condition, int(proxy.seed), int(proxy.horizon), start, self.terrain_ns, tuple(feature_names))
        if key != self._instance_key:
            self._instance_key = key
            self._instance = terrain_view.gaussian_instance(proxy.condition, int(proxy.seed), terrain.classes,
                                                            terrain.class_names, int(proxy.horizon), start,
                                                            feature_names)
            if self._instance is None:
                self.get_logger().warning(f"{proxy.condition} seed {proxy.seed}: the world could not be made again; "
                                          "the page shows the posterior per observation dimension")
        return self._instance

    def _web_answer(self, query_id: int, chosen: int) -> tuple[bool, str]:
        """``on_answer`` of the page: runs in the web server's thread, blocks until the reply."""
        if not self.is_active:
            return False, f"the designer node is {self.lifecycle_state}, not active: answers are not sent"
        if not self._client.service_is_ready():
            return False, f"inference node unavailable ({names.SRV_ANSWER} is not served)"
        request = AnswerQuery.Request(query_id=int(query_id), chosen=int(chosen), beta=0.0,
                                      answered_by=DesignerMode.WEB.value)
        try:
            response = self._client.call(request, timeout_sec=self.answer_timeout)
        except Exception as exc:  # noqa: BLE001 - the page shows why instead of a dead request
            return False, f"the answer failed: {type(exc).__name__}: {exc}"
        if response is None:
            return False, f"timeout: no reply from {names.SRV_ANSWER} within {self.answer_timeout} s"
        if response.success:  # the page says its own thank-you; the sampler's statistics go to the log
            self.get_logger().info(f"web answer: {response.message}")
            return True, f"Option {option_letter(int(chosen))} recorded for question #{int(query_id)}"
        message = str(response.message)
        if message.startswith("chosen:"):  # the inference node counts options from 0, the page in letters
            message = f"chosen: Option {option_letter(int(chosen))} is out of range for question #{int(query_id)}"
        return False, message


def main(args: list[str] | None = None) -> int:
    return run_node(DesignerNode, args)


if __name__ == "__main__":
    exit_process(main())
