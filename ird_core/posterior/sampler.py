"""The IRD posterior sampler: Laplace start, batched HMC, diagnostics (docs/spec.md sections 3 and 7).

``sample_joint_posterior`` draws from the joint posterior of ``ird_core.posterior.evidence``;
``sample_posterior`` is it with one ``ProxyObservation``. The method (Laplace approximation,
overdispersed starts, HMC with an adapted dense metric, split R-hat) is described in
``ird_core.posterior``'s docstring.

Warm start (``initial=`` a previous ``Posterior`` of the same weight space, typically before
one more answered query; evidence lists are appended to): no Laplace step
(:mod:`ird_core.posterior.warm_start`). Each chain then runs ``DEFAULT_WARM_MIN_ITERATIONS``
iterations, all of which enter R-hat.

Run until converged (``until_converged=RunUntil(...)``, cold or warm): the fixed-length run's
chains are extended in blocks (:mod:`ird_core.posterior.run_until`). Without it the run is the
fixed-length one above, unchanged.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from ird_core import mcmc
from ird_core.checks import check_int, check_real
from ird_core.mdp import GridMDP
from ird_core.posterior.evidence import ChoiceObservation, PosteriorModel, ProxyObservation, make_joint_model
from ird_core.posterior.observation_model import DEFAULT_OBSERVATION_MODEL, ObservationModel
from ird_core.posterior.laplace import laplace_approximation
from ird_core.posterior.likelihoods import DEFAULT_NUM_PROXY_SAMPLES
from ird_core.posterior.result import R_HAT_CAP, R_HAT_CONVERGED, Posterior, pool_draws
from ird_core.posterior.run_until import RunUntil, SamplerRun, run_until
from ird_core.posterior.warm_start import warm_start
from ird_core.vocabulary import ZMethod, parse

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
    "sample_joint_posterior",
    "sample_posterior",
]

DEFAULT_NUM_CHAINS: int = 16
#: Per-method sampler defaults (see the module docstring): Sample-Z's likelihood has much
#: stiffer creases (a near-hard max over the proxies' feature counts), so it needs a longer
#: warm-up to learn the metric, longer chains and more leapfrog steps per trajectory.
DEFAULT_WARMUP: dict[str, int] = {ZMethod.MAXENT_Z: 100, ZMethod.SAMPLE_Z: 150}
#: With ``thin=None`` each chain runs at least this many iterations after warm-up.
DEFAULT_MIN_ITERATIONS: dict[str, int] = {ZMethod.MAXENT_Z: 120, ZMethod.SAMPLE_Z: 100}
DEFAULT_MAX_LEAPFROG: dict[str, int] = {"maxent_z": 64, "sample_z": 64}
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


def _warn_unconverged(posterior: Posterior, caller: str) -> None:
    if not posterior.converged and posterior.run_until is not None:
        warnings.warn(f"{caller}: {posterior.diagnosis()}", RuntimeWarning, stacklevel=3)
    elif not posterior.converged:
        warnings.warn(f"{caller}: split R-hat {posterior.r_hat_max:.3g} > {R_HAT_CONVERGED} (or not computable): "
                      f"the {posterior.num_chains} chains have not converged; increase warmup or thin",
                      RuntimeWarning, stacklevel=3)


def sample_joint_posterior(observations: "Sequence[ProxyObservation | ChoiceObservation]", beta: float,
                           method: str, num_samples: int, seed: int, prior_sigma: "float | None" = None,
                           proxy_samples: "np.ndarray | None" = None, *,
                           num_chains: int = DEFAULT_NUM_CHAINS, warmup: "int | None" = None,
                           thin: "int | None" = None, kernel: str = DEFAULT_KERNEL,
                           num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES, init: str = "laplace",
                           init_scale: float = DEFAULT_INIT_SCALE, max_leapfrog: "int | None" = None,
                           trajectory_length: "float | None" = None, warmup_max_leapfrog: "int | None" = None,
                           initial: "Posterior | None" = None,
                           until_converged: "RunUntil | None" = None,
                           progress: "mcmc.ProgressFn | None" = None,
                           observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL) -> Posterior:
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
        prior_sigma: prior standard deviation, ``> 0``; ``None`` (default): the calibrated
            ``1 / (temperature * feature scale)`` of ``observation_model`` and the training maps
            (:mod:`ird_core.posterior.calibration`).
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
        observation_model: the designer-behaviour assumptions (``ObservationModel``: optimal-path
            or MaxEnt counts, the designer's temperature, Sample-Z's own term); observations
            carrying their own counts must have been built with the same model.
    Returns:
        The ``Posterior``. Emits a ``RuntimeWarning`` if it is not ``converged``.
    """
    posterior = _sample(observations, beta, method, num_samples, seed, prior_sigma, proxy_samples,
                        num_chains=num_chains, warmup=warmup, thin=thin, kernel=kernel,
                        num_proxy_samples=num_proxy_samples, init=init, init_scale=init_scale,
                        max_leapfrog=max_leapfrog, trajectory_length=trajectory_length,
                        warmup_max_leapfrog=warmup_max_leapfrog, initial=initial,
                        until_converged=until_converged, progress=progress,
                        observation_model=observation_model)
    _warn_unconverged(posterior, "sample_joint_posterior")
    return posterior


class _Schedule(NamedTuple):
    """The checked run length and HMC settings of one call.

    ``iterations`` retained iterations per chain (``per_chain`` of them kept, evenly spaced when
    ``evenly``), every ``thin``-th of ``iterations * thin`` post-warm-up iterations."""

    warmup: int
    thin: int
    iterations: int
    per_chain: int
    evenly: bool
    max_leapfrog: int
    trajectory_length: float
    warmup_max_leapfrog: int
    init_scale: float


def _schedule(method: str, num_samples: int, num_chains: int, warmup: "int | None", thin: "int | None",
              warm: bool, max_leapfrog: "int | None", trajectory_length: "float | None",
              warmup_max_leapfrog: "int | None", init: str, init_scale: float, kernel: str) -> _Schedule:
    """Validate the sampler's settings (cheap checks, before any MDP pass) and fill in the
    per-method defaults (``warm``: a warm start's)."""
    parse(ZMethod, method, "method")
    num_samples = check_int("num_samples", num_samples, 1)
    num_chains = check_int("num_chains", num_chains, 2)
    default_warmup = (DEFAULT_WARM_WARMUP if warm else DEFAULT_WARMUP)[method]
    warmup = default_warmup if warmup is None else check_int("warmup", warmup, 0)
    per_chain = -(-num_samples // num_chains)
    iterations = per_chain  # retained draws per chain
    if thin is not None:
        thin = check_int("thin", thin, 1)
    elif not warm:
        thin = max(1, -(-DEFAULT_MIN_ITERATIONS[method] // per_chain))
    else:  # every iteration retained, then per_chain evenly spaced ones kept (finer than integer thinning)
        thin, iterations = 1, max(per_chain, DEFAULT_WARM_MIN_ITERATIONS[method])
    evenly = warm and thin == 1 and iterations > per_chain
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
    return _Schedule(warmup, thin, iterations, per_chain, evenly, max_leapfrog, trajectory_length,
                     warmup_max_leapfrog, init_scale)


def _first_proxy_weights(observations: object) -> np.ndarray:
    """The first proxy observation's ``w~`` (``(0,)`` when there is none), read-only."""
    proxies = [o for o in observations if isinstance(o, ProxyObservation)] \
        if not isinstance(observations, (ProxyObservation, ChoiceObservation)) else [observations]
    proxy = np.array(proxies[0].proxy_weights if proxies else np.zeros(0), dtype=np.float64)
    proxy.setflags(write=False)
    return proxy


def _chain_starts(model: PosteriorModel, initial: "Posterior | None", init: str, init_scale: float,
                  num_chains: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Starting points ``(C, d)``, metric factor ``(d, d)``, its centre ``(d,)`` and the Laplace
    mode ``(d,)`` (NaN for a warm start): ``mode + init_scale * L z`` (``init="laplace"``), prior
    draws (``"prior"``) or the warm start's."""
    if initial is not None:
        starts, metric, centre = warm_start(initial, model, num_chains, rng)
        return starts, metric, centre, np.full(model.dim, np.nan)
    mode, cov = laplace_approximation(model)
    metric = np.linalg.cholesky(cov)
    if init == "laplace":
        starts = mode + init_scale * rng.standard_normal((num_chains, model.dim)) @ metric.T
    else:
        starts = model.prior_sigma * rng.standard_normal((num_chains, model.dim))
    return starts, metric, mode, mode


def _target(model: PosteriorModel, kernel: str) -> mcmc.LogDensityFn:
    """The batched log posterior, with its gradient when the kernel needs one."""
    def target(weights: np.ndarray) -> tuple[np.ndarray, "np.ndarray | None"]:
        if not mcmc.KERNEL_TABLE[kernel].needs_gradient:
            return model.log_density(weights), None
        return model.log_density_and_grad(weights)
    return target


def _sample(observations: "Sequence[ProxyObservation | ChoiceObservation]", beta: float, method: str,
            num_samples: int, seed: int, prior_sigma: "float | None" = None, proxy_samples: "np.ndarray | None" = None, *,
            num_chains: int = DEFAULT_NUM_CHAINS, warmup: "int | None" = None, thin: "int | None" = None,
            kernel: str = DEFAULT_KERNEL, num_proxy_samples: int = DEFAULT_NUM_PROXY_SAMPLES,
            init: str = "laplace", init_scale: float = DEFAULT_INIT_SCALE, max_leapfrog: "int | None" = None,
            trajectory_length: "float | None" = None, warmup_max_leapfrog: "int | None" = None,
            initial: "Posterior | None" = None, until_converged: "RunUntil | None" = None,
            progress: "mcmc.ProgressFn | None" = None,
            observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL) -> Posterior:
    """``sample_joint_posterior`` without the convergence warning (its callers emit it)."""
    started = time.monotonic()
    if until_converged is not None and not isinstance(until_converged, RunUntil):
        raise ValueError(f"until_converged: expected a RunUntil or None, got {type(until_converged).__name__}")
    plan = _schedule(method, num_samples, num_chains, warmup, thin, initial is not None, max_leapfrog,
                     trajectory_length, warmup_max_leapfrog, init, init_scale, kernel)
    model = make_joint_model(observations, beta, method, prior_sigma, proxy_samples, seed=seed,
                             num_proxy_samples=num_proxy_samples, observation_model=observation_model)
    chain_seed, init_seed = (int(s) for s in np.random.SeedSequence([seed, 1]).generate_state(2))
    starts, metric, centre, mode = _chain_starts(model, initial, init, plan.init_scale, num_chains,
                                                 np.random.default_rng(init_seed))
    target = _target(model, kernel)
    chains = dict(kernel=kernel, warmup=plan.warmup, seed=chain_seed, preconditioner="dense",
                  initial_preconditioner=mcmc.Preconditioner(metric, mean=centre),
                  trajectory_length=plan.trajectory_length, max_leapfrog=plan.max_leapfrog,
                  warmup_max_leapfrog=plan.warmup_max_leapfrog, progress=progress)
    if until_converged is None:
        result = mcmc.sample_chains(target, starts, plan.iterations, thin=plan.thin, **chains)
        kept = np.round(np.linspace(0, plan.iterations - 1, plan.per_chain)).astype(np.int64)
        run = SamplerRun(result.draws[:, kept], result.r_hat, result.ess, float(result.acceptance_rate.mean()),
                         result, result.num_evaluations, plan.thin, plan.iterations * plan.thin, "")
    else:
        run = run_until(target, starts, plan.iterations * plan.thin, plan.per_chain, plan.evenly, until_converged,
                        num_samples, started, chains)
    return _posterior(run, model, _first_proxy_weights(observations), num_samples, num_chains, seed, plan.warmup,
                      kernel, mode, initial is not None, until_converged)


def _posterior(run: SamplerRun, model: PosteriorModel, proxy: np.ndarray, num_samples: int, num_chains: int,
               seed: int, warmup: int, kernel: str, mode: np.ndarray, warm_started: bool,
               until_converged: "RunUntil | None") -> Posterior:
    """The ``Posterior`` of a run: pooled draws, capped diagnostics, the frozen metric."""
    r_hat = np.minimum(run.r_hat, R_HAT_CAP)
    r_hat_max = float(np.max(r_hat)) if not np.all(np.isnan(r_hat)) else float("nan")
    ess_min = float(np.nanmin(run.ess)) if not np.all(np.isnan(run.ess)) else float("nan")
    num_proxy = next((len(t.sample_features) for t in model.proxy_terms if t.sample_features is not None), 0)
    final_metric = np.array(run.last.preconditioner.chol, dtype=np.float64)
    final_metric.setflags(write=False)
    return Posterior(
        samples=pool_draws(run.kept, num_samples), method=model.method, beta=model.beta,
        prior_sigma=model.prior_sigma, proxy_weights=proxy, acceptance_rate=run.acceptance_rate,
        r_hat_max=r_hat_max, ess_min=ess_min, num_chains=num_chains, seed=seed, warmup=warmup, thin=run.thin,
        kernel=kernel, step_size=run.last.step_size, r_hat=r_hat, ess=run.ess, mode=mode,
        num_proxy_samples=num_proxy, num_evaluations=run.num_evaluations,
        num_proxies=len(model.proxy_terms), num_choices=len(model.choices), metric=final_metric,
        warm_started=warm_started, run_until=until_converged, iterations=run.iterations,
        stop_reason=run.stop_reason)


def sample_posterior(proxy_weights: np.ndarray, train_mdp: GridMDP, beta: float, method: str,
                     num_samples: int, seed: int, prior_sigma: "float | None" = None,
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
            ``initial``, ``until_converged``, ``progress``, ``observation_model``).
    Returns:
        The ``Posterior``. Emits a ``RuntimeWarning`` if it is not ``converged``.
    """
    observation = ProxyObservation(proxy_weights, train_mdp, proxy_features, proxy_sample_features)
    posterior = _sample([observation], beta, method, num_samples, seed, prior_sigma, proxy_samples,
                        **sampler_options)
    _warn_unconverged(posterior, "sample_posterior")
    return posterior
