"""Batched Markov chain Monte Carlo: many chains advanced together as one batch.

A target is a function ``log_density(x (C, d)) -> (log p (C,), grad (C, d) | None)`` evaluated on
every chain at once, so each MCMC step costs ONE batched call (``L`` calls for HMC with ``L``
leapfrog steps). The gradient may be any deterministic vector field: MALA and HMC stay exact
(the Metropolis-Hastings correction uses the same field at both ends), only their efficiency
depends on how well it matches ``grad log p``.

Kernels (one operator each):

- ``rwm``: random-walk Metropolis, ``x' = x + h L z``.
- ``mala``: Metropolis-adjusted Langevin, ``x' = x + h^2/2 M g(x) + h L z``.
- ``hmc``: Hamiltonian Monte Carlo with ``L`` leapfrog steps in whitened coordinates.

Here ``z ~ N(0, I)``, ``M = L L^T`` is a preconditioner (an estimate of the posterior
covariance) and ``h`` a step size shared by all chains.

Warm-up (Stan-style windowed adaptation, Hoffman & Gelman 2014 dual averaging):

1. an initial buffer (``max(15%, 5)`` iterations) adapts only the step size;
2. doubling windows: at the end of each window the preconditioner is re-estimated from that
   window's draws POOLED over all chains, shrunk towards the current preconditioner with a
   Ledoit-Wolf weight computed for the draws' effective sample size, and the dual averaging
   restarts from the current step size;
3. a final buffer (``max(10%, 10)`` iterations) adapts the step size for the final metric.

HMC warm-up may use shorter trajectories (``warmup_max_leapfrog``) until the final buffer.

Dual averaging drives the chain-averaged Metropolis acceptance probability towards the kernel's
target (0.234 RWM, 0.574 MALA, 0.8 HMC). Everything is frozen after warm-up, so the retained
draws come from a fixed, valid Markov kernel.

Diagnostics: split R-hat (Gelman et al., BDA3, 11.4), its rank-normalised and folded variant
(Vehtari et al. 2021) and the multi-chain effective sample size with Geyer's initial monotone
sequence estimator (as in Stan). ``sample_chains`` reports them over every post-warm-up
iteration, whatever the thinning.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np
from scipy.linalg import cholesky, solve_triangular
from scipy.special import ndtri
from scipy.stats import rankdata

__all__ = [
    "KERNELS",
    "PRECONDITIONERS",
    "TARGET_ACCEPT",
    "LogDensityFn",
    "ProgressFn",
    "Preconditioner",
    "DualAveraging",
    "MCMCResult",
    "estimate_preconditioner",
    "rwm_proposal",
    "mala_mean",
    "mala_log_proposal",
    "leapfrog",
    "metropolis_accept",
    "warmup_windows",
    "sample_chains",
    "split_chains",
    "rank_normalize",
    "split_r_hat",
    "rank_normalized_r_hat",
    "effective_sample_size",
    "bulk_effective_sample_size",
]

#: ``x (C, d) -> (log p (C,), grad (C, d) or None)``.
LogDensityFn = Callable[[np.ndarray], "tuple[np.ndarray, np.ndarray | None]"]
#: ``progress(step, total)``, called once per MCMC iteration (warm-up included).
ProgressFn = Callable[[int, int], None]

KERNELS: tuple[str, ...] = ("rwm", "mala", "hmc")
PRECONDITIONERS: tuple[str, ...] = ("identity", "diag", "dense")
#: Target mean acceptance probabilities: RWM and MALA from the optimal-scaling results of
#: Roberts, Gelman & Gilks (1997) and Roberts & Rosenthal (1998); HMC as Stan's default.
TARGET_ACCEPT: dict[str, float] = {"rwm": 0.234, "mala": 0.574, "hmc": 0.8}


# --------------------------------------------------------------------------------------------
# Preconditioner
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Preconditioner:
    """A linear change of variables ``x = L u`` with ``M = L L^T`` (posterior covariance estimate).

    Attributes:
        chol: ``(d, d)`` lower-triangular ``L`` (diagonal for ``diag``/``identity``).
        kind: one of ``PRECONDITIONERS``.
    """

    chol: np.ndarray
    kind: str = "dense"

    @classmethod
    def identity(cls, dim: int, scale: float = 1.0) -> "Preconditioner":
        return cls(scale * np.eye(dim), "identity")

    @property
    def cov(self) -> np.ndarray:
        """``M = L L^T``; ``(d, d)``."""
        return self.chol @ self.chol.T

    def scale(self, z: np.ndarray) -> np.ndarray:
        """``L z`` for a batch: ``(C, d) -> (C, d)``."""
        return z @ self.chol.T

    def whiten(self, v: np.ndarray) -> np.ndarray:
        """``L^{-1} v`` for a batch: ``(C, d) -> (C, d)``."""
        return solve_triangular(self.chol, v.T, lower=True).T

    def scale_gradient(self, g: np.ndarray) -> np.ndarray:
        """``L^T g``, the gradient in whitened coordinates: ``(C, d) -> (C, d)``."""
        return g @ self.chol

    def times_cov(self, g: np.ndarray) -> np.ndarray:
        """``M g`` for a batch: ``(C, d) -> (C, d)``."""
        return (g @ self.chol) @ self.chol.T


def estimate_preconditioner(draws: np.ndarray, kind: str,
                            reference: "Preconditioner | None" = None) -> Preconditioner:
    """Covariance of warm-up draws, shrunk towards the current preconditioner.

    The draws are whitened by ``reference`` (``u = L_ref^{-1} x``); their pooled covariance ``S``
    is shrunk towards ``mu I`` (``mu = tr S / d``) with the Ledoit-Wolf weight computed for the
    draws' effective sample size (autocorrelated warm-up draws carry fewer than ``C n`` draws'
    worth of information, and a sample covariance from ``n_eff ~ d`` draws has eigenvalues off by
    factors ``(1 +- sqrt(d / n_eff))^2``); the result is mapped back, ``M = L_ref S* L_ref^T``.
    ``diag`` keeps only the variances (in the original coordinates), shrunk the same way.

    Args:
        draws: ``(C, n, d)`` warm-up draws of ``C`` chains (``C n >= 2``), or ``(n, d)``.
        kind: one of ``PRECONDITIONERS``.
        reference: the preconditioner the draws were made with (default the identity).
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
    if kind == "identity":
        return Preconditioner.identity(dim)
    ref = Preconditioner.identity(dim) if reference is None else reference
    if kind == "diag":
        ref = Preconditioner(np.diag(np.sqrt(np.diag(ref.cov))), "diag")
    u = ref.whiten(x.reshape(c * n, dim)).reshape(c, n, dim)
    # Independent starting points make the pooled draws worth at least C independent ones.
    n_eff = float(c * n) if n < 4 else float(np.clip(np.nanmean(effective_sample_size(u)), c, c * n))
    centred = (u - u.reshape(-1, dim).mean(axis=0)).reshape(-1, dim)
    # Variances: shrink towards their mean (Ledoit-Wolf weight for n_eff draws).
    centred2 = centred**2
    var = centred2.mean(axis=0)
    spread = np.sum((var - var.mean()) ** 2)
    noise = np.sum((centred2 - var) ** 2) / len(centred) / n_eff
    lam = 1.0 if spread <= 0 else min(1.0, noise / spread)
    shrunk_var = (1.0 - lam) * var + lam * var.mean()
    if kind == "diag":
        return Preconditioner(ref.chol * np.sqrt(shrunk_var)[None, :], "diag")
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
    return Preconditioner(ref.chol @ cholesky(shrunk, lower=True), "dense")


# --------------------------------------------------------------------------------------------
# Kernels: one operator each
# --------------------------------------------------------------------------------------------


def rwm_proposal(x: np.ndarray, z: np.ndarray, step: np.ndarray, precond: Preconditioner) -> np.ndarray:
    """Random-walk proposal ``x + h L z``.

    Args:
        x: ``(C, d)`` positions; z: ``(C, d)`` standard normals; step: ``(C,)`` or scalar ``h``.
    Returns:
        ``(C, d)``.
    """
    return x + np.reshape(step, (-1, 1)) * precond.scale(z)


def mala_mean(x: np.ndarray, grad: np.ndarray, step: np.ndarray, precond: Preconditioner) -> np.ndarray:
    """Langevin proposal mean ``x + h^2 / 2 M g(x)``; ``(C, d)`` -> ``(C, d)``."""
    h = np.reshape(step, (-1, 1))
    return x + 0.5 * h**2 * precond.times_cov(grad)


def mala_log_proposal(x_to: np.ndarray, mean_from: np.ndarray, step: np.ndarray,
                      precond: Preconditioner) -> np.ndarray:
    """``log q(x_to | x_from)`` up to a constant shared by both directions; ``(C,)``.

    ``q = N(mean_from, h^2 M)``, so this is ``-|L^{-1}(x_to - mean_from)|^2 / (2 h^2)``.
    """
    u = precond.whiten(x_to - mean_from)
    return -0.5 * np.sum(u**2, axis=1) / np.reshape(step, (-1,)) ** 2


def leapfrog(x: np.ndarray, p: np.ndarray, grad: np.ndarray, step: np.ndarray, num_steps: int,
             log_density: LogDensityFn, precond: Preconditioner
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``num_steps`` leapfrog steps of HMC with whitened momentum ``p`` (kinetic ``|p|^2 / 2``).

    In whitened coordinates ``u = L^{-1} x`` the force is ``L^T g``, so a step is
    ``p += h/2 L^T g; x += h L p; p += h/2 L^T g``. Volume preserving and reversible for any
    deterministic field ``g``.

    Args:
        x, p, grad: ``(C, d)``; step: ``(C,)``; log_density: the batched target.
    Returns:
        The end position ``(C, d)``, momentum ``(C, d)``, log density ``(C,)`` and field ``(C, d)``.
    """
    h = np.reshape(step, (-1, 1))
    log_p = None
    p = p + 0.5 * h * precond.scale_gradient(grad)
    for i in range(num_steps):
        x = x + h * precond.scale(p)
        log_p, grad = log_density(x)
        if grad is None:
            raise ValueError("log_density: hmc needs a gradient, got None")
        p = p + (0.5 if i == num_steps - 1 else 1.0) * h * precond.scale_gradient(grad)
    return x, p, log_p, grad


def metropolis_accept(log_ratio: np.ndarray, uniform: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Metropolis-Hastings decisions for a batch of chains.

    Args:
        log_ratio: ``(C,)`` log acceptance ratios (NaN is treated as a rejection).
        uniform: ``(C,)`` uniforms on ``[0, 1)``.
    Returns:
        ``accept (C,)`` booleans and the acceptance probabilities ``min(1, ratio)`` ``(C,)``.
    """
    safe = np.where(np.isnan(log_ratio), -np.inf, log_ratio)
    prob = np.exp(np.minimum(safe, 0.0))
    return np.log(uniform) < safe, prob


# --------------------------------------------------------------------------------------------
# Step-size adaptation
# --------------------------------------------------------------------------------------------


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


# --------------------------------------------------------------------------------------------
# The sampler
# --------------------------------------------------------------------------------------------


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


def _check_int(name: str, value: int, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


@dataclass
class _Chains:
    """Mutable per-iteration state of the batch (private to ``sample_chains``)."""

    x: np.ndarray
    log_p: np.ndarray
    grad: "np.ndarray | None"


def _evaluate(log_density: LogDensityFn, x: np.ndarray, need_grad: bool
              ) -> "tuple[np.ndarray, np.ndarray | None]":
    log_p, grad = log_density(x)
    log_p = np.asarray(log_p, dtype=np.float64).reshape(x.shape[0])
    if need_grad:
        if grad is None:
            raise ValueError("log_density: this kernel needs a gradient, got None")
        grad = np.asarray(grad, dtype=np.float64).reshape(x.shape)
    return log_p, grad


def _transition(kernel: str, chains: _Chains, step: np.ndarray, num_leapfrog: int,
                precond: Preconditioner, log_density: LogDensityFn, rng: np.random.Generator
                ) -> tuple[_Chains, np.ndarray, np.ndarray]:
    """One MH transition of every chain. Returns the new state, accept mask and probabilities."""
    z = rng.standard_normal(chains.x.shape)
    if kernel == "rwm":
        proposal = rwm_proposal(chains.x, z, step, precond)
        log_p, grad = _evaluate(log_density, proposal, need_grad=False)
        log_ratio = log_p - chains.log_p
    elif kernel == "mala":
        proposal = mala_mean(chains.x, chains.grad, step, precond) + np.reshape(step, (-1, 1)) * precond.scale(z)
        log_p, grad = _evaluate(log_density, proposal, need_grad=True)
        forward = -0.5 * np.sum(z**2, axis=1)
        backward = mala_log_proposal(chains.x, mala_mean(proposal, grad, step, precond), step, precond)
        log_ratio = log_p - chains.log_p + backward - forward
    else:
        def wrapped(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            return _evaluate(log_density, x, need_grad=True)  # type: ignore[return-value]
        proposal, p_end, log_p, grad = leapfrog(chains.x, z, chains.grad, step, num_leapfrog, wrapped, precond)
        log_ratio = (log_p - 0.5 * np.sum(p_end**2, axis=1)) - (chains.log_p - 0.5 * np.sum(z**2, axis=1))
    accept, prob = metropolis_accept(log_ratio, rng.random(chains.x.shape[0]))
    keep = accept[:, None]
    new = _Chains(np.where(keep, proposal, chains.x), np.where(accept, log_p, chains.log_p),
                  None if chains.grad is None else np.where(keep, grad, chains.grad))
    return new, accept, prob


def _default_step(kernel: str, dim: int) -> float:
    """Optimal-scaling step for a standard normal target in ``dim`` dimensions."""
    return {"rwm": 2.38 / np.sqrt(dim), "mala": 1.65 * dim ** (-1.0 / 3.0), "hmc": dim ** (-0.25)}[kernel]


def _initial_step(kernel: str, chains: _Chains, precond: Preconditioner, log_density: LogDensityFn,
                  rng: np.random.Generator) -> tuple[float, int]:
    """Halve the default step until the mean acceptance probability exceeds half the target.

    Trial transitions are discarded (HMC trials use one leapfrog step). Returns the step and the
    number of batched evaluations spent.
    """
    step = _default_step(kernel, chains.x.shape[1])
    evaluations = 0
    for _ in range(40):
        _, _, prob = _transition(kernel, chains, np.full(chains.x.shape[0], step), 1, precond,
                                 log_density, rng)
        evaluations += 1
        if prob.mean() >= 0.5 * TARGET_ACCEPT[kernel]:
            break
        step *= 0.5
    return step, evaluations


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
    if kernel not in KERNELS:
        raise ValueError(f"kernel: expected one of {KERNELS}, got {kernel!r}")
    if preconditioner not in PRECONDITIONERS:
        raise ValueError(f"preconditioner: expected one of {PRECONDITIONERS}, got {preconditioner!r}")
    x0 = np.array(initial, dtype=np.float64)
    if x0.ndim != 2 or x0.shape[0] < 2 or x0.shape[1] < 1:
        raise ValueError(f"initial: expected shape (C >= 2, d >= 1), got {x0.shape}")
    if not np.all(np.isfinite(x0)):
        raise ValueError("initial: contains NaN or infinite values")
    num_draws = _check_int("num_draws", num_draws, 1)
    warmup = _check_int("warmup", warmup, 0)
    thin = _check_int("thin", thin, 1)
    seed = _check_int("seed", seed, 0)
    max_leapfrog = _check_int("max_leapfrog", max_leapfrog, 1)
    warmup_max_leapfrog = max_leapfrog if warmup_max_leapfrog is None else \
        _check_int("warmup_max_leapfrog", warmup_max_leapfrog, 1)
    target = TARGET_ACCEPT[kernel] if target_accept is None else float(target_accept)
    if not 0.0 < target < 1.0:
        raise ValueError(f"target_accept: expected a value in (0, 1), got {target_accept!r}")
    if not (np.isfinite(trajectory_length) and trajectory_length > 0):
        raise ValueError(f"trajectory_length: expected a finite value > 0, got {trajectory_length!r}")

    rng = np.random.default_rng(seed)
    num_chains, dim = x0.shape
    need_grad = kernel != "rwm"
    precond = initial_preconditioner if initial_preconditioner is not None else Preconditioner.identity(dim)
    if precond.chol.shape != (dim, dim):
        raise ValueError(f"initial_preconditioner: expected a ({dim}, {dim}) factor, got {precond.chol.shape}")

    log_p, grad = _evaluate(log_density, x0, need_grad)
    if not np.all(np.isfinite(log_p)):
        raise ValueError("initial: log_density is not finite at every starting point")
    chains = _Chains(x0, log_p, grad if need_grad else None)
    evaluations = 1

    def leapfrog_steps(step: float, cap: int = max_leapfrog) -> int:
        return int(np.clip(round(trajectory_length / step), 1, cap)) if kernel == "hmc" else 1

    if warmup > 0:
        step0, spent = _initial_step(kernel, chains, precond, log_density, rng)
    else:
        step0, spent = _default_step(kernel, dim), 0
    evaluations += spent
    adapt = DualAveraging.start(step0, target)
    windows = warmup_windows(warmup) if adapt_preconditioner else []
    window_draws: list[np.ndarray] = []

    total = warmup + num_draws * thin
    draws = np.empty((num_chains, num_draws, dim))
    draw_log_p = np.empty((num_chains, num_draws))
    accepted = np.zeros(num_chains)
    states = np.empty((num_chains, num_draws * thin, dim))  # every post-warm-up state

    for it in range(total):
        in_warmup = it < warmup
        step = adapt.step if in_warmup else adapt.final_step
        # Short warm-up trajectories only until the final buffer: the step size is then tuned
        # with the trajectory length the retained draws use.
        short = in_warmup and (not windows or it < windows[-1][1])
        steps = leapfrog_steps(step, warmup_max_leapfrog if short else max_leapfrog)
        step_c = np.full(num_chains, step)
        if kernel == "hmc":
            step_c = step_c * rng.uniform(0.9, 1.1, size=num_chains)
        chains, accept, prob = _transition(kernel, chains, step_c, steps, precond, log_density, rng)
        evaluations += steps
        if in_warmup:
            adapt = adapt.update(float(prob.mean()))
            if any(start <= it < end for start, end in windows):
                window_draws.append(chains.x.copy())
            if any(it + 1 == end for _, end in windows):
                precond = estimate_preconditioner(np.stack(window_draws, axis=1), preconditioner, precond)
                window_draws = []
                # Restart the adaptation near the current step size: the new metric changes it.
                adapt = DualAveraging.start(adapt.final_step, target, bias=1.0)
        else:
            accepted += accept
            states[:, it - warmup] = chains.x
            k, r = divmod(it - warmup + 1, thin)
            if r == 0:
                draws[:, k - 1] = chains.x
                draw_log_p[:, k - 1] = chains.log_p
        if progress is not None:
            progress(it + 1, total)

    final_step = adapt.final_step if warmup > 0 else step0
    iterations = num_draws * thin
    r_hat = rank_normalized_r_hat(states) if iterations >= 4 else np.full(dim, np.nan)
    ess = bulk_effective_sample_size(states) if iterations >= 8 else np.full(dim, np.nan)
    return MCMCResult(draws=draws, log_density=draw_log_p,
                      acceptance_rate=accepted / (num_draws * thin), step_size=final_step,
                      preconditioner=precond, kernel=kernel, warmup=warmup, thin=thin,
                      num_leapfrog=leapfrog_steps(final_step), num_evaluations=evaluations,
                      r_hat=r_hat, ess=ess)


# --------------------------------------------------------------------------------------------
# Diagnostics
# --------------------------------------------------------------------------------------------


def _check_draws(draws: np.ndarray, min_draws: int) -> np.ndarray:
    x = np.asarray(draws, dtype=np.float64)
    if x.ndim == 2:
        x = x[:, :, None]
    if x.ndim != 3 or x.shape[0] < 1 or x.shape[1] < min_draws:
        raise ValueError(f"draws: expected shape (C, N >= {min_draws}, d), got {np.shape(draws)}")
    if not np.all(np.isfinite(x)):
        raise ValueError("draws: contains NaN or infinite values")
    return x


def split_chains(draws: np.ndarray) -> np.ndarray:
    """Split each chain into halves (the middle draw of an odd chain is dropped).

    Args:
        draws: ``(C, N, d)``, ``N >= 2``.
    Returns:
        ``(2C, N // 2, d)``.
    """
    x = _check_draws(draws, 2)
    half = x.shape[1] // 2
    return np.concatenate([x[:, :half], x[:, x.shape[1] - half:]], axis=0)


def rank_normalize(draws: np.ndarray) -> np.ndarray:
    """Normal scores of the pooled ranks (Vehtari et al. 2021): ``Phi^-1((r - 3/8) / (S + 1/4))``.

    Args:
        draws: ``(C, N, d)``.
    Returns:
        ``(C, N, d)``; ties get their average rank.
    """
    x = _check_draws(draws, 1)
    c, n, d = x.shape
    ranks = rankdata(x.reshape(c * n, d), axis=0)
    return ndtri((ranks - 0.375) / (c * n + 0.25)).reshape(c, n, d)


def _r_hat(chains: np.ndarray) -> np.ndarray:
    """Potential scale reduction over the given chains ``(M, n, d) -> (d,)`` (no splitting)."""
    m, n, _ = chains.shape
    within = chains.var(axis=1, ddof=1).mean(axis=0)
    between = n * chains.mean(axis=1).var(axis=0, ddof=1)
    var_plus = (n - 1) / n * within + between / n
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.sqrt(var_plus / within)
    # Every draw of a coordinate equal: no evidence of non-convergence.
    return np.where((within == 0) & (between == 0), 1.0, r)


def split_r_hat(draws: np.ndarray) -> np.ndarray:
    """Split R-hat (Gelman et al., BDA3, section 11.4) of each coordinate.

    Chains are split in halves, then ``sqrt(var_plus / W)`` with ``W`` the mean within-chain
    variance, ``B`` the between-chain variance of the means (times ``n``) and
    ``var_plus = (n - 1)/n W + B/n``.

    Args:
        draws: ``(C, N, d)`` (or ``(C, N)`` for one coordinate), ``N >= 4``.
    Returns:
        ``(d,)``; ``1`` for a constant coordinate, ``inf`` if chains are constant but differ.
    """
    return _r_hat(split_chains(_check_draws(draws, 4)))


def rank_normalized_r_hat(draws: np.ndarray) -> np.ndarray:
    """Rank-normalised split R-hat (Vehtari et al. 2021): max of the bulk and folded (tail) values.

    Robust to heavy tails and sensitive to chains that differ in scale but not location.

    Args:
        draws: ``(C, N, d)``, ``N >= 4``.
    Returns:
        ``(d,)``.
    """
    x = _check_draws(draws, 4)
    bulk = split_r_hat(rank_normalize(x))
    folded = np.abs(x - np.median(x.reshape(-1, x.shape[2]), axis=0))
    return np.maximum(bulk, split_r_hat(rank_normalize(folded)))


def _autocovariance(x: np.ndarray) -> np.ndarray:
    """Biased autocovariance of each chain and coordinate by FFT; ``(M, n, d) -> (M, n, d)``."""
    n = x.shape[1]
    centred = x - x.mean(axis=1, keepdims=True)
    size = 1 << int(np.ceil(np.log2(2 * n)))
    spectrum = np.fft.rfft(centred, n=size, axis=1)
    return np.fft.irfft(spectrum * np.conj(spectrum), n=size, axis=1)[:, :n] / n


def effective_sample_size(draws: np.ndarray) -> np.ndarray:
    """Multi-chain effective sample size of each coordinate (BDA3 11.5 / Stan), chains as given.

    ``rho_t = 1 - (W - mean_m acov_m(t)) / var_plus``; Geyer's initial positive sequence of pair
    sums ``P_k = rho_2k + rho_2k+1`` truncated at the first negative pair and made monotone
    non-increasing; ``tau = -1 + 2 sum_k P_k``; ``ESS = C N / tau``, capped at
    ``C N log10(C N)`` as in Stan.

    Args:
        draws: ``(C, N, d)`` (or ``(C, N)``), ``N >= 4``.
    Returns:
        ``(d,)``; NaN for a constant coordinate.
    """
    x = _check_draws(draws, 4)
    m, n, d = x.shape
    acov = _autocovariance(x)  # (M, n, d)
    within = acov[:, 0].mean(axis=0) * n / (n - 1)  # mean within-chain variance (ddof=1)
    var_plus = within * (n - 1) / n
    if m > 1:
        var_plus = var_plus + x.mean(axis=1).var(axis=0, ddof=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        rho = 1.0 - (within - acov.mean(axis=0)) / var_plus  # (n, d)
    rho[0] = 1.0
    pairs = n // 2
    sums = rho[0 : 2 * pairs : 2] + rho[1 : 2 * pairs : 2]  # (pairs, d)
    positive = np.cumprod(sums > 0, axis=0).astype(bool)  # initial positive sequence
    monotone = np.minimum.accumulate(np.where(positive, sums, np.inf), axis=0)
    tau = -1.0 + 2.0 * np.sum(np.where(positive, monotone, 0.0), axis=0)
    total = m * n
    tau = np.maximum(tau, 1.0 / np.log10(total)) if total > 1 else tau
    with np.errstate(divide="ignore", invalid="ignore"):
        ess = total / tau
    return np.where(var_plus > 0, ess, np.nan)


def bulk_effective_sample_size(draws: np.ndarray) -> np.ndarray:
    """Bulk ESS (Vehtari et al. 2021): ``effective_sample_size`` of rank-normalised split chains.

    Args:
        draws: ``(C, N, d)``, ``N >= 8``.
    Returns:
        ``(d,)``.
    """
    x = _check_draws(draws, 8)
    return effective_sample_size(rank_normalize(split_chains(x)))
