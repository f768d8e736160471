"""The inference node's worker jobs (no ROS): a validated ``/ird/infer`` request as
:class:`InferenceJob`, and the re-sampling of ``/ird/answer`` as :class:`ResampleJob`.

The posterior (docs/spec.md section 3). The posterior of a seeded request is exactly
``sample_posterior(proxy_weights, GridMDP(training_map, (start_row, start_col), horizon), beta,
method, num_samples, seed, prior_sigma, **settings)`` where ``settings`` holds those of
``num_chains``, ``warmup``, ``thin``, ``num_proxy_samples`` that the node's parameters set (by
default none: the library's defaults), and the map's float32 values are used as float64.

Convergence: unless ``target_r_hat`` is 0 or ``thin`` is set, ``settings`` also holds
``until_converged=RunUntil(target_r_hat, min_ess, max_iterations=max_iterations,
time_budget_s=time_budget or None)`` (``ird_core.posterior.RunUntil``): the same chains
are extended until the split R-hat is at most ``target_r_hat`` and the bulk ESS at least
``max(min_ess, num_samples / 2)``, or a bound stops them, then thinned to ``num_samples``; so the
number of samples asked for does not decide whether the chains mix. The iteration cap is the
deterministic bound (a seeded request gives the same posterior on any machine); the time budget
is a safety stop only, checked in the first run as in the extension (``RunUntil``), so it holds
for any ``num_samples``: spent before every chain has its ``ceil(num_samples / C)`` draws, the
job fails with a ``ValueError`` naming ``num_samples``. A set ``thin`` means fixed-length chains (``ceil(num_samples /
num_chains) * thin`` iterations).

The proxy map (latent_classifier): with a proxy map, the proxy weights apply to its layers.
``phi~(w~)`` (``proxy_features`` of sample_posterior) is ``ird_core.posterior.proxy_feature_counts``
of the proxy planned on the proxy map (same grid, start and horizon) with the training map's
features as the hypothesis features. For Sample-Z the proxy prior samples are drawn in the
proxy's space (``proxy_prior_samples(N, p, sigma, seed)``, as
``ird_core.posterior.proxy_prior_features`` does) and counted the same way
(``proxy_sample_features``); see :func:`world_observation` (``ird_core.posterior.proxy_observation``).
The request's ``p`` proxy weights are recorded in the posterior as they are.

Several training worlds (docs/spec.md section 7): each extra world is one more
``ProxyObservation`` after the request's own; the posterior is then exactly
``sample_joint_posterior(job_observations(job), beta, method, num_samples, seed, prior_sigma,
**settings)``.

Re-sampling with answers: ``sample_joint_posterior([proxies] + answers, ..., seed=
resample_seed(seed, n), initial=<current posterior>)`` (a warm start, with the library's own
short warm-up).

The observation model (docs/spec.md section 3): every call above gets
``observation_model=job.observation_model`` (an ``ird_core.posterior.ObservationModel`` built by
:func:`observation_model` from the request's ``proxy_counts`` and ``designer_temperature``), and
the proxy observations that carry their own counts (a proxy map) are built with the same model,
so ``phi~``, Sample-Z's ``phi_i`` and its own term agree. A :class:`ResampleJob` re-samples with
its ``base`` job's model: the model of the posterior it extends. Sample-Z's own term is the
library's default (``ObservationModel().own_term``): an experiment control, not a ROS field.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ird_core import posterior as core_inference
from ird_core.mdp import GridMDP
from ird_core.posterior import DEFAULT_OBSERVATION_MODEL, ObservationModel, RunUntil, SamplerSettings
from ird_core.vocabulary import ZMethod

__all__ = ["sampler_settings", "observation_model", "ExtraWorld", "InferenceJob", "ResampleJob", "world_observation",
           "job_observations", "run_inference", "run_resample"]

#: ``ObservationModel``'s field names -> the request's (``ValueError`` messages name the latter).
_MODEL_FIELDS = {"counts": "proxy_counts", "temperature": "designer_temperature"}


def observation_model(proxy_counts: str, designer_temperature: float,
                      default: ObservationModel = DEFAULT_OBSERVATION_MODEL) -> ObservationModel:
    """The request's observation model: ``proxy_counts`` "" and ``designer_temperature`` 0 take
    ``default``'s (the node's parameters); the own term is ``default``'s.

    Raises:
        ValueError: starting with ``proxy_counts`` or ``designer_temperature`` (the library's check).
    """
    counts = proxy_counts or default.counts
    temperature = default.temperature if designer_temperature == 0.0 else designer_temperature
    try:
        return ObservationModel(counts, temperature, default.own_term)
    except ValueError as exc:
        name, rest = str(exc).split(":", 1)
        raise ValueError(f"{_MODEL_FIELDS.get(name, name)}:{rest}") from None


def sampler_settings(values: dict[str, Any]) -> SamplerSettings:
    """The node's sampler parameters as ``ird_core.posterior.SamplerSettings``: the sentinels (0,
    or -1 for ``warmup``) mean unset (the library's default); ``until_converged`` unless
    ``target_r_hat`` is 0 or ``thin`` is set.

    Raises:
        ValueError: ``until_converged.r_hat`` for a ``target_r_hat`` in (0, 1).
    """
    thin = int(values["thin"]) or None
    run = None
    if float(values["target_r_hat"]) > 0 and thin is None:
        budget = float(values["time_budget"])
        run = RunUntil(r_hat=float(values["target_r_hat"]), min_ess=float(values["min_ess"]),
                       max_iterations=int(values["max_iterations"]), time_budget_s=budget if budget > 0 else None)
    return SamplerSettings(
        num_chains=int(values["num_chains"]) or None,
        warmup=int(values["warmup"]) if values["warmup"] >= 0 else None,
        thin=thin,
        num_proxy_samples=int(values["num_proxy_samples"]) or None,
        until_converged=run,
    )


@dataclass(frozen=True)
class ExtraWorld:
    """One validated ``training_worlds[i]``: its training MDP ``(H_i, W_i, d)``, its proxy-map MDP
    ``(H_i, W_i, p_i)`` or ``None``, and its proxy weights ``(p_i,)``."""

    train_mdp: GridMDP
    proxy_mdp: GridMDP | None
    proxy_weights: np.ndarray


@dataclass(frozen=True)
class InferenceJob:
    """A validated request, as the worker process gets it.

    Attributes:
        train_mdp: the training MDP on the hypothesis features ``(H, W, d)`` (``training_map``).
        proxy_mdp: the same grid on the proxy's features ``(H, W, p)`` (``proxy_map``), or ``None``
            when the proxy's weights apply to the training map's layers.
        proxy_weights: ``(p,)``.
        beta, method, num_samples, seed, prior_sigma: as sample_posterior (``prior_sigma`` None: the
            calibrated sigma, ``ird_core.posterior.calibration``).
        sampler: the node's sampler settings.
        extra_worlds: the request's ``training_worlds`` (each one more ProxyObservation).
        observation_model: how every world's proxy behaviour is counted (module doc).
    """

    train_mdp: GridMDP
    proxy_mdp: GridMDP | None
    proxy_weights: np.ndarray
    beta: float
    method: ZMethod
    num_samples: int
    seed: int
    prior_sigma: float | None
    sampler: SamplerSettings
    extra_worlds: tuple[ExtraWorld, ...] = ()
    observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL


def _num_proxy_samples(job: InferenceJob) -> int:
    """Sample-Z's ``N``: the node's ``num_proxy_samples`` or the library's default."""
    return job.sampler.num_proxy_samples or core_inference.DEFAULT_NUM_PROXY_SAMPLES


def world_observation(job: InferenceJob, world: ExtraWorld,
                      proxy_prior_sigma: "float | None" = None) -> core_inference.ProxyObservation:
    """The ProxyObservation of one training world of ``job``.

    Without a proxy map the library computes ``phi~(w~)`` itself (with the sampler's
    ``observation_model``); with one, ``ird_core.posterior.proxy_observation`` plans the proxy on
    the proxy map under ``job.observation_model`` (and, for Sample-Z, the prior proxies drawn with
    the job's ``seed``, so every world plans the same ones, at ``proxy_prior_sigma``: the job's
    ``prior_sigma``, or when that is None the calibrated sigma of the proxy maps pooled over every
    world, :func:`job_observations`).
    """
    if world.proxy_mdp is None:
        return core_inference.ProxyObservation(world.proxy_weights, world.train_mdp)
    sample_z = job.method == ZMethod.SAMPLE_Z
    return core_inference.proxy_observation(
        world.train_mdp, world.proxy_weights, proxy_mdp=world.proxy_mdp,
        num_proxy_samples=_num_proxy_samples(job) if sample_z else None, seed=job.seed,
        prior_sigma=job.prior_sigma if proxy_prior_sigma is None else proxy_prior_sigma,
        observation_model=job.observation_model)


def job_observations(job: InferenceJob) -> list[core_inference.ProxyObservation]:
    """One ProxyObservation per training world: the request's own, then ``training_worlds`` in order
    (:func:`world_observation` each)."""
    worlds = [ExtraWorld(job.train_mdp, job.proxy_mdp, job.proxy_weights), *job.extra_worlds]
    proxy_maps = [w.proxy_mdp.features for w in worlds if w.proxy_mdp is not None]
    sigma = None  # the calibrated prior of the proxies' space, pooled as lavaland.proxy_observations does
    if job.prior_sigma is None and proxy_maps:
        sigma = core_inference.resolve_prior_sigma(None, job.observation_model.temperature, proxy_maps)
    return [world_observation(job, world, sigma) for world in worlds]  # a few worlds, each one batched MDP pass


def run_inference(job: InferenceJob) -> core_inference.Posterior:
    """The worker-process job: ``sample_posterior`` on a validated request (see the module doc);
    with ``training_worlds``, ``sample_joint_posterior`` on :func:`job_observations`."""
    kwargs: dict[str, Any] = job.sampler.kwargs()
    kwargs["observation_model"] = job.observation_model
    if job.extra_worlds:
        return core_inference.sample_joint_posterior(job_observations(job), job.beta, job.method, job.num_samples,
                                                     job.seed, job.prior_sigma, **kwargs)
    observation = world_observation(job, ExtraWorld(job.train_mdp, job.proxy_mdp, job.proxy_weights))
    if observation.proxy_features is not None:
        kwargs["proxy_features"] = observation.proxy_features
    if observation.proxy_sample_features is not None:
        kwargs["proxy_sample_features"] = observation.proxy_sample_features
    return core_inference.sample_posterior(job.proxy_weights, job.train_mdp, job.beta, job.method, job.num_samples,
                                           job.seed, job.prior_sigma, **kwargs)


@dataclass(frozen=True)
class ResampleJob:
    """Re-sampling with the answers: ``base``'s proxy observation plus ``choices``, warm-started at
    ``initial`` (the current posterior), with ``seed``."""

    base: InferenceJob
    choices: tuple[core_inference.ChoiceObservation, ...]
    initial: core_inference.Posterior
    seed: int


def run_resample(job: ResampleJob) -> core_inference.Posterior:
    """The worker-process job of /ird/answer: ``sample_joint_posterior`` on all the evidence, with
    the observation model of ``base`` (the posterior being extended)."""
    base = job.base
    kwargs: dict[str, Any] = base.sampler.kwargs()
    kwargs["observation_model"] = base.observation_model
    kwargs.pop("warmup", None)  # a warm start has its own short warm-up (the library's default)
    proxies = job_observations(base)
    return core_inference.sample_joint_posterior(
        [*proxies, *job.choices], base.beta, base.method, base.num_samples, job.seed, base.prior_sigma,
        initial=job.initial, **kwargs)
