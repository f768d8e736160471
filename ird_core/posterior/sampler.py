"""The IRD posterior sampler: Laplace start, batched HMC, diagnostics (docs/spec.md sections 3 and 7).

``sample_joint_posterior`` draws from the joint posterior of ``ird_core.posterior.evidence``;
``sample_posterior`` is it with one ``ProxyObservation``. The method (Laplace approximation,
overdispersed starts, HMC with an adapted dense metric, split R-hat) is described in
``ird_core.posterior``'s docstring.

Warm start (``initial=`` a previous ``Posterior`` of the same weight space, typically before
one more answered query; evidence lists are appended to): no Laplace step. The previous draws
are importance-weighted by the new choice terms (closed form, no MDP pass); ``num_chains``
distinct draws picked with those weights start the chains, and the weighted covariance is the
initial metric, re-adapted in a short warm-up (``DEFAULT_WARM_WARMUP``, one metric window);
the step size is re-tuned from the sampler's heuristic start (``mcmc.sample_chains`` takes no
initial step). Each chain then runs ``DEFAULT_WARM_MIN_ITERATIONS`` iterations, all of which
enter R-hat. On latent_raw (15x15, T = 30, d = 50, MaxEnt-Z, 1000 draws, seeds 0-2, two
successive answers each) this took 2550-3330 batched evaluations against 4640-5060 for the cold
run, with split R-hat 1.032-1.049 (``scripts/bench_queries.py``); a 30 / 70 split gave up to
1.076, 50 / 90 1.030-1.045 at 10% more cost, and starting from uniformly picked previous draws
with the previous metric (no importance weights) gave R-hat up to 1.19.

Run until converged (``until_converged=RunUntil(...)``, cold or warm): the fixed-length run's
chains are extended in blocks with the frozen kernel and metric (``mcmc.continue_chains``) until
split R-hat and bulk ESS pass on the latest half of the post-warm-up draws, or the iteration cap
(deterministic) or the time budget (a safety stop) ends the run; see ``RunUntil``. Without it the
run is the fixed-length one above, unchanged.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from ird_core import mcmc
from ird_core.checks import check_int, check_real
from ird_core.mdp import GridMDP
from ird_core.posterior.evidence import ChoiceObservation, PosteriorModel, ProxyObservation, make_joint_model
from ird_core.posterior.laplace import laplace_approximation
from ird_core.posterior.likelihoods import DEFAULT_NUM_PROXY_SAMPLES, METHODS, choice_log_likelihood

__all__ = [
    "DEFAULT_NUM_CHAINS",
    "DEFAULT_WARMUP",
    "DEFAULT_WARM_WARMUP",
    "DEFAULT_MIN_ITERATIONS",
    "DEFAULT_WARM_MIN_ITERATIONS",
    "DEFAULT_KERNEL",
    "DEFAULT_MAX_LEAPFROG",
    "DEFAULT_TRAJECTORY_LENGTH",
    "DEFAULT_WARMUP_MAX_LEAPFROG",
    "DEFAULT_INIT_SCALE",
    "R_HAT_CONVERGED",
    "GIVE_UP_R_HAT",
    "laplace_approximation",
    "Posterior",
    "RunUntil",
    "pool_draws",
    "sample_joint_posterior",
    "sample_posterior",
]

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
#: Warm-up of a warm-started run (``initial=``): one metric window and a step-size buffer (the
#: importance-weighted start is already near the target and its metric close to the posterior's).
DEFAULT_WARM_WARMUP: dict[str, int] = {"maxent_z": 30, "sample_z": 40}
#: Post-warm-up iterations per chain of a warm-started run with ``thin=None`` (every one enters
#: R-hat; ``ceil(num_samples / num_chains)`` evenly spaced ones are kept). The chains start in
#: the previous posterior's typical set, so fewer suffice than cold (``DEFAULT_MIN_ITERATIONS``).
DEFAULT_WARM_MIN_ITERATIONS: dict[str, int] = {"maxent_z": 90, "sample_z": 90}
#: Chains start at ``mode + DEFAULT_INIT_SCALE * L z`` (Laplace covariance ``L L^T``).
DEFAULT_INIT_SCALE: float = 2.0
#: A run with a larger maximum split R-hat is reported as not converged.
R_HAT_CONVERGED: float = 1.1
#: R-hat values above this are stored as this (``inf`` is not representable in ROS messages).
_R_HAT_CAP: float = 1e6

ProgressFn = Callable[[int, int], None]


@dataclass(frozen=True)
class RunUntil:
    """Run the chains until the diagnostics pass (``sample_joint_posterior(until_converged=...)``).

    After the usual warm-up and post-warm-up run (``n0`` iterations per chain, the fixed-length
    run's), the SAME chains are extended with the frozen kernel and metric
    (``mcmc.continue_chains``) in blocks of ``check_every`` iterations (default ``max(n0, 50)``)
    until, on the diagnostic window, the rank-normalised split R-hat is ``<= r_hat`` and the bulk
    ESS is ``>= required_ess(num_samples)``, or a bound stops it; then ``ceil(num_samples / C)``
    draws per chain are kept from the window, evenly spaced.

    The window is the latest ``max(n0, ceil(n / 2))`` of the ``n`` post-warm-up iterations. Its
    first check is exactly the fixed-length run's diagnostics (a run that is converged at ``n0``
    costs nothing more and returns the fixed-length run's samples bit for bit); later checks drop
    the oldest draws, where a transient left by a short warm-up lives, instead of diluting it
    (Gelman and Rubin's discard-the-first-half rule), and the samples come from the draws that
    were diagnosed.

    Bounds: ``max_iterations`` (post-warm-up iterations per chain, never below ``n0``) is the
    deterministic one: the same seed gives the same samples on any machine. ``time_budget_s``
    (wall seconds of the whole call, checked between blocks, so it may be exceeded by one
    block) is only a safety stop and makes the result machine-dependent when it is hit. Either
    way the posterior says so (``converged`` False, ``stop_reason``).

    Attributes:
        r_hat: largest acceptable split R-hat, ``>= 1``.
        min_ess: floor of the required bulk ESS (400: Vehtari et al. 2021 ask for 100 per chain
            with four chains before trusting R-hat and ESS estimates at all).
        ess_per_sample: the required ESS is also at least this times ``num_samples`` (0.5: the
            returned draws are worth at least half their number).
        max_iterations: cap on post-warm-up iterations per chain.
        time_budget_s: wall-clock safety stop in seconds, or None.
        give_up_after: 0 (never), or stop at the first check after at least this many
            post-warm-up iterations whose split R-hat is still above ``GIVE_UP_R_HAT``
            (``stop_reason`` "futile"): a run that far off spends its remaining budget for
            nothing. Deterministic, like ``max_iterations``.
        check_every: 0 (blocks of ``max(n0, 50)``), or the iterations per chain between checks
            after the first. A run stops on average half a block after it first passes, so
            small blocks save that; each check costs a diagnostic (milliseconds in 50-d). The
            experiments use 16 (``experiments.CHECK_EVERY``: 7-13% fewer gradient evaluations
            than blocks of 64 on the d = 50 Sample-Z posteriors).
    """

    r_hat: float = 1.05
    min_ess: float = 400.0
    ess_per_sample: float = 0.5
    max_iterations: int = 2000
    time_budget_s: "float | None" = None
    give_up_after: int = 0
    check_every: int = 0

    def __post_init__(self) -> None:
        if not check_real("until_converged.r_hat", self.r_hat, positive=True) >= 1.0:
            raise ValueError(f"until_converged.r_hat: expected a value >= 1, got {self.r_hat!r}")
        check_real("until_converged.min_ess", self.min_ess, positive=False)
        check_real("until_converged.ess_per_sample", self.ess_per_sample, positive=False)
        check_int("until_converged.max_iterations", self.max_iterations, 1)
        check_int("until_converged.give_up_after", self.give_up_after, 0)
        check_int("until_converged.check_every", self.check_every, 0)
        if self.time_budget_s is not None:
            check_real("until_converged.time_budget_s", self.time_budget_s, positive=True)

    def required_ess(self, num_samples: int) -> float:
        """``max(min_ess, ess_per_sample * num_samples)``."""
        return max(float(self.min_ess), float(self.ess_per_sample) * num_samples)


# --------------------------------------------------------------------------------------------
# Posterior sampling
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class Posterior:
    """Posterior samples of the true reward weights and how they were obtained.

    Attributes:
        samples: ``(K, d)`` draws, ``K = num_samples``, pooled draw-major over chains.
        method, beta, prior_sigma, seed: the inputs; proxy_weights: the first proxy
            observation's ``w~`` (``(0,)`` when there is none).
        acceptance_rate: mean Metropolis acceptance rate after warm-up.
        r_hat_max: max over coordinates of the rank-normalised split R-hat (bulk and folded),
            over every post-warm-up iteration of every chain (NaN if fewer than 4 iterations).
        ess_min: min over coordinates of the bulk effective sample size of those iterations
            (NaN if fewer than 8).
        num_chains, warmup, thin: the sampler settings; ``kernel``: one of ``mcmc.KERNELS``.
        step_size: the frozen step size (in preconditioned units; 1.0 and unused by the kernels
            without a step: elliptical, independence).
        r_hat: ``(d,)`` and ess: ``(d,)`` per coordinate.
        mode: ``(d,)`` the MAP of the Laplace approximation (NaN if none was computed: warm start,
            ``init="prior"`` still computes it for the metric).
        num_proxy_samples: ``N`` for Sample-Z, 0 for MaxEnt-Z.
        num_evaluations: batched log-density calls of the sampler (warm-up included).
        num_proxies, num_choices: the proxy and choice observations conditioned on.
        metric: ``(d, d)`` lower Cholesky factor of the frozen HMC metric (warm starts reuse it).
        warm_started: True if the run started from a previous posterior (``initial=``).
        run_until: the ``RunUntil`` criteria of the run, or None (fixed length).
        iterations: post-warm-up iterations per chain that were run (0: not recorded).
        stop_reason: with ``run_until``: ``"converged"``, ``"max_iterations"``, ``"futile"``
            (``RunUntil.give_up_after``) or ``"time_budget"``; else ``""``.
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
    num_proxies: int = 1
    num_choices: int = 0
    metric: "np.ndarray | None" = None
    warm_started: bool = False
    run_until: "RunUntil | None" = None
    iterations: int = 0
    stop_reason: str = ""

    @property
    def converged(self) -> bool:
        """``r_hat_max <= 1.1`` (False for NaN); with ``run_until``, its criteria:
        ``r_hat_max <= run_until.r_hat`` and ``ess_min >= run_until.required_ess(num_samples)``."""
        if self.run_until is None:
            return bool(self.r_hat_max <= R_HAT_CONVERGED)
        return bool(self.r_hat_max <= self.run_until.r_hat
                    and self.ess_min >= self.run_until.required_ess(self.num_samples))

    def diagnosis(self) -> str:
        """One line on convergence, e.g. ``r_hat_max 1.032, ess_min 512`` then ``(NOT converged)``
        or, with ``run_until``, ``converged after 240 iterations per chain`` or ``not converged:
        iteration cap 2000 reached, R-hat 1.07 > 1.05, ESS 300 < 400``."""
        head = f"r_hat_max {self.r_hat_max:.3f}, ess_min {self.ess_min:.0f}"
        rule = self.run_until
        if rule is None:
            return head + ("" if self.converged else " (NOT converged)")
        if self.converged:
            return f"{head}, converged after {self.iterations} iterations per chain"
        bound = (f"time budget {rule.time_budget_s:g} s spent" if self.stop_reason == "time_budget" else
                 f"iteration cap {rule.max_iterations} reached" if self.stop_reason == "max_iterations" else
                 f"given up (R-hat above {GIVE_UP_R_HAT:g})" if self.stop_reason == "futile" else "stopped")
        need = rule.required_ess(self.num_samples)
        return (f"{head}, not converged: {bound} after {self.iterations} iterations per chain, "
                f"R-hat {self.r_hat_max:.3f} (target <= {rule.r_hat:g}), ESS {self.ess_min:.0f} "
                f"(target >= {need:.0f})")

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



def _warn_unconverged(posterior: Posterior, caller: str) -> None:
    if not posterior.converged and posterior.run_until is not None:
        warnings.warn(f"{caller}: {posterior.diagnosis()}", RuntimeWarning, stacklevel=3)
    elif not posterior.converged:
        warnings.warn(f"{caller}: split R-hat {posterior.r_hat_max:.3g} > {R_HAT_CONVERGED} (or not computable): "
                      f"the {posterior.num_chains} chains have not converged; increase warmup or thin",
                      RuntimeWarning, stacklevel=3)


def _warm_start(initial: object, model: PosteriorModel, num_chains: int, rng: np.random.Generator
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Starting points ``(C, d)``, metric factor ``(d, d)`` and centre ``(d,)`` (the weighted
    mean, for the elliptical kernel) from a previous ``Posterior``.

    The previous draws are importance-weighted by the choice terms they were not conditioned on
    (the model's choices after the first ``initial.num_choices``: evidence is appended), which
    costs no MDP pass; ``C`` distinct draws are picked with those weights, and their weighted
    covariance is the initial metric when the weights' effective sample size exceeds ``2 d``
    (else the previous metric). Only efficiency depends on this: the chains are valid from any
    start, and R-hat checks them.
    """
    dim = model.dim
    if not isinstance(initial, Posterior):
        raise ValueError(f"initial: expected a Posterior, got {type(initial).__name__}")
    samples = initial.samples
    if samples.ndim != 2 or samples.shape[1] != dim or not np.all(np.isfinite(samples)):
        raise ValueError(f"initial: expected finite samples of shape (K, {dim}), got {samples.shape}")
    if len(samples) < num_chains:
        raise ValueError(f"initial: needs at least num_chains = {num_chains} samples, got {len(samples)}")
    log_w = np.zeros(len(samples))
    for choice in model.choices[initial.num_choices:]:
        log_w += choice_log_likelihood(samples, choice.option_features, choice.chosen, choice.beta)
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    starts = samples[rng.choice(len(samples), num_chains, replace=False, p=w)]
    centre = w @ samples
    if 1.0 / np.sum(w**2) > 2 * dim:
        centred = samples - centre
        cov = (centred * w[:, None]).T @ centred
        return starts, np.linalg.cholesky(cov + 1e-9 * np.trace(cov) / dim * np.eye(dim)), centre
    if initial.metric is not None and initial.metric.shape == (dim, dim):
        return starts, initial.metric, centre
    cov = np.atleast_2d(np.cov(samples, rowvar=False))
    return starts, np.linalg.cholesky(cov + 1e-9 * np.trace(cov) / dim * np.eye(dim)), centre


def sample_joint_posterior(observations: "Sequence[ProxyObservation | ChoiceObservation]", beta: float,
                           method: str, num_samples: int, seed: int, prior_sigma: float = 1.0,
                           proxy_samples: "np.ndarray | None" = None, *,
                           num_chains: int = DEFAULT_NUM_CHAINS, warmup: "int | None" = None,
                           thin: "int | None" = None, kernel: str = DEFAULT_KERNEL,
                           num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES, init: str = "laplace",
                           init_scale: float = DEFAULT_INIT_SCALE, max_leapfrog: "int | None" = None,
                           trajectory_length: "float | None" = None, warmup_max_leapfrog: "int | None" = None,
                           initial: "Posterior | None" = None,
                           until_converged: "RunUntil | None" = None,
                           progress: "ProgressFn | None" = None) -> Posterior:
    """Draw ``num_samples`` weights from the joint IRD posterior with batched MCMC (docs/spec.md section 7).

    Args:
        observations: ``ProxyObservation`` s and ``ChoiceObservation`` s (``ird_core.posterior.evidence``),
            at least one; all in the same weight space ``R^d``.
        beta: the proxies' rationality, finite ``>= 0`` (each choice carries its own).
        method: ``"maxent_z"`` or ``"sample_z"``.
        num_samples: draws returned, ``>= 1``.
        seed: ``>= 0``; seeds the default proxy samples (``proxy_prior_samples(N, d, sigma, seed)``,
            shared by every training MDP) and, through an independent stream, the chains.
            Same seed, same samples.
        prior_sigma: prior standard deviation, ``> 0``.
        proxy_samples: ``(N, d)`` Sample-Z proxy weights, default drawn as above.
        num_chains: chains, run as one batch (``>= 2``).
        warmup: adaptation iterations per chain, discarded (``>= 0``; default per method,
            ``DEFAULT_WARMUP``, or ``DEFAULT_WARM_WARMUP`` with ``initial``).
        thin: keep every ``thin``-th iteration after warm-up; each chain runs
            ``ceil(num_samples / num_chains) * thin`` iterations after warm-up. Default: the
            smallest thinning giving ``DEFAULT_MIN_ITERATIONS[method]`` iterations per chain;
            with ``initial``, ``DEFAULT_WARM_MIN_ITERATIONS[method]`` iterations of which
            ``ceil(num_samples / num_chains)`` evenly spaced ones are kept (``thin`` 1 recorded).
        kernel: ``"hmc"`` (default), ``"mala"``, ``"rwm"``, or a gradient-free kernel around the
            adapted Gaussian: ``"elliptical"`` (slice moves), ``"independence"`` (Student-t
            proposals) or ``"independence_elliptical"`` (both); see ``ird_core.mcmc.kernels``.
        num_proxy_samples: ``N`` for Sample-Z when the proxy samples are drawn here.
        init: ``"laplace"`` (chains start at ``mode + init_scale * L z``) or ``"prior"``;
            ignored with ``initial``.
        init_scale: overdispersion of the Laplace start, ``> 0``.
        max_leapfrog: HMC leapfrog cap (default per method, ``DEFAULT_MAX_LEAPFROG``).
        trajectory_length: HMC integration time in preconditioned units, ``> 0`` (default
            ``DEFAULT_TRAJECTORY_LENGTH``).
        warmup_max_leapfrog: leapfrog cap before the warm-up's final buffer, ``>= 1`` (default
            ``DEFAULT_WARMUP_MAX_LEAPFROG``; short trajectories are cheap while the chains
            converge, but on a posterior with steep walls they explore too little to learn the
            metric: set it to ``max_leapfrog`` there).
        initial: a previous ``Posterior`` in the same weight space to warm start from (module
            docstring): no Laplace step, chains start at its draws, its metric is re-adapted.
        until_converged: a ``RunUntil``: extend the chains until R-hat and ESS pass or a bound
            stops them (see ``RunUntil``); None (default): the fixed-length run above.
        progress: optional ``progress(step, total)`` callback, once per MCMC step.
    Returns:
        The ``Posterior``. Emits a ``RuntimeWarning`` if it is not ``converged``.
    """
    posterior = _sample(observations, beta, method, num_samples, seed, prior_sigma, proxy_samples,
                        num_chains=num_chains, warmup=warmup, thin=thin, kernel=kernel,
                        num_proxy_samples=num_proxy_samples, init=init, init_scale=init_scale,
                        max_leapfrog=max_leapfrog, trajectory_length=trajectory_length,
                        warmup_max_leapfrog=warmup_max_leapfrog, initial=initial,
                        until_converged=until_converged, progress=progress)
    _warn_unconverged(posterior, "sample_joint_posterior")
    return posterior


def _sample(observations: "Sequence[ProxyObservation | ChoiceObservation]", beta: float, method: str,
            num_samples: int, seed: int, prior_sigma: float = 1.0, proxy_samples: "np.ndarray | None" = None, *,
            num_chains: int = DEFAULT_NUM_CHAINS, warmup: "int | None" = None, thin: "int | None" = None,
            kernel: str = DEFAULT_KERNEL, num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES,
            init: str = "laplace", init_scale: float = DEFAULT_INIT_SCALE, max_leapfrog: "int | None" = None,
            trajectory_length: "float | None" = None, warmup_max_leapfrog: "int | None" = None,
            initial: "Posterior | None" = None, until_converged: "RunUntil | None" = None,
            progress: "ProgressFn | None" = None) -> Posterior:
    """``sample_joint_posterior`` without the convergence warning (its callers emit it)."""
    started = time.monotonic()
    if until_converged is not None and not isinstance(until_converged, RunUntil):
        raise ValueError(f"until_converged: expected a RunUntil or None, got {type(until_converged).__name__}")
    # Cheap checks first, so that a bad request fails before any MDP pass.
    if not isinstance(method, str) or method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    num_samples = check_int("num_samples", num_samples, 1)
    num_chains = check_int("num_chains", num_chains, 2)
    default_warmup = (DEFAULT_WARMUP if initial is None else DEFAULT_WARM_WARMUP)[method]
    warmup = default_warmup if warmup is None else check_int("warmup", warmup, 0)
    per_chain = -(-num_samples // num_chains)
    iterations = per_chain  # retained draws per chain
    if thin is not None:
        thin = check_int("thin", thin, 1)
    elif initial is None:
        thin = max(1, -(-DEFAULT_MIN_ITERATIONS[method] // per_chain))
    else:  # every iteration retained, then per_chain evenly spaced ones kept (finer than integer thinning)
        thin, iterations = 1, max(per_chain, DEFAULT_WARM_MIN_ITERATIONS[method])
    evenly = initial is not None and thin == 1 and iterations > per_chain
    max_leapfrog = DEFAULT_MAX_LEAPFROG[method] if max_leapfrog is None else \
        check_int("max_leapfrog", max_leapfrog, 1)
    trajectory_length = DEFAULT_TRAJECTORY_LENGTH if trajectory_length is None else \
        check_real("trajectory_length", trajectory_length, positive=True)
    warmup_max_leapfrog = DEFAULT_WARMUP_MAX_LEAPFROG if warmup_max_leapfrog is None else \
        check_int("warmup_max_leapfrog", warmup_max_leapfrog, 1)
    if init not in ("laplace", "prior"):
        raise ValueError(f"init: expected 'laplace' or 'prior', got {init!r}")
    init_scale = check_real("init_scale", init_scale, positive=True)
    if kernel not in mcmc.KERNELS:
        raise ValueError(f"kernel: expected one of {mcmc.KERNELS}, got {kernel!r}")
    model = make_joint_model(observations, beta, method, prior_sigma, proxy_samples, seed=seed,
                             num_proxy_samples=num_proxy_samples)
    dim = model.dim
    proxies = [o for o in observations if isinstance(o, ProxyObservation)] \
        if not isinstance(observations, (ProxyObservation, ChoiceObservation)) else [observations]
    proxy = np.array(proxies[0].proxy_weights if proxies else np.zeros(0), dtype=np.float64)
    proxy.setflags(write=False)

    chain_seed, init_seed = (int(s) for s in np.random.SeedSequence([seed, 1]).generate_state(2))
    init_rng = np.random.default_rng(init_seed)
    if initial is not None:
        starts, metric, centre = _warm_start(initial, model, num_chains, init_rng)
        mode = np.full(dim, np.nan)
    else:
        mode, cov = laplace_approximation(model)
        metric, centre = np.linalg.cholesky(cov), mode
        if init == "laplace":
            starts = mode + init_scale * init_rng.standard_normal((num_chains, dim)) @ metric.T
        else:
            starts = model.prior_sigma * init_rng.standard_normal((num_chains, dim))

    def target(weights: np.ndarray) -> tuple[np.ndarray, "np.ndarray | None"]:
        if not mcmc.KERNEL_TABLE[kernel].needs_gradient:
            return model.log_density(weights), None
        return model.log_density_and_grad(weights)

    chains = dict(kernel=kernel, warmup=warmup, seed=chain_seed, preconditioner="dense",
                  initial_preconditioner=mcmc.Preconditioner(metric, mean=centre),
                  trajectory_length=trajectory_length, max_leapfrog=max_leapfrog,
                  warmup_max_leapfrog=warmup_max_leapfrog, progress=progress)
    if until_converged is None:
        result = mcmc.sample_chains(target, starts, iterations, thin=thin, **chains)
        kept = np.round(np.linspace(0, iterations - 1, per_chain)).astype(np.int64)
        run = _Run(result.draws[:, kept], result.r_hat, result.ess, float(result.acceptance_rate.mean()),
                   result, result.num_evaluations, thin, iterations * thin, "")
    else:
        run = _run_until(target, starts, iterations * thin, per_chain, evenly, until_converged,
                         num_samples, started, chains)
    r_hat = np.minimum(run.r_hat, _R_HAT_CAP)
    r_hat_max = float(np.max(r_hat)) if not np.all(np.isnan(r_hat)) else float("nan")
    ess_min = float(np.nanmin(run.ess)) if not np.all(np.isnan(run.ess)) else float("nan")
    num_proxy = next((len(t.sample_features) for t in model.proxy_terms if t.sample_features is not None), 0)
    final_metric = np.array(run.last.preconditioner.chol, dtype=np.float64)
    final_metric.setflags(write=False)
    posterior = Posterior(
        samples=pool_draws(run.kept, num_samples), method=method, beta=model.beta,
        prior_sigma=model.prior_sigma, proxy_weights=proxy, acceptance_rate=run.acceptance_rate,
        r_hat_max=r_hat_max, ess_min=ess_min, num_chains=num_chains, seed=seed, warmup=warmup, thin=run.thin,
        kernel=kernel, step_size=run.last.step_size, r_hat=r_hat, ess=run.ess, mode=mode,
        num_proxy_samples=num_proxy, num_evaluations=run.num_evaluations,
        num_proxies=len(model.proxy_terms), num_choices=len(model.choices), metric=final_metric,
        warm_started=initial is not None, run_until=until_converged, iterations=run.iterations,
        stop_reason=run.stop_reason)
    return posterior


class _Run(NamedTuple):
    """The post-warm-up outcome ``_sample`` turns into a ``Posterior``: ``kept`` ``(C, k, d)``
    draws, diagnostics ``(d,)``, mean acceptance, the last ``MCMCResult`` (frozen step and
    metric), batched evaluations, thinning, post-warm-up iterations per chain, stop reason."""

    kept: np.ndarray
    r_hat: np.ndarray
    ess: np.ndarray
    acceptance_rate: float
    last: mcmc.MCMCResult
    num_evaluations: int
    thin: int
    iterations: int
    stop_reason: str


#: ``RunUntil.give_up_after``'s threshold. Measured on Sample-Z at beta 50 in d = 50 (4 HMC chains,
#: checks at 64 iterations, then every 50 up to 300): latent_classifier runs, which converge by
#: 300, never showed a window R-hat above 1.16 at any check, nor above 1.12 at the first (10
#: runs); latent_raw runs, which never converge, never one below 1.58 (6 runs).
GIVE_UP_R_HAT: float = 1.4

#: Smallest block by which ``RunUntil`` extends the chains unless its ``check_every`` says
#: otherwise (diagnostics cost little, but a block of a few iterations would re-test nearly the
#: same draws).
_MIN_BLOCK: int = 50


def _run_until(target: mcmc.LogDensityFn, starts: np.ndarray, first: int, per_chain: int, evenly: bool,
               rule: RunUntil, num_samples: int, started: float, chains: dict) -> _Run:
    """Run ``first`` post-warm-up iterations, then extend the same chains until ``rule`` passes
    on the window or a bound stops them (``RunUntil``); keep ``per_chain`` draws of the window.

    ``evenly`` picks the kept draws as the warm start does (``linspace`` over the window), else
    as integer thinning ending at the last iteration, so the first check reproduces the
    fixed-length run's draws exactly.
    """
    progress = chains.pop("progress")
    result = mcmc.sample_chains(target, starts, first, thin=1, progress=progress, **chains)
    blocks, accepted, evaluations = [result.draws], result.acceptance_rate * first, result.num_evaluations
    n, last, need = first, result, rule.required_ess(num_samples)
    cap, block = max(rule.max_iterations, first), rule.check_every or max(first, _MIN_BLOCK)
    while True:
        states = np.concatenate(blocks, axis=1) if len(blocks) > 1 else blocks[0]
        window = states[:, n - max(first, -(-n // 2)):]
        w = window.shape[1]
        r_hat = mcmc.rank_normalized_r_hat(window) if w >= 4 else np.full(states.shape[2], np.nan)
        ess = mcmc.bulk_effective_sample_size(window) if w >= 8 else np.full(states.shape[2], np.nan)
        if np.max(r_hat) <= rule.r_hat and np.nanmin(ess, initial=np.inf) >= need and not np.any(np.isnan(ess)):
            reason = "converged"
        elif rule.give_up_after and n >= rule.give_up_after and np.max(r_hat) > GIVE_UP_R_HAT:
            reason = "futile"
        elif n >= cap:
            reason = "max_iterations"
        elif rule.time_budget_s is not None and time.monotonic() - started >= rule.time_budget_s:
            reason = "time_budget"
        else:
            step = min(block, cap - n)
            done = chains["warmup"] + n
            report = None if progress is None else (lambda i, _t, done=done, step=step: progress(done + i, done + step))
            last = mcmc.continue_chains(target, last.continuation, step, progress=report)
            blocks = [states, last.draws]
            accepted, evaluations, n = accepted + last.acceptance_rate * step, evaluations + last.num_evaluations, n + step
            continue
        break
    if evenly:
        kept, thin = np.round(np.linspace(0, w - 1, per_chain)).astype(np.int64), 1
    else:
        thin = w // per_chain
        kept = w - 1 - thin * np.arange(per_chain - 1, -1, -1)
    acceptance = float(result.acceptance_rate.mean()) if n == first else float((accepted / n).mean())
    return _Run(window[:, kept], r_hat, ess, acceptance, last, evaluations, thin, n, reason)


def sample_posterior(proxy_weights: np.ndarray, train_mdp: GridMDP, beta: float, method: str,
                     num_samples: int, seed: int, prior_sigma: float = 1.0,
                     proxy_samples: "np.ndarray | None" = None, *,
                     proxy_features: "np.ndarray | None" = None,
                     proxy_sample_features: "np.ndarray | None" = None,
                     **sampler_options) -> Posterior:
    """Draw ``num_samples`` weights from the single-proxy IRD posterior (docs/spec.md section 3):
    ``sample_joint_posterior([ProxyObservation(proxy_weights, train_mdp, proxy_features,
    proxy_sample_features)], beta, method, num_samples, seed, prior_sigma, proxy_samples,
    **sampler_options)``.

    Args:
        proxy_weights, train_mdp, proxy_features, proxy_sample_features: the
            ``ProxyObservation`` (``ird_core.posterior.evidence``); the rest as ``sample_joint_posterior``
            (``num_chains``, ``warmup``, ``thin``, ``kernel``, ``num_proxy_samples``, ``init``,
            ``init_scale``, ``max_leapfrog``, ``trajectory_length``, ``warmup_max_leapfrog``,
            ``initial``, ``until_converged``, ``progress``).
    Returns:
        The ``Posterior``. Emits a ``RuntimeWarning`` if it is not ``converged``.
    """
    observation = ProxyObservation(proxy_weights, train_mdp, proxy_features, proxy_sample_features)
    posterior = _sample([observation], beta, method, num_samples, seed, prior_sigma, proxy_samples,
                        **sampler_options)
    _warn_unconverged(posterior, "sample_posterior")
    return posterior
