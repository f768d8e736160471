"""What the IRD observation model assumes about the designer's proxy behaviour (docs/spec.md section 3).

The observation model conditions on the behaviour a proxy ``w~`` produces in its training MDP,
summarised by feature counts ``phi~(w~)``. The paper leaves the summary open for MaxEnt-Z and,
for Sample-Z, writes ``Z(w) ~ exp(beta w . phi_w) + sum_i exp(beta w . phi_i)`` with ``phi_i``,
``phi_w`` "the vector of feature counts realized optimizing ``w_i`` and ``w``".
:class:`ObservationModel` makes the choice explicit:

- ``counts = "optimal"``: ``phi~`` is the feature count of the proxy's optimal path
  (:func:`ird_core.mdp.optimal_feature_counts`), deterministic and scale-free; Sample-Z's
  ``phi_i`` and its own term ``phi_w`` likewise (the paper's reading).
- ``counts = "maxent"``: expected counts of the MaxEnt trajectory distribution
  ``P(xi) ∝ exp(w . phi(xi) / temperature)``; ``temperature`` is the designer's rationality the
  model assumes (1 = the unit-temperature MaxEnt agent; smaller approaches "optimal"). The
  default is the calibrated designer (:mod:`ird_core.posterior.calibration`), whose prior scale
  follows the temperature.
- ``own_term``: Sample-Z includes the candidate's own term ``exp(beta w . phi_w)`` in its
  normaliser (the paper: "it helped to include the candidate sample w in the sum"); ``False`` is
  the ablation.

The same model must build a posterior's ``phi~``, ``phi_i`` and own term: the
``proxy_observations`` builders and ``make_joint_model`` take it as one argument.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ird_core.mdp import GridMDP, expected_visitation, feature_expectations
from ird_core.mdp.optimal_paths import optimal_feature_counts
from ird_core.posterior.calibration import CALIBRATED_TEMPERATURE
from ird_core.vocabulary import ProxyCounts, parse

__all__ = ["ObservationModel", "DEFAULT_OBSERVATION_MODEL", "MAXENT_OBSERVATION_MODEL", "RAY_STEP", "behaviour_counts",
           "own_counts", "own_counts_and_ray"]

#: Relative step along the ray ``t w`` for the MaxEnt own-term derivative ``H(w) w``.
RAY_STEP: float = 1e-6


@dataclass(frozen=True)
class ObservationModel:
    """The designer-behaviour assumptions of the IRD observation model (module docstring).

    Attributes:
        counts: one of ``PROXY_COUNTS`` (``"optimal"`` or ``"maxent"``).
        temperature: in ``[0.001, 1000]``; the MaxEnt designer's temperature (used by ``"maxent"``
            counts; with either counts it sets the calibrated prior scale
            ``1 / (temperature * feature scale)``, :mod:`ird_core.posterior.calibration`).
        own_term: Sample-Z includes the candidate's own term in its normaliser.

    Raises ``ValueError`` naming the field.
    """

    counts: str = ProxyCounts.MAXENT.value
    temperature: float = CALIBRATED_TEMPERATURE
    own_term: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "counts", parse(ProxyCounts, self.counts, "counts").value)
        t = self.temperature
        if isinstance(t, bool) or not isinstance(t, (int, float, np.floating, np.integer)) \
                or not math.isfinite(float(t)) or not 1e-3 <= float(t) <= 1e3:
            raise ValueError(f"temperature: expected a finite number in [0.001, 1000], got {t!r}")
        object.__setattr__(self, "temperature", float(t))
        if not isinstance(self.own_term, (bool, np.bool_)):
            raise ValueError(f"own_term: expected a bool, got {self.own_term!r}")
        object.__setattr__(self, "own_term", bool(self.own_term))

    @property
    def optimal(self) -> bool:
        return self.counts == ProxyCounts.OPTIMAL


#: The default (``ObservationModel()``): MaxEnt counts of the calibrated designer
#: (``CALIBRATED_TEMPERATURE``) with the own term, chosen on tuning seeds and evaluated on the
#: committed results' seeds (docs/experiments.md, "The calibrated designer").
DEFAULT_OBSERVATION_MODEL = ObservationModel()
#: The unit-temperature MaxEnt reading (the library's default before the calibrated designer).
MAXENT_OBSERVATION_MODEL = ObservationModel(ProxyCounts.MAXENT.value, 1.0)


def _scaled(weights: np.ndarray, model: ObservationModel) -> np.ndarray:
    return weights if model.temperature == 1.0 else weights / model.temperature


def behaviour_counts(planning_mdp: GridMDP, weights: np.ndarray, model: ObservationModel,
                     hypothesis_features: "np.ndarray | None" = None) -> np.ndarray:
    """``phi~`` of each reward in ``planning_mdp`` under ``model``, counted in the hypothesis space.

    Args:
        planning_mdp: the MDP the rewards are planned on, ``(H, W, p)`` features.
        weights: ``(K, p)`` checked weights.
        model: the observation model.
        hypothesis_features: ``(H, W, d)`` checked features to count (``None``: the planning
            features).
    Returns:
        ``(K, d)`` counts over the ``T + 1`` states.
    """
    if model.optimal:
        return optimal_feature_counts(planning_mdp, weights, hypothesis_features)
    scaled = _scaled(weights, model)
    if hypothesis_features is None:
        return feature_expectations(planning_mdp, scaled)
    visits = expected_visitation(planning_mdp, scaled)
    return visits.reshape(len(visits), -1) @ hypothesis_features.reshape(-1, hypothesis_features.shape[2])


def own_counts(model: ObservationModel, mdp: GridMDP, weights: np.ndarray) -> "np.ndarray | None":
    """Sample-Z's own term ``phi~(w)`` ``(K, d)`` for candidates ``(K, d)`` (``None``: no own term)."""
    if not model.own_term:
        return None
    if model.optimal:
        return optimal_feature_counts(mdp, weights)
    return feature_expectations(mdp, _scaled(weights, model))


def own_counts_and_ray(model: ObservationModel, mdp: GridMDP, weights: np.ndarray
                       ) -> "tuple[np.ndarray | None, np.ndarray | None]":
    """``phi~(w)`` and ``H(w) w``, the derivative of ``w . phi~(w)`` minus ``phi~(w)``.

    MaxEnt counts at temperature ``tau`` are ``phi~(w / tau)``; their ray term ``H(w / tau) w / tau``
    is a forward difference along the ray ``t w`` (one pass on ``2K`` weights, relative error
    ~1e-6). Optimal-path counts are piecewise constant in ``w``: the ray term is zero (``None``).
    ``(None, None)`` without the own term.
    """
    if not model.own_term:
        return None, None
    if model.optimal:
        return optimal_feature_counts(mdp, weights), None
    scaled = _scaled(weights, model)
    k = len(weights)
    both = feature_expectations(mdp, np.concatenate([scaled, (1.0 + RAY_STEP) * scaled]))
    return both[:k], (both[k:] - both[:k]) / RAY_STEP
