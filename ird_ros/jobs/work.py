"""Work models of the inference node's services (no ROS): how much computing a request asks for,
known from sizes before any work starts, so a request that would run for minutes or exhaust a
worker's memory is refused up front with the field and the limit named.

The unit is one cell-step: one cell of one time step of an MDP pass for one weight vector, as
in the planner's ``ird_core.planning.plan_work`` (``K x (T + 1) x H x W``).

Inference (:func:`inference_work`, ``/ird/infer``): the work the sampler cannot do without, i.e.
the Laplace start, the warm-up and the first run (``RunUntil`` extends the chains past it only
within ``max_iterations`` and the time budget). With ``C`` chains, ``K`` samples, ``d`` features,
Sample-Z's ``N`` prior proxies and the worlds ``i`` (the request's own and its ``training_worlds``):

- gradient of one weight ``G = d^2 + sum_i m (T_i + 1) H_i W_i`` (``m`` = 1 MaxEnt-Z; 2 Sample-Z,
  whose own term's ray doubles the pass) ``+ N d`` per world for Sample-Z (scoring the proxies);
- gradients ``C (warmup + I) L + 30 (d + 9)``: ``I = ceil(K / C) thin`` post-warm-up iterations
  (``thin`` the node's, else ``max(1, ceil(min_iterations / ceil(K / C)))`` as the sampler's
  schedule), ``L`` the method's leapfrog cap (``DEFAULT_MAX_LEAPFROG``), and the Laplace
  start's at most 30 Newton steps of ``d + 9`` gradients;
- work ``= gradients x G``, plus for Sample-Z ``N sum_i (T_i + 1) H_i W_i`` (planning the prior
  proxies once).

``/ird/answer`` re-samples the accepted ``/ird/infer`` job from a warm start (a shorter warm-up
and run) with the answers' choice terms (``q d`` per gradient each): within its work.

Query (:func:`query_work`, ``/ird/query``): the literal plans of the posterior's ``K`` samples
on the query map, their rewards, and the information-gain search over at most ``K`` distinct
candidates (every pair, then ``q - 2`` greedy extensions):
``K (T + 1) H W + K H W d + K^3 / 2 + q^2 K^2``.

Every check raises ``ValueError`` whose message starts with the field a client can change.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from ird_core.posterior import (
    DEFAULT_MAX_LEAPFROG,
    DEFAULT_MIN_ITERATIONS,
    DEFAULT_NUM_CHAINS,
    DEFAULT_NUM_PROXY_SAMPLES,
    DEFAULT_WARMUP,
    SamplerSettings,
)
from ird_core.vocabulary import ZMethod

__all__ = ["WorldSize", "InferenceWork", "inference_work", "check_inference_work", "query_work",
           "check_query_work", "LAPLACE_STEPS"]

#: Newton steps of the Laplace start at most (``ird_core.posterior.laplace``), each ``d + 9`` gradients.
LAPLACE_STEPS = 30


@dataclass(frozen=True)
class WorldSize:
    """One training world's sizes: ``H``, ``W``, horizon ``T``."""

    height: int
    width: int
    horizon: int

    @property
    def pass_cells(self) -> int:
        """``(T + 1) H W``: the cell-steps of one MDP pass on one weight."""
        return (self.horizon + 1) * self.height * self.width


@dataclass(frozen=True)
class InferenceWork:
    """The terms of :func:`inference_work` (for the refusal's message)."""

    chains: int
    iterations: int  # warm-up plus the first run, per chain
    leapfrog: int
    gradient: int  # cell-steps of one gradient of one weight
    total: float

    def describe(self) -> str:
        return (f"{self.chains} chains x {self.iterations} iterations x {self.leapfrog} leapfrog steps x "
                f"{self.gradient:.3g} per gradient = {self.total:.3g}")


def inference_work(worlds: Sequence[WorldSize], num_features: int, method: str, num_samples: int,
                   sampler: SamplerSettings) -> InferenceWork:
    """The work of an inference request (module doc); ``worlds`` first the request's own."""
    sample_z = method == ZMethod.SAMPLE_Z
    chains = sampler.num_chains or DEFAULT_NUM_CHAINS
    warmup = sampler.warmup if sampler.warmup is not None else DEFAULT_WARMUP[method]
    per_chain = -(-int(num_samples) // chains)
    thin = sampler.thin or max(1, -(-DEFAULT_MIN_ITERATIONS[method] // per_chain))
    iterations = warmup + per_chain * thin
    leapfrog = DEFAULT_MAX_LEAPFROG[method]
    proxies = (sampler.num_proxy_samples or DEFAULT_NUM_PROXY_SAMPLES) if sample_z else 0
    d = int(num_features)
    passes = sum(w.pass_cells for w in worlds)
    gradient = d * d + (2 if sample_z else 1) * passes + proxies * d * len(worlds)
    gradients = chains * iterations * leapfrog + LAPLACE_STEPS * (d + 9)
    total = float(gradients) * gradient + float(proxies) * passes
    return InferenceWork(chains, iterations, leapfrog, gradient, total)


def check_inference_work(worlds: Sequence[WorldSize], num_features: int, method: str, num_samples: int,
                         sampler: SamplerSettings, limit: float) -> InferenceWork:
    """Refuse an inference whose work exceeds ``limit`` (``max_inference_work``).

    Raises:
        ValueError: naming ``num_samples`` when fewer samples would fit, else ``training_map``
            (the request's own world is too large even for one sample) or ``training_worlds``.
    """
    work = inference_work(worlds, num_features, method, num_samples, sampler)
    if work.total <= limit:
        return work
    if inference_work(worlds, num_features, method, 1, sampler).total <= limit:
        field = "num_samples"
    elif inference_work(worlds[:1], num_features, method, 1, sampler).total > limit:
        field = "training_map"
    else:
        field = "training_worlds"
    sizes = ", ".join(f"{w.height}x{w.width} T={w.horizon}" for w in worlds[:4]) + (", ..." if len(worlds) > 4 else "")
    raise ValueError(f"{field}: {num_samples} {method} samples on {len(worlds)} world(s) ({sizes}) with "
                     f"d={num_features}: inference work {work.describe()} exceeds max_inference_work={limit:.3g}")


def query_work(num_samples: int, height: int, width: int, horizon: int, num_features: int, num_options: int) -> float:
    """The work of a query (module doc): ``K (T + 1) H W + K H W d + K^3 / 2 + q^2 K^2``."""
    k, cells = float(num_samples), float(height) * float(width)
    return k * (horizon + 1) * cells + k * cells * num_features + k**3 / 2 + float(num_options) ** 2 * k * k


def check_query_work(num_samples: int, height: int, width: int, horizon: int, num_features: int,
                     num_options: int, limit: float) -> float:
    """Refuse a query whose :func:`query_work` exceeds ``limit`` (``max_query_work``).

    Raises:
        ValueError: naming ``num_options`` when two options would fit, else ``map``.
    """
    work = query_work(num_samples, height, width, horizon, num_features, num_options)
    if work <= limit:
        return work
    field = "num_options" if query_work(num_samples, height, width, horizon, num_features, 2) <= limit else "map"
    raise ValueError(f"{field}: {num_options} options from {num_samples} posterior samples on a {height}x{width} map "
                     f"(d={num_features}) at horizon {horizon}: query work {work:.3g} exceeds "
                     f"max_query_work={limit:.3g}")

