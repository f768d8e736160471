"""The calibrated designer: the MaxEnt designer's temperature and the prior's scale, chosen together
(docs/spec.md section 3, docs/modelling.md "The calibrated designer").

The observation model reads the proxy ``w~`` through the behaviour it produces in training: MaxEnt
expected counts at temperature ``tau``, which are the unit-temperature counts of the reward
``w~ / tau`` (:mod:`ird_core.posterior.observation_model`). Both likelihoods then compare those
counts with what a *unit-temperature* agent does under a candidate true reward ``w``: MaxEnt-Z's
``beta (w . phi~ - log Z(w))`` and Sample-Z's normaliser over ``phi_i``. So rewards live in the
units of ``w~ / tau``: a proxy written where the target is worth 1 gives the target ``1 / tau``
there.

Two consequences, both measured (docs/experiments.md, "The calibrated designer"):

- ``tau`` must make the modelled designer act on its proxy. At ``tau = 1`` a Lavaland proxy
  (target +1, dirt +0.1 per step) is barely preferred over a random walk: in about two thirds of
  seeds its expected visits to the training target are under 0.5, so the posterior learns little
  about the target, and IRD does not go for it at test time.
- The prior must be on the scale of rewards in those units. The rule is stated for the reward of a
  cell, not for a weight: a priori, a training cell's reward ``w . phi(s)`` has standard deviation
  ``1 / tau``, the size the designer's unit rewards have in the likelihood's units. Under
  ``w ~ N(0, sigma^2 I)`` that standard deviation is ``sigma |phi(s)|``, so

      sigma = 1 / (tau * rms_s |phi(s)|)

  with the root-mean-square feature norm over the cells of the training maps
  (:func:`feature_scale`, :func:`calibrated_prior_sigma`). One-hot terrain indicators have norm 1
  and the rule is ``sigma = 1 / tau``. A prior one reward unit wide at ``tau = 0.2`` is five times
  too narrow: the evidence then fights the prior and IRD touches lava in 10-15% of trials. The
  latent conditions' 50-d observations have norm about 8: a weight-space ``sigma = 1 / tau`` would
  give every cell a prior reward spread of about 40, whose near-deterministic MaxEnt planner makes
  the posterior too creased for HMC to converge on (45-46 of 50 chains with R-hat > 1.1).

:data:`CALIBRATED_TEMPERATURE` is the default, chosen on tuning seeds 400-449 (a sweep over
``tau`` in {1, 0.5, 0.2, 0.1}; ``scripts/calibration_sweep.sh``) and evaluated on the committed
results' seeds 0-99, which the choice never saw. A caller who passes ``prior_sigma=None``
anywhere in :mod:`ird_core.posterior` gets the calibrated sigma of the observation model in use
and of the weight space's training features; an explicit ``prior_sigma`` overrides the rule (and
is recorded as given). Sample-Z draws its prior proxies ``w_i`` from the prior of the proxy's own
space (the paper's ``P(w)``), calibrated on that space's features by the same rule.
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

__all__ = ["CALIBRATED_TEMPERATURE", "PRIOR_RULE", "feature_scale", "calibrated_prior_sigma", "resolve_prior_sigma"]

#: The default temperature of the modelled MaxEnt designer (module docstring).
CALIBRATED_TEMPERATURE: float = 0.2
#: The stated rule tying the prior's scale to the temperature, as recorded with results.
PRIOR_RULE: str = "sigma = 1 / (temperature * rms training feature norm)"


def feature_scale(features: "Iterable[np.ndarray]") -> float:
    """The root-mean-square feature norm ``sqrt(mean_s |phi(s)|^2)`` over every cell of the maps.

    Args:
        features: ``(H, W, d)`` feature maps (one or more, pooled cell by cell; a list, or a
            single array).
    Returns:
        The scale, ``> 0``. Raises ``ValueError`` naming ``features`` when there are no cells, a
        value is not finite, or every feature is zero.
    """
    maps = [features] if isinstance(features, np.ndarray) else list(features)
    cells = [np.asarray(f, dtype=np.float64).reshape(-1, np.shape(f)[-1]) for f in maps if np.size(f)]
    if not cells:
        raise ValueError("features: expected at least one cell")
    squares = np.concatenate([np.sum(c * c, axis=1) for c in cells])
    scale = float(np.sqrt(squares.mean()))
    if not math.isfinite(scale) or scale <= 0:
        raise ValueError(f"features: expected finite features, not all zero (rms norm {scale!r})")
    return scale


def calibrated_prior_sigma(temperature: float, scale: float = 1.0) -> float:
    """``1 / (temperature * scale)``: the prior standard deviation that gives a cell of feature norm
    ``scale`` (:func:`feature_scale`; 1 for one-hot terrains) the reward spread ``1 / temperature``.

    Raises ``ValueError`` naming ``temperature`` or ``scale`` unless each is finite and ``> 0``.
    """
    t, s = float(temperature), float(scale)
    if not math.isfinite(t) or t <= 0:
        raise ValueError(f"temperature: expected a finite number > 0, got {temperature!r}")
    if not math.isfinite(s) or s <= 0:
        raise ValueError(f"scale: expected a finite number > 0, got {scale!r}")
    return 1.0 / (t * s)


def resolve_prior_sigma(prior_sigma: "float | None", temperature: float,
                        features: "Iterable[np.ndarray] | None" = None) -> float:
    """``prior_sigma`` itself, or with ``None`` the calibrated sigma of ``temperature`` and the
    training ``features`` of the weight space (``None``: scale 1, the one-hot rule ``1 / temperature``).

    The value is returned unchecked; the callers check it (``> 0``, finite) under its own name.
    """
    if prior_sigma is not None:
        return prior_sigma
    return calibrated_prior_sigma(temperature, 1.0 if features is None else feature_scale(features))
