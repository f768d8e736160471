"""The inference node: serves IRD posterior sampling on ``/ird/infer`` and latches the result.

Run: ``python -m ird_ros.inference --ros-args --params-file msgs_config/params/graph.yaml``

``/ird/infer`` (InferReward) validates every field first and answers a bad request at once with
``success: false`` and a message that starts with the field's name (``training_map.data: ...``,
``start_row: ...``, ``proxy_weights: ...``). A good request is sampled with
``ird_core.inference.sample_posterior`` in a worker process and the result is returned and
published on ``/ird/posterior`` (reliable, transient local). The posterior of a seeded request is
exactly ``sample_posterior(proxy_weights, GridMDP(training_map, (start_row, start_col), horizon),
beta, method, num_samples, seed, prior_sigma, **settings)`` where ``settings`` holds those of
``num_chains``, ``warmup``, ``thin``, ``num_proxy_samples`` that the node's parameters set (by
default none: the library's defaults), and the map's float32 values are used as float64.

The proxy map (latent_classifier): with ``proxy_map`` non-empty, the proxy weights apply to
``proxy_map``'s layers. The proxy's MaxEnt behaviour is planned on ``proxy_map`` (same grid,
start and horizon), and its expected visits contracted with ``training_map``'s features give the
``phi~(w~)`` IRD conditions on (``proxy_features`` of sample_posterior). For Sample-Z the proxy
prior samples are drawn in the proxy's space (``proxy_prior_samples(N, p, sigma, seed)``, as
``ird_core.lavaland.proxy_prior_features`` does), planned on ``proxy_map`` and contracted the
same way (``proxy_sample_features``). See :func:`proxy_map_terms` and :func:`run_inference`;
the request's ``p`` proxy weights are recorded in the posterior as they are.

Responsiveness: the service callback is a coroutine that awaits the worker process
(``node_main.WorkerPool``); the executor keeps serving parameters and other requests meanwhile.
Concurrency: requests are computed one at a time in arrival order (``max_workers`` = 1 by
default); invalid requests never queue; more than ``max_pending`` valid requests waiting at once
get ``success: false`` ("busy").
"""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node

from ird_core import inference as core_inference
from ird_core import mdp as core_mdp
from ird_msgs.msg import RewardPosterior
from ird_msgs.srv import InferReward
from ird_ros import conversions as conv
from ird_ros import names
from ird_ros.node_main import BrokenProcessPool, WorkerPool, declare, run_node, exit_process

__all__ = ["InferenceNode", "RequestError", "proxy_map_terms", "run_inference", "main"]


class RequestError(ValueError):
    """A bad request; the message starts with the field's name."""


def proxy_map_terms(
    training_features: np.ndarray,
    proxy_features: np.ndarray,
    start: tuple[int, int],
    horizon: int,
    proxy_weights: np.ndarray,
    method: str,
    prior_sigma: float,
    seed: int,
    num_proxy_samples: int,
) -> tuple[np.ndarray, np.ndarray | None]:
    """``phi~(w~)`` (d,) and, for Sample-Z, the ``phi_i`` (N, d) of a proxy defined on a proxy map.

    The proxy (and each prior proxy) is planned by the MaxEnt agent on ``proxy_features``
    (H, W, p); its expected visits are contracted with ``training_features`` (H, W, d).
    """
    proxy_mdp = core_mdp.GridMDP(proxy_features, start, horizon)
    train = np.asarray(training_features, dtype=np.float64)
    visits = core_mdp.expected_visitation(proxy_mdp, np.asarray(proxy_weights, dtype=np.float64)[None, :])
    phi = np.einsum("khw,hwd->kd", visits, train, optimize=True)[0]
    if method != "sample_z":
        return phi, None
    samples = core_inference.proxy_prior_samples(num_proxy_samples, proxy_mdp.num_features, prior_sigma, seed)
    sample_phi = np.empty((num_proxy_samples, train.shape[2]))
    batch = 256  # bounded memory: (T+1, batch, H, W) per call
    for lo in range(0, num_proxy_samples, batch):
        v = core_mdp.expected_visitation(proxy_mdp, samples[lo : lo + batch])
        sample_phi[lo : lo + len(v)] = np.einsum("khw,hwd->kd", v, train, optimize=True)
    return phi, sample_phi


def run_inference(job: dict[str, Any]) -> Any:
    """The worker-process job: ``sample_posterior`` on a validated request (see the module doc)."""
    train_mdp = core_mdp.GridMDP(job["training_features"], job["start"], job["horizon"])
    kwargs: dict[str, Any] = dict(job["sampler"])
    if job.get("proxy_features") is not None:
        phi, sample_phi = proxy_map_terms(
            job["training_features"], job["proxy_features"], job["start"], job["horizon"],
            job["proxy_weights"], job["method"], job["prior_sigma"], job["seed"],
            kwargs.get("num_proxy_samples", core_inference.DEFAULT_NUM_PROXY_SAMPLES))
        kwargs["proxy_features"] = phi
        if sample_phi is not None:
            kwargs["proxy_sample_features"] = sample_phi
    return core_inference.sample_posterior(
        job["proxy_weights"], train_mdp, job["beta"], job["method"], job["num_samples"], job["seed"],
        job["prior_sigma"], **kwargs)


def _finite_number(field: str, value: float, *, allow_zero: bool = True) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise RequestError(f"{field}: must be finite, got {value!r}")
    if value < 0 or (value == 0 and not allow_zero):
        raise RequestError(f"{field}: must be {'>=' if allow_zero else '>'} 0, got {value!r}")
    return value


class InferenceNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_INFERENCE, **kwargs)
        self.default_prior_sigma = declare(
            self, "default_prior_sigma", 1.0, "Prior standard deviation used when a request has prior_sigma 0",
            min_value=1e-12)
        # Sampler settings: passed to sample_posterior only when set (else the library decides).
        self.num_chains = declare(self, "num_chains", 0,
                                  "MCMC chains run as one batch (0 = the library's default)",
                                  min_value=0, max_value=100000)
        self.warmup = declare(self, "warmup", -1, "MCMC warm-up steps per chain (-1 = the library's default)",
                              min_value=-1, max_value=10**7)
        self.thin = declare(self, "thin", 0, "Keep every thin-th MCMC step after warm-up (0 = the library's default)",
                            min_value=0, max_value=10**6)
        self.num_proxy_samples = declare(
            self, "num_proxy_samples", 0,
            "Sample-Z: proxies drawn from the proxy prior to approximate Z (0 = the library's default)",
            min_value=0, max_value=10**6)
        self.max_num_samples = declare(self, "max_num_samples", 100000,
                                       "Largest num_samples a request may ask for", min_value=1)
        self.max_horizon = declare(self, "max_horizon", 1000, "Largest horizon a request may ask for",
                                   min_value=1)
        self.max_map_values = declare(self, "max_map_values", 5_000_000,
                                      "Largest H*W*d of a training or proxy map", min_value=1)
        self.max_workers = declare(self, "max_workers", 1,
                                   "Worker processes: inferences computed at the same time (others queue)",
                                   min_value=1, max_value=64, read_only=True)
        self.max_pending = declare(self, "max_pending", 16,
                                   "Valid requests allowed to wait or run at once; more are refused as busy",
                                   min_value=1)
        self.worker_threads = declare(
            self, "worker_threads", 1,
            "BLAS/OpenMP threads per worker process (0 = the library default); 1 leaves the other "
            "cores to the node and the rest of the graph", min_value=0, max_value=1024, read_only=True)
        if self.worker_threads > 0:
            # Read by numpy's BLAS when the spawned worker imports it (the node's numpy is loaded).
            for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
                os.environ[var] = str(self.worker_threads)
        self._pool = WorkerPool(self.max_workers, warm_modules=("ird_core.inference",))
        self._pending = 0
        self._pub = self.create_publisher(RewardPosterior, names.TOPIC_POSTERIOR, names.latched_qos())
        self.create_service(InferReward, names.SRV_INFER, self._on_infer,
                            # Own reentrant group: a pending (awaiting) request must not hold the
                            # default group, which serves parameters (and subscriptions).
                            callback_group=ReentrantCallbackGroup())

    def destroy_node(self) -> None:
        self._pool.shutdown()
        super().destroy_node()

    # ------------------------------------------------------------------ validation

    def validate(self, req: InferReward.Request) -> dict[str, Any]:
        """Check every field; return the worker job, or raise :class:`RequestError`."""
        try:
            train = conv.feature_grid_from_msg(req.training_map, field="training_map")
        except ValueError as exc:
            raise RequestError(str(exc)) from None
        h, w, d = train.shape
        if h * w * d > self.max_map_values:
            raise RequestError(f"training_map.data: {h * w * d} values exceed max_map_values={self.max_map_values}")
        proxy_features = None
        proxy_dim, proxy_source = d, "training_map.layers"
        if len(req.proxy_map.layers) or len(req.proxy_map.data):
            try:
                proxy = conv.feature_grid_from_msg(req.proxy_map, field="proxy_map")
            except ValueError as exc:
                raise RequestError(str(exc)) from None
            if proxy.shape[:2] != (h, w):
                raise RequestError(f"proxy_map.info: a {proxy.shape[0]}x{proxy.shape[1]} map does not match "
                                   f"the {h}x{w} training_map")
            if proxy.features.size > self.max_map_values:
                raise RequestError(f"proxy_map.data: {proxy.features.size} values exceed max_map_values")
            proxy_features = proxy.features.astype(np.float64)
            proxy_dim, proxy_source = proxy.shape[2], "proxy_map.layers"
        if req.start_row >= h:
            raise RequestError(f"start_row: {req.start_row} is off the map (height {h})")
        if req.start_col >= w:
            raise RequestError(f"start_col: {req.start_col} is off the map (width {w})")
        if req.horizon == 0:
            raise RequestError("horizon: must be > 0, got 0")
        if req.horizon > self.max_horizon:
            raise RequestError(f"horizon: {req.horizon} exceeds max_horizon={self.max_horizon}")
        beta = _finite_number("beta", req.beta)
        if req.method not in core_inference.METHODS:
            raise RequestError(f"method: must be one of {list(core_inference.METHODS)}, got {req.method!r}")
        if req.num_samples == 0:
            raise RequestError("num_samples: must be > 0, got 0")
        if req.num_samples > self.max_num_samples:
            raise RequestError(f"num_samples: {req.num_samples} exceeds max_num_samples={self.max_num_samples}")
        prior_sigma = _finite_number("prior_sigma", req.prior_sigma)
        if prior_sigma == 0.0:
            prior_sigma = float(self.default_prior_sigma)
        weights = np.array(req.proxy_weights, dtype=np.float64).reshape(-1)
        if weights.size != proxy_dim:
            raise RequestError(f"proxy_weights: expected {proxy_dim} values (one per {proxy_source}), "
                               f"got {weights.size}")
        if not np.all(np.isfinite(weights)):
            raise RequestError("proxy_weights: contains NaN or infinite values")
        return dict(
            training_features=train.features.astype(np.float64),
            layers=train.layers,
            proxy_features=proxy_features,
            start=(int(req.start_row), int(req.start_col)),
            horizon=int(req.horizon),
            proxy_weights=weights,
            beta=beta,
            method=req.method,
            num_samples=int(req.num_samples),
            seed=int(req.seed),
            prior_sigma=prior_sigma,
            sampler=self.sampler_settings(),
        )

    def sampler_settings(self) -> dict[str, Any]:
        """The keyword arguments of sample_posterior set by the node's parameters (unset ones are
        left out, so the library's defaults apply)."""
        settings: dict[str, Any] = {}
        if self.num_chains > 0:
            settings["num_chains"] = int(self.num_chains)
        if self.warmup >= 0:
            settings["warmup"] = int(self.warmup)
        if self.thin > 0:
            settings["thin"] = int(self.thin)
        if self.num_proxy_samples > 0:
            settings["num_proxy_samples"] = int(self.num_proxy_samples)
        return settings

    # ------------------------------------------------------------------ service

    async def _on_infer(self, req: InferReward.Request, response: InferReward.Response) -> InferReward.Response:
        try:
            job = self.validate(req)
        except RequestError as exc:
            response.success, response.message = False, str(exc)
            self.get_logger().debug(f"{names.SRV_INFER} rejected: {exc}")
            return response
        if self._pending >= self.max_pending:
            response.success = False
            response.message = f"busy: {self._pending} requests are pending (max_pending={self.max_pending})"
            return response
        self._pending += 1
        try:
            posterior = await self._pool.submit(self.executor, run_inference, job)
        except ValueError as exc:  # the library's own validation (names the argument)
            response.success, response.message = False, str(exc)
            return response
        except BrokenProcessPool as exc:
            response.success, response.message = False, f"internal error: the worker process died ({exc})"
            self.get_logger().error(response.message)
            return response
        except Exception as exc:  # noqa: BLE001 - keep serving; report it
            response.success, response.message = False, f"internal error: {type(exc).__name__}: {exc}"
            self.get_logger().error(response.message)
            return response
        finally:
            self._pending -= 1
        try:
            msg = conv.posterior_to_msg(posterior, feature_names=job["layers"],
                                        proxy_weights=job["proxy_weights"],
                                        stamp=self.get_clock().now().to_msg())
        except ValueError as exc:
            response.success, response.message = False, f"internal error: {exc}"
            self.get_logger().error(response.message)
            return response
        self._pub.publish(msg)
        response.success = True
        response.posterior = msg
        response.message = (f"{posterior.method}: {posterior.num_samples} samples, acceptance "
                            f"{posterior.acceptance_rate:.2f}, r_hat_max {posterior.r_hat_max:.3f}"
                            + ("" if posterior.converged else " (NOT converged)"))
        self.get_logger().info(response.message)
        return response


def main(args: list[str] | None = None) -> int:
    return run_node(InferenceNode, args)


if __name__ == "__main__":
    exit_process(main())
