"""Per-term log likelihoods of the IRD posterior and their exact gradients (docs/spec.md sections 3 and 7).

Every function is batched over candidate weights ``(K, d)``. The MDP quantities they consume
(``log Z(w)``, ``phi~(w)``) are computed by the caller (``ird_core.posterior.evidence``) in one batched pass
per training MDP; the choice terms need no MDP pass at all.

- Prior ``N(0, sigma^2 I)``: ``-|w|^2 / (2 sigma^2)``.
- MaxEnt-Z proxy term: ``beta * (w . phi~(w~) - log Z(w))``.
- Sample-Z proxy term: ``beta * w . phi~(w~) - logsumexp([beta w . phi~(w)] + [beta w . phi_i]_i)``.
- Choice term (an answered query): ``beta_c * w . f_chosen - logsumexp_k(beta_c * w . f_k)``.
"""

from __future__ import annotations

import numpy as np
from scipy.special import softmax

from ird_core.mdp import GridMDP
from ird_core.posterior.observation_model import RAY_STEP, DEFAULT_OBSERVATION_MODEL, ObservationModel, behaviour_counts
from ird_core.vocabulary import METHODS

__all__ = [
    "METHODS",
    "DEFAULT_NUM_PROXY_SAMPLES",
    "PROXY_BATCH",
    "logsumexp_rows",
    "log_prior",
    "log_prior_grad",
    "maxent_z_log_likelihood",
    "maxent_z_log_likelihood_grad",
    "sample_z_scores",
    "sample_z_log_likelihood",
    "sample_z_log_likelihood_grad",
    "sample_z_log_likelihood_and_grad",
    "choice_log_likelihood",
    "choice_log_likelihood_and_grad",
    "proxy_prior_samples",
    "proxy_feature_counts",
]

#: Default ``N`` of Sample-Z proxy samples (see ``ird_core.posterior``'s docstring for the study).
DEFAULT_NUM_PROXY_SAMPLES: int = 1000





#: OpenBLAS runs a gemm on one thread when ``M * N * K`` is at most this (its
#: ``SMP_THRESHOLD_MIN * GEMM_MULTITHREAD_THRESHOLD``); larger products start threads.
_SINGLE_THREAD_GEMM: int = 65536 * 4


def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` for ``(K, m) x (m, n)``, as BLAS calls small enough to stay on one thread.

    A multithreaded gemm oversubscribes a loaded machine with few cores (its time becomes
    erratic and far above the single-threaded one), and the Sample-Z terms do two such products
    per MCMC step. Splitting the columns keeps every call
    under OpenBLAS's threading threshold whatever ``OPENBLAS_NUM_THREADS`` says.
    """
    k, m = a.shape
    n = b.shape[1]
    width = max(1, _SINGLE_THREAD_GEMM // max(1, k * m))
    if n <= width:
        return a @ b
    return np.concatenate([a @ b[:, lo:lo + width] for lo in range(0, n, width)], axis=1)


def logsumexp_rows(scores: np.ndarray) -> np.ndarray:
    """``scipy.special.logsumexp(scores, axis=1)`` for finite ``scores`` ``(K, n) -> (K,)``, bit
    for bit (the same steps as scipy 1.17's: the maxima are taken out of the sum and added back as
    ``log1p(rest / count) + log(count) + max``), without scipy's array-API dispatch, whose
    per-call overhead dominates on these small arrays."""
    peak = scores.max(axis=1, keepdims=True)
    at_peak = scores == peak
    count = at_peak.sum(axis=1, keepdims=True, dtype=np.float64)
    rest = np.exp(np.where(at_peak, -np.inf, scores) - peak).sum(axis=1, keepdims=True)
    rest = np.where(rest == 0, rest, rest / count)
    return (np.log1p(rest) + np.log(count) + peak)[:, 0]


def log_prior(weights: np.ndarray, prior_sigma: float) -> np.ndarray:
    """Unnormalised Gaussian log prior ``-|w|^2 / (2 sigma^2)``; ``(K, d) -> (K,)``."""
    return -0.5 * np.sum(weights**2, axis=1) / prior_sigma**2


def log_prior_grad(weights: np.ndarray, prior_sigma: float) -> np.ndarray:
    """``-w / sigma^2``; ``(K, d) -> (K, d)``."""
    return -weights / prior_sigma**2


def maxent_z_log_likelihood(weights: np.ndarray, proxy_features: np.ndarray, log_z: np.ndarray,
                            beta: float) -> np.ndarray:
    """``beta * (w . phi~(w~) - log Z(w))``.

    Args:
        weights: ``(K, d)``; proxy_features: ``(d,)`` = ``phi~(w~)``; log_z: ``(K,)``.
    Returns:
        ``(K,)``.
    """
    return beta * (weights @ proxy_features - log_z)


def maxent_z_log_likelihood_grad(proxy_features: np.ndarray, expectations: np.ndarray,
                                 beta: float) -> np.ndarray:
    """``beta * (phi~(w~) - phi~(w))``; ``(d,), (K, d) -> (K, d)``."""
    return beta * (proxy_features[None, :] - expectations)


def sample_z_scores(weights: np.ndarray, own_features: "np.ndarray | None", sample_features: np.ndarray,
                    beta: float) -> np.ndarray:
    """The terms of the Sample-Z normaliser: ``[beta w . phi~(w), beta w . phi_1, ...]``.

    Args:
        weights: ``(K, d)``; own_features: ``(K, d)`` = ``phi~(w)``, or ``None`` to leave the
            candidate's own term out (the ablation); sample_features: ``(N, d)``.
    Returns:
        ``(K, N + 1)``, column 0 the candidate's own term (``(K, N)`` without it).
    """
    samples = _product(weights, sample_features.T)
    if own_features is None:
        return beta * samples
    own = np.sum(weights * own_features, axis=1, keepdims=True)
    return beta * np.concatenate([own, samples], axis=1)


def _expected_counts(p: np.ndarray, own_features: "np.ndarray | None", own_ray_derivative: "np.ndarray | None",
                     sample_features: np.ndarray) -> np.ndarray:
    """``sum_j p_j d(score_j / beta)/dw``: ``p_0 (phi~(w) + H(w) w) + sum_i p_i phi_i`` (no own
    term: ``sum_i p_i phi_i``); a ``None`` ray derivative is zero (optimal-path counts)."""
    if own_features is None:
        return _product(p, sample_features)
    own = own_features if own_ray_derivative is None else own_features + own_ray_derivative
    return p[:, :1] * own + _product(p[:, 1:], sample_features)


def sample_z_log_likelihood(weights: np.ndarray, proxy_features: np.ndarray, own_features: "np.ndarray | None",
                            sample_features: np.ndarray, beta: float) -> np.ndarray:
    """``beta * w . phi~(w~) - logsumexp(sample_z_scores)``; ``(K,)``.

    No ``- log(N + 1)``: the constant cancels in the posterior. ``own_features=None`` leaves the
    candidate's own term out.
    """
    scores = sample_z_scores(weights, own_features, sample_features, beta)
    return beta * (weights @ proxy_features) - logsumexp_rows(scores)


def sample_z_log_likelihood_grad(weights: np.ndarray, proxy_features: np.ndarray,
                                 own_features: "np.ndarray | None", own_ray_derivative: "np.ndarray | None",
                                 sample_features: np.ndarray, beta: float) -> np.ndarray:
    """Gradient of ``sample_z_log_likelihood``.

    ``beta * (phi~(w~) - p_0 (phi~(w) + H(w) w) - sum_i p_i phi_i)``, ``p = softmax(scores)``.

    Args:
        weights, own_features: ``(K, d)`` (``own_features`` ``None``: no own term);
        own_ray_derivative: ``(K, d)`` = ``H(w) w`` (``None``: zero, as for optimal-path counts,
        whose Jacobian vanishes almost everywhere); proxy_features: ``(d,)``;
        sample_features: ``(N, d)``.
    Returns:
        ``(K, d)``.
    """
    p = softmax(sample_z_scores(weights, own_features, sample_features, beta), axis=1)
    expected = _expected_counts(p, own_features, own_ray_derivative, sample_features)
    return beta * (proxy_features[None, :] - expected)


def sample_z_log_likelihood_and_grad(weights: np.ndarray, proxy_features: np.ndarray,
                                     own_features: "np.ndarray | None", own_ray_derivative: "np.ndarray | None",
                                     sample_features: np.ndarray, beta: float
                                     ) -> tuple[np.ndarray, np.ndarray]:
    """``sample_z_log_likelihood`` ``(K,)`` and ``sample_z_log_likelihood_grad`` ``(K, d)``
    from one evaluation of the scores (the sampler's hot path; same arguments)."""
    scores = sample_z_scores(weights, own_features, sample_features, beta)
    peak = scores.max(axis=1, keepdims=True)
    terms = np.exp(scores - peak)
    total = terms.sum(axis=1, keepdims=True)
    p = terms / total
    value = beta * (weights @ proxy_features) - (peak + np.log(total))[:, 0]
    expected = _expected_counts(p, own_features, own_ray_derivative, sample_features)
    return value, beta * (proxy_features[None, :] - expected)


def _choice_scores(weights: np.ndarray, option_features: np.ndarray, beta: float) -> np.ndarray:
    """``beta_c * F w`` for every candidate; ``(K, d), (q, d) -> (K, q)``."""
    return beta * (weights @ option_features.T)


def choice_log_likelihood(weights: np.ndarray, option_features: np.ndarray, chosen: int,
                          beta: float) -> np.ndarray:
    """Boltzmann choice ``log P(chosen | w) = beta_c w . f_chosen - logsumexp_k(beta_c w . f_k)``.

    Args:
        weights: ``(K, d)``; option_features: ``(q, d)``; chosen: index in ``[0, q)``;
        beta: the answer's rationality ``beta_c >= 0``.
    Returns:
        ``(K,)`` (normalised: ``<= 0``).
    """
    scores = _choice_scores(weights, option_features, beta)
    return scores[:, chosen] - logsumexp_rows(scores)


def choice_log_likelihood_and_grad(weights: np.ndarray, option_features: np.ndarray, chosen: int,
                                   beta: float) -> tuple[np.ndarray, np.ndarray]:
    """``choice_log_likelihood`` ``(K,)`` and its gradient
    ``beta_c * (f_chosen - sum_k p_k f_k)``, ``p = softmax(beta_c F w)``, ``(K, d)``."""
    scores = _choice_scores(weights, option_features, beta)
    # By hand rather than scipy's logsumexp: this runs once per leapfrog step, where scipy's
    # per-call overhead is not negligible next to a small map's MDP pass.
    peak = scores.max(axis=1, keepdims=True)
    terms = np.exp(scores - peak)
    total = terms.sum(axis=1, keepdims=True)
    p = terms / total
    value = scores[:, chosen] - (peak + np.log(total))[:, 0]
    return value, beta * (option_features[chosen][None, :] - p @ option_features)


def proxy_prior_samples(num: int, dim: int, prior_sigma: float, seed: int | np.random.Generator) -> np.ndarray:
    """``num`` proxies from ``N(0, sigma^2 I)``: ``prior_sigma * default_rng(seed).standard_normal``
    (a Generator as ``seed`` is used as it is).

    The draws of every Sample-Z term: :func:`ird_core.posterior.proxy_observation` plans them in
    the proxy's space, ``make_joint_model`` in the hypothesis space.

    Returns:
        ``(num, dim)``.
    """
    return prior_sigma * np.random.default_rng(seed).standard_normal((num, dim))


#: Proxies per batched MDP call in :func:`proxy_feature_counts`: bounds the working set to
#: ``(T + 1, batch, H, W)`` floats whatever the number of proxies.
PROXY_BATCH: int = 256


def proxy_feature_counts(planning_mdp: GridMDP, proxy_weights: np.ndarray,
                         hypothesis_features: np.ndarray | None = None,
                         model: ObservationModel = DEFAULT_OBSERVATION_MODEL) -> np.ndarray:
    """``phi~(w~)``: hypothesis-space feature counts of proxies' behaviour in their training MDP.

    The designer's proxy acts on the features it was written for (``planning_mdp.features``,
    ``(H, W, p)``); IRD conditions on what that behaviour does in the hypothesis space
    (``hypothesis_features``, ``(H, W, d)``, the same cells). When the two coincide (every
    Lavaland condition but latent_classifier) pass ``None``. This is the one place where the
    proxy is "planned on its own map and contracted with the hypothesis features": Lavaland,
    the inference node and the planner's training-features baseline all call it. ``model``
    says which behaviour: the optimal path's counts or MaxEnt expectations at a temperature
    (:class:`ird_core.posterior.ObservationModel`).

    Args:
        planning_mdp: the training MDP on the proxy's features, ``(H, W, p)``.
        proxy_weights: ``(K, p)`` (or ``(p,)`` for one proxy).
        hypothesis_features: ``(H, W, d)`` or ``None`` (= ``planning_mdp.features``).
        model: the observation model (default: the calibrated designer's MaxEnt expectations).

    Returns:
        ``(K, d)`` (``(d,)`` for a ``(p,)`` input): counts over the ``T + 1`` states.

    Raises:
        ValueError: naming ``proxy_weights`` or ``hypothesis_features`` when a size is wrong or
            a value is not finite.
    """
    weights = np.asarray(proxy_weights, dtype=np.float64)
    single = weights.ndim == 1
    weights = np.atleast_2d(weights)
    p = planning_mdp.num_features
    if weights.ndim != 2 or weights.shape[1] != p or len(weights) == 0:
        raise ValueError(f"proxy_weights: expected shape (K, {p}) with K >= 1, got {np.shape(proxy_weights)}")
    if not np.all(np.isfinite(weights)):
        raise ValueError("proxy_weights: contains NaN or infinite values")
    hyp = None
    if hypothesis_features is not None:
        hyp = np.asarray(hypothesis_features, dtype=np.float64)
        if hyp.ndim != 3 or hyp.shape[:2] != (planning_mdp.height, planning_mdp.width) or hyp.shape[2] < 1:
            raise ValueError(f"hypothesis_features: expected shape ({planning_mdp.height}, {planning_mdp.width}, d), "
                             f"got {hyp.shape}")
        if not np.all(np.isfinite(hyp)):
            raise ValueError("hypothesis_features: contains NaN or infinite values")
    out = np.concatenate([behaviour_counts(planning_mdp, weights[lo: lo + PROXY_BATCH], model, hyp)
                          for lo in range(0, len(weights), PROXY_BATCH)])
    return out[0] if single else out
