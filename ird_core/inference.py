"""The IRD posterior over the true reward weights (IRD_SPEC.md section 3) and its sampler.

Observation model (Hadfield-Menell et al. 2017, section 4): the designer picks the proxy ``w~``
with ``P(w~ | w*, M~) ∝ exp(beta * w* . phi~(w~))``, where ``phi~(w~)`` are the proxy's expected
feature counts in the training MDP ``M~`` under the MaxEnt agent. With a Gaussian prior
``N(0, sigma^2 I)`` the unnormalised log posterior of a candidate ``w`` is

- ``maxent_z``: ``beta * (w . phi~(w~) - log Z(w)) - |w|^2 / (2 sigma^2)``, i.e. MaxEnt IRL with
  ``beta`` pretend demonstrations whose feature counts are ``phi~(w~)``. Exact gradient
  ``beta * (phi~(w~) - phi~(w)) - w / sigma^2``; the log posterior is strictly concave.
- ``sample_z``: ``beta * w . phi~(w~) - logsumexp([beta w . phi~(w)] + [beta w . phi_i]_i)
  - |w|^2 / (2 sigma^2)``, with ``phi_i = phi~(w_i)`` for ``N`` proxies ``w_i`` drawn from the
  proxy prior ``N(0, sigma^2 I)`` once per training MDP, and the candidate's own ``phi~(w)``
  included as the paper recommends.

Sample-Z gradient. ``d/dw [w . phi~(w)] = phi~(w) + H(w) w`` with ``H(w) = Cov_w[phi]`` (the
Hessian of ``log Z``). ``H(w) w`` is the derivative of ``phi~(t w)`` in ``t`` at ``t = 1``; it is
computed by a forward difference along the ray, ``(phi~((1 + eps) w) - phi~(w)) / eps``
(``eps = 1e-6``, agrees with central differences of the log posterior to ~1e-6 relative), so
the value and the gradient come from ONE batched MDP call on ``2K`` weights. HMC stays exact
with this deterministic field; dropping the ``H(w) w`` term (half the cost) is also exact but
shrank the stable HMC step ten-fold on latent_raw, so the term is kept.

Posterior geometry (measured on latent_raw, d = 50, beta = 1). Both posteriors are a Gaussian
prior times a likelihood that is nearly piecewise linear: at typical posterior weights the
MaxEnt trajectory distribution is close to deterministic, so ``log Z`` is close to a max over
trajectories and the log posterior has sharp creases (curvature up to ~100x that at the mode,
in preconditioned units) where the preferred trajectory changes. Sample-Z is stiffer still: its
``logsumexp`` over the proxies' feature counts (norms ~100-250) is a near-hard max, and its
posterior is up to ~9x wider (in sd) than the Laplace approximation at its mode. The creases cap
the stable step size (~0.05 preconditioned units for MaxEnt-Z, ~0.02 for Sample-Z), so MALA and
RWM mix far too slowly in 50-d; HMC's ballistic trajectories do not.

Sampler (``sample_posterior``), defaults chosen on the 15x15, T = 30, d = 50 ``latent_raw``
benchmark (``scripts/bench_inference.py``):

1. A Laplace approximation: the MAP by damped Newton from ``w = 0``, each iteration one batched
   call for the gradient at ``w`` and at ``w + delta e_j`` (forward-difference Hessian, ``d + 1``
   weights) and one batched line search. The inverse negative Hessian at the MAP (eigenvalues
   floored) is the initial preconditioner: posterior standard deviations span ~0.02 to ~1 across
   directions, and a dense 50-d metric cannot be learnt from scratch in a short warm-up.
2. ``num_chains`` (16) chains start at ``mode + 2 L z`` (``L L^T`` the Laplace covariance), i.e.
   overdispersed relative to the Laplace approximation, in the spirit of Gelman & Rubin (1992).
   Starting from the prior ``N(0, sigma^2 I)`` (``init="prior"``, available) is more
   conservative, but in 50-d the prior mass is hundreds of nats away from the posterior and the
   chains need far longer warm-ups to get there. R-hat is computed on post-warm-up draws only,
   rank-normalised and folded, so chains that disagree in location or in scale are both caught.
3. HMC (``kernel="hmc"``; ``"mala"`` and ``"rwm"`` are available) with a dense metric: a shared
   step size adapted by dual averaging towards acceptance 0.8 (chain-averaged acceptance
   probability), trajectories of 1.5 preconditioned units (at most ``DEFAULT_MAX_LEAPFROG``
   leapfrog steps, per-chain step jitter +-10%), and Stan-style windows that re-estimate the
   metric from the draws of all chains pooled, shrunk towards the current metric with
   Ledoit-Wolf weights (see ``ird_core.mcmc``). Warm-up trajectories are capped at 8 leapfrog
   steps until the final buffer, which tunes the step at the full trajectory length. Everything
   is frozen after warm-up, so the retained draws come from one fixed, valid kernel.
   Per-method defaults: MaxEnt-Z 100 warm-up iterations, >= 120 iterations per chain after
   warm-up, <= 32 leapfrog steps; Sample-Z 150, >= 100 and <= 64 (``thin=None`` picks the
   thinning that gives each chain at least that many iterations).
4. Draws are thinned, pooled draw-major (first retained draw of every chain, then the second,
   ...) and cut to exactly ``num_samples``; diagnostics use every retained draw: rank-normalised
   split R-hat (max of bulk and folded, Vehtari et al. 2021) and bulk ESS.

Default number of proxy samples for Sample-Z: ``DEFAULT_NUM_PROXY_SAMPLES = 1000``. Their
feature expectations cost one batched pass once (about 0.4 s on 15x15, T = 30), and each MCMC
step only adds a ``(K, d) x (d, N)`` product and a softmax, negligible next to the MDP pass, so
``N`` is cheap. It matters: the Sample-Z normaliser is a log-mean-exp of near-max terms and
converges slowly. On latent_raw (seed 0, beta 1) the rms error of log-posterior differences
between 256 posterior-typical weights, against N = 6400 proxies, is 6.0 / 4.1 / 3.4 / 2.5 / 1.9 /
0.9 nats for N = 25 / 100 / 200 / 400 / 800 / 1600, for differences whose spread is 8.0 nats
(``scripts/bench_inference.py --proxy-study``). 1000 keeps the approximation error near 1.5
nats at well under a second of set-up.

``beta = 0`` is allowed (the posterior is then the prior); negative beta is an error.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.special import logsumexp, softmax

from ird_core import mcmc
from ird_core.mdp import GridMDP, feature_expectations, log_partition, log_partition_and_feature_expectations

__all__ = [
    "METHODS",
    "DEFAULT_NUM_PROXY_SAMPLES",
    "DEFAULT_NUM_CHAINS",
    "DEFAULT_WARMUP",
    "DEFAULT_MIN_ITERATIONS",
    "DEFAULT_KERNEL",
    "DEFAULT_MAX_LEAPFROG",
    "DEFAULT_TRAJECTORY_LENGTH",
    "DEFAULT_INIT_SCALE",
    "R_HAT_CONVERGED",
    "log_prior",
    "log_prior_grad",
    "maxent_z_log_likelihood",
    "maxent_z_log_likelihood_grad",
    "sample_z_scores",
    "sample_z_log_likelihood",
    "sample_z_log_likelihood_grad",
    "sample_z_log_likelihood_and_grad",
    "proxy_prior_samples",
    "PosteriorModel",
    "make_posterior_model",
    "log_posterior",
    "log_posterior_grad",
    "laplace_approximation",
    "Posterior",
    "pool_draws",
    "sample_posterior",
]

METHODS: tuple[str, ...] = ("maxent_z", "sample_z")
DEFAULT_NUM_PROXY_SAMPLES: int = 1000
DEFAULT_NUM_CHAINS: int = 16
#: Per-method sampler defaults (see the module docstring): Sample-Z's likelihood has much
#: stiffer creases (a near-hard max over the proxies' feature counts), so it needs a longer
#: warm-up to learn the metric, longer chains and more leapfrog steps per trajectory.
#: MaxEnt-Z: measured on latent_raw (15x15, T = 30, d = 50, beta 1, 1000 draws), seeds 0-5,
#: 60 / 60 gave split R-hat 1.045-1.073 and 100 / 120 gave 1.021-1.035 (about 3 s).
DEFAULT_WARMUP: dict[str, int] = {"maxent_z": 100, "sample_z": 150}
#: With ``thin=None`` each chain runs at least this many iterations after warm-up.
DEFAULT_MIN_ITERATIONS: dict[str, int] = {"maxent_z": 120, "sample_z": 100}
DEFAULT_MAX_LEAPFROG: dict[str, int] = {"maxent_z": 32, "sample_z": 64}
DEFAULT_KERNEL: str = "hmc"
#: HMC integration time in preconditioned units.
DEFAULT_TRAJECTORY_LENGTH: float = 1.5
#: Leapfrog cap during warm-up before the final step-size buffer.
DEFAULT_WARMUP_MAX_LEAPFROG: int = 8
#: Chains start at ``mode + DEFAULT_INIT_SCALE * L z`` (Laplace covariance ``L L^T``).
DEFAULT_INIT_SCALE: float = 2.0
#: A run with a larger maximum split R-hat is reported as not converged.
R_HAT_CONVERGED: float = 1.1
#: Relative step along the ray ``t w`` for the Sample-Z own-term derivative ``H(w) w``.
_RAY_STEP: float = 1e-6
#: Absolute coordinate step of the forward-difference Hessian (Laplace approximation only).
_HESSIAN_STEP: float = 1e-4
#: R-hat values above this are stored as this (``inf`` is not representable in ROS messages).
_R_HAT_CAP: float = 1e6

ProgressFn = Callable[[int, int], None]


# --------------------------------------------------------------------------------------------
# Operators
# --------------------------------------------------------------------------------------------


#: OpenBLAS runs a gemm on one thread when ``M * N * K`` is at most this (its
#: ``SMP_THRESHOLD_MIN * GEMM_MULTITHREAD_THRESHOLD``); larger products start threads.
_SINGLE_THREAD_GEMM: int = 65536 * 4


def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a @ b`` for ``(K, m) x (m, n)``, as BLAS calls small enough to stay on one thread.

    A multithreaded gemm oversubscribes a loaded 2-core machine: a ``(16, 50) x (50, 1000)``
    product measured 0.29-57 ms there with threads against 0.04 ms single-threaded, and the
    Sample-Z terms do two such products per MCMC step. Splitting the columns keeps every call
    under OpenBLAS's threading threshold whatever ``OPENBLAS_NUM_THREADS`` says.
    """
    k, m = a.shape
    n = b.shape[1]
    width = max(1, _SINGLE_THREAD_GEMM // max(1, k * m))
    if n <= width:
        return a @ b
    return np.concatenate([a @ b[:, lo:lo + width] for lo in range(0, n, width)], axis=1)


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


def sample_z_scores(weights: np.ndarray, own_features: np.ndarray, sample_features: np.ndarray,
                    beta: float) -> np.ndarray:
    """The terms of the Sample-Z normaliser: ``[beta w . phi~(w), beta w . phi_1, ...]``.

    Args:
        weights: ``(K, d)``; own_features: ``(K, d)`` = ``phi~(w)``; sample_features: ``(N, d)``.
    Returns:
        ``(K, N + 1)``, column 0 the candidate's own term.
    """
    own = np.sum(weights * own_features, axis=1, keepdims=True)
    return beta * np.concatenate([own, _product(weights, sample_features.T)], axis=1)


def sample_z_log_likelihood(weights: np.ndarray, proxy_features: np.ndarray, own_features: np.ndarray,
                            sample_features: np.ndarray, beta: float) -> np.ndarray:
    """``beta * w . phi~(w~) - logsumexp(sample_z_scores)``; ``(K,)``.

    No ``- log(N + 1)``: the constant cancels in the posterior.
    """
    scores = sample_z_scores(weights, own_features, sample_features, beta)
    return beta * (weights @ proxy_features) - logsumexp(scores, axis=1)


def sample_z_log_likelihood_grad(weights: np.ndarray, proxy_features: np.ndarray,
                                 own_features: np.ndarray, own_ray_derivative: np.ndarray,
                                 sample_features: np.ndarray, beta: float) -> np.ndarray:
    """Gradient of ``sample_z_log_likelihood``.

    ``beta * (phi~(w~) - p_0 (phi~(w) + H(w) w) - sum_i p_i phi_i)``, ``p = softmax(scores)``.

    Args:
        weights, own_features: ``(K, d)``; own_ray_derivative: ``(K, d)`` = ``H(w) w``;
        proxy_features: ``(d,)``; sample_features: ``(N, d)``.
    Returns:
        ``(K, d)``.
    """
    p = softmax(sample_z_scores(weights, own_features, sample_features, beta), axis=1)
    expected = p[:, :1] * (own_features + own_ray_derivative) + _product(p[:, 1:], sample_features)
    return beta * (proxy_features[None, :] - expected)


def sample_z_log_likelihood_and_grad(weights: np.ndarray, proxy_features: np.ndarray,
                                     own_features: np.ndarray, own_ray_derivative: np.ndarray,
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
    expected = p[:, :1] * (own_features + own_ray_derivative) + _product(p[:, 1:], sample_features)
    return value, beta * (proxy_features[None, :] - expected)


def proxy_prior_samples(num: int, dim: int, prior_sigma: float, seed: int) -> np.ndarray:
    """``num`` proxies from ``N(0, sigma^2 I)``: ``prior_sigma * default_rng(seed).standard_normal``.

    The same draws as ``ird_core.lavaland.proxy_prior_features(instance, num, seed, sigma)``
    makes for conditions whose proxy lives in the hypothesis space.

    Returns:
        ``(num, dim)``.
    """
    return prior_sigma * np.random.default_rng(seed).standard_normal((num, dim))


# --------------------------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------------------------


def _check_int(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def _check_real(name: str, value: object, *, positive: bool) -> float:
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a real number, got {value!r}") from exc
    if isinstance(value, bool) or not np.isfinite(x) or (x <= 0 if positive else x < 0):
        bound = "> 0" if positive else ">= 0"
        raise ValueError(f"{name}: expected a finite number {bound}, got {value!r}")
    return x


def _check_array(name: str, value: object, shape: tuple[int | None, ...]) -> np.ndarray:
    """A finite float64 array whose shape matches ``shape`` (``None`` = any size >= 1)."""
    try:
        x = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a numeric array, got {type(value).__name__}") from exc
    ok = x.ndim == len(shape) and all((s is None and n >= 1) or n == s for n, s in zip(x.shape, shape))
    if not ok:
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise ValueError(f"{name}: expected shape {want}, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    return x


# --------------------------------------------------------------------------------------------
# The posterior as a batched log density
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class PosteriorModel:
    """Everything a log-posterior evaluation needs, with the proxy terms computed once.

    Attributes:
        train_mdp: the training MDP ``M~`` on the hypothesis features ``(H, W, d)``.
        method: one of ``METHODS``.
        beta: ``>= 0``.
        prior_sigma: ``> 0``.
        proxy_features: ``(d,)`` = ``phi~(w~)``.
        sample_features: ``(N, d)`` = ``phi_i`` (Sample-Z), else ``None``.
    """

    train_mdp: GridMDP
    method: str
    beta: float
    prior_sigma: float
    proxy_features: np.ndarray
    sample_features: "np.ndarray | None" = None

    @property
    def dim(self) -> int:
        return self.train_mdp.num_features

    def log_density(self, weights: np.ndarray) -> np.ndarray:
        """Unnormalised log posterior; ``(K, d) -> (K,)``. One batched MDP call."""
        if self.method == "maxent_z":
            log_z = log_partition(self.train_mdp, weights)
            like = maxent_z_log_likelihood(weights, self.proxy_features, log_z, self.beta)
        else:
            own = feature_expectations(self.train_mdp, weights)
            like = sample_z_log_likelihood(weights, self.proxy_features, own, self.sample_features, self.beta)
        return like + log_prior(weights, self.prior_sigma)

    def log_density_and_grad(self, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Value ``(K,)`` and gradient ``(K, d)`` from one batched MDP call (``2K`` weights for
        Sample-Z, whose gradient uses a forward difference along the ray)."""
        if self.method == "maxent_z":
            log_z, expectations = log_partition_and_feature_expectations(self.train_mdp, weights)
            value = maxent_z_log_likelihood(weights, self.proxy_features, log_z, self.beta)
            grad = maxent_z_log_likelihood_grad(self.proxy_features, expectations, self.beta)
        else:
            k = len(weights)
            both = feature_expectations(self.train_mdp,
                            np.concatenate([weights, (1.0 + _RAY_STEP) * weights]))
            own, ray = both[:k], (both[k:] - both[:k]) / _RAY_STEP
            value, grad = sample_z_log_likelihood_and_grad(weights, self.proxy_features, own, ray,
                                                           self.sample_features, self.beta)
        return value + log_prior(weights, self.prior_sigma), grad + log_prior_grad(weights, self.prior_sigma)

    def check_weights(self, weights: object) -> np.ndarray:
        return _check_array("weights", weights, (None, self.dim))


def make_posterior_model(proxy_weights: np.ndarray, train_mdp: GridMDP, beta: float, method: str,
                         prior_sigma: float = 1.0, proxy_samples: "np.ndarray | None" = None, *,
                         proxy_features: "np.ndarray | None" = None,
                         proxy_sample_features: "np.ndarray | None" = None, seed: int = 0,
                         num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES) -> PosteriorModel:
    """Validate the arguments and precompute ``phi~(w~)`` and (Sample-Z) the ``phi_i``.

    Args: as ``log_posterior``.
    Returns:
        The ``PosteriorModel``.
    """
    if not isinstance(train_mdp, GridMDP):
        raise ValueError(f"train_mdp: expected a GridMDP, got {type(train_mdp).__name__}")
    dim = train_mdp.num_features
    # With proxy_features given, the proxy may live in another feature space (latent_classifier:
    # p classifier outputs); its weights are then only recorded, so any length p >= 1 is valid.
    proxy = _check_array("proxy_weights", proxy_weights, (None,) if proxy_features is not None else (dim,))
    beta = _check_real("beta", beta, positive=False)
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    sigma = _check_real("prior_sigma", prior_sigma, positive=True)
    seed = _check_int("seed", seed, 0)
    num_proxy_samples = _check_int("num_proxy_samples", num_proxy_samples, 1)
    if proxy_features is not None:
        phi_proxy = _check_array("proxy_features", proxy_features, (dim,))
    else:
        phi_proxy = feature_expectations(train_mdp, proxy[None, :])[0]
    samples = None if proxy_samples is None else _check_array("proxy_samples", proxy_samples, (None, dim))
    sample_phi = None
    if proxy_sample_features is not None:
        sample_phi = _check_array("proxy_sample_features", proxy_sample_features, (None, dim))
    elif method == "sample_z":
        if samples is None:
            samples = proxy_prior_samples(num_proxy_samples, dim, sigma, seed)
        sample_phi = feature_expectations(train_mdp, samples)
    for array in (phi_proxy, sample_phi):
        if array is not None:
            array.setflags(write=False)
    return PosteriorModel(train_mdp, method, beta, sigma, phi_proxy,
                          sample_phi if method == "sample_z" else None)


def log_posterior(weights: np.ndarray, proxy_weights: np.ndarray, train_mdp: GridMDP, beta: float,
                  method: str, prior_sigma: float = 1.0, proxy_samples: "np.ndarray | None" = None, *,
                  proxy_features: "np.ndarray | None" = None,
                  proxy_sample_features: "np.ndarray | None" = None, seed: int = 0,
                  num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES) -> np.ndarray:
    """Unnormalised IRD log posterior of candidate weights (module docstring, IRD_SPEC 3).

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
                       method: str, prior_sigma: float = 1.0, proxy_samples: "np.ndarray | None" = None, *,
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


# --------------------------------------------------------------------------------------------
# Laplace approximation (initial preconditioner)
# --------------------------------------------------------------------------------------------


def _gradient_and_hessian(model: PosteriorModel, w: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Value, gradient ``(d,)`` and symmetrised forward-difference Hessian ``(d, d)`` at ``w``,
    from one batched call on ``d + 1`` weights."""
    dim = len(w)
    points = w[None, :] + np.concatenate([np.zeros((1, dim)), _HESSIAN_STEP * np.eye(dim)])
    values, grads = model.log_density_and_grad(points)
    hessian = (grads[1:] - grads[0]) / _HESSIAN_STEP
    return float(values[0]), grads[0], 0.5 * (hessian + hessian.T)


def laplace_approximation(model: PosteriorModel, max_iterations: int = 30
                          ) -> tuple[np.ndarray, np.ndarray]:
    """MAP by damped Newton from ``w = 0`` and the covariance ``(-Hessian)^{-1}`` there.

    The negative Hessian's eigenvalues are floored at ``0.5 / sigma^2`` (for MaxEnt-Z they are at
    least ``1 / sigma^2`` anyway: ``log Z`` is convex), so the Newton direction is an ascent
    direction and the covariance is positive definite. Each iteration is two batched calls: the
    Hessian (``d + 1`` weights) and a line search over 8 step lengths at once.

    Returns:
        The mode ``(d,)`` and the covariance ``(d, d)``.
    """
    dim = model.dim
    w = np.zeros(dim)
    floor = 0.5 / model.prior_sigma**2
    steps = 0.5 ** np.arange(8)
    for _ in range(max_iterations):
        value, grad, hessian = _gradient_and_hessian(model, w)
        eigval, eigvec = np.linalg.eigh(-hessian)
        eigval = np.maximum(eigval, floor)
        direction = eigvec @ ((eigvec.T @ grad) / eigval)
        decrement = float(grad @ direction)
        if decrement < 1e-8:
            break
        candidates = w[None, :] + steps[:, None] * direction[None, :]
        values = model.log_density(candidates)
        best = int(np.argmax(values))
        if values[best] <= value:
            break
        w = candidates[best]
    _, _, hessian = _gradient_and_hessian(model, w)
    eigval, eigvec = np.linalg.eigh(-hessian)
    cov = (eigvec / np.maximum(eigval, floor)) @ eigvec.T
    return w, 0.5 * (cov + cov.T)


# --------------------------------------------------------------------------------------------
# Posterior sampling
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Posterior:
    """Posterior samples of the true reward weights and how they were obtained.

    Attributes:
        samples: ``(K, d)`` draws, ``K = num_samples``, pooled draw-major over chains.
        method, beta, prior_sigma, proxy_weights ``(d,)``, seed: the inputs.
        acceptance_rate: mean Metropolis acceptance rate after warm-up.
        r_hat_max: max over coordinates of the rank-normalised split R-hat (bulk and folded),
            over every post-warm-up iteration of every chain (NaN if fewer than 4 iterations).
        ess_min: min over coordinates of the bulk effective sample size of those iterations
            (NaN if fewer than 8).
        num_chains, warmup, thin: the sampler settings; ``kernel``: ``"hmc"``, ``"mala"`` or ``"rwm"``.
        step_size: the frozen step size (in preconditioned units).
        r_hat: ``(d,)`` and ess: ``(d,)`` per coordinate.
        mode: ``(d,)`` the MAP of the Laplace approximation (or NaN if none was computed).
        num_proxy_samples: ``N`` for Sample-Z, 0 for MaxEnt-Z.
        num_evaluations: batched log-density calls of the sampler (warm-up included).
    """

    samples: np.ndarray
    method: str
    beta: float
    prior_sigma: float
    proxy_weights: np.ndarray
    acceptance_rate: float
    r_hat_max: float
    ess_min: float
    num_chains: int
    seed: int
    warmup: int
    thin: int
    kernel: str
    step_size: float
    r_hat: np.ndarray
    ess: np.ndarray
    mode: np.ndarray
    num_proxy_samples: int
    num_evaluations: int

    @property
    def converged(self) -> bool:
        """``r_hat_max <= 1.1`` (False for NaN)."""
        return bool(self.r_hat_max <= R_HAT_CONVERGED)

    @property
    def num_samples(self) -> int:
        return int(self.samples.shape[0])

    @property
    def mean(self) -> np.ndarray:
        """Posterior mean ``(d,)``."""
        return self.samples.mean(axis=0)

    @property
    def cov(self) -> np.ndarray:
        """Posterior covariance ``(d, d)``."""
        return np.atleast_2d(np.cov(self.samples, rowvar=False))


def pool_draws(draws: np.ndarray, num_samples: int) -> np.ndarray:
    """Pool ``(C, n, d)`` chains draw-major (all chains' first draw, then second, ...) and keep
    the first ``num_samples``; ``-> (num_samples, d)``."""
    c, n, d = draws.shape
    if num_samples > c * n:
        raise ValueError(f"num_samples: {num_samples} exceeds the {c * n} draws available")
    return np.ascontiguousarray(draws.transpose(1, 0, 2).reshape(c * n, d)[:num_samples])


def sample_posterior(proxy_weights: np.ndarray, train_mdp: GridMDP, beta: float, method: str,
                     num_samples: int, seed: int, prior_sigma: float = 1.0,
                     proxy_samples: "np.ndarray | None" = None, *,
                     proxy_features: "np.ndarray | None" = None,
                     proxy_sample_features: "np.ndarray | None" = None,
                     num_chains: int = DEFAULT_NUM_CHAINS, warmup: "int | None" = None,
                     thin: "int | None" = None, kernel: str = DEFAULT_KERNEL,
                     num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES, init: str = "laplace",
                     init_scale: float = DEFAULT_INIT_SCALE, max_leapfrog: "int | None" = None,
                     progress: "ProgressFn | None" = None) -> Posterior:
    """Draw ``num_samples`` weights from the IRD posterior with batched MCMC.

    Args:
        proxy_weights, train_mdp, beta, method, prior_sigma, proxy_samples, proxy_features,
            proxy_sample_features, num_proxy_samples: as ``log_posterior``.
        num_samples: draws returned, ``>= 1``.
        seed: ``>= 0``; seeds the default proxy samples (``proxy_prior_samples(N, d, sigma, seed)``)
            and, through an independent stream, the chains. Same seed, same samples.
        num_chains: chains, run as one batch (``>= 2``).
        warmup: adaptation iterations per chain, discarded (``>= 0``; default per method,
            ``DEFAULT_WARMUP``).
        thin: keep every ``thin``-th iteration after warm-up; each chain runs
            ``ceil(num_samples / num_chains) * thin`` iterations after warm-up. Default: the
            smallest thinning giving ``DEFAULT_MIN_ITERATIONS[method]`` iterations per chain.
        kernel: ``"hmc"`` (default), ``"mala"`` or ``"rwm"``.
        num_proxy_samples: ``N`` for Sample-Z when the proxy samples are drawn here.
        init: ``"laplace"`` (chains start at ``mode + init_scale * L z``) or ``"prior"``.
        init_scale: overdispersion of the Laplace start, ``> 0``.
        max_leapfrog: HMC leapfrog cap (default per method, ``DEFAULT_MAX_LEAPFROG``).
        progress: optional ``progress(step, total)`` callback, once per MCMC step.
    Returns:
        The ``Posterior``. Emits a ``RuntimeWarning`` if ``r_hat_max > 1.1``.
    """
    # Cheap checks first, so that a bad request fails before any MDP pass.
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    num_samples = _check_int("num_samples", num_samples, 1)
    num_chains = _check_int("num_chains", num_chains, 2)
    warmup = DEFAULT_WARMUP[method] if warmup is None else _check_int("warmup", warmup, 0)
    per_chain = -(-num_samples // num_chains)
    thin = max(1, -(-DEFAULT_MIN_ITERATIONS[method] // per_chain)) if thin is None else _check_int("thin", thin, 1)
    max_leapfrog = DEFAULT_MAX_LEAPFROG[method] if max_leapfrog is None else \
        _check_int("max_leapfrog", max_leapfrog, 1)
    if init not in ("laplace", "prior"):
        raise ValueError(f"init: expected 'laplace' or 'prior', got {init!r}")
    init_scale = _check_real("init_scale", init_scale, positive=True)
    if kernel not in mcmc.KERNELS:
        raise ValueError(f"kernel: expected one of {mcmc.KERNELS}, got {kernel!r}")
    model = make_posterior_model(proxy_weights, train_mdp, beta, method, prior_sigma, proxy_samples,
                                 proxy_features=proxy_features, proxy_sample_features=proxy_sample_features,
                                 seed=seed, num_proxy_samples=num_proxy_samples)
    proxy = np.array(proxy_weights, dtype=np.float64)
    proxy.setflags(write=False)
    dim = model.dim

    mode, cov = laplace_approximation(model)
    chain_seed, init_seed = (int(s) for s in np.random.SeedSequence([seed, 1]).generate_state(2))
    init_rng = np.random.default_rng(init_seed)
    if init == "laplace":
        initial = mode + init_scale * init_rng.standard_normal((num_chains, dim)) @ np.linalg.cholesky(cov).T
    else:
        initial = model.prior_sigma * init_rng.standard_normal((num_chains, dim))

    def target(weights: np.ndarray) -> tuple[np.ndarray, "np.ndarray | None"]:
        if kernel == "rwm":
            return model.log_density(weights), None
        return model.log_density_and_grad(weights)

    result = mcmc.sample_chains(target, initial, per_chain, kernel=kernel, warmup=warmup, thin=thin,
                                seed=chain_seed, preconditioner="dense",
                                initial_preconditioner=mcmc.Preconditioner(np.linalg.cholesky(cov)),
                                trajectory_length=DEFAULT_TRAJECTORY_LENGTH, max_leapfrog=max_leapfrog,
                                warmup_max_leapfrog=DEFAULT_WARMUP_MAX_LEAPFROG, progress=progress)
    draws = result.draws
    r_hat = np.minimum(result.r_hat, _R_HAT_CAP)
    r_hat_max = float(np.max(r_hat)) if not np.all(np.isnan(r_hat)) else float("nan")
    ess_min = float(np.nanmin(result.ess)) if not np.all(np.isnan(result.ess)) else float("nan")
    posterior = Posterior(
        samples=pool_draws(draws, num_samples), method=method, beta=model.beta, prior_sigma=model.prior_sigma,
        proxy_weights=proxy, acceptance_rate=float(result.acceptance_rate.mean()), r_hat_max=r_hat_max,
        ess_min=ess_min, num_chains=num_chains, seed=seed, warmup=warmup, thin=thin, kernel=kernel,
        step_size=result.step_size, r_hat=r_hat, ess=result.ess, mode=mode,
        num_proxy_samples=0 if model.sample_features is None else len(model.sample_features),
        num_evaluations=result.num_evaluations)
    if not posterior.converged:
        warnings.warn(f"sample_posterior: split R-hat {r_hat_max:.3g} > {R_HAT_CONVERGED} (or not computable): "
                      f"the {num_chains} chains have not converged; increase warmup or thin",
                      RuntimeWarning, stacklevel=2)
    return posterior
