"""The inference node's requests as validated jobs: sizes first, then decoding, then the library.

:func:`infer_job` turns an ``InferReward`` request into the worker's ``InferenceJob`` in three
stages, each refusing with a ``ValueError`` whose message starts with the field's name:

1. Sizes and work from the declared lengths, nothing decoded yet (:mod:`ird_ros.conversions.sizes`):
   every map against ``max_map_values``; ``training_worlds`` against ``max_training_worlds`` and
   all maps together against ``max_request_values``; proxy weights (one per layer) against
   ``max_map_values``; ``horizon`` (and each world's) in ``[1, max_horizon]``; ``num_samples`` up to
   ``max_num_samples``; ``method``; then the work model (:func:`ird_ros.jobs.work.check_inference_work`
   against ``max_inference_work``) and one MDP pass's memory against the worker's memory; then the
   observation model (``proxy_counts``, ``designer_temperature``; "" and 0 = the node's
   parameters) by :func:`ird_ros.jobs.inference.observation_model`.
2. Decoding (``conversions.feature_grid_from_msg``): layers, lengths, finite values, ``|value| <=
   MAX_ABS_FEATURE``, matching grids, start cells.
3. The library's argument checks (``checks.check_posterior_arguments``, ``GridMDP``); each training
   world's proxy weights are checked here by their own name (``training_worlds[i].proxy_weights``,
   the same ``|w| <= MAX_ABS_WEIGHT`` range), so no bad value reaches the worker, where it would be
   reported as the request's own ``proxy_weights``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ird_core import checks
from ird_core import planning as core_planning
from ird_core.checks import MAX_ABS_FEATURE, MAX_ABS_WEIGHT
from ird_core.mdp import GridMDP
from ird_core.posterior import DEFAULT_OBSERVATION_MODEL, ObservationModel, SamplerSettings, calibrated_prior_sigma
from ird_core.vocabulary import ZMethod, parse
from ird_ros.conversions.grids import FeatureGridData, feature_grid_from_msg
from ird_ros.conversions.sizes import check_grid_size, grid_is_empty
from ird_ros.jobs.inference import ExtraWorld, InferenceJob, observation_model
from ird_ros.jobs.work import WorldSize, check_inference_work

__all__ = ["InferenceLimits", "infer_job", "check_pass_memory"]


@dataclass(frozen=True)
class InferenceLimits:
    """The inference node's request limits (its parameters of the same names; ``memory_limit``
    in bytes, 0 = none) and the settings a job is built with (``observation_model``: the node's
    ``proxy_counts`` and ``designer_temperature``, for requests that leave them unset)."""

    max_num_samples: int
    max_horizon: int
    max_map_values: int
    max_training_worlds: int
    max_request_values: int
    max_inference_work: float
    memory_limit: int
    default_prior_sigma: float
    sampler: SamplerSettings
    observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL


def check_pass_memory(field: str, height: int, width: int, horizon: int, bytes_per_cell: int,
                      memory_limit: int) -> None:
    """Refuse a map whose one-weight MDP table (``bytes_per_cell x (T + 1) x H x W``) alone
    exceeds the worker's memory (``memory_limit`` bytes, 0 = none)."""
    need = bytes_per_cell * (horizon + 1) * height * width
    if memory_limit and need > memory_limit:
        raise ValueError(f"{field}: one weight's {horizon + 1} x {height} x {width} MDP table needs "
                         f"{need / 2**20:.0f} MiB, more than worker_memory_mb={memory_limit // 2**20}")


def _declared_world(prefix: str, msg: Any, horizon: int, limits: InferenceLimits) -> tuple[WorldSize, int]:
    """One world's declared size, its maps and proxy weights checked against ``max_map_values``
    and its ``horizon`` against ``[1, max_horizon]``; ``(WorldSize, values its maps hold)``."""
    values = check_grid_size(msg.training_map, f"{prefix}training_map", limits.max_map_values)
    if not grid_is_empty(msg.proxy_map):
        values += check_grid_size(msg.proxy_map, f"{prefix}proxy_map", limits.max_map_values)
    if len(msg.proxy_weights) > limits.max_map_values:  # one per layer: never more than a map's values
        raise ValueError(f"{prefix}proxy_weights: {len(msg.proxy_weights)} values, more than a map may have layers "
                         f"(max_map_values={limits.max_map_values})")
    if not 0 < horizon <= limits.max_horizon:
        raise ValueError(f"{prefix}horizon: must be in [1, max_horizon={limits.max_horizon}], got {horizon}")
    return WorldSize(int(msg.training_map.info.height), int(msg.training_map.info.width), int(horizon)), values


def _check_sizes(req: Any, limits: InferenceLimits) -> None:
    """Stage 1 (module doc): every size and the work, from declared lengths only."""
    worlds_msgs = req.training_worlds
    if len(worlds_msgs) > limits.max_training_worlds:
        raise ValueError(f"training_worlds: {len(worlds_msgs)} worlds exceed max_training_worlds="
                         f"{limits.max_training_worlds}")
    own, total = _declared_world("", req, int(req.horizon), limits)
    worlds = [own]
    for i, world in enumerate(worlds_msgs):
        size, values = _declared_world(f"training_worlds[{i}].", world, int(world.horizon), limits)
        worlds.append(size)
        total += values
    if total > limits.max_request_values:
        raise ValueError(f"{'training_worlds' if len(worlds_msgs) else 'training_map'}: the request's maps hold "
                         f"{total} values in all, more than max_request_values={limits.max_request_values}")
    if req.num_samples > limits.max_num_samples:
        raise ValueError(f"num_samples: {req.num_samples} exceeds max_num_samples={limits.max_num_samples}")
    method = parse(ZMethod, req.method, "method")
    checks.check_int("num_samples", int(req.num_samples), 1)
    check_inference_work(worlds, len(req.training_map.layers), method, int(req.num_samples), limits.sampler,
                         limits.max_inference_work)
    for i, world in enumerate(worlds):
        # One weight's pass keeps two (T + 1) x (H + 1) x (W + 1) float64 tables (ird_core.mdp.passes).
        field = "training_map" if i == 0 else f"training_worlds[{i - 1}].training_map"
        check_pass_memory(field, world.height + 1, world.width + 1, world.horizon, 16, limits.memory_limit)


def _world_maps(prefix: str, msg: Any, layers: tuple[str, ...] | None = None
                ) -> tuple[FeatureGridData, FeatureGridData | None, tuple[int, int]]:
    """A world's decoded training map, proxy map (or None) and start, for the request itself
    (``prefix`` "") and each ``training_worlds[i].``; errors name ``<prefix><field>``."""
    train = feature_grid_from_msg(msg.training_map, field=f"{prefix}training_map", max_abs=MAX_ABS_FEATURE)
    h, w, _ = train.shape
    if layers is not None and train.layers != layers:
        raise ValueError(f"{prefix}training_map.layers: {list(train.layers)} must be the request's training_map "
                         f"layers {list(layers)}")
    proxy = None
    if not grid_is_empty(msg.proxy_map):
        proxy = feature_grid_from_msg(msg.proxy_map, field=f"{prefix}proxy_map", max_abs=MAX_ABS_FEATURE)
        if proxy.shape[:2] != (h, w):
            raise ValueError(f"{prefix}proxy_map.info: a {proxy.shape[0]}x{proxy.shape[1]} map does not match "
                             f"the {h}x{w} {prefix}training_map")
    try:
        start = core_planning.check_start((msg.start_row, msg.start_col), h, w)
    except ValueError as exc:
        raise ValueError(f"{prefix}{exc}") from None
    return train, proxy, start


def _training_world(i: int, msg: Any, layers: tuple[str, ...], default_weights: np.ndarray) -> ExtraWorld:
    """``training_worlds[i]`` validated (ValueError naming ``training_worlds[i].<field>``)."""
    key = f"training_worlds[{i}]"
    train, proxy, start = _world_maps(key + ".", msg, layers)
    weights = np.asarray(msg.proxy_weights, dtype=np.float64) if len(msg.proxy_weights) else default_weights
    expected = train.shape[2] if proxy is None else proxy.shape[2]
    if weights.shape != (expected,) or not np.all(np.isfinite(weights)):
        raise ValueError(f"{key}.proxy_weights: expected {expected} finite values (one per "
                         f"{'training_map' if proxy is None else 'proxy_map'} layer), got {weights.tolist()}")
    checks.check_magnitude(f"{key}.proxy_weights", weights, MAX_ABS_WEIGHT)
    train_mdp = GridMDP(train.features.astype(np.float64), start, int(msg.horizon))
    proxy_mdp = None if proxy is None else train_mdp.with_features(proxy.features.astype(np.float64))
    return ExtraWorld(train_mdp, proxy_mdp, weights)


def infer_job(req: Any, limits: InferenceLimits) -> tuple[InferenceJob, tuple[str, ...]]:
    """The worker job of an ``InferReward`` request and the training map's layer names.

    Raises:
        ValueError: naming the request field (module doc: sizes, decoding, the library's checks).
    """
    _check_sizes(req, limits)
    model = observation_model(req.proxy_counts, float(req.designer_temperature), limits.observation_model)
    train, proxy, start = _world_maps("", req)
    d = train.shape[2]
    # 0 = the node's default_prior_sigma; that 0 = None, the calibrated sigma of the temperature and
    # the training maps' features, resolved by the library (ird_core.posterior.calibration)
    prior_sigma = float(req.prior_sigma) or float(limits.default_prior_sigma) or None
    weights = checks.check_posterior_arguments(
        np.asarray(req.proxy_weights, dtype=np.float64), d if proxy is None else proxy.shape[2], req.beta,
        req.method, int(req.num_samples),
        calibrated_prior_sigma(model.temperature) if prior_sigma is None else prior_sigma)
    train_mdp = GridMDP(train.features.astype(np.float64), start, int(req.horizon))
    job = InferenceJob(
        train_mdp=train_mdp,
        proxy_mdp=None if proxy is None else train_mdp.with_features(proxy.features.astype(np.float64)),
        proxy_weights=weights,
        beta=float(req.beta),
        method=ZMethod(req.method),
        num_samples=int(req.num_samples),
        seed=int(req.seed),
        prior_sigma=prior_sigma,
        sampler=limits.sampler,
        extra_worlds=tuple(_training_world(i, world, train.layers, weights)
                           for i, world in enumerate(req.training_worlds)),
        observation_model=model,
    )
    return job, train.layers
