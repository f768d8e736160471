"""Sample ird_msgs messages and the echo server's behaviour, shared by the round-trip
test (tests/ros/test_message_roundtrip.py) and the helper process (_echo_node.py).

Topics: the echo node subscribes to ``/roundtrip/<case>/in`` and republishes every
message on ``/roundtrip/<case>/out``. Services: ``/roundtrip/<service>`` answers with
``respond(request)``, which is deterministic, so the test computes the expected response
itself. ``respond`` puts a SHA-256 of the request's field values into ``message``: equal
digests mean every field of the request arrived bit for bit.

Note: serialized CDR bytes (rclpy.serialization.serialize_message) are NOT comparable
across processes: alignment padding bytes are left uninitialised. Hence ``canonical``.
"""

from __future__ import annotations

import array
import hashlib
from typing import Any, Callable

import numpy as np
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header

from ird_msgs.msg import FeatureGrid, PlanInfo, ProxyReward, QueryRecord, RewardPosterior, RobStatus, TerrainGrid
from ird_msgs.srv import AnswerQuery, GenerateWorld, InferReward, PlanPath, ProposeQuery
from ird_ros import conversions as conv

QOS = QoSProfile(depth=2, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
READY = "ECHO NODE READY"


def _rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


def _header(sec: int = 1700000000, nanosec: int = 123456789, frame_id: str = "map") -> Header:
    h = Header(frame_id=frame_id)
    h.stamp.sec = sec
    h.stamp.nanosec = nanosec
    return h


def feature_grid(h: int, w: int, d: int, seed: int = 0) -> FeatureGrid:
    values = _rng(seed).normal(size=(h, w, d)).astype(np.float32)
    msg = conv.feature_grid_to_msg(values, [f"obs_{k}" for k in range(d)], resolution=0.5, origin=(-3.25, 1.5))
    msg.header = _header()
    return msg


def terrain_grid(with_optional: bool) -> TerrainGrid:
    rng = _rng(1)
    classes = rng.integers(0, 4, size=(7, 9)).astype(np.uint8)
    classes[0, 0] = conv.UNKNOWN_CLASS
    probs = rng.dirichlet(np.ones(4), size=(7, 9)).astype(np.float32) if with_optional else None
    novelty = rng.exponential(size=(7, 9)).astype(np.float32) if with_optional else None
    msg = conv.terrain_grid_to_msg(
        classes, ["dirt", "grass", "target", "lava"], probabilities=probs, novelty=novelty, resolution=2.0
    )
    msg.header = _header(frame_id="map")
    return msg


class _Posterior:  # duck-typed like ird_core.posterior.Posterior
    def __init__(self, samples: np.ndarray) -> None:
        self.samples = samples
        self.method = "sample_z"
        self.beta = 2.5
        self.acceptance_rate = 0.41
        self.r_hat_max = 1.03
        self.ess_min = 812.25
        self.prior_sigma = 1.0
        self.num_chains = 4
        self.seed = 4242
        self.proxy_counts = "maxent"  # the observation model, copied into the message
        self.designer_temperature = 0.625


def reward_posterior() -> RewardPosterior:
    rng = _rng(2)
    samples = rng.normal(size=(200, 6))
    msg = conv.posterior_to_msg(
        _Posterior(samples), feature_names=[f"f{k}" for k in range(6)], proxy_weights=rng.normal(size=6)
    )
    msg.header = _header()
    return msg


def proxy_reward() -> ProxyReward:
    return ProxyReward(
        header=_header(),
        condition="latent_raw",
        seed=7,
        feature_names=[f"obs_{k}" for k in range(50)],
        weights=_rng(3).normal(size=50).tolist(),
        start_row=3,
        start_col=11,
        horizon=25,
        test_start_row=7,
        test_start_col=0,
        test_horizon=30,
        terrain_names=["dirt", "grass", "target", "lava"],
        true_terrain_rewards=[0.1, -0.2, 1.0, -10.0],
    )


def rob_status() -> RobStatus:
    return RobStatus(
        header=_header(),
        row=4,
        col=9,
        terrain="grass",
        step=12,
        horizon=30,
        done=False,
        touched_lava=True,
        reached_target=False,
        true_return=-10.7,
        plan_label="ird_per_step ✓",  # non-ASCII survives too
        plan_stamp=_header(sec=1700000001, nanosec=5).stamp,
    )


def plan_info() -> PlanInfo:
    return PlanInfo(header=_header(), label="ird_trajectory_log_z", mode="trajectory", baseline="log_z",
                    objective=-3.0625, rows=[1, 1, 2, 3], cols=[2, 3, 3, 3], risk="cvar", risk_level=0.1)


def _options() -> list[Any]:
    cells = [[(0, 0), (1, 0), (1, 1)], [(0, 0), (0, 1), (0, 1)]]
    return conv.options_to_paths([np.array(c) for c in cells], resolution=0.5, origin=(-1.0, 2.0))


def query_record() -> QueryRecord:
    return conv.query_record_to_msg(query_id=7, event="answered", strategy="info_gain", options=_options(),
                                    feature_names=("dirt", "grass", "target"),
                                    option_features=_rng(6).normal(size=(2, 3)), information_gain=0.3125,
                                    chosen=1, beta=2.5, answered_by="simulated", num_answers=3,
                                    stamp=_header().stamp)


# name -> (message type, builder)
TOPIC_CASES: dict[str, tuple[type, Callable[[], Any]]] = {
    "feature_grid": (FeatureGrid, lambda: feature_grid(15, 15, 4)),
    "feature_grid_100x100x50": (FeatureGrid, lambda: feature_grid(100, 100, 50, seed=5)),
    "terrain_grid": (TerrainGrid, lambda: terrain_grid(with_optional=True)),
    "terrain_grid_ground_truth": (TerrainGrid, lambda: terrain_grid(with_optional=False)),
    "reward_posterior": (RewardPosterior, reward_posterior),
    "proxy_reward": (ProxyReward, proxy_reward),
    "rob_status": (RobStatus, rob_status),
    "plan_info": (PlanInfo, plan_info),
    "query_record": (QueryRecord, query_record),
}

SERVICES: dict[str, type] = {
    "infer_reward": InferReward,
    "plan_path": PlanPath,
    "generate_world": GenerateWorld,
    "propose_query": ProposeQuery,
    "answer_query": AnswerQuery,
}


def canonical(msg: Any) -> bytes:
    """Deterministic bytes of a message's field values (floats exact, arrays raw)."""
    parts = [type(msg).__name__.encode()]
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        if hasattr(value, "get_fields_and_field_types"):
            parts.append(canonical(value))
        elif isinstance(value, array.array):
            parts.append(value.typecode.encode() + value.tobytes())
        elif isinstance(value, (list, tuple)):
            parts.append(b"[" + b",".join(canonical(v) if hasattr(v, "get_fields_and_field_types")
                                          else repr(v).encode() for v in value) + b"]")
        else:
            parts.append(repr(value).encode())
    return b"|".join(parts)


def digest(request: Any) -> str:
    return hashlib.sha256(canonical(request)).hexdigest()


def infer_request(*, short_data: bool = False) -> InferReward.Request:
    req = InferReward.Request()
    req.training_map = feature_grid(10, 12, 3, seed=9)
    if short_data:
        req.training_map.data = req.training_map.data[:-1]
    req.start_row, req.start_col, req.horizon = 2, 5, 20
    req.proxy_weights = [0.1, -0.2]
    req.proxy_map = feature_grid(10, 12, 2, seed=12)  # the proxy lives on its own 2 layers
    req.beta, req.method, req.num_samples, req.seed, req.prior_sigma = 3.0, "maxent_z", 50, 11, 0.0
    req.proxy_counts, req.designer_temperature = "optimal", 0.3
    return req


def plan_request() -> PlanPath.Request:
    req = PlanPath.Request()
    req.map = feature_grid(6, 8, 3, seed=10)
    req.start_row, req.start_col, req.horizon = 1, 2, 4
    req.mode, req.baseline, req.label = "trajectory", "log_z", "ird_trajectory"
    req.weights = _rng(4).normal(size=(5, 3)).reshape(-1).tolist()
    req.reference_features = [0.7, 0.2, 0.1]
    req.risk, req.risk_level = "cvar", 0.1  # 0.1 has no exact binary form: the bits must survive
    return req


def generate_request() -> GenerateWorld.Request:
    return GenerateWorld.Request(condition="reward_hacking", seed=123)


def propose_request() -> ProposeQuery.Request:
    return ProposeQuery.Request(map=feature_grid(6, 8, 3, seed=13), start_row=1, start_col=2, horizon=4,
                                num_options=3, strategy="random", seed=17)


def answer_request() -> AnswerQuery.Request:
    return AnswerQuery.Request(query_id=42, chosen=1, beta=0.75, answered_by="web")


SERVICE_REQUESTS: dict[str, Callable[[], Any]] = {
    "infer_reward": infer_request,
    "plan_path": plan_request,
    "generate_world": generate_request,
    "propose_query": propose_request,
    "answer_query": answer_request,
}


def respond(request: Any) -> Any:
    """The echo server's deterministic response to ``request`` (validated like a real node)."""
    if isinstance(request, InferReward.Request):
        resp = InferReward.Response()
        try:
            grid = conv.feature_grid_from_msg(request.training_map, field="training_map")
            proxy_map = conv.feature_grid_from_msg(request.proxy_map, field="proxy_map")
            proxy = conv.weights_from_flat(request.proxy_weights, len(proxy_map.layers), field="proxy_weights")[0]
        except ValueError as exc:
            resp.success, resp.message = False, str(exc)
            return resp
        d = len(grid.layers)
        post = _Posterior(np.arange(request.num_samples * d, dtype=float).reshape(-1, d) / 7.0)
        post.method, post.beta, post.seed = request.method, request.beta, request.seed
        post.prior_sigma = request.prior_sigma or 1.0
        post.proxy_counts, post.designer_temperature = request.proxy_counts, request.designer_temperature
        resp.posterior = conv.posterior_to_msg(post, feature_names=grid.layers, proxy_weights=proxy)
        resp.posterior.header = request.training_map.header
        resp.success, resp.message = True, digest(request)
        return resp
    if isinstance(request, PlanPath.Request):
        resp = PlanPath.Response()
        grid = conv.feature_grid_from_msg(request.map, field="map")
        weights = conv.weights_from_flat(request.weights, len(grid.layers), field="weights")
        cells = [(request.start_row, request.start_col + min(t, grid.shape[1] - 1 - request.start_col))
                 for t in range(request.horizon + 1)]
        resp.path = conv.cells_to_path(cells, resolution=grid.resolution, origin=grid.origin)
        resp.rows = [r for r, _ in cells]
        resp.cols = [c for _, c in cells]
        resp.objective = float(weights.sum()) + len(request.label)
        resp.risk, resp.risk_level = request.risk, request.risk_level * 2  # the response's own fields travel
        resp.success, resp.message = True, digest(request)
        return resp
    if isinstance(request, ProposeQuery.Request):
        grid = conv.feature_grid_from_msg(request.map, field="map")
        q, d = int(request.num_options), len(grid.layers)
        cells = [np.array([(request.start_row, request.start_col + min(t * k, grid.shape[1] - 1 - request.start_col))
                           for t in range(request.horizon + 1)]) for k in range(q)]
        return ProposeQuery.Response(
            success=True, message=digest(request), query_id=request.seed + 1,
            options=conv.options_to_paths(cells, resolution=grid.resolution, origin=grid.origin),
            feature_names=list(grid.layers), option_features=np.arange(q * d, dtype=float).tolist(),
            information_gain=0.5)
    if isinstance(request, AnswerQuery.Request):
        resp = AnswerQuery.Response(success=True, message=digest(request))
        post = _Posterior(np.full((2, 3), request.beta))
        post.method, post.beta, post.seed, post.prior_sigma = "sample_z", 1.0, request.query_id, 1.0
        resp.posterior = conv.posterior_to_msg(post, feature_names=("a", "b", "c"), proxy_weights=np.ones(3))
        return resp
    if isinstance(request, GenerateWorld.Request):
        return GenerateWorld.Response(success=True, message=f"{request.condition}/{request.seed}/{digest(request)}")
    raise TypeError(f"no echo behaviour for {type(request).__name__}")
