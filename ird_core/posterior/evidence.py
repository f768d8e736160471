"""The designer's evidence and the joint IRD log posterior (docs/spec.md sections 3 and 7).

Evidence kinds, all in one weight space ``R^d``:

- ``ProxyObservation(proxy_weights, train_mdp, proxy_features=None, proxy_sample_features=None)``:
  the designer wrote this proxy for this training MDP.
- ``ChoiceObservation(option_features, chosen, beta)``: the designer was shown ``q >= 2`` paths
  with feature counts ``option_features`` ``(q, d)`` and chose ``chosen`` (Boltzmann, its own
  ``beta``).

Joint log posterior (unnormalised) of a candidate ``w``::

    log prior(w) + sum_proxies term_method(w; phi~(w~), M~) + sum_choices log P(chosen | w)

Sample-Z draws ONE set of proxy samples ``w_i`` (``proxy_samples``, or
``proxy_prior_samples(num_proxy_samples, d, prior_sigma, seed)``) and uses it in every training
MDP, ``phi_i`` computed in that MDP. Proxy observations that share a training MDP object share
its MDP pass (``log Z(w)`` or ``phi~(w)``), so the cost of an evaluation is one batched pass per
distinct training MDP; choice terms cost one ``(K, d) x (d, q)`` product each.

Extension of the spec: ``ProxyObservation.proxy_sample_features`` ``(N, d)`` supplies the
Sample-Z ``phi_i`` directly. A proxy that lives in another feature space (latent_classifier:
``proxy_features`` given) needs it, because its ``phi_i`` come from proxy-space prior weights
planned on the proxy-space training map (``proxy_feature_counts(planning_mdp, w_i,
hypothesis_features)``); without it the ``phi_i`` are computed from the shared hypothesis-space
``w_i`` in ``train_mdp``. Supplying it also saves the ``N``-weight pass when a posterior is
re-sampled many times with the same proxy (query rounds).

The single-proxy functions ``log_posterior`` / ``log_posterior_grad`` / ``make_posterior_model``
are the joint ones with one ``ProxyObservation`` (one code path).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Union

import numpy as np

from ird_core.checks import check_array, check_int, check_real
from ird_core.mdp import GridMDP, feature_expectations, log_partition, log_partition_and_feature_expectations
from ird_core.posterior.likelihoods import (
    DEFAULT_NUM_PROXY_SAMPLES,
    choice_log_likelihood,
    choice_log_likelihood_and_grad,
    log_prior,
    log_prior_grad,
    maxent_z_log_likelihood,
    maxent_z_log_likelihood_grad,
    proxy_feature_counts,
    proxy_prior_samples,
    sample_z_log_likelihood,
    sample_z_log_likelihood_and_grad,
)
from ird_core.posterior.calibration import resolve_prior_sigma
from ird_core.posterior.observation_model import (
    DEFAULT_OBSERVATION_MODEL,
    ObservationModel,
    own_counts,
    own_counts_and_ray,
)
from ird_core.vocabulary import ZMethod, parse

__all__ = [
    "ProxyObservation",
    "ChoiceObservation",
    "Observation",
    "ProxyTerm",
    "PosteriorModel",
    "make_joint_model",
    "make_posterior_model",
    "joint_log_posterior",
    "joint_log_posterior_grad",
    "log_posterior",
    "log_posterior_grad",
]


def _frozen(array: np.ndarray) -> np.ndarray:
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class ProxyObservation:
    """The designer wrote ``proxy_weights`` for ``train_mdp`` (docs/spec.md sections 3 and 7).

    Attributes:
        proxy_weights: ``(d,)`` the proxy ``w~``; ``(p,)`` of any length when ``proxy_features``
            is given (it is then only recorded).
        train_mdp: the training MDP on the hypothesis features ``(H, W, d)``.
        proxy_features: ``(d,)`` ``phi~(w~)`` when given (latent_classifier), else computed from
            ``proxy_weights`` in ``train_mdp`` when the posterior is built.
        proxy_sample_features: ``(N, d)`` Sample-Z ``phi_i`` for this MDP when given (extension of
            the spec, see the module docstring), else computed from the shared proxy samples.

    Arrays are stored as read-only float64 copies. Raises ``ValueError`` naming the field.
    """

    proxy_weights: np.ndarray
    train_mdp: GridMDP
    proxy_features: "np.ndarray | None" = None
    proxy_sample_features: "np.ndarray | None" = None

    def __post_init__(self) -> None:
        if not isinstance(self.train_mdp, GridMDP):
            raise ValueError(f"train_mdp: expected a GridMDP, got {type(self.train_mdp).__name__}")
        dim = self.train_mdp.num_features
        given = self.proxy_features is not None
        fields = {"proxy_weights": _frozen(check_array("proxy_weights", self.proxy_weights,
                                                       (None,) if given else (dim,)))}
        if given:
            fields["proxy_features"] = _frozen(check_array("proxy_features", self.proxy_features, (dim,)))
        if self.proxy_sample_features is not None:
            fields["proxy_sample_features"] = _frozen(
                check_array("proxy_sample_features", self.proxy_sample_features, (None, dim)))
        for name, value in fields.items():
            object.__setattr__(self, name, value)

    @property
    def dim(self) -> int:
        return self.train_mdp.num_features


@dataclass(frozen=True, eq=False)
class ChoiceObservation:
    """The designer chose option ``chosen`` among ``q >= 2`` shown paths (docs/spec.md section 7).

    ``P(chosen | w) = exp(beta w . f_chosen) / sum_k exp(beta w . f_k)``.

    Attributes:
        option_features: ``(q, d)`` feature counts of the options (finite).
        chosen: index in ``[0, q)``.
        beta: the answer's rationality, finite and ``>= 0``.

    Raises ``ValueError`` naming the field.
    """

    option_features: np.ndarray
    chosen: int
    beta: float

    def __post_init__(self) -> None:
        options = check_array("option_features", self.option_features, (None, None))
        if options.shape[0] < 2:
            raise ValueError(f"option_features: expected q >= 2 options, got shape {options.shape}")
        chosen = check_int("chosen", self.chosen, 0)
        if chosen >= options.shape[0]:
            raise ValueError(f"chosen: expected an index in [0, {options.shape[0]}), got {chosen}")
        object.__setattr__(self, "option_features", _frozen(options))
        object.__setattr__(self, "chosen", chosen)
        object.__setattr__(self, "beta", check_real("beta", self.beta, positive=False))

    @property
    def dim(self) -> int:
        return int(self.option_features.shape[1])

    @property
    def num_options(self) -> int:
        return int(self.option_features.shape[0])


#: One piece of evidence from the designer.
Observation = Union[ProxyObservation, ChoiceObservation]


@dataclass(frozen=True, eq=False)
class ProxyTerm:
    """One proxy observation's precomputed likelihood inputs.

    Attributes:
        train_mdp: ``M~`` on the hypothesis features.
        proxy_features: ``(d,)`` ``phi~(w~)``.
        sample_features: ``(N, d)`` the Sample-Z ``phi_i`` in ``M~`` (None for MaxEnt-Z).
    """

    train_mdp: GridMDP
    proxy_features: np.ndarray
    sample_features: "np.ndarray | None" = None


@dataclass(frozen=True, eq=False)
class PosteriorModel:
    """The joint posterior as a batched log density, every data term precomputed.

    Attributes:
        method: one of ``METHODS``; beta: the proxies' rationality ``>= 0``; prior_sigma: ``> 0``.
        dim: ``d``.
        proxy_terms: one ``ProxyTerm`` per proxy observation, in order.
        choices: the ``ChoiceObservation`` s, in order.
        observation: the designer-behaviour assumptions (:class:`ObservationModel`): Sample-Z's
            own term ``phi~(w)`` is the candidate's optimal-path counts or its MaxEnt
            expectations at ``observation.temperature``, or left out.
    The single-proxy attributes ``train_mdp``, ``proxy_features`` and ``sample_features`` are
    those of the first proxy term.
    """

    method: str
    beta: float
    prior_sigma: float
    dim: int
    proxy_terms: tuple[ProxyTerm, ...] = ()
    choices: tuple[ChoiceObservation, ...] = ()
    observation: ObservationModel = DEFAULT_OBSERVATION_MODEL

    @property
    def train_mdp(self) -> GridMDP:
        return self.proxy_terms[0].train_mdp

    @property
    def proxy_features(self) -> np.ndarray:
        return self.proxy_terms[0].proxy_features

    @property
    def sample_features(self) -> "np.ndarray | None":
        return self.proxy_terms[0].sample_features

    @cached_property
    def _groups(self) -> list[tuple[GridMDP, list[ProxyTerm]]]:
        """Proxy terms grouped by training MDP object: one MDP pass per group."""
        groups: dict[int, tuple[GridMDP, list[ProxyTerm]]] = {}
        for term in self.proxy_terms:
            groups.setdefault(id(term.train_mdp), (term.train_mdp, []))[1].append(term)
        return list(groups.values())

    def log_density(self, weights: np.ndarray) -> np.ndarray:
        """Unnormalised joint log posterior; ``(K, d) -> (K,)``. One MDP pass per training MDP."""
        total = log_prior(weights, self.prior_sigma)
        for mdp, terms in self._groups:
            if self.method == ZMethod.MAXENT_Z:
                log_z = log_partition(mdp, weights)
                for term in terms:
                    total = total + maxent_z_log_likelihood(weights, term.proxy_features, log_z, self.beta)
            else:
                own = own_counts(self.observation, mdp, weights)
                for term in terms:
                    total = total + sample_z_log_likelihood(weights, term.proxy_features, own,
                                                            term.sample_features, self.beta)
        for choice in self.choices:
            total = total + choice_log_likelihood(weights, choice.option_features, choice.chosen, choice.beta)
        return total

    def log_density_and_grad(self, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Value ``(K,)`` and exact gradient ``(K, d)``: one MDP pass per training MDP (on ``2K``
        weights for Sample-Z, whose own-term derivative ``H(w) w`` is a forward difference along
        the ray ``t w``, relative error ~1e-6)."""
        value = log_prior(weights, self.prior_sigma)
        grad = log_prior_grad(weights, self.prior_sigma)
        for mdp, terms in self._groups:
            if self.method == ZMethod.MAXENT_Z:
                log_z, expectations = log_partition_and_feature_expectations(mdp, weights)
                for term in terms:
                    value = value + maxent_z_log_likelihood(weights, term.proxy_features, log_z, self.beta)
                    grad = grad + maxent_z_log_likelihood_grad(term.proxy_features, expectations, self.beta)
            else:
                own, ray = own_counts_and_ray(self.observation, mdp, weights)
                for term in terms:
                    v, g = sample_z_log_likelihood_and_grad(weights, term.proxy_features, own, ray,
                                                            term.sample_features, self.beta)
                    value, grad = value + v, grad + g
        for choice in self.choices:
            v, g = choice_log_likelihood_and_grad(weights, choice.option_features, choice.chosen, choice.beta)
            value, grad = value + v, grad + g
        return value, grad

    def check_weights(self, weights: object) -> np.ndarray:
        return check_array("weights", weights, (None, self.dim))


def _check_observations(observations: object, dim: "int | None") -> tuple[list, int]:
    """The observations as a list and their common dimension ``d`` (``dim``, the weights', if given)."""
    source = "the weights'" if dim is not None else None
    if isinstance(observations, (ProxyObservation, ChoiceObservation)):
        observations = [observations]
    if not isinstance(observations, Sequence) or isinstance(observations, str):
        raise ValueError(f"observations: expected a sequence of ProxyObservation / ChoiceObservation, "
                         f"got {type(observations).__name__}")
    items = list(observations)
    for i, item in enumerate(items):
        if not isinstance(item, (ProxyObservation, ChoiceObservation)):
            raise ValueError(f"observations[{i}]: expected a ProxyObservation or ChoiceObservation, "
                             f"got {type(item).__name__}")
        if dim is None:
            dim, source = item.dim, f"observations[{i}]'s"
        elif item.dim != dim:
            raise ValueError(f"observations[{i}]: feature dimension {item.dim} differs from {source} {dim}")
    if dim is None:
        raise ValueError("observations: empty; at least one observation is needed to know the dimension d")
    return items, dim


def make_joint_model(observations: "Sequence[Observation]", beta: float, method: str,
                     prior_sigma: "float | None" = None, proxy_samples: "np.ndarray | None" = None, *,
                     seed: int = 0, num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES,
                     dim: "int | None" = None,
                     observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL) -> PosteriorModel:
    """Validate the arguments and precompute every ``phi~(w~)`` and (Sample-Z) ``phi_i``.

    Args:
        observations: ``ProxyObservation`` s and ``ChoiceObservation`` s in one weight space ``R^d``
            (a single observation is accepted too). May be empty only when ``dim`` is given.
        beta: the proxies' rationality, finite ``>= 0`` (each choice carries its own).
        method: ``"maxent_z"`` or ``"sample_z"``.
        prior_sigma: prior standard deviation, ``> 0``; ``None``: the calibrated
            ``1 / (temperature * feature scale)`` of ``observation_model`` and the proxy
            observations' training maps (:mod:`ird_core.posterior.calibration`).
        proxy_samples: ``(N, d)`` Sample-Z proxy weights ``w_i``, shared by every training MDP;
            default ``proxy_prior_samples(num_proxy_samples, d, prior_sigma, seed)``. Drawn and
            planned only for proxy observations without ``proxy_sample_features``.
        seed: ``>= 0``, seeds the default proxy samples.
        num_proxy_samples: ``N`` when the proxy samples are drawn here, ``>= 1``.
        dim: ``d`` when known from elsewhere (the weights); then checked against the observations.
        observation_model: how ``phi~(w~)``, the ``phi_i`` and Sample-Z's own term summarise
            behaviour (:class:`ObservationModel`); observations that carry their
            ``proxy_features`` / ``proxy_sample_features`` must have been built with the same
            model (``proxy_observations(..., observation_model=...)``).
    Returns:
        The ``PosteriorModel``.
    """
    items, dim = _check_observations(observations, dim)
    if not isinstance(observation_model, ObservationModel):
        raise ValueError(f"observation_model: expected an ObservationModel, got {type(observation_model).__name__}")
    beta = check_real("beta", beta, positive=False)
    parse(ZMethod, method, "method")
    # The calibrated prior's feature scale pools the proxies' training maps (scale 1: only choices).
    train_maps = [o.train_mdp.features for o in items if isinstance(o, ProxyObservation)] or None
    sigma = check_real("prior_sigma", resolve_prior_sigma(prior_sigma, observation_model.temperature, train_maps),
                       positive=True)
    seed = check_int("seed", seed, 0)
    num_proxy_samples = check_int("num_proxy_samples", num_proxy_samples, 1)
    samples = None if proxy_samples is None else check_array("proxy_samples", proxy_samples, (None, dim))
    sample_phi: dict[int, np.ndarray] = {}  # per training MDP object: computed once
    terms: list[ProxyTerm] = []
    for obs in (o for o in items if isinstance(o, ProxyObservation)):
        phi = obs.proxy_features
        if phi is None:
            phi = _frozen(proxy_feature_counts(obs.train_mdp, obs.proxy_weights, model=observation_model))
        phi_i = None
        if method == ZMethod.SAMPLE_Z:
            phi_i = obs.proxy_sample_features
            if phi_i is None:
                if samples is None:
                    samples = proxy_prior_samples(num_proxy_samples, dim, sigma, seed)
                key = id(obs.train_mdp)
                if key not in sample_phi:
                    sample_phi[key] = _frozen(proxy_feature_counts(obs.train_mdp, samples, model=observation_model))
                phi_i = sample_phi[key]
        terms.append(ProxyTerm(obs.train_mdp, phi, phi_i))
    choices = tuple(o for o in items if isinstance(o, ChoiceObservation))
    return PosteriorModel(method, beta, sigma, dim, tuple(terms), choices, observation_model)


def joint_log_posterior(weights: np.ndarray, observations: "Sequence[Observation]",
                        beta: float, method: str, prior_sigma: "float | None" = None,
                        proxy_samples: "np.ndarray | None" = None, *, seed: int = 0,
                        num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES) -> np.ndarray:
    """Unnormalised joint IRD log posterior of candidate weights (docs/spec.md section 7).

    Args:
        weights: ``(K, d)`` candidates ``w``.
        observations, beta, method, prior_sigma, proxy_samples, seed, num_proxy_samples: as
            ``make_joint_model``.
    Returns:
        ``(K,)``; only differences between candidates are meaningful.
    """
    w = check_array("weights", weights, (None, None))
    model = make_joint_model(observations, beta, method, prior_sigma, proxy_samples, seed=seed,
                             num_proxy_samples=num_proxy_samples, dim=w.shape[1])
    return model.log_density(w)


def joint_log_posterior_grad(weights: np.ndarray, observations: "Sequence[Observation]",
                             beta: float, method: str, prior_sigma: "float | None" = None,
                             proxy_samples: "np.ndarray | None" = None, *, seed: int = 0,
                             num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES) -> np.ndarray:
    """Gradient of ``joint_log_posterior``; ``(K, d) -> (K, d)`` (same arguments)."""
    w = check_array("weights", weights, (None, None))
    model = make_joint_model(observations, beta, method, prior_sigma, proxy_samples, seed=seed,
                             num_proxy_samples=num_proxy_samples, dim=w.shape[1])
    return model.log_density_and_grad(w)[1]


# --------------------------------------------------------------------------------------------
# Single proxy (docs/spec.md section 3): the joint posterior with one ProxyObservation
# --------------------------------------------------------------------------------------------


def make_posterior_model(proxy_weights: np.ndarray, train_mdp: GridMDP, beta: float, method: str,
                         prior_sigma: "float | None" = None, proxy_samples: "np.ndarray | None" = None, *,
                         proxy_features: "np.ndarray | None" = None,
                         proxy_sample_features: "np.ndarray | None" = None, seed: int = 0,
                         num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES) -> PosteriorModel:
    """``make_joint_model([ProxyObservation(proxy_weights, train_mdp, proxy_features,
    proxy_sample_features)], ...)``. Args: as ``log_posterior``."""
    observation = ProxyObservation(proxy_weights, train_mdp, proxy_features, proxy_sample_features)
    return make_joint_model([observation], beta, method, prior_sigma, proxy_samples, seed=seed,
                            num_proxy_samples=num_proxy_samples)


def log_posterior(weights: np.ndarray, proxy_weights: np.ndarray, train_mdp: GridMDP, beta: float,
                  method: str, prior_sigma: "float | None" = None, proxy_samples: "np.ndarray | None" = None, *,
                  proxy_features: "np.ndarray | None" = None,
                  proxy_sample_features: "np.ndarray | None" = None, seed: int = 0,
                  num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES) -> np.ndarray:
    """Unnormalised IRD log posterior of candidate weights (docs/spec.md section 3).

    Args:
        weights: ``(K, d)`` candidates ``w``.
        proxy_weights: ``(d,)`` the proxy ``w~`` (finite); ``(p,)`` of any length when
            ``proxy_features`` is given (then only recorded).
        train_mdp: the training MDP on the hypothesis features.
        beta: designer rationality, finite and ``>= 0`` (0: the prior only).
        method: ``"maxent_z"`` or ``"sample_z"``.
        prior_sigma: prior standard deviation, ``> 0``.
        proxy_samples: ``(N, d)`` proxy-prior weights ``w_i`` for Sample-Z; default
            ``num_proxy_samples`` draws of ``N(0, prior_sigma^2 I)`` seeded by ``seed``.
        proxy_features: ``(d,)`` ``phi~(w~)`` supplied directly (overrides ``proxy_weights`` for
            the computation, e.g. latent_classifier, whose proxy is planned on other features).
        proxy_sample_features: ``(N, d)`` the ``phi_i`` supplied directly (overrides
            ``proxy_samples``).
        seed: seeds the default proxy samples.
        num_proxy_samples: ``N`` when the proxy samples are drawn here.
    Returns:
        ``(K,)``; only differences between candidates are meaningful.
    """
    model = make_posterior_model(proxy_weights, train_mdp, beta, method, prior_sigma, proxy_samples,
                                 proxy_features=proxy_features, proxy_sample_features=proxy_sample_features,
                                 seed=seed, num_proxy_samples=num_proxy_samples)
    return model.log_density(model.check_weights(weights))


def log_posterior_grad(weights: np.ndarray, proxy_weights: np.ndarray, train_mdp: GridMDP, beta: float,
                       method: str, prior_sigma: "float | None" = None, proxy_samples: "np.ndarray | None" = None, *,
                       proxy_features: "np.ndarray | None" = None,
                       proxy_sample_features: "np.ndarray | None" = None, seed: int = 0,
                       num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES) -> np.ndarray:
    """Gradient of ``log_posterior`` with respect to the candidates; ``(K, d) -> (K, d)``.

    MaxEnt-Z: exact, ``beta * (phi~(w~) - phi~(w)) - w / sigma^2``. Sample-Z: exact except for
    ``H(w) w``, a forward difference along the ray (relative error ~1e-6). Arguments as
    ``log_posterior``.
    """
    model = make_posterior_model(proxy_weights, train_mdp, beta, method, prior_sigma, proxy_samples,
                                 proxy_features=proxy_features, proxy_sample_features=proxy_sample_features,
                                 seed=seed, num_proxy_samples=num_proxy_samples)
    return model.log_density_and_grad(model.check_weights(weights))[1]
