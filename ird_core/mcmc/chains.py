"""Batched Markov chain Monte Carlo: many chains advanced together as one batch.

The kernels (:mod:`ird_core.mcmc.kernels`, chosen by name) are ``init``/``step`` pairs;
:func:`sample_chains` adapts their parameters in a warm-up (:mod:`ird_core.mcmc.adaptation`),
freezes them and runs the fixed kernel; :func:`continue_chains` extends a finished run with the
same frozen kernel and the same generator stream. Every step makes ONE batched ``log_density``
call on all ``C`` chains (``L`` calls for HMC with ``L`` leapfrog steps); positions are
``(C, d)`` arrays throughout.

Diagnostics (:mod:`ird_core.mcmc.diagnostics`): a run reports the rank-normalised split R-hat and
the bulk ESS over every post-warm-up iteration, whatever the thinning.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from ird_core.mcmc.adaptation import DualAveraging, WarmupState, find_initial_step, warmup_schedule, warmup_update
from ird_core.mcmc.base import PRECONDITIONERS, ChainState, Kernel, KernelParams, LogDensityFn, Preconditioner, StepInfo
from ird_core.mcmc.diagnostics import bulk_effective_sample_size, rank_normalized_r_hat
from ird_core.mcmc.kernels import get_kernel, num_leapfrog_steps, step_sizes

__all__ = ["ProgressFn", "MCMCResult", "ChainContinuation", "sample_chains", "continue_chains"]

#: ``progress(step, total)``, called once per MCMC iteration (warm-up included).
ProgressFn = Callable[[int, int], None]


@dataclass(frozen=True)
class MCMCResult:
    """Draws of ``C`` chains after warm-up and thinning.

    Attributes:
        draws: ``(C, N, d)``.
        log_density: ``(C, N)`` target values of the draws.
        acceptance_rate: ``(C,)`` fraction of accepted proposals after warm-up.
        step_size: the frozen step size ``h`` (per-iteration jitter of +-10% for HMC).
        preconditioner: the frozen preconditioner.
        kernel, warmup, thin, num_leapfrog: the settings used (``num_leapfrog`` is 1 unless HMC).
        num_evaluations: batched ``log_density`` calls made, warm-up included.
        r_hat: ``(d,)`` rank-normalised split R-hat over EVERY post-warm-up iteration (thinning
            only decides what is stored); NaN with fewer than 4 iterations.
        ess: ``(d,)`` bulk ESS over every post-warm-up iteration; NaN with fewer than 8.
        num_divergent: ``(C,)`` divergent transitions after warm-up (see ``StepInfo``).
    """

    draws: np.ndarray
    log_density: np.ndarray
    acceptance_rate: np.ndarray
    step_size: float
    preconditioner: Preconditioner
    kernel: str
    warmup: int
    thin: int
    num_leapfrog: int
    num_evaluations: int
    r_hat: np.ndarray
    ess: np.ndarray
    num_divergent: "np.ndarray | None" = None
    continuation: "ChainContinuation | None" = None


@dataclass(frozen=True)
class ChainContinuation:
    """Everything ``continue_chains`` needs to extend the chains with the frozen kernel exactly as
    if the run had been longer: the last state, the generator's state and the kernel settings.

    Attributes:
        kernel: one of ``KERNELS``.
        state: the chains' last ``ChainState`` (positions ``(C, d)``).
        rng_state: ``bit_generator.state`` of the run's PCG64 generator after its last draw (a
            snapshot: continuing twice from one continuation gives the same draws).
        step_size: the frozen step size; preconditioner: the frozen metric.
        trajectory_length, max_leapfrog: the HMC trajectory settings.
    """

    kernel: str
    state: ChainState
    rng_state: dict
    step_size: float
    preconditioner: Preconditioner
    trajectory_length: float
    max_leapfrog: int


def _check_int(name: str, value: int, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def _check_initial(initial: np.ndarray) -> np.ndarray:
    x0 = np.array(initial, dtype=np.float64)
    if x0.ndim != 2 or x0.shape[0] < 2 or x0.shape[1] < 1:
        raise ValueError(f"initial: expected shape (C >= 2, d >= 1), got {x0.shape}")
    if not np.all(np.isfinite(x0)):
        raise ValueError("initial: contains NaN or infinite values")
    return x0


class _Settings(NamedTuple):
    """``sample_chains``' validated settings."""

    name: str
    kernel: Kernel
    num_draws: int
    warmup: int
    thin: int
    seed: int
    target_accept: float
    preconditioner: str
    trajectory_length: float
    max_leapfrog: int
    warmup_max_leapfrog: int


def _check_settings(kernel: str, initial: np.ndarray, num_draws: int, warmup: int, thin: int, seed: int, target_accept: "float | None",
                    preconditioner: str, trajectory_length: float, max_leapfrog: int,
                    warmup_max_leapfrog: "int | None") -> tuple[_Settings, np.ndarray]:
    """Validate ``sample_chains``' arguments (the settings and the ``(C, d)`` starting points);
    ValueError naming the field."""
    kern = get_kernel(kernel)
    if preconditioner not in PRECONDITIONERS:
        raise ValueError(f"preconditioner: expected one of {PRECONDITIONERS}, got {preconditioner!r}")
    x0 = _check_initial(initial)
    num_draws = _check_int("num_draws", num_draws, 1)
    warmup = _check_int("warmup", warmup, 0)
    thin = _check_int("thin", thin, 1)
    seed = _check_int("seed", seed, 0)
    max_leapfrog = _check_int("max_leapfrog", max_leapfrog, 1)
    warmup_max_leapfrog = max_leapfrog if warmup_max_leapfrog is None else \
        _check_int("warmup_max_leapfrog", warmup_max_leapfrog, 1)
    target = kern.target_accept if target_accept is None else float(target_accept)
    if kern.tunes_step and not 0.0 < target < 1.0:
        raise ValueError(f"target_accept: expected a value in (0, 1), got {target_accept!r}")
    if not (np.isfinite(trajectory_length) and trajectory_length > 0):
        raise ValueError(f"trajectory_length: expected a finite value > 0, got {trajectory_length!r}")
    return _Settings(kernel, kern, num_draws, warmup, thin, seed, target, preconditioner, trajectory_length,
                     max_leapfrog, warmup_max_leapfrog), x0


def _transition(kern: Kernel, rng: np.random.Generator, state: ChainState, log_density: LogDensityFn, step: float,
                precond: Preconditioner, num_leapfrog: int) -> tuple[ChainState, StepInfo]:
    """One step of every chain: per-chain (jittered) step sizes, then the kernel's transition."""
    params = KernelParams(step_sizes(kern, step, state.position.shape[0], rng), precond, num_leapfrog)
    return kern.step(rng, state, log_density, params)


def _warm_up(settings: _Settings, rng: np.random.Generator, state: ChainState, log_density: LogDensityFn,
             warm: WarmupState, adapt_preconditioner: bool, progress: "ProgressFn | None", total: int
             ) -> tuple[ChainState, WarmupState, int]:
    """The adaptive warm-up: the chains' state after it, the adapted parameters, evaluations made."""
    kern, evaluations = settings.kernel, 0
    for it, stage in enumerate(warmup_schedule(settings.warmup, adapt_preconditioner)):
        step = warm.step_size.step
        cap = settings.warmup_max_leapfrog if stage.short else settings.max_leapfrog
        state, info = _transition(kern, rng, state, log_density, step, warm.preconditioner,
                                  num_leapfrog_steps(kern, step, settings.trajectory_length, cap))
        evaluations += info.num_evaluations
        warm = warmup_update(warm, stage, state, info, settings.preconditioner, kern.tunes_step)
        if progress is not None:
            progress(it + 1, total)
    return state, warm, evaluations


class _Sweep(NamedTuple):
    """``n`` iterations of a frozen kernel: every state ``(C, n, d)``, its log density ``(C, n)``,
    accepted and divergent counts ``(C,)``, evaluations made, and the last state."""

    states: np.ndarray
    log_density: np.ndarray
    accepted: np.ndarray
    divergent: np.ndarray
    evaluations: int
    state: ChainState


def _sweep(kern: Kernel, rng: np.random.Generator, state: ChainState, log_density: LogDensityFn, step: float,
           precond: Preconditioner, num_leapfrog: int, iterations: int, progress: "ProgressFn | None",
           done: int, total: int) -> _Sweep:
    """Run the frozen kernel ``iterations`` times, keeping every state (``progress(done + it + 1, total)``)."""
    num_chains, dim = state.position.shape
    states = np.empty((num_chains, iterations, dim))
    state_log_p = np.empty((num_chains, iterations))
    accepted, divergent = np.zeros(num_chains), np.zeros(num_chains, dtype=np.int64)
    evaluations = 0
    for it in range(iterations):
        state, info = _transition(kern, rng, state, log_density, step, precond, num_leapfrog)
        evaluations += info.num_evaluations
        accepted += info.is_accepted
        divergent += info.is_divergent
        states[:, it], state_log_p[:, it] = state.position, state.log_density
        if progress is not None:
            progress(done + it + 1, total)
    return _Sweep(states, state_log_p, accepted, divergent, evaluations, state)


def _diagnostics(states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R-hat (NaN below 4 iterations) and bulk ESS (NaN below 8) of ``(C, n, d)`` states."""
    iterations, dim = states.shape[1:]
    return (rank_normalized_r_hat(states) if iterations >= 4 else np.full(dim, np.nan),
            bulk_effective_sample_size(states) if iterations >= 8 else np.full(dim, np.nan))


def sample_chains(log_density: LogDensityFn, initial: np.ndarray, num_draws: int, *,
                  kernel: str = "mala", warmup: int = 300, thin: int = 1, seed: int = 0,
                  target_accept: "float | None" = None, preconditioner: str = "dense",
                  initial_preconditioner: "Preconditioner | None" = None,
                  adapt_preconditioner: bool = True,
                  trajectory_length: float = 1.5, max_leapfrog: int = 32,
                  warmup_max_leapfrog: "int | None" = None,
                  progress: "ProgressFn | None" = None) -> MCMCResult:
    """Run ``C`` chains as one batch: adaptive warm-up, then ``num_draws * thin`` fixed-kernel steps.

    Args:
        log_density: batched target ``(C, d) -> ((C,), (C, d) | None)``; ``rwm`` ignores the
            gradient (and the target may return None).
        initial: ``(C, d)`` starting points, ideally overdispersed relative to the target so
            that R-hat is meaningful; ``C >= 2`` chains.
        num_draws: retained draws per chain after thinning, ``>= 1``.
        kernel: one of ``KERNELS``.
        warmup: adaptation steps, discarded (``>= 0``).
        thin: keep every ``thin``-th post-warm-up state (``>= 1``).
        seed: seeds the numpy Generator; same seed, same draws.
        target_accept: mean acceptance probability for dual averaging (default ``TARGET_ACCEPT``).
        preconditioner: ``identity``, ``diag`` or ``dense``, estimated in warm-up windows.
        initial_preconditioner: used until the first window ends (default the identity).
        adapt_preconditioner: if False, keep ``initial_preconditioner`` and adapt only the step.
        trajectory_length: HMC integration time in whitened units; the number of leapfrog steps
            is ``clip(round(length / h), 1, max_leapfrog)``, recomputed as ``h`` adapts.
        max_leapfrog: upper bound on leapfrog steps per HMC iteration.
        warmup_max_leapfrog: cap on leapfrog steps in warm-up before the final buffer (cheaper,
            shorter trajectories while the chains converge and the metric is learnt); default
            ``max_leapfrog``.
        progress: optional ``progress(step, total)`` callback, once per iteration.
    Returns:
        An ``MCMCResult`` with ``draws`` of shape ``(C, num_draws, d)``.
    """
    settings, x0 = _check_settings(kernel, initial, num_draws, warmup, thin, seed, target_accept, preconditioner,
                                   trajectory_length, max_leapfrog, warmup_max_leapfrog)
    kern = settings.kernel
    num_chains, dim = x0.shape
    precond = initial_preconditioner if initial_preconditioner is not None else Preconditioner.identity(dim)
    if precond.chol.shape != (dim, dim):
        raise ValueError(f"initial_preconditioner: expected a ({dim}, {dim}) factor, got {precond.chol.shape}")

    rng = np.random.default_rng(settings.seed)
    state = kern.init(x0, log_density)
    if not np.all(np.isfinite(state.log_density)):
        raise ValueError("initial: log_density is not finite at every starting point")
    step0, evaluations = find_initial_step(kern, state, precond, log_density, rng) \
        if settings.warmup > 0 and kern.tunes_step else (kern.default_step(dim), 0)
    iterations = settings.num_draws * settings.thin
    total = settings.warmup + iterations
    state, warm, warm_evaluations = _warm_up(settings, rng, state, log_density,
                                             WarmupState(DualAveraging.start(step0, settings.target_accept), precond),
                                             adapt_preconditioner, progress, total)
    frozen = warm.step_size.final_step
    run = _sweep(kern, rng, state, log_density, frozen, warm.preconditioner,
                 num_leapfrog_steps(kern, frozen, trajectory_length, settings.max_leapfrog), iterations, progress,
                 settings.warmup, total)
    return _result(settings, run, step0, warm, 1 + evaluations + warm_evaluations, rng)


def _result(settings: _Settings, run: _Sweep, step0: float, warm: WarmupState, evaluations: int,
            rng: np.random.Generator) -> MCMCResult:
    """``sample_chains``' result: the thinned draws, diagnostics over every iteration, continuation."""
    thin, kern = settings.thin, settings.kernel
    final_step = warm.step_size.final_step if settings.warmup > 0 else step0
    r_hat, ess = _diagnostics(run.states)
    kernel = settings.name
    return MCMCResult(draws=np.ascontiguousarray(run.states[:, thin - 1::thin]),
                      log_density=np.ascontiguousarray(run.log_density[:, thin - 1::thin]),
                      acceptance_rate=run.accepted / run.states.shape[1], step_size=final_step,
                      preconditioner=warm.preconditioner, kernel=kernel, warmup=settings.warmup, thin=thin,
                      num_leapfrog=num_leapfrog_steps(kern, final_step, settings.trajectory_length,
                                                      settings.max_leapfrog),
                      num_evaluations=evaluations + run.evaluations, r_hat=r_hat, ess=ess,
                      num_divergent=run.divergent,
                      continuation=ChainContinuation(kernel, run.state, rng.bit_generator.state,
                                                     warm.step_size.final_step, warm.preconditioner,
                                                     float(settings.trajectory_length), settings.max_leapfrog))


def continue_chains(log_density: LogDensityFn, continuation: ChainContinuation, num_draws: int, *,
                    progress: "ProgressFn | None" = None) -> MCMCResult:
    """Extend the chains of a finished run by ``num_draws`` iterations of its frozen kernel.

    ``sample_chains(..., n1 + n2)``'s post-warm-up states equal those of ``sample_chains(..., n1)``
    followed by ``continue_chains(log_density, result.continuation, n2)`` (same generator stream),
    so a run can be lengthened in blocks until its diagnostics pass.

    Args:
        log_density: the run's target.
        continuation: ``MCMCResult.continuation`` of the run (or of a previous continuation).
        num_draws: iterations to add, every one kept (``>= 1``).
        progress: optional ``progress(step, num_draws)`` callback, once per iteration.
    Returns:
        An ``MCMCResult`` of the new iterations only: ``draws`` ``(C, num_draws, d)``, ``warmup``
        0, ``thin`` 1, acceptance, evaluations and diagnostics of these iterations, and the
        continuation after them.
    """
    kern = get_kernel(continuation.kernel)
    num_draws = _check_int("num_draws", num_draws, 1)
    rng = np.random.Generator(np.random.PCG64(0))
    rng.bit_generator.state = continuation.rng_state
    step, precond = continuation.step_size, continuation.preconditioner
    cap = num_leapfrog_steps(kern, step, continuation.trajectory_length, continuation.max_leapfrog)
    run = _sweep(kern, rng, continuation.state, log_density, step, precond, cap, num_draws, progress, 0, num_draws)
    r_hat, ess = _diagnostics(run.states)
    return MCMCResult(draws=run.states, log_density=run.log_density, acceptance_rate=run.accepted / num_draws,
                      step_size=step, preconditioner=precond, kernel=continuation.kernel, warmup=0, thin=1,
                      num_leapfrog=cap, num_evaluations=run.evaluations, r_hat=r_hat, ess=ess,
                      num_divergent=run.divergent,
                      continuation=ChainContinuation(continuation.kernel, run.state, rng.bit_generator.state, step,
                                                     precond, continuation.trajectory_length,
                                                     continuation.max_leapfrog))
