"""The one builder of proxy observations: what the designer's proxy did in its training MDP
(docs/spec.md sections 3 and 7).

A proxy ``w~`` acts on the features it was written for (the training map's hypothesis features,
or, for latent_classifier, the classifier outputs on the same grid: ``proxy_mdp``); IRD
conditions on its expected counts in the hypothesis space, ``phi~(w~) = E[phi(xi) | w~]`` over the
``T + 1`` states (:func:`ird_core.posterior.proxy_feature_counts`). For Sample-Z the prior proxies
``w_i ~ N(0, sigma^2 I)`` are drawn in the proxy's own space and counted the same way
(``phi_i``).

The draws are ``prior_sigma * default_rng(seed).standard_normal((N, p))``
(:func:`ird_core.posterior.proxy_prior_samples`; a numpy Generator as ``seed`` is used as it is):
the same ``seed`` in every training world plans the same prior proxies in each. The Lavaland
conveniences (:func:`proxy_feature_expectations`, :func:`proxy_prior_features`,
:func:`proxy_observations`) and the inference node's jobs build their observations here.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ird_core.checks import check_int, check_real
from ird_core.mdp import GridMDP
from ird_core.posterior.evidence import ProxyObservation
from ird_core.posterior.likelihoods import proxy_feature_counts, proxy_prior_samples
from ird_core.posterior.calibration import resolve_prior_sigma
from ird_core.posterior.observation_model import DEFAULT_OBSERVATION_MODEL, ObservationModel
from ird_core.worlds.lavaland import LavalandInstance, TrainingWorld, train_mdp
from ird_core.worlds.terrain import as_generator

__all__ = ["proxy_observation", "proxy_feature_expectations", "proxy_prior_features", "proxy_observations"]


def _counts(train: GridMDP, proxy_mdp: GridMDP | None, weights: np.ndarray,
            model: ObservationModel = DEFAULT_OBSERVATION_MODEL) -> np.ndarray:
    """(K, p) proxy weights -> (K, d) hypothesis-space counts in the training MDP."""
    if proxy_mdp is None:
        return proxy_feature_counts(train, weights, model=model)
    return proxy_feature_counts(proxy_mdp, weights, train.features, model=model)


def _prior_counts(train: GridMDP, proxy_mdp: GridMDP | None, num: int,
                  seed: int | np.random.Generator, prior_sigma: "float | None",
                  model: ObservationModel = DEFAULT_OBSERVATION_MODEL) -> np.ndarray:
    """Sample-Z ``phi_i`` (num, d) of ``num`` proxies drawn from the prior in the proxy's space
    (``prior_sigma`` ``None``: the calibrated sigma of ``model`` on the proxy space's training features)."""
    num = check_int("num_proxy_samples", num, 1)
    space = train if proxy_mdp is None else proxy_mdp
    prior_sigma = check_real("prior_sigma", resolve_prior_sigma(prior_sigma, model.temperature, [space.features]),
                             positive=True, ranged=False)
    return _counts(train, proxy_mdp, proxy_prior_samples(num, space.num_features, prior_sigma, as_generator(seed)),
                   model)


def proxy_observation(
    train_mdp: GridMDP,
    proxy_weights: np.ndarray,
    *,
    proxy_mdp: GridMDP | None = None,
    num_proxy_samples: int | None = None,
    seed: int | np.random.Generator = 0,
    prior_sigma: "float | None" = None,
    observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL,
) -> ProxyObservation:
    """The :class:`ProxyObservation` of a proxy written for ``train_mdp``, with ``phi~(w~)`` computed.

    Args:
        train_mdp: the training MDP on the hypothesis features ``(H, W, d)``.
        proxy_weights: ``(p,)`` the proxy; ``p = d`` without ``proxy_mdp``.
        proxy_mdp: the same grid, start and horizon on the proxy's own features ``(H, W, p)``
            (latent_classifier's classifier outputs), or ``None`` when the proxy acts on
            ``train_mdp``'s features.
        num_proxy_samples: ``N``; when given, the observation carries its Sample-Z ``phi_i``
            ``(N, d)`` (prior proxies drawn in the proxy's space with ``seed``, ``prior_sigma``).
        seed: int seed or numpy Generator of the prior draws.
        prior_sigma: prior standard deviation, ``> 0``; ``None``: the calibrated sigma of
            ``observation_model`` on the proxy space's training features
            (:mod:`ird_core.posterior.calibration`).
        observation_model: how behaviour is counted (optimal path or MaxEnt expectations).

    Returns:
        ``ProxyObservation(proxy_weights, train_mdp, proxy_features=(d,),
        proxy_sample_features=(N, d) or None)``.
    """
    weights = np.asarray(proxy_weights, dtype=np.float64)
    phi = _counts(train_mdp, proxy_mdp, weights[None], observation_model)[0]
    sample_phi = None
    if num_proxy_samples is not None:
        sample_phi = _prior_counts(train_mdp, proxy_mdp, num_proxy_samples, seed, prior_sigma, observation_model)
    return ProxyObservation(weights, train_mdp, proxy_features=phi, proxy_sample_features=sample_phi)


def _proxy_mdp(instance: LavalandInstance) -> GridMDP | None:
    """The training grid on the proxy's features when they are not the hypothesis features (a
    classifier's outputs, or hypothesis features the proxy does not have, such as *novel*)."""
    same = instance.classifier is None and tuple(instance.proxy_feature_names) == tuple(instance.feature_names)
    return None if same else train_mdp(instance, proxy=True)


def proxy_feature_expectations(instance: LavalandInstance,
                               observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL) -> np.ndarray:
    """The proxy's feature counts in the instance's training map, in the hypothesis space.

    The proxy's behaviour (MaxEnt by default, or its optimal path: ``observation_model``) is
    planned on the proxy features (identical to the hypothesis features except for
    latent_classifier, where it is planned on the classified cells); its visits are contracted
    with the hypothesis features.

    Returns:
        (d,) = ``E[phi(xi) | proxy]`` over the T + 1 states of the training MDP.
    """
    return _counts(train_mdp(instance), _proxy_mdp(instance), instance.proxy_weights[None], observation_model)[0]


def _check_prior(num: int, prior_sigma: "float | None") -> None:
    if isinstance(num, bool) or not isinstance(num, (int, np.integer)) or num < 1:
        raise ValueError(f"num must be an integer >= 1, got {num!r}")
    if prior_sigma is not None and (not np.isfinite(prior_sigma) or prior_sigma <= 0):
        raise ValueError(f"prior_sigma must be finite and > 0, got {prior_sigma!r}")


def proxy_prior_features(
    instance: LavalandInstance,
    num: int,
    seed: int | np.random.Generator,
    prior_sigma: "float | None" = None,
) -> np.ndarray:
    """Expected hypothesis-space feature counts of proxies drawn from the designer's prior.

    For Sample-Z. Proxies are ``N(0, prior_sigma^2 I)`` weights in the proxy feature space
    (the hypothesis space for the first three conditions, the 3 classifier outputs for
    latent_classifier), planned in the training map like :func:`proxy_feature_expectations`.

    Args:
        instance: the Lavaland instance.
        num: number of proxies (>= 1).
        seed: int seed or numpy Generator.
        prior_sigma: prior standard deviation (> 0); ``None``: the calibrated sigma of the
            default observation model on the proxy space's training features.

    Returns:
        (num, d).
    """
    _check_prior(num, prior_sigma)
    return _prior_counts(train_mdp(instance), _proxy_mdp(instance), int(num), seed, prior_sigma)


def _training_views(instance: LavalandInstance) -> list[LavalandInstance]:
    """The instance seen through each of its training worlds (the first, then the extra ones)."""
    first = TrainingWorld(instance.train_labels, instance.train_features, instance.proxy_train_features,
                          instance.train_start, instance.train_horizon, instance.proxy_weights)
    return [dataclasses.replace(instance, train_labels=world.labels, train_features=world.features,
                                proxy_train_features=world.proxy_features, train_start=world.start,
                                train_horizon=world.horizon, proxy_weights=world.proxy_weights,
                                extra_training_worlds=())
            for world in (first, *instance.extra_training_worlds)]


def proxy_observations(
    instance: LavalandInstance,
    num_proxy_samples: int | None = None,
    seed: int = 0,
    prior_sigma: "float | None" = None,
    observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL,
) -> list[ProxyObservation]:
    """One :class:`ProxyObservation` per training world (the first, then
    ``instance.extra_training_worlds``), for ``sample_joint_posterior``.

    Args:
        instance: the instance.
        num_proxy_samples: if given, each observation carries its Sample-Z counts
            ``proxy_prior_features(world, num_proxy_samples, seed, prior_sigma)``: the same proxy
            draws planned in every world (needed when the proxy lives on classifier outputs);
            ``prior_sigma`` ``None``: the calibrated sigma of the proxy space's features pooled
            over every training world.
        observation_model: how behaviour is counted; pass the posterior's own.
    """
    views = _training_views(instance)
    if num_proxy_samples is not None:
        _check_prior(num_proxy_samples, prior_sigma)
        if prior_sigma is None:  # one calibrated sigma for every world: the same draws planned in each
            spaces = [(train_mdp(v) if _proxy_mdp(v) is None else _proxy_mdp(v)).features for v in views]
            prior_sigma = resolve_prior_sigma(None, observation_model.temperature, spaces)
    return [proxy_observation(train_mdp(view), view.proxy_weights, proxy_mdp=_proxy_mdp(view),
                              num_proxy_samples=num_proxy_samples, seed=seed, prior_sigma=prior_sigma,
                              observation_model=observation_model)
            for view in views]
