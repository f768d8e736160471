"""The planner node: literal and risk-averse plans on the perceived test map (``/ird/plan``).

Run: ``python -m ird_ros.nodes.planner --ros-args --params-file msgs_config/params/graph.yaml``

Keeps the latest (latched) ``/world/hypothesis/test_features``, ``/world/test_features``,
``/terrain/features``, ``/world/hypothesis/train_features``, ``/world/train_features``,
``/world/train_proxy_features``, ``/world/proxy`` and ``/ird/posterior`` (the two
``/world/hypothesis/...`` maps come only from a world whose hypothesis space is not the sensors':
``ird_ros.nodes.world``).

``/ird/plan`` (PlanPath) fills in what a request leaves empty:

- ``weights`` empty: the latest posterior's samples; for mode ``literal`` the latest proxy's
  weights. Their feature names are the posterior's ``feature_names`` / the proxy's.
- ``map`` empty: the latest perceived test map whose layer names equal those feature names,
  looked up in ``/world/hypothesis/test_features`` and ``/world/test_features`` (the hypothesis
  space: posterior samples) and then ``/terrain/features`` (the proxy's space: the classifier
  proxy's literal plan). With explicit
  ``weights`` and no map, the first of those two maps whose layer count fits the weights (K*d
  values, d = its layer count; K = 1 for literal) is used.
- ``reference_features`` empty (needed by baseline ``training_features`` only): computed in the
  worker (:mod:`ird_ros.jobs.planning`): the proxy is planned (MaxEnt) on the training map in the
  proxy's own features (``/world/train_proxy_features``, start and horizon from ``/world/proxy``),
  and its expected visits are contracted with the training map whose layers match the weights
  (``/world/hypothesis/train_features`` or ``/world/train_features`` for posterior samples,
  ``/world/train_proxy_features`` for the proxy's own weights).
- ``sample_scale`` (default ``training_spread``): IRD plans divide each sample by its reward range
  over the training maps with their layers (``/world/hypothesis/train_features`` or
  ``/world/train_features``, and the other training worlds of the same generation's
  ``/world/infer_request`` whose layers match, as the experiments scale over every training
  world; ``ird_core.planning.sample_scale``); without the first map they are planned unscaled
  and the message says so (``sample_scale=none (...)``).

Every field is validated before the plan is queued (``success: false``, the message starts with
the field's name): sizes first, from the declared lengths before anything is decoded (the map's
``len(data)`` and ``H x W x len(layers)`` against ``max_map_values``, the explicit weights'
``len(weights) / d`` samples against ``max_plan_work`` through ``planning.check_plan_size``,
``reference_features`` against ``d``, ``label`` against ``sizes.MAX_TEXT`` characters); then the
map is decoded by ``ird_ros.conversions``, the arguments are checked by
``ird_core.planning.check_plan_arguments``, ``check_start`` and ``GridMDP``; the node itself checks
its limits (``max_horizon``; ``max_plan_work`` for defaulted weights) and which received inputs
fit together. Every handler runs in ``ird_ros.runtime.guard``'s guard (an unexpected exception
is a ``success: false`` answer, never the end of the node). The
plan (docs/spec.md section 4) is :func:`ird_ros.jobs.planning.run_plan`, computed in a worker process: trajectory plans
in one of their own, so a long one never delays a ``literal`` or ``per_step`` plan. A
trajectory plan that reaches ``time_limit`` is answered with the best path found, marked in the
message as ``FALLBACK, not proven optimal`` with its objective and proven upper bound. It is
published on ``/plan`` (nav_msgs/Path, poses at cell centres, stamp = now, frame ``map``) and
``/ird/plan_info`` (same stamp; label, mode, baseline, objective, cells), both latched.

The response message ends with the inputs a request left empty and where they came from, as
``; inputs: weights=/ird/posterior@<sec>.<nanosec>, map=/world/test_features@<sec>.<nanosec>,
reference_features=/world/proxy@...+/world/train_proxy_features@...+/world/train_features@...``
(header stamps of the messages used), so a caller can tell which world generation was planned on.
Inputs given in the request are not listed.

Risk measures (docs/spec.md section 4): ``risk`` "" and ``risk_level`` 0 take the parameters
``risk`` / ``risk_level``; the request's measure is resolved and checked before the plan is
queued by :func:`ird_ros.jobs.planning.request_risk` (``ird_core``'s ``check_risk``: refusals name
``risk`` or ``risk_level``; ``mean_sd`` with ``trajectory`` names ``risk``). Trajectory CVaR is
the library's MILP, bounded by ``time_limit`` alone (no work limit is passed). The response,
``/ird/plan_info`` and the log line say which measure and level the plan used (``min``, level 0,
for ``literal``).

``/ird/risk_map`` (OccupancyGrid 0..100, ``planning.risk_map`` of the posterior samples on the
matching perceived test map, latched) is the reward spread of the samples (``risk_statistic``),
whatever measure plans use; ``/ird/plan_info`` says which measure the current plan maximised. It
is republished whenever a new posterior or a new matching map arrives. With
``replan_on_posterior`` true, every new posterior also triggers a plan with ``default_mode`` /
``default_baseline`` (and the default risk) from the proxy's test start and horizon.

Life cycle (``ird_ros.runtime.lifecycle``): the worker pools start at configure and end at
cleanup; plans are served and ``/plan``, ``/ird/plan_info``, ``/ird/risk_map`` published only
while active (activating publishes the current risk map). Every parameter but the pools'
(``worker_memory_mb``, ``max_pending``: read-only) may change at run time and is used from the
next request on (``risk_statistic``: the risk map is published again).

Longer than 450 lines: the validation of every request field sits next to the service that
answers it, and the defaults it fills in come from the inputs this node keeps.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from nav_msgs.msg import OccupancyGrid, Path
from rclpy.callback_groups import ReentrantCallbackGroup

from ird_core import planning
from ird_core.checks import MAX_ABS_FEATURE
from ird_core.mdp import GridMDP
from ird_core.planning.risk_measures import MAX_LAMBDA, MIN_RISK
from ird_core.vocabulary import RISK_MEASURES, Baseline, PlanMode
from ird_msgs.msg import FeatureGrid, PlanInfo, ProxyReward, RewardPosterior
from ird_msgs.srv import InferReward, PlanPath
from ird_ros import conversions as conv
from ird_ros.graph import names
from ird_ros.conversions.sizes import check_grid_size, check_text, grid_is_empty
from ird_ros.jobs.planning import PlanJob, ReferenceJob, reported_level, request_risk, risk_text, run_plan
from ird_ros.runtime.guard import guard_callback
from ird_ros.runtime.node_main import StartupError, exit_process, run_node
from ird_ros.runtime.lifecycle import ManagedNode
from ird_ros.runtime.node_params import Param, runtime_except
from ird_ros.runtime.offload import Offload, OffloadError, service_qos
from ird_ros.stamps import stamp_text

__all__ = ["PlannerNode", "PARAMETERS", "main"]

TEST_MAP_TOPICS = (names.TOPIC_HYPOTHESIS_TEST_FEATURES, names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN_FEATURES)
"""The perceived test maps, in the order defaults are looked up: the hypothesis space first (its own
topic when the world's hypothesis space is not the sensors', then the sensors' map), then the
proxy's space."""

TRAIN_MAP_TOPICS = (names.TOPIC_HYPOTHESIS_TRAIN_FEATURES, names.TOPIC_TRAIN_FEATURES)
"""The training maps posterior samples are scaled on and counted in, in the same order."""

PARAMETERS: dict[str, Param] = {
    "replan_on_posterior": Param(False, "Plan (default_mode, default_baseline, proxy's test start/horizon) on "
                                        "every new posterior"),
    "default_mode": Param("per_step", "Mode of plans made on a new posterior", choices=planning.MODES),
    "default_baseline": Param("training_features", "Baseline of plans made on a new posterior",
                              choices=planning.BASELINES),
    "risk": Param("min", "Risk measure of a request with risk \"\" (and of replans): min | cvar | mean_sd "
                         "(per_step only)", choices=RISK_MEASURES),
    "risk_level": Param(0.0, "Level of the default risk measure: cvar's alpha in (0, 1], mean_sd's lambda "
                             "(0 for min)", min_value=0.0, max_value=MAX_LAMBDA),
    "sample_scale": Param("training_spread", "IRD plans' samples scaled by their training reward range, or none",
                          choices=planning.SAMPLE_SCALES),
    "risk_statistic": Param("std", "Spread statistic of the risk map", choices=planning.STATISTICS),
    "time_limit": Param(10.0, "Seconds a trajectory plan may take (label search and MILP); past it the best "
                              "path found is answered as a fallback", min_value=0.001),
    "max_horizon": Param(1000, "Largest horizon a request may ask for", min_value=1),
    "worker_memory_mb": Param(4096, "Address space of each planning worker process in MiB (0 = no limit); a plan "
                                    "past it fails with MemoryError", min_value=0),
    "max_map_values": Param(5_000_000, "Largest H*W*d of a request's map", min_value=1),
    "max_plan_work": Param(50_000_000, "Largest samples x (horizon + 1) x cells of a plan (planning.plan_work)",
                           min_value=1),
    "max_pending": Param(16, "Valid requests allowed to wait or run at once; more are refused as busy",
                         min_value=1),
}
#: The worker pools' (read when configured, read-only); the others may change at run time.
PARAMETERS = runtime_except(PARAMETERS, ("worker_memory_mb", "max_pending"))


@dataclass(frozen=True)
class _Accepted:
    """A validated request: the job and what the answer needs besides the plan."""

    job: PlanJob
    grid: conv.FeatureGridData
    label: str
    sources: tuple[str, ...]  # where defaulted inputs came from (reported in the message)


def _flat(values: Any) -> np.ndarray:
    return np.array(values, dtype=np.float64).reshape(-1)


def _reshape_weights(flat: np.ndarray, grid: conv.FeatureGridData) -> np.ndarray:
    """Explicit weights as ``(K, d)``, d = the map's layer count (``ValueError`` naming ``weights``)."""
    d = grid.shape[2]
    if flat.size % d:
        raise ValueError(f"weights: {flat.size} values are not a multiple of d={d} (map.layers)")
    return flat.reshape(-1, d)


class PlannerNode(ManagedNode):
    """The planner (managed): worker pools from configure to cleanup, plans and the risk map while
    active; every setting but the pools' may change at run time."""

    PARAMETERS = PARAMETERS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_PLANNER, **kwargs)

    def apply_parameters(self, p: dict[str, Any], changed: set[str]) -> None:
        """Check the default risk measure of ``p``, then apply every setting (``ValueError``: refused)."""
        try:  # the default measure, checked once (a bad pair would refuse every defaulted request)
            default = request_risk(p["risk"], p["risk_level"], MIN_RISK,
                                   p["default_mode"] if p["replan_on_posterior"] else None)
        except ValueError as exc:
            raise StartupError(f"parameter {exc}") from None
        self.default_risk = default
        self.replan_on_posterior = p["replan_on_posterior"]
        self.default_mode, self.default_baseline = p["default_mode"], p["default_baseline"]
        self.risk_statistic, self.sample_scale = p["risk_statistic"], p["sample_scale"]
        self.time_limit, self.max_horizon = p["time_limit"], p["max_horizon"]
        self.max_plan_work, self.max_map_values = p["max_plan_work"], p["max_map_values"]
        if "risk_statistic" in changed and hasattr(self, "_risk_key"):
            self._risk_key = None
            self._update_risk_map()

    def configure(self, p: dict[str, Any]) -> None:
        self.apply_parameters(p, set())
        # Trajectory plans (seconds, up to time_limit) get their own worker: a long one never
        # delays a literal or per_step plan (milliseconds), which queue on the other.
        pool = dict(warm_modules=("ird_core.planning", "ird_core.posterior", "ird_core.mdp"),
                    memory_limit=p["worker_memory_mb"] * 2**20, logger=self.get_logger())
        self._offloads = {"dp": Offload("planning", p["max_pending"], **pool),
                          "trajectory": Offload("planning", p["max_pending"], **pool)}
        latched = names.latched_qos()
        self._plan_pub = self.create_publisher(Path, names.TOPIC_PLAN, latched)
        self._info_pub = self.create_publisher(PlanInfo, names.TOPIC_PLAN_INFO, latched)
        self._risk_pub = self.create_publisher(OccupancyGrid, names.TOPIC_RISK_MAP, latched)
        self.maps: dict[str, conv.FeatureGridData] = {}
        self._versions: dict[str, int] = {}  # messages received per topic (risk map freshness)
        self._stamps: dict[str, str] = {}  # header stamp of the latest message per topic
        self.proxy: ProxyReward | None = None
        self.posterior: conv.PosteriorData | None = None
        self._risk_key: Any = None
        for topic in (*TEST_MAP_TOPICS, *TRAIN_MAP_TOPICS, names.TOPIC_TRAIN_PROXY_FEATURES):
            self.create_subscription(FeatureGrid, topic, lambda msg, t=topic: self._on_map(t, msg), latched)
        self.create_subscription(ProxyReward, names.TOPIC_PROXY, self._on_proxy, latched)
        # The world's other training worlds: (stamp of its generation, their maps), decoded once.
        self._other_worlds: tuple[str, list[conv.FeatureGridData]] = ("", [])
        self.create_subscription(InferReward.Request, names.TOPIC_INFER_REQUEST, self._on_infer_request, latched)
        self.create_subscription(RewardPosterior, names.TOPIC_POSTERIOR, self._on_posterior, latched)
        self.create_service(PlanPath, names.SRV_PLAN, self._on_plan, qos_profile=service_qos(),
                            # Own reentrant group: a pending (awaiting) request must not hold the
                            # default group, which serves parameters (and subscriptions).
                            callback_group=ReentrantCallbackGroup())

    def activate(self) -> None:
        self._risk_key = None  # publish the current risk map (again)
        self._update_risk_map()

    def release(self) -> None:
        for offload in getattr(self, "_offloads", {}).values():
            offload.shutdown()
        self._offloads = {}

    # ------------------------------------------------------------------ inputs

    def _on_map(self, topic: str, msg: FeatureGrid) -> None:
        try:
            self.maps[topic] = conv.feature_grid_from_msg(msg, field=topic)
        except ValueError as exc:
            self.get_logger().error(f"ignoring a bad map: {exc}")
            return
        self._versions[topic] = self._versions.get(topic, 0) + 1
        self._stamps[topic] = stamp_text(msg.header.stamp)
        self._update_risk_map()

    def _on_proxy(self, msg: ProxyReward) -> None:
        self.proxy = msg

    def _on_infer_request(self, msg: InferReward.Request) -> None:
        try:
            grids = [conv.feature_grid_from_msg(world.training_map, field=f"training_worlds[{i}].training_map")
                     for i, world in enumerate(msg.training_worlds)]
        except ValueError as exc:
            self.get_logger().error(f"ignoring a bad {names.TOPIC_INFER_REQUEST}: {exc}")
            grids = []
        self._other_worlds = (stamp_text(msg.training_map.header.stamp), grids)

    def _on_posterior(self, msg: RewardPosterior) -> None:
        try:
            self.posterior = conv.posterior_from_msg(msg, field=names.TOPIC_POSTERIOR)
        except ValueError as exc:
            self.get_logger().error(f"ignoring a bad posterior: {exc}")
            return
        self._versions[names.TOPIC_POSTERIOR] = self._versions.get(names.TOPIC_POSTERIOR, 0) + 1
        self._stamps[names.TOPIC_POSTERIOR] = stamp_text(msg.header.stamp)
        self._update_risk_map()
        if self.replan_on_posterior and self.is_active:
            self.executor.create_task(guard_callback(self._replan, self.get_logger(), "replan_on_posterior")())

    def matching_map(self, layers: tuple[str, ...]) -> tuple[str, conv.FeatureGridData] | None:
        """The latest perceived test map whose layers are ``layers`` (test features first)."""
        return conv.first_with_layers(self.maps, TEST_MAP_TOPICS, layers)

    def _update_risk_map(self) -> None:
        if self.posterior is None or not self.is_active:
            return
        found = self.matching_map(self.posterior.feature_names)
        if found is None:
            return
        topic, grid = found
        # Keyed on the map's world generation (header stamp), not on the topic it came by:
        # /terrain/features carries /world/test_features' stamp and, when its layers match, the
        # same values, so whichever of the two arrives second (DDS delivery order varies under
        # load) is the same map and must not publish a second, identical risk map.
        key = (self._versions.get(names.TOPIC_POSTERIOR), self._stamps[topic])
        if key == self._risk_key:
            return
        self._risk_key = key
        try:
            costs = planning.risk_map(grid.features.astype(np.float64), self.posterior.samples, self.risk_statistic)
        except ValueError as exc:
            self.get_logger().error(f"risk map: {exc}")
            return
        self._risk_pub.publish(conv.occupancy_grid_to_msg(
            costs, resolution=grid.resolution, origin=grid.origin, stamp=conv.now_stamp(self)))

    # ------------------------------------------------------------------ validation

    def validate(self, req: PlanPath.Request) -> _Accepted:
        """Check every field and fill in the defaults.

        Raises:
            ValueError: naming the request field (from the decoders and the library's checks).
        """
        # Mode and baseline first: which inputs are defaulted depends on them.
        planning.check_plan_arguments(req.mode, req.baseline)
        mode, baseline = PlanMode(req.mode), Baseline(req.baseline)
        risk = request_risk(req.risk, req.risk_level, self.default_risk, mode)
        if req.horizon > self.max_horizon:
            raise ValueError(f"horizon: {req.horizon} exceeds max_horizon={self.max_horizon}")
        check_text(req.label, "label")
        sources: list[str] = []
        weights, feature_names, grid = self._weights_and_map(req, mode is PlanMode.LITERAL, sources)
        h, w, d = grid.shape
        planning.check_plan_size(len(weights), int(req.horizon), h, w, self.max_plan_work)
        if len(req.reference_features) not in (0, d):  # before converting it
            raise ValueError(f"reference_features: expected shape ({d},), got ({len(req.reference_features)},)")
        start = planning.check_start((req.start_row, req.start_col), h, w)
        mdp = GridMDP(grid.features.astype(np.float64), start, int(req.horizon))
        ref_flat = _flat(req.reference_features)
        reference = ref_flat if ref_flat.size else None
        time_limit = float(self.time_limit)
        weights = planning.check_plan_arguments(mode, baseline, weights, d, reference, time_limit=time_limit)
        reference_job = None
        if reference is None and baseline is Baseline.TRAINING_FEATURES:
            reference_job, used = self._reference_job(feature_names)
            sources.append("reference_features=" + "+".join(used))
        scale_features = None if mode is PlanMode.LITERAL else self._scale_features(feature_names, sources)
        job = PlanJob(mdp=mdp, weights=weights, mode=mode, baseline=baseline, reference_features=reference,
                      reference_job=reference_job, time_limit=time_limit, risk=risk, scale_features=scale_features)
        label = req.label or (mode.value if mode is PlanMode.LITERAL else f"ird_{mode.value}_{baseline.value}")
        return _Accepted(job=job, grid=grid, label=label, sources=tuple(sources))

    def _weights_and_map(self, req: PlanPath.Request, literal: bool, sources: list[str]
                         ) -> tuple[np.ndarray, tuple[str, ...], conv.FeatureGridData]:
        """The plan's weights ``(K, d)``, their feature names and the map, each from the request
        or defaulted (see the module doc); ``sources`` gets the ``name=topic@stamp`` of defaults."""
        grid = self._request_map(req)
        count = len(req.weights)
        if count:
            grid = grid if grid is not None else self._map_fitting(count, literal, sources)
            h, w, d = grid.shape
            if count % d == 0:  # the samples' work from the declared length, before converting them
                planning.check_plan_size(count // d, int(req.horizon), h, w, self.max_plan_work)
            return _reshape_weights(_flat(req.weights), grid), grid.layers, grid
        weights, feature_names = self._latched_weights(literal, sources)
        if grid is None:
            return weights, feature_names, self._map_with_layers(feature_names, sources)
        if grid.layers != feature_names:
            raise ValueError(f"map.layers: {list(grid.layers)[:4]}... do not match the weights' features "
                             f"{list(feature_names)[:4]}...")
        return weights, feature_names, grid

    def _request_map(self, req: PlanPath.Request) -> conv.FeatureGridData | None:
        """The request's own map, or ``None`` when it left ``map`` empty."""
        if grid_is_empty(req.map):
            return None
        check_grid_size(req.map, "map", self.max_map_values)  # before decoding it
        return conv.feature_grid_from_msg(req.map, field="map", max_abs=MAX_ABS_FEATURE)

    def _latched_weights(self, literal: bool, sources: list[str]) -> tuple[np.ndarray, tuple[str, ...]]:
        """Empty ``weights``: the latest proxy's (literal) or the latest posterior's samples."""
        if literal:
            if self.proxy is None:
                raise ValueError("weights: empty and no proxy received on /world/proxy yet")
            sources.append(f"weights={names.TOPIC_PROXY}@{stamp_text(self.proxy.header.stamp)}")
            return _flat(self.proxy.weights)[None, :], tuple(self.proxy.feature_names)
        if self.posterior is None:
            raise ValueError("weights: empty and no posterior received on /ird/posterior yet")
        sources.append(f"weights={names.TOPIC_POSTERIOR}@{self._stamps[names.TOPIC_POSTERIOR]}")
        return self.posterior.samples, self.posterior.feature_names

    def _map_with_layers(self, feature_names: tuple[str, ...], sources: list[str]) -> conv.FeatureGridData:
        """Empty ``map`` with defaulted weights: the latest perceived test map with their layers."""
        found = self.matching_map(feature_names)
        if found is None:
            raise ValueError(f"map: empty and no perceived test map has the layers "
                             f"{list(feature_names)[:4]}{'...' if len(feature_names) > 4 else ''} of the weights")
        sources.append(f"map={found[0]}@{self._stamps[found[0]]}")
        return found[1]

    def _map_fitting(self, num_values: int, literal: bool, sources: list[str]) -> conv.FeatureGridData:
        """Empty ``map`` with explicit weights: the first perceived test map whose layer count d
        fits ``num_values`` (K*d values; K = 1 for literal)."""
        for topic in TEST_MAP_TOPICS:
            candidate = self.maps.get(topic)
            if candidate is None:
                continue
            d = candidate.shape[2]
            if (literal and num_values == d) or (not literal and num_values % d == 0):
                sources.append(f"map={topic}@{self._stamps[topic]}")
                return candidate
        raise ValueError(f"map: empty and no perceived test map fits {num_values} weight values")

    def _scale_features(self, feature_names: tuple[str, ...], sources: list[str]
                        ) -> "np.ndarray | tuple[np.ndarray, ...] | None":
        """The training map(s) the samples are scaled on (``sample_scale``), or ``None``
        (unscaled; ``sources`` then says why)."""
        if self.sample_scale == "none":
            return None
        found = conv.first_with_layers(self.maps, TRAIN_MAP_TOPICS, feature_names)
        if found is None:
            sources.append(f"sample_scale=none (no training map with the weights' layers on {' or '.join(TRAIN_MAP_TOPICS)})")
            return None
        sources.append(f"sample_scale=training_spread@{found[0]}@{self._stamps[found[0]]}")
        first = found[1].features.astype(np.float64)
        extra = self._other_training_maps(self._stamps[found[0]], feature_names)
        if not extra:
            return first
        sources.append(f"+{len(extra)} training worlds@{names.TOPIC_INFER_REQUEST}@{self._stamps[found[0]]}")
        return (first, *extra)

    def _other_training_maps(self, stamp: str, feature_names: tuple[str, ...]) -> list[np.ndarray]:
        """The training maps of the world's other training worlds, from the latest
        ``/world/infer_request`` of the generation stamped ``stamp``, when every one has
        ``feature_names`` as its layers (else none: the samples are scaled on the first alone)."""
        generation, grids = self._other_worlds
        if generation != stamp or any(grid.layers != tuple(feature_names) for grid in grids):
            return []  # another generation's, or not in the samples' space
        return [grid.features.astype(np.float64) for grid in grids]

    def _reference_job(self, feature_names: tuple[str, ...]) -> tuple[ReferenceJob, list[str]]:
        """The default reference features' inputs from the latest proxy and training maps, and
        the ``topic@stamp`` of each input used."""
        if self.proxy is None:
            raise ValueError("reference_features: empty, and no proxy received on /world/proxy to compute them")
        used = [f"{names.TOPIC_PROXY}@{stamp_text(self.proxy.header.stamp)}"]
        # The proxy is planned on its own features: the classified training map, or (no separate
        # proxy space) the training features themselves.
        proxy_train = conv.first_with_layers(self.maps, (names.TOPIC_TRAIN_PROXY_FEATURES, names.TOPIC_TRAIN_FEATURES),
                                             self.proxy.feature_names)
        if proxy_train is None:
            raise ValueError("reference_features: empty, and no training map with the proxy's layers "
                             "was received on /world/train_proxy_features or /world/train_features")
        target = conv.first_with_layers(self.maps, (*TRAIN_MAP_TOPICS, names.TOPIC_TRAIN_PROXY_FEATURES),
                                        feature_names)
        if target is None:
            raise ValueError("reference_features: empty, and no training map has the layers of the weights")
        used += [f"{topic}@{self._stamps[topic]}" for topic, _ in (proxy_train, target)]
        return self._reference_inputs(proxy_train[1], target[1]), used

    def _reference_inputs(self, proxy_train: conv.FeatureGridData, target: conv.FeatureGridData) -> ReferenceJob:
        """The reference job of the latest proxy on ``proxy_train`` counted in ``target``."""
        assert self.proxy is not None
        if target.shape[:2] != proxy_train.shape[:2]:
            raise ValueError("reference_features: empty, and the training maps have different sizes")
        try:
            proxy_mdp = GridMDP(proxy_train.features.astype(np.float64),
                                (int(self.proxy.start_row), int(self.proxy.start_col)), int(self.proxy.horizon))
        except ValueError as exc:
            raise ValueError(f"reference_features: empty, and the proxy on {names.TOPIC_PROXY} does not fit "
                             f"its training map ({exc})") from None
        return ReferenceJob(proxy_mdp=proxy_mdp, proxy_weights=_flat(self.proxy.weights),
                            target_features=target.features.astype(np.float64))

    # ------------------------------------------------------------------ planning

    async def _plan(self, req: PlanPath.Request, response: PlanPath.Response) -> PlanPath.Response:
        try:
            accepted = self.validate(req)
            offload = self._offloads["trajectory" if accepted.job.mode is PlanMode.TRAJECTORY else "dp"]
            outcome = await offload.run(self.executor, run_plan, accepted.job)
        except (ValueError, OffloadError) as exc:
            response.success, response.message = False, str(exc)
            return response
        sources, plan = accepted.sources, outcome.plan
        label = accepted.label
        path, info = self._publish_plan(accepted, plan)
        response.success = True
        response.risk, response.risk_level = info.risk, info.risk_level
        measure = risk_text(plan.mode, info.risk, info.risk_level)
        response.message = (f"{label}: {plan.mode}/{plan.baseline}, {measure}, objective {plan.objective:.6g} "
                            f"({plan.solver}, {len(plan.cells) - 1} moves)"
                            + (f"; {outcome.fallback}" if outcome.fallback else "")
                            + (f"; inputs: {', '.join(sources)}" if sources else ""))
        response.path = path
        response.objective = float(plan.objective)
        response.rows, response.cols = info.rows, info.cols
        self.get_logger().info(response.message)
        return response

    def _publish_plan(self, accepted: _Accepted, plan: planning.Plan) -> tuple[Path, PlanInfo]:
        """Publish the plan on ``/ird/plan_info`` and then ``/plan``, both stamped now."""
        grid, stamp = accepted.grid, conv.now_stamp(self)
        path = conv.cells_to_path(plan.cells, resolution=grid.resolution, origin=grid.origin,
                                  height=grid.shape[0], width=grid.shape[1], stamp=stamp)
        info = PlanInfo(header=conv.make_header(stamp), label=accepted.label, mode=str(plan.mode),
                        baseline=str(plan.baseline), objective=float(plan.objective), risk=str(plan.risk.measure),
                        risk_level=reported_level(plan.risk),
                        rows=[int(r) for r, _ in plan.cells], cols=[int(c) for _, c in plan.cells])
        self._info_pub.publish(info)  # before the path: Rob can label the plan as soon as it starts
        self._plan_pub.publish(path)
        return path, info

    async def _on_plan(self, req: PlanPath.Request, response: PlanPath.Response) -> PlanPath.Response:
        return await self._plan(req, response)

    async def _replan(self) -> None:
        if self.proxy is None:
            self.get_logger().warning("replan_on_posterior: no proxy yet (test start/horizon unknown)")
            return
        req = PlanPath.Request()
        req.start_row, req.start_col = int(self.proxy.test_start_row), int(self.proxy.test_start_col)
        req.horizon = int(self.proxy.test_horizon)
        req.mode, req.baseline = self.default_mode, self.default_baseline
        response = await self._plan(req, PlanPath.Response())
        if not response.success:
            self.get_logger().warning(f"replan_on_posterior: {response.message}")


def main(args: list[str] | None = None) -> int:
    return run_node(PlannerNode, args)


if __name__ == "__main__":
    exit_process(main())
