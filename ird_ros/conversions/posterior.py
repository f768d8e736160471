"""numpy <-> ROS posterior messages: RewardPosterior and the flat ``float64[]`` weights fields.

Part of :mod:`ird_ros.conversions` (import that). A posterior's ``converged`` flag on the wire is
the sampler's verdict ``r_hat_max <= ird_core.posterior.R_HAT_CONVERGED`` (docs/spec.md
section 3); every function raises ``ValueError`` naming the offending field. The observation model
a posterior was sampled with travels as ``proxy_counts`` ("optimal" or "maxent") and
``designer_temperature`` (finite, in [0.001, 1000]); "" and 0 mean "not recorded" (a posterior
built by hand or recorded before the fields existed) and are read back as they are.
"""

from __future__ import annotations

import array
import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np
from builtin_interfaces.msg import Time

from ird_core.vocabulary import PROXY_COUNTS, ZMethod, parse
from ird_msgs.msg import RewardPosterior
from ird_ros.conversions.grids import MAP_FRAME, _as_float_array, _check_finite, _check_names, _f, _read, make_header

__all__ = ["PosteriorData", "posterior_to_msg", "posterior_from_msg", "weights_to_flat", "weights_from_flat"]


# --------------------------------------------------------------------------- data classes


@dataclass(frozen=True)
class PosteriorData:
    """A RewardPosterior as numpy: ``samples`` (K, d) float64, ``proxy_weights`` (p,), where
    p = d unless the proxy lives on its own proxy map (latent_classifier).

    Has the attributes of ``ird_core.posterior.Posterior`` (samples, method, beta,
    acceptance_rate, r_hat_max, ess_min, prior_sigma, num_chains, seed), so it can be
    passed back to ``posterior_to_msg``, and the observation model it was sampled with
    (``proxy_counts`` "" and ``designer_temperature`` 0: not recorded).
    """

    samples: np.ndarray
    feature_names: tuple[str, ...]
    proxy_weights: np.ndarray
    method: ZMethod
    beta: float
    prior_sigma: float
    acceptance_rate: float
    r_hat_max: float
    ess_min: float
    num_chains: int
    seed: int
    converged: bool
    proxy_counts: str = ""
    designer_temperature: float = 0.0


# --------------------------------------------------------------------------- weights


def weights_to_flat(weights: np.ndarray, *, field: str = "weights") -> array.array:
    """Flatten (K, d) or (d,) weights row-major into a float64 array for a ``float64[]`` field."""
    arr = _as_float_array(field, weights, np.float64)
    if arr.ndim not in (1, 2):
        raise _f(field, f"expected a (K, d) or (d,) array, got shape {arr.shape}")
    if arr.size == 0:
        raise _f(field, "must not be empty")
    _check_finite(field, arr)
    return array.array("d", np.ascontiguousarray(arr).tobytes())


def weights_from_flat(flat: Any, d: int, *, field: str = "weights") -> np.ndarray:
    """Read a row-major ``float64[]`` of K*d values into a (K, d) float64 array (K >= 1)."""
    if int(d) <= 0:
        raise _f(field, f"the feature dimension d must be > 0, got {d}")
    arr = _read(field, flat, np.float64).reshape(-1)
    if arr.size == 0:
        raise _f(field, "must not be empty")
    if arr.size % d:
        raise _f(field, f"length {arr.size} is not a multiple of d={d}")
    _check_finite(field, arr)
    return arr.reshape(-1, d)


# --------------------------------------------------------------------------- RewardPosterior


def _check_uint32(field: str, value: Any) -> int:
    v = int(value)
    if v < 0 or v > 0xFFFFFFFF:
        raise _f(field, f"must fit in uint32, got {value}")
    return v


def _check_method(field: str, method: str) -> ZMethod:
    """``method`` as a :class:`ird_core.vocabulary.ZMethod` (``ValueError`` naming ``field``)."""
    return parse(ZMethod, method, field)


def posterior_to_msg(
    posterior: Any,
    *,
    feature_names: Sequence[str],
    proxy_weights: np.ndarray,
    stamp: Time | None = None,
    frame_id: str = MAP_FRAME,
    observation_model: Any = None,
) -> RewardPosterior:
    """Build an ``ird_msgs/RewardPosterior`` from any object with the attributes of
    ``ird_core.posterior.Posterior``: ``samples`` (K, d), ``method``, ``beta``,
    ``acceptance_rate``, ``r_hat_max``, ``ess_min``, ``prior_sigma``, ``num_chains``, ``seed``.

    ``feature_names`` has d entries; ``proxy_weights`` has shape (p,), p = d unless the
    proxy was defined on a proxy map with its own layers (InferReward.proxy_map). ``r_hat_max`` and
    ``ess_min`` may be NaN (not computed); ``converged`` is set to
    ``r_hat_max <= ird_core.posterior.R_HAT_CONVERGED``. ``observation_model`` (an
    ``ird_core.posterior.ObservationModel``: its ``counts`` and ``temperature``) fills
    ``proxy_counts`` and ``designer_temperature``; ``None`` copies the posterior's own
    ``proxy_counts`` / ``designer_temperature`` attributes (a ``PosteriorData``), else "" and 0
    (not recorded).
    """
    # Imported here: ird_core.posterior loads scipy, which nodes that never publish a posterior
    # (rob, the recorder) should not pay for at start-up.
    from ird_core.posterior import R_HAT_CONVERGED

    field = "RewardPosterior"
    names = _check_names(f"{field}.feature_names", feature_names)
    samples = _as_float_array(f"{field}.samples", posterior.samples, np.float64)
    if samples.ndim != 2 or samples.shape[0] == 0 or samples.shape[1] != len(names):
        raise _f(f"{field}.samples", f"expected shape (K>=1, d={len(names)}), got {samples.shape}")
    _check_finite(f"{field}.samples", samples)
    proxy = _as_float_array(f"{field}.proxy_weights", proxy_weights, np.float64).reshape(-1)
    if proxy.size == 0:
        raise _f(f"{field}.proxy_weights", "must not be empty")
    _check_finite(f"{field}.proxy_weights", proxy)
    msg = RewardPosterior()
    msg.header = make_header(stamp, frame_id)
    msg.feature_names = list(names)
    _fill_sampler_fields(msg, posterior, field)
    if observation_model is not None:
        counts, temperature = observation_model.counts, observation_model.temperature
    else:
        counts = getattr(posterior, "proxy_counts", "")
        temperature = getattr(posterior, "designer_temperature", 0.0)
    msg.proxy_counts, msg.designer_temperature = _check_observation_model(field, counts, temperature)
    msg.proxy_weights = array.array("d", proxy.tobytes())
    msg.samples = array.array("d", np.ascontiguousarray(samples).tobytes())
    msg.num_samples = int(samples.shape[0])
    msg.converged = bool(msg.r_hat_max <= R_HAT_CONVERGED)  # False for NaN
    return msg


def _fill_sampler_fields(msg: RewardPosterior, posterior: Any, field: str) -> None:
    """Check and copy the sampler's scalars (method, beta, prior_sigma, acceptance_rate, r_hat_max,
    ess_min, num_chains, seed) into ``msg``; ``ValueError`` naming ``<field>.<name>``."""
    msg.method = _check_method(f"{field}.method", str(posterior.method)).value
    beta = float(posterior.beta)
    if not math.isfinite(beta) or beta < 0.0:
        raise _f(f"{field}.beta", f"must be finite and >= 0, got {posterior.beta!r}")
    sigma = float(posterior.prior_sigma)
    if not math.isfinite(sigma) or sigma <= 0.0:
        raise _f(f"{field}.prior_sigma", f"must be finite and > 0, got {posterior.prior_sigma!r}")
    acc = float(posterior.acceptance_rate)
    if not (0.0 <= acc <= 1.0):
        raise _f(f"{field}.acceptance_rate", f"must be in [0, 1], got {posterior.acceptance_rate!r}")
    r_hat = _check_diagnostic(f"{field}.r_hat_max", posterior.r_hat_max)
    ess = _check_diagnostic(f"{field}.ess_min", posterior.ess_min)
    num_chains = _check_uint32(f"{field}.num_chains", posterior.num_chains)
    if num_chains == 0:
        raise _f(f"{field}.num_chains", "must be > 0")
    msg.seed = _check_uint32(f"{field}.seed", posterior.seed)
    msg.beta, msg.prior_sigma, msg.acceptance_rate = beta, sigma, acc
    msg.r_hat_max, msg.ess_min, msg.num_chains = r_hat, ess, num_chains


def _check_observation_model(field: str, counts: Any, temperature: Any) -> tuple[str, float]:
    """``(proxy_counts, designer_temperature)`` checked: one of ``PROXY_COUNTS`` or "", and a
    temperature in [0.001, 1000] or 0 (not recorded); ``ValueError`` naming ``<field>.<name>``."""
    if counts not in ("", *PROXY_COUNTS):
        raise _f(f"{field}.proxy_counts", f"expected one of {list(PROXY_COUNTS)} or \"\" (not recorded), "
                                          f"got {counts!r}")
    t = float(temperature)
    if not (t == 0.0 or 1e-3 <= t <= 1e3):  # False for NaN
        raise _f(f"{field}.designer_temperature", f"expected 0 (not recorded) or a value in [0.001, 1000], "
                                                  f"got {temperature!r}")
    return str(counts), t


def _check_diagnostic(field: str, value: Any) -> float:
    """An MCMC diagnostic: a finite value >= 0, or NaN (not computed)."""
    v = float(value)
    if math.isinf(v) or (not math.isnan(v) and v < 0.0):
        raise _f(field, f"must be >= 0 or NaN (not computed), got {value!r}")
    return v


def posterior_from_msg(msg: RewardPosterior, *, field: str = "RewardPosterior") -> PosteriorData:
    """Read an ``ird_msgs/RewardPosterior`` into a ``PosteriorData`` (samples (K, d))."""
    names = _check_names(f"{field}.feature_names", msg.feature_names)
    d = len(names)
    samples = weights_from_flat(msg.samples, d, field=f"{field}.samples")
    if samples.shape[0] != msg.num_samples:
        raise _f(f"{field}.num_samples", f"is {msg.num_samples} but samples holds {samples.shape[0]} rows of d={d}")
    proxy = _read(f"{field}.proxy_weights", msg.proxy_weights, np.float64)
    if proxy.size == 0:
        raise _f(f"{field}.proxy_weights", "must not be empty")
    _check_finite(f"{field}.proxy_weights", proxy)
    method = _check_method(f"{field}.method", msg.method)
    if not math.isfinite(msg.beta) or msg.beta < 0.0:
        raise _f(f"{field}.beta", f"must be finite and >= 0, got {msg.beta!r}")
    counts, temperature = _check_observation_model(field, msg.proxy_counts, msg.designer_temperature)
    return PosteriorData(
        samples=samples,
        feature_names=names,
        proxy_weights=proxy,
        method=method,
        beta=float(msg.beta),
        prior_sigma=float(msg.prior_sigma),
        acceptance_rate=float(msg.acceptance_rate),
        r_hat_max=float(msg.r_hat_max),
        ess_min=float(msg.ess_min),
        num_chains=int(msg.num_chains),
        seed=int(msg.seed),
        converged=bool(msg.converged),
        proxy_counts=counts,
        designer_temperature=temperature,
    )
