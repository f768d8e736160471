"""Warm-up adaptation of the MCMC kernels' parameters (Stan-style windowed adaptation; Hoffman &
Gelman 2014 dual averaging), laid out by :func:`warmup_schedule` and applied by
:func:`warmup_update`:

1. an initial buffer (``max(15%, 5)`` iterations) adapts only the step size;
2. doubling windows: at the end of each window the preconditioner is re-estimated from that
   window's draws POOLED over all chains, shrunk towards the current preconditioner with a
   Ledoit-Wolf weight computed for the draws' effective sample size, and the dual averaging
   restarts from the current step size;
3. a final buffer (``max(10%, 10)`` iterations) adapts the step size for the final metric.

HMC warm-up may use shorter trajectories (``warmup_max_leapfrog``) until the final buffer.

Dual averaging drives the chain-averaged Metropolis acceptance probability towards the kernel's
target (0.234 RWM, 0.574 MALA, 0.8 HMC). Everything is frozen after warm-up
(:mod:`ird_core.mcmc.chains`), so the retained draws come from a fixed, valid Markov kernel.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.linalg import cholesky

from ird_core.mcmc.base import PRECONDITIONERS, ChainState, Kernel, KernelParams, LogDensityFn, Preconditioner, StepInfo
from ird_core.mcmc.diagnostics import effective_sample_size

__all__ = [
    "estimate_preconditioner",
    "DualAveraging",
    "warmup_windows",
    "WarmupStep",
    "warmup_schedule",
    "WarmupState",
    "warmup_update",
    "find_initial_step",
]


def estimate_preconditioner(draws: np.ndarray, kind: str,
                            reference: "Preconditioner | None" = None,
                            discount_autocorrelation: bool = True) -> Preconditioner:
    """Covariance of warm-up draws, shrunk towards the current preconditioner.

    The draws are whitened by ``reference`` (``u = L_ref^{-1} x``); their pooled covariance ``S``
    is shrunk towards ``mu I`` (``mu = tr S / d``) with the Ledoit-Wolf weight computed for the
    draws' effective sample size (autocorrelated warm-up draws carry fewer than ``C n`` draws'
    worth of information, and a sample covariance from ``n_eff ~ d`` draws has eigenvalues off by
    factors ``(1 +- sqrt(d / n_eff))^2``); the result is mapped back, ``M = L_ref S* L_ref^T``.
    ``diag`` keeps only the variances (in the original coordinates), shrunk the same way.
    The pooled mean of the draws becomes the preconditioner's ``mean``.

    Args:
        draws: ``(C, n, d)`` warm-up draws of ``C`` chains (``C n >= 2``), or ``(n, d)``.
        kind: one of ``PRECONDITIONERS``.
        reference: the preconditioner the draws were made with (default the identity).
        discount_autocorrelation: weigh the shrinkage by the draws' ESS (default) or by their
            number. The elliptical kernel uses the number: its early draws mix slowly exactly
            because its Gaussian is off, and an ESS-weighted shrinkage back towards that
            Gaussian then keeps it off.
    Returns:
        The preconditioner.
    """
    if kind not in PRECONDITIONERS:
        raise ValueError(f"kind: expected one of {PRECONDITIONERS}, got {kind!r}")
    x = np.asarray(draws, dtype=np.float64)
    if x.ndim == 2:
        x = x[None]
    if x.ndim != 3 or x.shape[0] * x.shape[1] < 2 or not np.all(np.isfinite(x)):
        raise ValueError(f"draws: expected finite values of shape (C, n, d), C n >= 2, got {np.shape(draws)}")
    c, n, dim = x.shape
    mean = x.reshape(-1, dim).mean(axis=0)  # the elliptical kernel's centre
    if kind == "identity":
        return Preconditioner(np.eye(dim), "identity", mean)
    ref = Preconditioner.identity(dim) if reference is None else reference
    if kind == "diag":
        ref = Preconditioner(np.diag(np.sqrt(np.diag(ref.cov))), "diag")
    u = ref.whiten(x.reshape(c * n, dim)).reshape(c, n, dim)
    # Independent starting points make the pooled draws worth at least C independent ones.
    n_eff = float(c * n) if n < 4 or not discount_autocorrelation else \
        float(np.clip(np.nanmean(effective_sample_size(u)), c, c * n))
    centred = (u - u.reshape(-1, dim).mean(axis=0)).reshape(-1, dim)
    # Variances: shrink towards their mean (Ledoit-Wolf weight for n_eff draws).
    centred2 = centred**2
    var = centred2.mean(axis=0)
    spread = np.sum((var - var.mean()) ** 2)
    noise = np.sum((centred2 - var) ** 2) / len(centred) / n_eff
    lam = 1.0 if spread <= 0 else min(1.0, noise / spread)
    shrunk_var = (1.0 - lam) * var + lam * var.mean()
    if kind == "diag":
        return Preconditioner(ref.chol * np.sqrt(shrunk_var)[None, :], "diag", mean)
    # Correlations: shrink the off-diagonal covariances towards zero (Ledoit-Wolf, diagonal target).
    cov = centred.T @ centred / len(centred)
    off = ~np.eye(dim, dtype=bool)
    spread = np.sum(cov[off] ** 2)
    # sum_{i != j} Var(c_i c_j) = mean_k [(sum_i c_ki^2)^2 - sum_i c_ki^4] - sum_{i != j} s_ij^2.
    fourth = np.mean(np.sum(centred2, axis=1) ** 2 - np.sum(centred2**2, axis=1))
    noise = max(0.0, fourth - spread) / n_eff
    lam = 1.0 if spread <= 0 else float(np.clip(noise / spread, 0.0, 1.0))
    target = (1.0 - lam) * cov + lam * np.diag(var)
    scale = np.sqrt(shrunk_var / var)
    shrunk = scale[:, None] * target * scale[None, :]
    return Preconditioner(ref.chol @ cholesky(shrunk, lower=True), "dense", mean)


@dataclass(frozen=True)
class DualAveraging:
    """Nesterov dual averaging of ``log h`` (Hoffman & Gelman 2014, Algorithm 5), immutable.

    ``gamma = 0.1`` (Stan: 0.05): the acceptance probability it sees is already averaged over
    all chains, hence far less noisy than one chain's, and a gentler controller oscillates less.
    Restarts after a metric update start from the averaged step with no bias to larger steps.

    ``update(accept_prob)`` returns the next state; ``step`` is the current iterate,
    ``final_step`` the averaged one to freeze after warm-up.
    """

    target: float
    mu: float
    log_step: float
    log_step_bar: float = 0.0
    h_bar: float = 0.0
    count: int = 0
    gamma: float = 0.1
    t0: float = 10.0
    kappa: float = 0.75

    @classmethod
    def start(cls, step: float, target: float, bias: float = 10.0) -> "DualAveraging":
        """Start at ``step``, shrinking towards ``bias * step`` (Stan's 10: explore larger steps)."""
        return cls(target=target, mu=float(np.log(bias * step)), log_step=float(np.log(step)),
                   log_step_bar=float(np.log(step)))

    @property
    def step(self) -> float:
        return float(np.exp(self.log_step))

    @property
    def final_step(self) -> float:
        return float(np.exp(self.log_step_bar))

    def update(self, accept_prob: float) -> "DualAveraging":
        m = self.count + 1
        eta = 1.0 / (m + self.t0)
        h_bar = (1.0 - eta) * self.h_bar + eta * (self.target - accept_prob)
        log_step = self.mu - np.sqrt(m) / self.gamma * h_bar
        weight = m ** (-self.kappa)
        log_step_bar = weight * log_step + (1.0 - weight) * self.log_step_bar
        return DualAveraging(self.target, self.mu, float(log_step), float(log_step_bar),
                             float(h_bar), m, self.gamma, self.t0, self.kappa)


def warmup_windows(warmup: int) -> list[tuple[int, int]]:
    """Preconditioner windows ``[start, end)`` of the warm-up (Stan's schedule, scaled).

    An initial buffer of ``max(15%, 5)`` steps, doubling windows of at least 10 steps (the last
    one absorbs the remainder, at most 5), a final buffer of ``max(10%, 10)`` steps for the step
    size alone. Fewer than 30 warm-up steps: no windows (step size only).
    """
    if warmup < 30:
        return []
    start = max(5, int(0.15 * warmup))
    end = warmup - max(10, int(0.10 * warmup))
    length = end - start
    num = max(1, min(5, int(np.floor(np.log2(length / 10.0 + 1.0)))))
    base = length / (2**num - 1)
    windows, cursor = [], start
    for i in range(num):
        stop = end if i == num - 1 else cursor + int(round(base * 2**i))
        windows.append((cursor, stop))
        cursor = stop
    return windows


class WarmupStep(NamedTuple):
    """What one warm-up iteration does besides updating the step size.

    Attributes:
        collect: the iteration's draws join the current preconditioner window.
        window_end: re-estimate the preconditioner after this iteration.
        short: HMC trajectories are capped at ``warmup_max_leapfrog`` (before the final buffer).
    """

    collect: bool
    window_end: bool
    short: bool


def warmup_schedule(warmup: int, adapt_preconditioner: bool = True) -> list[WarmupStep]:
    """The warm-up, one ``WarmupStep`` per iteration, from ``warmup_windows`` (no windows if
    ``adapt_preconditioner`` is False: the step size alone adapts, with short trajectories)."""
    windows = warmup_windows(warmup) if adapt_preconditioner else []
    collect = np.zeros(warmup, dtype=bool)
    window_end = np.zeros(warmup, dtype=bool)
    for start, end in windows:
        collect[start:end] = True
        window_end[end - 1] = True
    # Short trajectories only until the final buffer: the step size is then tuned with the
    # trajectory length the retained draws use.
    last = windows[-1][1] if windows else warmup
    return [WarmupStep(bool(c), bool(e), it < last) for it, (c, e) in enumerate(zip(collect, window_end))]


class WarmupState(NamedTuple):
    """The adapted parameters during warm-up.

    Attributes:
        step_size: the dual averaging of ``log h``.
        preconditioner: the current preconditioner.
        window_draws: ``(C, d)`` positions collected in the current window.
    """

    step_size: DualAveraging
    preconditioner: Preconditioner
    window_draws: tuple[np.ndarray, ...] = ()


def warmup_update(warm: WarmupState, stage: WarmupStep, state: ChainState, info: StepInfo,
                  preconditioner: str, tune_step: bool = True) -> WarmupState:
    """Adapt after one warm-up iteration: step size from the chain-averaged acceptance (unless
    ``tune_step`` is False: a kernel without a step); at a window's end, the ``preconditioner``
    kind from the window's pooled draws."""
    adapt = warm.step_size.update(float(info.acceptance_probability.mean())) if tune_step else warm.step_size
    draws = warm.window_draws + (state.position,) if stage.collect else warm.window_draws
    if not stage.window_end:
        return WarmupState(adapt, warm.preconditioner, draws)
    precond = estimate_preconditioner(np.stack(draws, axis=1), preconditioner, warm.preconditioner,
                                      discount_autocorrelation=tune_step)
    # Restart the adaptation near the current step size: the new metric changes it.
    return WarmupState(DualAveraging.start(adapt.final_step, adapt.target, bias=1.0), precond)


def find_initial_step(kernel: Kernel, state: ChainState, precond: Preconditioner,
                      log_density: LogDensityFn, rng: np.random.Generator) -> tuple[float, int]:
    """Halve the kernel's default step until the mean acceptance probability exceeds half its target.

    Trial transitions are discarded (HMC trials use one leapfrog step). Returns the step and the
    number of batched evaluations spent.
    """
    num_chains, dim = state.position.shape
    step = kernel.default_step(dim)
    evaluations = 0
    for _ in range(40):
        _, info = kernel.step(rng, state, log_density, KernelParams(np.full(num_chains, step), precond))  # no jitter
        evaluations += info.num_evaluations
        if info.acceptance_probability.mean() >= 0.5 * kernel.target_accept:
            break
        step *= 0.5
    return step, evaluations
