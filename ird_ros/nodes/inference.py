"""The inference node: serves IRD posterior sampling on ``/ird/infer`` and latches the result.

Run: ``python -m ird_ros.nodes.inference --ros-args --params-file msgs_config/params/graph.yaml``

``/ird/infer`` (InferReward) validates every field first and answers a bad request at once with
``success: false`` and a message that starts with the field's name (``training_map.data: ...``,
``start_row: ...``, ``proxy_weights: ...``), by
:func:`ird_ros.conversions.inference_requests.infer_job`: sizes from the declared lengths before
anything is decoded (``max_map_values``, ``max_training_worlds``, ``max_request_values``,
``max_horizon``, ``max_num_samples``), the work model (``max_inference_work``,
:mod:`ird_ros.jobs.work`) and one MDP pass's memory (``worker_memory_mb``), then the decoders of
``ird_ros.conversions`` and the library's checks (``GridMDP``, ``planning.check_start``,
``checks.check_posterior_arguments``). Every worker process is capped at ``worker_memory_mb``
(``RLIMIT_AS``): a job past it fails naming ``worker_memory_mb``; a worker that dies fails only
the request it was running. Every handler runs in ``ird_ros.runtime.guard``'s guard: nothing a
request raises reaches the executor.
A good request is sampled in a worker process by :func:`ird_ros.jobs.inference.run_inference`
(the exact library call, convergence, proxy map and training worlds are documented in
:mod:`ird_ros.jobs.inference`), and the result is returned and published on ``/ird/posterior``
(reliable, transient local).

Convergence (``/ird/infer`` and ``/ird/answer``): an unconverged run is still ``success: true``
(its samples are valid draws of a run that was too short, and the client decides), with the
response's ``converged`` False and a message naming the bound: ``not converged: time budget 60 s
spent after ... iterations per chain, R-hat ... (target <= 1.05), ESS ... (target >= ...)``. The
posterior message's ``converged`` is the sampler's verdict (with ``until_converged`` its target,
stricter than ``ird_core.posterior.R_HAT_CONVERGED``).

The observation model (docs/spec.md section 3): ``proxy_counts`` "" and ``designer_temperature`` 0 take
the parameters of those names (defaults: ``ObservationModel()``, the calibrated designer); ``prior_sigma``
0 takes ``default_prior_sigma``, whose 0 is the calibrated ``1 / (temperature * rms training feature norm)``
(``ird_core.posterior.calibration``; ``1 / temperature`` for one-hot layers). A bad
value is refused naming the field. The model is passed to every library call of the request, recorded
in the posterior message and kept with the evidence (``/ird/answer`` re-samples with it). Sample-Z's
own term stays the library's default (an experiment control, not a service field).

The proxy map (latent_classifier): with ``proxy_map`` non-empty, the proxy weights apply to
``proxy_map``'s layers (same grid as ``training_map``).

Several training worlds (docs/spec.md section 7): each ``training_worlds[i]`` (TrainingWorld) is one
more ``ProxyObservation`` after the request's own training map; its ``training_map`` must have the
request's layers (the same hypothesis space, any grid size), its ``proxy_map`` is optional as
above, empty ``proxy_weights`` = the request's. Bad fields fail naming ``training_worlds[i].<field>``.
An empty list keeps the single-proxy posterior.

Responsiveness: the service callback is a coroutine that awaits the worker process
(``ird_ros.runtime.workers.WorkerPool``); the executor keeps serving parameters and other requests meanwhile.
Concurrency: requests are computed one at a time in arrival order (``max_workers`` = 1 by
default); invalid requests never queue; more than ``max_pending`` valid requests waiting at once
get ``success: false`` ("busy"); see ``ird_ros.runtime.offload``.

Questions to the designer (docs/spec.md section 7; the evidence's lifetime is documented in
:mod:`ird_ros.jobs.inference_queries`):

- ``/ird/query`` (ProposeQuery) proposes ``queries.propose_query(query_mdp, samples, answer_beta,
  num_options, strategy, seed, plan)`` from the current posterior's samples, ``plan`` Rob's
  default plan (the planner's defaults: per step, the min over the samples rescaled on the
  evidence's training map, the ``training_features`` baseline of the evidence's proxy:
  ``inference_queries.query_reference``): candidates and EVOI are those of the plan Rob will
  drive. Empty ``map`` = the latest test map with the posterior's features
  (``/world/test_features``, else ``/terrain/features``); ``horizon`` 0 = ``/world/proxy``'s test
  horizon; ``num_options`` 0 = 2; ``strategy`` "" = ``evoi``. The map's size is checked from its
  declared lengths before it is decoded (``max_map_values``), the query's work
  (``max_query_work``, :func:`ird_ros.jobs.work.query_work`) and one sample's plan table
  (``worker_memory_mb``) before it is queued. Too few distinct candidates is ``success: false``
  naming ``num_options``.
- ``kind`` "proxies" (Active IRD; "" or "paths" is the path query above; any other is refused
  naming ``kind``): the options are proxy rewards for the evidence's training world, from
  ``proxy_queries.propose_proxy_query`` with the evidence job's maps, proxy and observation
  model (:func:`ird_ros.jobs.inference_queries.proxy_query_job`: ``map`` empty, start and
  ``horizon`` 0; ``evoi`` re-plans on the latest test map); ``options`` are each proxy's plan on
  the training map, ``option_proxies`` their weights, ``option_features`` their behaviour counts.
- ``/ird/answer`` (AnswerQuery) adds ``ChoiceObservation(option_features, chosen, beta)`` to the
  evidence and re-samples ``sample_joint_posterior([proxy] + answers, ..., seed=
  resample_seed(seed, n), initial=<current posterior>)`` (warm start), returns it and publishes it
  on ``/ird/posterior``. Unknown, forgotten or answered ``query_id``, out-of-range ``chosen``, bad
  ``beta``, ``answered_by`` over ``sizes.MAX_TEXT`` fail naming the field; an answer during a
  re-sample is ``busy``; in every failure the evidence is unchanged.
- Every proposal and taken answer is on ``/ird/queries`` (QueryRecord, ``names.history_qos()``).

Life cycle (``ird_ros.runtime.lifecycle``): the worker pool starts at configure and ends at
cleanup; requests are answered and posteriors published only while active. The worker pool's
parameters (``worker_memory_mb``, ``max_workers``, ``max_pending``, ``worker_threads``) are
read-only; the limits, the sampler settings and the observation model may change at run time
and apply from the next request on.

Longer than 450 lines: the three services share the node's evidence, maps and worker pool, and
each validates its request next to where it is answered.
"""

from __future__ import annotations

import os
import time
from typing import Any

import numpy as np
from rclpy.callback_groups import ReentrantCallbackGroup

from ird_core import planning as core_planning
from ird_core.checks import MAX_ABS_FEATURE, PRIOR_SIGMA_RANGE
from ird_core.mdp import GridMDP
from ird_core.posterior import ObservationModel, Posterior
from ird_core.vocabulary import PROXY_COUNTS, QueryEvent, QueryKind, QueryStrategy, parse
from ird_msgs.msg import FeatureGrid, ProxyReward, QueryRecord, RewardPosterior
from ird_msgs.srv import AnswerQuery, InferReward, ProposeQuery
from ird_ros import conversions as conv
from ird_ros.conversions.inference_requests import InferenceLimits, check_pass_memory, infer_job
from ird_ros.conversions.sizes import check_grid_size, check_text, grid_is_empty
from ird_ros.graph import names
from ird_ros.jobs.inference import (InferenceJob, ResampleJob, observation_model, run_inference, run_resample,
                                    sampler_settings)
from ird_ros.jobs.inference_queries import (ProposalRecord, ProxyQueryJob, QueryJob, WorldEvidence, proxy_query_job,
                                            proxy_test_mdp, query_reference, resample_seed, run_query)
from ird_ros.jobs.work import check_query_work
from ird_ros.runtime.node_main import Arrivals, StartupError, exit_process, run_node
from ird_ros.runtime.lifecycle import ManagedNode
from ird_ros.runtime.node_params import Param, runtime_except
from ird_ros.runtime.offload import BUSY_PREFIX, Offload, OffloadError, service_qos
from ird_ros.stamps import stamp_key

__all__ = ["InferenceNode", "PARAMETERS", "main"]

TEST_MAP_TOPICS = (names.TOPIC_HYPOTHESIS_TEST_FEATURES, names.TOPIC_TEST_FEATURES, names.TOPIC_TERRAIN_FEATURES)
"""Where /ird/query's default map is looked up, in order: the hypothesis space first (its own topic
when the world's hypothesis space is not the sensors', else the sensors' map)."""

MAP_WAIT = 10.0  # seconds /ird/query waits for the latched test map it defaults to (discovery lags)


class _MapMissing(ValueError):
    """No test map with the posterior's features has arrived (yet)."""


PARAMETERS: dict[str, Param] = {
    "default_prior_sigma": Param(0.0, "Prior standard deviation used when a request has prior_sigma 0 (0 = the "
                                      "calibrated 1 / (designer temperature x rms training feature norm))",
                                 min_value=0.0, max_value=PRIOR_SIGMA_RANGE[1]),
    "proxy_counts": Param(ObservationModel().counts, "Observation model of a request with proxy_counts \"\": "
                                                     "optimal (optimal-path counts) | maxent", choices=PROXY_COUNTS),
    "designer_temperature": Param(ObservationModel().temperature, "MaxEnt designer's temperature of a request with "
                                                                  "designer_temperature 0", min_value=1e-3,
                                  max_value=1e3),
    # The sampler settings are passed to sample_posterior only when set (see ird_core.posterior.SamplerSettings).
    "num_chains": Param(0, "MCMC chains run as one batch (0 = the library's default)", min_value=0,
                        max_value=100000),
    "warmup": Param(-1, "MCMC warm-up steps per chain (-1 = the library's default)", min_value=-1,
                    max_value=10**7),
    "thin": Param(0, "Keep every thin-th MCMC step after warm-up (0 = the library's default)", min_value=0,
                  max_value=10**6),
    "num_proxy_samples": Param(0, "Sample-Z: proxies drawn from the proxy prior to approximate Z "
                                  "(0 = the library's default)", min_value=0, max_value=10**6),
    # Run until converged (see the module doc); target_r_hat 0 or thin set: fixed-length chains.
    "target_r_hat": Param(1.05, "Run the chains until their split R-hat is at most this (0 = fixed-length "
                                "chains, the library's default run)", min_value=0.0, max_value=10.0),
    "min_ess": Param(400.0, "With target_r_hat: the bulk ESS must also reach max(min_ess, num_samples / 2)",
                     min_value=0.0),
    "max_iterations": Param(2000, "With target_r_hat: cap on post-warm-up iterations per chain (the "
                                  "deterministic bound)", min_value=1, max_value=10**7),
    "time_budget": Param(60.0, "With target_r_hat: wall seconds of one request after which the chains are not "
                               "extended further (a safety stop, checked in the first run too: spent before "
                               "num_samples draws exist, the request fails naming num_samples; 0 = none)",
                         min_value=0.0),
    "max_num_samples": Param(100000, "Largest num_samples a request may ask for", min_value=1),
    "max_horizon": Param(1000, "Largest horizon a request may ask for", min_value=1),
    "max_map_values": Param(5_000_000, "Largest H*W*d of a training, proxy or query map", min_value=1),
    "max_training_worlds": Param(16, "Largest number of training_worlds of a request", min_value=0),
    "max_request_values": Param(20_000_000, "Largest number of map values of an /ird/infer request, all its maps "
                                            "(training_worlds included) together", min_value=1),
    "max_inference_work": Param(2e11, "Largest work of an /ird/infer request: chains x (warm-up + first run) "
                                      "iterations x leapfrog steps x gradient cost (ird_ros.jobs.work)",
                                min_value=1.0),
    "max_query_work": Param(5e9, "Largest work of an /ird/query request: K (T+1) H W + K H W d + K^3/2 + q^2 K^2 "
                                 "for K posterior samples (ird_ros.jobs.work)", min_value=1.0),
    "worker_memory_mb": Param(4096, "Address space of each inference worker process in MiB (0 = no limit); a "
                                    "request past it fails naming worker_memory_mb", min_value=0),
    "max_workers": Param(1, "Worker processes: inferences computed at the same time (others queue)",
                         min_value=1, max_value=64),
    "max_pending": Param(16, "Valid requests allowed to wait or run at once; more are refused as busy",
                         min_value=1),
    "answer_beta": Param(1.0, "Rationality (Boltzmann beta) of a designer's answer: the default of /ird/answer "
                              "and what /ird/query assumes", min_value=0.0),
    "max_options": Param(8, "Largest num_options a query may ask for", min_value=2, max_value=1000),
    "worker_threads": Param(1, "BLAS/OpenMP threads per worker process (0 = the library default); 1 leaves "
                               "the other cores to the node and the rest of the graph",
                            min_value=0, max_value=1024),
}
#: Read when the node is configured (the worker pool's, read-only); the others may change at run time.
_AT_CONFIGURE = ("worker_memory_mb", "max_workers", "max_pending", "worker_threads")
PARAMETERS = runtime_except(PARAMETERS, _AT_CONFIGURE)


def _record_msg(query_id: int, record: ProposalRecord, event: QueryEvent,
                num_answers: int, stamp: Any, **answer: Any) -> QueryRecord:
    """The ``/ird/queries`` record of a proposal (``answer`` empty) or of its answer."""
    return conv.query_record_to_msg(
        query_id=query_id, event=event, strategy=record.strategy, options=record.options,
        feature_names=record.feature_names, option_features=record.option_features,
        information_gain=record.information_gain, num_answers=num_answers, stamp=stamp, kind=record.kind,
        option_proxies=record.option_proxies, **answer)


def _publish_result(node: "InferenceNode", posterior: Posterior, job: InferenceJob,
                    layers: tuple[str, ...]) -> RewardPosterior:
    """The posterior of ``job`` as a message stamped now, with the sampler's own ``converged``
    verdict and the job's observation model (``ValueError`` if it does not fit a message)."""
    msg = conv.posterior_to_msg(posterior, feature_names=layers, proxy_weights=job.proxy_weights,
                                stamp=conv.now_stamp(node), observation_model=job.observation_model)
    msg.converged = posterior.converged
    return msg


class InferenceNode(ManagedNode):
    """Inference (managed): the worker pool starts at configure and ends at cleanup; requests are
    answered while active; the limits, the sampler and the observation model change at run time."""

    PARAMETERS = PARAMETERS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_INFERENCE, **kwargs)

    def apply_parameters(self, p: dict[str, Any], changed: set[str]) -> None:
        """Check every setting of ``p``, then apply them all (``ValueError`` names a bad one)."""
        sampler = sampler_settings(p)
        try:
            model = observation_model(p["proxy_counts"], float(p["designer_temperature"]))
        except ValueError as exc:
            raise StartupError(f"parameter {exc}") from None
        limits = InferenceLimits(
            max_num_samples=p["max_num_samples"], max_horizon=p["max_horizon"], max_map_values=p["max_map_values"],
            max_training_worlds=p["max_training_worlds"], max_request_values=p["max_request_values"],
            max_inference_work=float(p["max_inference_work"]), memory_limit=self.memory_limit,
            default_prior_sigma=float(p["default_prior_sigma"]), sampler=sampler, observation_model=model)
        self.max_horizon, self.max_map_values = p["max_horizon"], p["max_map_values"]
        self.max_query_work = float(p["max_query_work"])
        self.sampler, self.limits = sampler, limits
        self.answer_beta, self.max_options = float(p["answer_beta"]), int(p["max_options"])

    def configure(self, p: dict[str, Any]) -> None:
        self.memory_limit = int(p["worker_memory_mb"]) * 2**20
        self.apply_parameters(p, set(p))
        if p["worker_threads"] > 0:
            # Read by numpy's BLAS when the spawned worker imports it (the node's numpy is loaded).
            for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
                os.environ[var] = str(p["worker_threads"])
        self._offload = Offload("inference", p["max_pending"], max_workers=p["max_workers"],
                                warm_modules=("ird_core.posterior", "ird_core.mdp"), memory_limit=self.memory_limit,
                                logger=self.get_logger())
        self._pub = self.create_publisher(RewardPosterior, names.TOPIC_POSTERIOR, names.latched_qos())
        self.evidence = WorldEvidence()
        self.maps: dict[str, conv.FeatureGridData] = {}
        self._map_arrivals = Arrivals(self)
        self.proxy: ProxyReward | None = None
        self._queries_pub = self.create_publisher(QueryRecord, names.TOPIC_QUERIES, names.history_qos())
        for topic in TEST_MAP_TOPICS:
            self.create_subscription(FeatureGrid, topic, lambda msg, t=topic: self._on_map(t, msg),
                                     names.latched_qos())
        self.create_subscription(ProxyReward, names.TOPIC_PROXY, self._on_proxy, names.latched_qos())
        # Own reentrant group: a pending (awaiting) request must not hold the default group, which
        # serves parameters (and subscriptions).
        group = ReentrantCallbackGroup()
        self.create_service(InferReward, names.SRV_INFER, self._on_infer, callback_group=group,
                            qos_profile=service_qos())
        self.create_service(ProposeQuery, names.SRV_QUERY, self._on_query, callback_group=group,
                            qos_profile=service_qos())
        self.create_service(AnswerQuery, names.SRV_ANSWER, self._on_answer, callback_group=group,
                            qos_profile=service_qos())

    def release(self) -> None:
        if getattr(self, "_offload", None) is not None:
            self._offload.shutdown()
            self._offload = None

    # ------------------------------------------------------------------ validation

    def validate(self, req: InferReward.Request) -> tuple[InferenceJob, tuple[str, ...]]:
        """The worker job of a request and the training map's layer names.

        Raises:
            ValueError: naming the request field (``inference_requests.infer_job``).
        """
        return infer_job(req, self.limits)

    # ------------------------------------------------------------------ service

    async def _on_infer(self, req: InferReward.Request, response: InferReward.Response) -> InferReward.Response:
        try:
            job, layers = self.validate(req)
        except ValueError as exc:
            response.success, response.message = False, str(exc)
            self.get_logger().debug(f"{names.SRV_INFER} rejected: {exc}")
            return response
        try:
            posterior = await self._offload.run(self.executor, run_inference, job)
            msg = _publish_result(self, posterior, job, layers)
        except OffloadError as exc:
            response.success, response.message = False, str(exc)
            return response
        except ValueError as exc:  # the posterior does not fit a message: a bug, not a bad request
            response.success, response.message = False, f"internal error: {exc}"
            self.get_logger().error(response.message)
            return response
        self._pub.publish(msg)
        info = req.training_map.info
        self.evidence.reset(job, posterior, layers, stamp_key(req.training_map.header.stamp),
                            None if grid_is_empty(req.proxy_map) else tuple(req.proxy_map.layers),
                            (float(info.resolution), (float(info.origin.position.x), float(info.origin.position.y))))
        response.success = True
        response.posterior = msg
        model = job.observation_model
        response.message = (f"{posterior.method} ({model.counts} proxy counts"
                            + (f", designer temperature {model.temperature:g}" if not model.optimal else "")
                            + f"): {posterior.num_samples} samples, acceptance "
                            f"{posterior.acceptance_rate:.2f}, {posterior.diagnosis()}")
        self.get_logger().info(response.message)
        return response

    # ------------------------------------------------------------------ designer queries

    def _on_map(self, topic: str, msg: FeatureGrid) -> None:
        try:
            self.maps[topic] = conv.feature_grid_from_msg(msg, field=topic)
        except ValueError as exc:
            self.get_logger().error(f"ignoring a bad map: {exc}")
        self._map_arrivals.notify()

    def _on_proxy(self, msg: ProxyReward) -> None:
        self.proxy = msg
        if self.evidence.on_proxy(stamp_key(msg.header.stamp)):
            self.get_logger().info("a new world: the evidence (proxy, answers, open queries) was forgotten")

    def _query_map(self, req: ProposeQuery.Request) -> conv.FeatureGridData:
        names_ = self.evidence.feature_names
        if not grid_is_empty(req.map):
            check_grid_size(req.map, "map", self.max_map_values)  # before decoding it
            grid = conv.feature_grid_from_msg(req.map, field="map", max_abs=MAX_ABS_FEATURE)
            if grid.layers != names_:
                raise ValueError(f"map.layers: {list(grid.layers)} must be the posterior's features {list(names_)}")
            return grid
        found = conv.first_with_layers(self.maps, TEST_MAP_TOPICS, names_)
        if found is not None:
            return found[1]
        raise _MapMissing(f"map: empty, and no test map with the posterior's features {list(names_)} was received")

    def validate_query(self, req: ProposeQuery.Request
                       ) -> tuple[QueryJob | ProxyQueryJob, conv.FeatureGridData | None]:
        """The worker job of a query request and its map, ``None`` for kind "proxies" (``ValueError``
        naming the field)."""
        kind = parse(QueryKind, req.kind or QueryKind.PATHS, "kind")
        if self.evidence.posterior is None:
            raise ValueError("evidence: no posterior for the current world: call /ird/infer first")
        if kind is QueryKind.PROXIES:  # evoi re-plans on the latest test map from the proxy's test start
            evoi = (req.strategy or QueryStrategy.EVOI) == QueryStrategy.EVOI and grid_is_empty(req.map)
            return proxy_query_job(
                self.evidence, map_empty=grid_is_empty(req.map), start=(req.start_row, req.start_col),
                horizon=int(req.horizon), num_options=int(req.num_options), strategy=req.strategy, seed=int(req.seed),
                beta=self.answer_beta, max_options=self.max_options, max_query_work=self.max_query_work,
                test=proxy_test_mdp(self._query_map(req), self.proxy) if evoi else None), None
        grid = self._query_map(req)
        h, w, d = grid.shape
        if h * w * d > self.max_map_values:
            raise ValueError(f"map.data: {h * w * d} values exceed max_map_values={self.max_map_values}")
        start = core_planning.check_start((req.start_row, req.start_col), h, w)
        horizon = int(req.horizon)
        if horizon == 0:
            if self.proxy is None:
                raise ValueError("horizon: 0 means /world/proxy's test horizon, and no proxy was received")
            horizon = int(self.proxy.test_horizon)
        if horizon > self.max_horizon:
            raise ValueError(f"horizon: {horizon} exceeds max_horizon={self.max_horizon}")
        num_options = int(req.num_options) or 2
        if not 2 <= num_options <= self.max_options:
            raise ValueError(f"num_options: must be in [2, max_options={self.max_options}], got {num_options}")
        strategy = parse(QueryStrategy, req.strategy or QueryStrategy.EVOI, "strategy")
        samples = self.evidence.posterior.samples
        check_query_work(len(samples), h, w, horizon, d, num_options, self.max_query_work)
        check_pass_memory("map", h, w, horizon, 8, self.memory_limit)  # one sample's plan table (float64)
        mdp = GridMDP(grid.features.astype(np.float64), start, horizon)
        return QueryJob(mdp, samples, self.answer_beta, num_options, strategy, int(req.seed),
                        query_reference(self.evidence)), grid

    async def _on_query(self, req: ProposeQuery.Request, response: ProposeQuery.Response) -> ProposeQuery.Response:
        ev = self.evidence
        try:
            if ev.resampling:
                raise ValueError(f"{BUSY_PREFIX}: re-sampling the posterior with an answer; ask again when it is "
                                 "published")
            deadline = time.monotonic() + MAP_WAIT
            while True:
                try:
                    job, grid = self.validate_query(req)
                    break
                except _MapMissing:
                    if time.monotonic() >= deadline or not await self._map_arrivals.wait(deadline - time.monotonic()):
                        raise
        except ValueError as exc:
            response.success, response.message = False, str(exc)
            return response
        epoch = ev.epoch
        try:
            query = await self._offload.run(self.executor, run_query, job)
        except OffloadError as exc:
            response.success, response.message = False, str(exc)
            return response
        if ev.epoch != epoch:
            response.success, response.message = False, "the evidence was replaced (new world or /ird/infer) meanwhile"
            return response
        kind, proxies, stamp = QueryKind.PATHS, getattr(query, "proxies", None), conv.now_stamp(self)
        if grid is None:  # proxies: their plans on the evidence's training map
            kind, (resolution, origin), (h, w) = QueryKind.PROXIES, ev.train_geometry, job.train_mdp.features.shape[:2]
        else:
            resolution, origin, (h, w, _) = grid.resolution, grid.origin, grid.shape
        paths = conv.options_to_paths(query.option_cells, resolution=resolution, origin=origin, height=h, width=w,
                                      stamp=stamp)
        record = ProposalRecord(QueryStrategy(query.strategy), tuple(paths), ev.feature_names, query.option_features,
                                float(query.information_gain), kind, proxies)
        qid = ev.add_query(query, record)
        self._queries_pub.publish(_record_msg(qid, record, QueryEvent.PROPOSED, len(ev.answers), stamp))
        response.success, response.query_id = True, qid
        response.options, response.feature_names = paths, list(ev.feature_names)
        response.option_features = conv.weights_to_flat(query.option_features, field="option_features")
        response.information_gain, response.kind = float(query.information_gain), kind.value
        if proxies is not None:
            response.option_proxies = conv.weights_to_flat(proxies, field="option_proxies")
            response.proxy_feature_names = list(ev.proxy_feature_names)
        response.message = (f"query {qid}: {query.num_options} {kind} options ({query.strategy}, of "
                            f"{query.num_candidates} candidates), information gain {query.information_gain:.4f} nats")
        self.get_logger().info(response.message)
        return response

    async def _on_answer(self, req: AnswerQuery.Request, response: AnswerQuery.Response) -> AnswerQuery.Response:
        ev = self.evidence
        try:
            check_text(req.answered_by, "answered_by")
            open_query, beta = ev.check_answer(int(req.query_id), int(req.chosen), float(req.beta), self.answer_beta)
            if ev.resampling:
                raise ValueError(f"{BUSY_PREFIX}: re-sampling the posterior with another answer; answer again "
                                 "when it is published")
        except ValueError as exc:
            response.success, response.message = False, str(exc)
            return response
        choice = ev.choice(open_query, int(req.chosen), beta)
        base, layers = ev.job, ev.feature_names
        assert base is not None and ev.posterior is not None  # an open query belongs to current evidence
        job = ResampleJob(base, (*ev.answers, choice), ev.posterior, resample_seed(base.seed, len(ev.answers) + 1))
        epoch, ev.resampling = ev.epoch, True
        try:
            posterior = await self._offload.run(self.executor, run_resample, job)
            msg = _publish_result(self, posterior, base, layers)
        except (OffloadError, ValueError) as exc:
            response.success, response.message = False, f"the answer was not taken: {exc}"
            return response
        finally:
            if ev.epoch == epoch:
                ev.resampling = False
        if ev.epoch != epoch:
            response.success = False
            response.message = "the answer was not taken: the evidence was replaced (new world or /ird/infer) meanwhile"
            return response
        ev.commit(open_query, choice, posterior)
        self._pub.publish(msg)
        who = req.answered_by or "client"
        self._queries_pub.publish(_record_msg(open_query.query_id, open_query.record, QueryEvent.ANSWERED,
                                              len(ev.answers), msg.header.stamp, chosen=int(req.chosen), beta=beta,
                                              answered_by=who))
        response.success, response.posterior = True, msg
        response.message = (f"query {open_query.query_id}: option {req.chosen} by {who}; {len(ev.answers)} answers, "
                            f"acceptance {posterior.acceptance_rate:.2f}, {posterior.diagnosis()}")
        self.get_logger().info(response.message)
        return response


def main(args: list[str] | None = None) -> int:
    return run_node(InferenceNode, args)


if __name__ == "__main__":
    exit_process(main())
