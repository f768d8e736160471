"""The planner node: literal and risk-averse plans on the perceived test map (``/ird/plan``).

Run: ``python -m ird_ros.planner --ros-args --params-file msgs_config/params/graph.yaml``

Keeps the latest (latched) ``/world/test_features``, ``/terrain/features``,
``/world/train_features``, ``/world/train_proxy_features``, ``/world/proxy`` and
``/ird/posterior``.

``/ird/plan`` (PlanPath) fills in what a request leaves empty:

- ``weights`` empty: the latest posterior's samples; for mode ``literal`` the latest proxy's
  weights. Their feature names are the posterior's ``feature_names`` / the proxy's.
- ``map`` empty: the latest perceived test map whose layer names equal those feature names,
  looked up in ``/world/test_features`` (the hypothesis space: posterior samples) and then
  ``/terrain/features`` (the proxy's space: the classifier proxy's literal plan). With explicit
  ``weights`` and no map, the first of those two maps whose layer count fits the weights (K*d
  values, d = its layer count; K = 1 for literal) is used.
- ``reference_features`` empty (needed by baseline ``training_features`` only): the proxy's
  expected feature counts in the training MDP divided by (training horizon + 1), in the space
  of the weights: the proxy is planned (MaxEnt) on the training map in the proxy's own features
  (``/world/train_proxy_features``, start and horizon from ``/world/proxy``), and its expected
  visits are contracted with the training map whose layers match the weights
  (``/world/train_features`` for posterior samples, ``/world/train_proxy_features`` for the
  proxy's own weights). This is ``ird_core.lavaland.proxy_feature_expectations / (T + 1)``.

Every field is validated (``success: false``, the message starts with the field's name). The
plan is ``ird_core.planning.plan_path(GridMDP(map, start, horizon), weights, mode, baseline,
reference_features)``, computed in a worker process (the trajectory MILP can take seconds), and
published on ``/plan`` (nav_msgs/Path, poses at cell centres, stamp = now, frame ``map``) and
``/ird/plan_info`` (same stamp; label, mode, baseline, objective, cells), both latched.

The response message ends with the inputs a request left empty and where they came from, as
``; inputs: weights=/ird/posterior@<sec>.<nanosec>, map=/world/test_features@<sec>.<nanosec>,
reference_features=/world/proxy@...+/world/train_proxy_features@...+/world/train_features@...``
(header stamps of the messages used), so a caller can tell which world generation was planned on.
Inputs given in the request are not listed.

``/ird/risk_map`` (OccupancyGrid 0..100, ``planning.risk_map`` of the posterior samples on the
matching perceived test map, latched) is republished whenever a new posterior or a new matching
map arrives. With ``replan_on_posterior`` true, every new posterior also triggers a plan with
``default_mode`` / ``default_baseline`` from the proxy's test start and horizon.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node

from ird_core import mdp as core_mdp
from ird_core import planning
from ird_msgs.msg import FeatureGrid, PlanInfo, ProxyReward, RewardPosterior
from ird_msgs.srv import PlanPath
from nav_msgs.msg import OccupancyGrid, Path
from ird_ros import conversions as conv
from ird_ros import names
from ird_ros.node_main import BrokenProcessPool, WorkerPool, declare, run_node, exit_process

__all__ = ["PlannerNode", "RequestError", "reference_features", "run_plan", "main"]


class RequestError(ValueError):
    """A bad request; the message starts with the field's name."""


def reference_features(
    proxy_train_features: np.ndarray,
    target_train_features: np.ndarray,
    proxy_weights: np.ndarray,
    start: tuple[int, int],
    horizon: int,
) -> np.ndarray:
    """``f_ref``: the proxy's expected training counts of ``target_train_features`` / (T + 1).

    The proxy (weights over ``proxy_train_features``' layers) is planned by the MaxEnt agent on
    ``proxy_train_features`` from ``start`` for ``horizon`` moves.
    """
    proxy_mdp = core_mdp.GridMDP(proxy_train_features, start, horizon)
    visits = core_mdp.expected_visitation(proxy_mdp, np.asarray(proxy_weights, dtype=np.float64)[None, :])
    counts = np.einsum("khw,hwd->kd", visits, np.asarray(target_train_features, dtype=np.float64), optimize=True)[0]
    return counts / (horizon + 1)


def run_plan(job: dict[str, Any]) -> tuple[planning.Plan, np.ndarray | None]:
    """The worker-process job: the default reference features if asked for, then plan_path."""
    reference = job["reference_features"]
    if reference is None and job["reference_job"] is not None:
        reference = reference_features(**job["reference_job"])
    mdp = core_mdp.GridMDP(job["features"], job["start"], job["horizon"])
    plan = planning.plan_path(mdp, job["weights"], job["mode"], job["baseline"], reference,
                              time_limit=job["time_limit"])
    return plan, reference


def _stamp(stamp: Any) -> str:
    """A header stamp as ``sec.nanosec`` (nanoseconds zero-padded), as in the response message."""
    return f"{int(stamp.sec)}.{int(stamp.nanosec):09d}"


def _flat(values: Any) -> np.ndarray:
    return np.array(values, dtype=np.float64).reshape(-1)


class PlannerNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_PLANNER, **kwargs)
        self.replan_on_posterior = declare(
            self, "replan_on_posterior", False,
            "Plan (default_mode, default_baseline, proxy's test start/horizon) on every new posterior")
        self.default_mode = declare(self, "default_mode", "per_step", "Mode of plans made on a new posterior",
                                    choices=planning.MODES)
        self.default_baseline = declare(self, "default_baseline", "training_features",
                                        "Baseline of plans made on a new posterior", choices=planning.BASELINES)
        self.risk_statistic = declare(self, "risk_statistic", "std",
                                      "Spread statistic of the risk map", choices=planning.STATISTICS)
        self.milp_time_limit = declare(self, "milp_time_limit", 0.0,
                                       "Seconds for the trajectory MILP (0 = no limit)", min_value=0.0)
        self.max_horizon = declare(self, "max_horizon", 1000, "Largest horizon a request may ask for", min_value=1)
        self.max_pending = declare(self, "max_pending", 16,
                                   "Valid requests allowed to wait or run at once; more are refused as busy",
                                   min_value=1)
        self._pool = WorkerPool(1, warm_modules=("ird_core.planning",))
        self._pending = 0
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
        for topic in (names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN_FEATURES,
                      names.TOPIC_TRAIN_FEATURES, names.TOPIC_TRAIN_PROXY_FEATURES):
            self.create_subscription(FeatureGrid, topic, lambda msg, t=topic: self._on_map(t, msg), latched)
        self.create_subscription(ProxyReward, names.TOPIC_PROXY, self._on_proxy, latched)
        self.create_subscription(RewardPosterior, names.TOPIC_POSTERIOR, self._on_posterior, latched)
        self.create_service(PlanPath, names.SRV_PLAN, self._on_plan,
                            # Own reentrant group: a pending (awaiting) request must not hold the
                            # default group, which serves parameters (and subscriptions).
                            callback_group=ReentrantCallbackGroup())

    def destroy_node(self) -> None:
        self._pool.shutdown()
        super().destroy_node()

    # ------------------------------------------------------------------ inputs

    def _on_map(self, topic: str, msg: FeatureGrid) -> None:
        try:
            self.maps[topic] = conv.feature_grid_from_msg(msg, field=topic)
        except ValueError as exc:
            self.get_logger().error(f"ignoring a bad map: {exc}")
            return
        self._versions[topic] = self._versions.get(topic, 0) + 1
        self._stamps[topic] = _stamp(msg.header.stamp)
        self._update_risk_map()

    def _on_proxy(self, msg: ProxyReward) -> None:
        self.proxy = msg

    def _on_posterior(self, msg: RewardPosterior) -> None:
        try:
            self.posterior = conv.posterior_from_msg(msg, field=names.TOPIC_POSTERIOR)
        except ValueError as exc:
            self.get_logger().error(f"ignoring a bad posterior: {exc}")
            return
        self._versions[names.TOPIC_POSTERIOR] = self._versions.get(names.TOPIC_POSTERIOR, 0) + 1
        self._stamps[names.TOPIC_POSTERIOR] = _stamp(msg.header.stamp)
        self._update_risk_map()
        if self.replan_on_posterior:
            self.executor.create_task(self._replan())

    def matching_map(self, layers: tuple[str, ...]) -> tuple[str, conv.FeatureGridData] | None:
        """The latest perceived test map whose layers are ``layers`` (test features first)."""
        for topic in (names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN_FEATURES):
            grid = self.maps.get(topic)
            if grid is not None and grid.layers == tuple(layers):
                return topic, grid
        return None

    def _update_risk_map(self) -> None:
        if self.posterior is None:
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
            costs, resolution=grid.resolution, origin=grid.origin, stamp=self.get_clock().now().to_msg()))

    # ------------------------------------------------------------------ validation

    def validate(self, req: PlanPath.Request) -> dict[str, Any]:
        """Check every field, fill in the defaults; return the worker job or raise RequestError."""
        if req.mode not in planning.MODES:
            raise RequestError(f"mode: must be one of {list(planning.MODES)}, got {req.mode!r}")
        if req.baseline not in planning.BASELINES:
            raise RequestError(f"baseline: must be one of {list(planning.BASELINES)}, got {req.baseline!r}")
        if req.horizon == 0:
            raise RequestError("horizon: must be > 0, got 0")
        if req.horizon > self.max_horizon:
            raise RequestError(f"horizon: {req.horizon} exceeds max_horizon={self.max_horizon}")
        literal = req.mode == "literal"
        grid: conv.FeatureGridData | None = None
        if len(req.map.layers) or len(req.map.data):
            try:
                grid = conv.feature_grid_from_msg(req.map, field="map")
            except ValueError as exc:
                raise RequestError(str(exc)) from None
        flat = _flat(req.weights)
        feature_names: tuple[str, ...] | None = None  # names of the weights, when known
        sources: list[str] = []  # where defaulted inputs came from (reported in the message)
        if flat.size == 0:
            if literal:
                if self.proxy is None:
                    raise RequestError("weights: empty and no proxy received on /world/proxy yet")
                weights = _flat(self.proxy.weights)[None, :]
                feature_names = tuple(self.proxy.feature_names)
                sources.append(f"weights={names.TOPIC_PROXY}@{_stamp(self.proxy.header.stamp)}")
            else:
                if self.posterior is None:
                    raise RequestError("weights: empty and no posterior received on /ird/posterior yet")
                weights = self.posterior.samples
                feature_names = self.posterior.feature_names
                sources.append(f"weights={names.TOPIC_POSTERIOR}@{self._stamps[names.TOPIC_POSTERIOR]}")
            if grid is None:
                found = self.matching_map(feature_names)
                if found is None:
                    raise RequestError(f"map: empty and no perceived test map has the layers "
                                       f"{list(feature_names)[:4]}{'...' if len(feature_names) > 4 else ''} "
                                       "of the weights")
                grid = found[1]
                sources.append(f"map={found[0]}@{self._stamps[found[0]]}")
            elif grid.layers != feature_names:
                raise RequestError(f"map.layers: {list(grid.layers)[:4]}... do not match the weights' features "
                                   f"{list(feature_names)[:4]}...")
        else:
            if not np.all(np.isfinite(flat)):
                raise RequestError("weights: contains NaN or infinite values")
            if grid is None:
                for topic in (names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN_FEATURES):
                    candidate = self.maps.get(topic)
                    if candidate is None:
                        continue
                    d = candidate.shape[2]
                    if (literal and flat.size == d) or (not literal and flat.size % d == 0):
                        grid = candidate
                        sources.append(f"map={topic}@{self._stamps[topic]}")
                        break
                if grid is None:
                    raise RequestError(f"map: empty and no perceived test map fits {flat.size} weight values")
            d = grid.shape[2]
            if flat.size % d:
                raise RequestError(f"weights: {flat.size} values are not a multiple of d={d} (map.layers)")
            weights = flat.reshape(-1, d)
            feature_names = grid.layers
        h, w, d = grid.shape
        if literal and weights.shape[0] != 1:
            raise RequestError(f"weights: mode literal takes one weight vector (d={d} values), "
                               f"got {weights.shape[0]}")
        if req.start_row >= h:
            raise RequestError(f"start_row: {req.start_row} is off the map (height {h})")
        if req.start_col >= w:
            raise RequestError(f"start_col: {req.start_col} is off the map (width {w})")
        reference = None
        reference_job = None
        ref_flat = _flat(req.reference_features)
        if ref_flat.size:
            if ref_flat.size != d:
                raise RequestError(f"reference_features: expected d={d} values, got {ref_flat.size}")
            if not np.all(np.isfinite(ref_flat)):
                raise RequestError("reference_features: contains NaN or infinite values")
            reference = ref_flat
        elif req.baseline == "training_features":
            reference_job, used = self._reference_job(feature_names)
            sources.append("reference_features=" + "+".join(used))
        return dict(
            features=grid.features.astype(np.float64),
            grid=grid,
            start=(int(req.start_row), int(req.start_col)),
            horizon=int(req.horizon),
            weights=weights,
            mode=req.mode,
            baseline=req.baseline,
            reference_features=reference,
            reference_job=reference_job,
            time_limit=float(self.milp_time_limit) or None,
            label=req.label or (req.mode if literal else f"ird_{req.mode}_{req.baseline}"),
            sources=sources,
        )

    def _reference_job(self, feature_names: tuple[str, ...]) -> tuple[dict[str, Any], list[str]]:
        """The arguments of :func:`reference_features` from the latest proxy and training maps,
        and the ``topic@stamp`` of each input used."""
        if self.proxy is None:
            raise RequestError("reference_features: empty, and no proxy received on /world/proxy to compute them")
        proxy_names = tuple(self.proxy.feature_names)
        used = [f"{names.TOPIC_PROXY}@{_stamp(self.proxy.header.stamp)}"]
        proxy_train = None
        # The proxy is planned on its own features: the classified training map, or (no separate
        # proxy space) the training features themselves.
        for topic in (names.TOPIC_TRAIN_PROXY_FEATURES, names.TOPIC_TRAIN_FEATURES):
            grid = self.maps.get(topic)
            if grid is not None and grid.layers == proxy_names:
                proxy_train = grid
                used.append(f"{topic}@{self._stamps[topic]}")
                break
        if proxy_train is None:
            raise RequestError("reference_features: empty, and no training map with the proxy's layers "
                               "was received on /world/train_proxy_features or /world/train_features")
        target = None
        for topic in (names.TOPIC_TRAIN_FEATURES, names.TOPIC_TRAIN_PROXY_FEATURES):
            grid = self.maps.get(topic)
            if grid is not None and grid.layers == feature_names:
                target = grid
                used.append(f"{topic}@{self._stamps[topic]}")
                break
        if target is None:
            raise RequestError("reference_features: empty, and no training map has the layers of the weights")
        if target.shape[:2] != proxy_train.shape[:2]:
            raise RequestError("reference_features: empty, and the training maps have different sizes")
        return dict(
            proxy_train_features=proxy_train.features.astype(np.float64),
            target_train_features=target.features.astype(np.float64),
            proxy_weights=_flat(self.proxy.weights),
            start=(int(self.proxy.start_row), int(self.proxy.start_col)),
            horizon=int(self.proxy.horizon),
        ), used

    # ------------------------------------------------------------------ planning

    async def _plan(self, req: PlanPath.Request, response: PlanPath.Response) -> PlanPath.Response:
        try:
            job = self.validate(req)
        except RequestError as exc:
            response.success, response.message = False, str(exc)
            return response
        if self._pending >= self.max_pending:
            response.success = False
            response.message = f"busy: {self._pending} requests are pending (max_pending={self.max_pending})"
            return response
        grid, label, sources = job.pop("grid"), job.pop("label"), job.pop("sources")
        self._pending += 1
        try:
            plan, _ = await self._pool.submit(self.executor, run_plan, job)
        except ValueError as exc:
            response.success, response.message = False, str(exc)
            return response
        except (BrokenProcessPool, RuntimeError, Exception) as exc:  # noqa: BLE001
            response.success, response.message = False, f"planning failed: {type(exc).__name__}: {exc}"
            self.get_logger().error(response.message)
            return response
        finally:
            self._pending -= 1
        stamp = self.get_clock().now().to_msg()
        path = conv.cells_to_path(plan.cells, resolution=grid.resolution, origin=grid.origin,
                                  height=grid.shape[0], width=grid.shape[1], stamp=stamp)
        rows = [int(r) for r, _ in plan.cells]
        cols = [int(c) for _, c in plan.cells]
        info = PlanInfo()
        info.header = conv.make_header(stamp)
        info.label = label
        info.mode = plan.mode
        info.baseline = plan.baseline
        info.objective = float(plan.objective)
        info.rows = rows
        info.cols = cols
        self._info_pub.publish(info)  # before the path: Rob can label the plan as soon as it starts
        self._plan_pub.publish(path)
        response.success = True
        response.message = (f"{label}: {plan.mode}/{plan.baseline} objective {plan.objective:.6g} "
                            f"({plan.solver}, {len(plan.cells) - 1} moves)"
                            + (f"; inputs: {', '.join(sources)}" if sources else ""))
        response.path = path
        response.objective = float(plan.objective)
        response.rows = rows
        response.cols = cols
        self.get_logger().info(response.message)
        return response

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
