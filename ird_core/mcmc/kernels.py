"""MCMC transition kernels for a batch of chains, shaped like blackjax: ``init``/``step`` pairs.

A target is a function ``log_density(x (C, d)) -> (log p (C,), grad (C, d) | None)`` evaluated on
every chain at once, so each step costs ONE batched call (``L`` calls for HMC with ``L`` leapfrog
steps). The gradient may be any deterministic vector field: MALA and HMC stay exact (the
Metropolis-Hastings correction uses the same field at both ends), only their efficiency depends on
how well it matches ``grad log p``.

Each kernel is a ``Kernel`` in ``KERNEL_TABLE``:

- ``init(position (C, d), log_density) -> ChainState`` evaluates the target at the start;
- ``step(rng, state, log_density, params) -> (ChainState, StepInfo)`` makes one Metropolis-Hastings
  transition of every chain with ``KernelParams`` (per-chain step size, preconditioner, leapfrog
  steps) fixed by the caller, who owns adaptation.

Kernels (one operator each):

- ``rwm``: random-walk Metropolis, ``x' = x + h L z``.
- ``mala``: Metropolis-adjusted Langevin, ``x' = x + h^2/2 M g(x) + h L z``.
- ``hmc``: Hamiltonian Monte Carlo with ``L`` leapfrog steps in whitened coordinates.
- ``elliptical``: generalised elliptical slice sampling (Murray, Adams & MacKay 2010; Nishihara,
  Murray & Adams 2014): the target is written ``N(x; m, M) * exp(r(x))`` with the
  preconditioner's Gaussian ``N(m, M)`` (its ``mean`` and covariance) and the residual
  ``r = log p - log N(m, M)``, and a slice move on the ellipse through ``x`` and a draw of
  ``N(m, M)`` leaves the target invariant. No gradient and no step size; it is never rejected,
  and it shrinks its angle bracket until the residual clears the slice, one batched call per
  shrink, so it stays valid and keeps moving on targets whose log density has creases (the
  Sample-Z likelihood at large beta) where gradient kernels need tiny steps.
- ``independence``: independence Metropolis-Hastings with a multivariate Student-t proposal
  ``t_nu(m, w^2 M)`` around the preconditioner's Gaussian (``nu = INDEPENDENCE_DOF``,
  ``w = INDEPENDENCE_WIDTH``): one batched call per step, no gradient, no step size, and a
  proposal that does not depend on the current point, so creases cost nothing. Efficient only
  while the t covers the target well, which in practice means a few dimensions: with a fitted
  ``(m, M)`` it accepted ~30% on the d = 4 Sample-Z posteriors at beta 50, where the elliptical
  kernel needed ~18 calls per step.
- ``independence_elliptical``: an ``independence`` step, then an ``elliptical`` step around the
  same ``(m, M)`` (a composition of two invariant kernels is invariant). The independence move
  jumps across the target; the slice move keeps a chain moving where the t proposal is too thin
  (without it a chain that reaches such a region sits there for hundreds of steps).

Here ``z ~ N(0, I)``, ``M = L L^T`` is a preconditioner (an estimate of the posterior
covariance) and ``h`` a step size. Random numbers are drawn in a fixed order (proposal normals,
then the acceptance uniforms) so that a seed fixes the draws.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from typing import Callable, NamedTuple

import numpy as np
from scipy.linalg import solve_triangular

__all__ = [
    "KERNELS",
    "KERNEL_TABLE",
    "PRECONDITIONERS",
    "TARGET_ACCEPT",
    "DIVERGENCE_THRESHOLD",
    "ELLIPTICAL_MAX_SHRINKS",
    "ELLIPTICAL_WIDTH",
    "LogDensityFn",
    "Preconditioner",
    "ChainState",
    "StepInfo",
    "KernelParams",
    "Kernel",
    "rwm_proposal",
    "mala_mean",
    "mala_log_proposal",
    "leapfrog",
    "metropolis_accept",
    "rwm_init",
    "gradient_init",
    "rwm_step",
    "mala_step",
    "hmc_step",
    "elliptical_residual",
    "elliptical_step",
    "INDEPENDENCE_DOF",
    "INDEPENDENCE_WIDTH",
    "independence_log_proposal",
    "independence_step",
    "independence_elliptical_step",
    "get_kernel",
    "num_leapfrog_steps",
    "step_sizes",
]

#: ``x (C, d) -> (log p (C,), grad (C, d) or None)``.
LogDensityFn = Callable[[np.ndarray], "tuple[np.ndarray, np.ndarray | None]"]

PRECONDITIONERS: tuple[str, ...] = ("identity", "diag", "dense")
#: A transition whose energy error (minus the log Metropolis-Hastings ratio) exceeds this many nats
#: is flagged divergent, as in Stan and blackjax.
DIVERGENCE_THRESHOLD = 1000.0


# --------------------------------------------------------------------------------------------
# Preconditioner
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Preconditioner:
    """A linear change of variables ``x = L u`` with ``M = L L^T`` (posterior covariance estimate).

    Attributes:
        chol: ``(d, d)`` lower-triangular ``L`` (diagonal for ``diag``/``identity``).
        kind: one of ``PRECONDITIONERS``.
        mean: ``(d,)`` centre of the Gaussian approximation ``N(mean, M)`` the ``elliptical``
            kernel slices around (the gradient kernels use ``L`` only); None = the origin.
    """

    chol: np.ndarray
    kind: str = "dense"
    mean: "np.ndarray | None" = None

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

    @property
    def centre(self) -> np.ndarray:
        """``mean``, or zeros; ``(d,)``."""
        return np.zeros(len(self.chol)) if self.mean is None else self.mean


# --------------------------------------------------------------------------------------------
# Operators
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
# Kernels: init / step pairs
# --------------------------------------------------------------------------------------------


class ChainState(NamedTuple):
    """State of ``C`` chains.

    Attributes:
        position: ``(C, d)``.
        log_density: ``(C,)`` target values at ``position``.
        gradient: ``(C, d)`` target field at ``position``; None for kernels that need none (RWM).
    """

    position: np.ndarray
    log_density: np.ndarray
    gradient: "np.ndarray | None"


class StepInfo(NamedTuple):
    """What one transition of ``C`` chains did.

    Attributes:
        acceptance_probability: ``(C,)`` ``min(1, MH ratio)``.
        is_accepted: ``(C,)`` booleans.
        is_divergent: ``(C,)`` booleans: energy error above ``DIVERGENCE_THRESHOLD`` or NaN.
        num_evaluations: batched ``log_density`` calls made.
    """

    acceptance_probability: np.ndarray
    is_accepted: np.ndarray
    is_divergent: np.ndarray
    num_evaluations: int


class KernelParams(NamedTuple):
    """Parameters of one transition, set by the caller (the warm-up adapts them).

    Attributes:
        step_size: ``(C,)`` step size ``h`` of each chain.
        preconditioner: ``M = L L^T``.
        num_leapfrog: leapfrog steps (HMC only).
    """

    step_size: np.ndarray
    preconditioner: Preconditioner
    num_leapfrog: int = 1


class Kernel(NamedTuple):
    """An MCMC kernel: its ``init``/``step`` pair and what the warm-up needs to tune it.

    Attributes:
        init: ``(position (C, d), log_density) -> ChainState``.
        step: ``(rng, state, log_density, params) -> (ChainState, StepInfo)``.
        target_accept: default target of the mean acceptance probability.
        default_step: ``dim -> h``, the optimal-scaling step for a standard normal target.
        step_jitter: range of a uniform factor applied to each chain's step at every iteration, or None.
        uses_trajectory: True if ``num_leapfrog`` follows the trajectory length (HMC).
        needs_gradient: False if the step uses the log density only (RWM, elliptical).
        tunes_step: False if the step has no step size to adapt (elliptical: it never rejects).
    """

    init: Callable[[np.ndarray, LogDensityFn], ChainState]
    step: Callable[[np.random.Generator, ChainState, LogDensityFn, KernelParams], "tuple[ChainState, StepInfo]"]
    target_accept: float
    default_step: Callable[[int], float]
    step_jitter: "tuple[float, float] | None" = None
    uses_trajectory: bool = False
    needs_gradient: bool = True
    tunes_step: bool = True


def _evaluate(log_density: LogDensityFn, x: np.ndarray, need_grad: bool
              ) -> "tuple[np.ndarray, np.ndarray | None]":
    log_p, grad = log_density(x)
    log_p = np.asarray(log_p, dtype=np.float64).reshape(x.shape[0])
    if need_grad:
        if grad is None:
            raise ValueError("log_density: this kernel needs a gradient, got None")
        grad = np.asarray(grad, dtype=np.float64).reshape(x.shape)
    return log_p, grad


def rwm_init(position: np.ndarray, log_density: LogDensityFn) -> ChainState:
    """State of a gradient-free kernel at ``position`` ``(C, d)``: one batched call."""
    log_p, _ = _evaluate(log_density, position, need_grad=False)
    return ChainState(position, log_p, None)


def gradient_init(position: np.ndarray, log_density: LogDensityFn) -> ChainState:
    """State of a gradient kernel (MALA, HMC) at ``position`` ``(C, d)``: one batched call."""
    log_p, grad = _evaluate(log_density, position, need_grad=True)
    return ChainState(position, log_p, grad)


def _metropolis_step(rng: np.random.Generator, state: ChainState, proposal: np.ndarray, log_p: np.ndarray,
                     grad: "np.ndarray | None", log_ratio: np.ndarray, num_evaluations: int
                     ) -> tuple[ChainState, StepInfo]:
    """Accept or reject every chain's proposal ``(C, d)`` given its log MH ratio ``(C,)``."""
    accept, prob = metropolis_accept(log_ratio, rng.random(state.position.shape[0]))
    keep = accept[:, None]
    new = ChainState(np.where(keep, proposal, state.position), np.where(accept, log_p, state.log_density),
                     None if state.gradient is None else np.where(keep, grad, state.gradient))
    divergent = ~(log_ratio > -DIVERGENCE_THRESHOLD)  # NaN counts as divergent
    return new, StepInfo(prob, accept, divergent, num_evaluations)


def _gradient_of(state: ChainState, kernel: str) -> np.ndarray:
    if state.gradient is None:
        raise ValueError(f"state: {kernel} needs a gradient, got None (initialise with gradient_init)")
    return state.gradient


def rwm_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn, params: KernelParams
             ) -> tuple[ChainState, StepInfo]:
    """One random-walk Metropolis transition of every chain (one batched call)."""
    z = rng.standard_normal(state.position.shape)
    proposal = rwm_proposal(state.position, z, params.step_size, params.preconditioner)
    log_p, _ = _evaluate(log_density, proposal, need_grad=False)
    return _metropolis_step(rng, state, proposal, log_p, None, log_p - state.log_density, 1)


def mala_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn, params: KernelParams
              ) -> tuple[ChainState, StepInfo]:
    """One Metropolis-adjusted Langevin transition of every chain (one batched call)."""
    h, precond = params.step_size, params.preconditioner
    z = rng.standard_normal(state.position.shape)
    proposal = mala_mean(state.position, _gradient_of(state, "mala"), h, precond) + np.reshape(h, (-1, 1)) * precond.scale(z)
    log_p, grad = _evaluate(log_density, proposal, need_grad=True)
    forward = -0.5 * np.sum(z**2, axis=1)
    backward = mala_log_proposal(state.position, mala_mean(proposal, grad, h, precond), h, precond)
    return _metropolis_step(rng, state, proposal, log_p, grad, log_p - state.log_density + backward - forward, 1)


def hmc_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn, params: KernelParams
             ) -> tuple[ChainState, StepInfo]:
    """One HMC transition of every chain: ``params.num_leapfrog`` batched calls."""
    z = rng.standard_normal(state.position.shape)
    target = partial(_evaluate, log_density, need_grad=True)
    proposal, p_end, log_p, grad = leapfrog(state.position, z, _gradient_of(state, "hmc"), params.step_size,
                                            params.num_leapfrog, target, params.preconditioner)
    log_ratio = (log_p - 0.5 * np.sum(p_end**2, axis=1)) - (state.log_density - 0.5 * np.sum(z**2, axis=1))
    return _metropolis_step(rng, state, proposal, log_p, grad, log_ratio, params.num_leapfrog)


#: Shrinks of the elliptical bracket before a chain gives up and stays put (the bracket is then
#: ``2 pi / 2^50`` wide; never reached on a continuous target, whose slice contains a
#: neighbourhood of the current point).
ELLIPTICAL_MAX_SHRINKS = 50


#: The elliptical kernel slices around ``N(m, w^2 M)``, ``w`` this factor: wider than the
#: covariance estimate so that chains can spread out when the estimate is too narrow (an
#: ellipse never leaves the span of ``x - m`` and the reference draw), at the price of a few
#: more shrinks when it is right.
ELLIPTICAL_WIDTH: float = 1.5


def elliptical_residual(log_p: np.ndarray, x: np.ndarray, precond: Preconditioner) -> np.ndarray:
    """``r(x) = log p(x) - log N(x; m, w^2 M)`` up to a constant (``w = ELLIPTICAL_WIDTH``):
    ``log p + |L^-1 (x - m)|^2 / (2 w^2)``; ``(C,), (C, d) -> (C,)``."""
    u = precond.whiten(x - precond.centre)
    return log_p + 0.5 * np.sum(u**2, axis=1) / ELLIPTICAL_WIDTH**2


def elliptical_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn,
                    params: KernelParams) -> tuple[ChainState, StepInfo]:
    """One generalised elliptical slice move of every chain (Murray et al. 2010, Figure 2).

    With ``m``, ``L`` from ``params.preconditioner``, draws ``nu = L z`` and a slice level
    ``y = r(x) + log U``, then proposes ``m + (x - m) cos t + nu sin t`` for ``t`` uniform on a
    bracket ``[t - 2 pi, t]`` that shrinks towards 0 after each rejected angle, until
    ``r > y``. Every shrink is one batched call on the chains still searching. The step size
    and leapfrog count are ignored. Random numbers in a fixed order: ``z``, the uniforms of the
    level, the first angles, then one uniform per searching chain per shrink.
    """
    x, precond = state.position, params.preconditioner
    num_chains = x.shape[0]
    centre = precond.centre
    nu = ELLIPTICAL_WIDTH * precond.scale(rng.standard_normal(x.shape))
    level = elliptical_residual(state.log_density, x, precond) + np.log(rng.random(num_chains))
    angle = rng.uniform(0.0, 2.0 * np.pi, num_chains)
    low, high = angle - 2.0 * np.pi, angle.copy()
    position, log_p = x.copy(), state.log_density.copy()
    searching = np.arange(num_chains)
    evaluations = 0
    for _ in range(ELLIPTICAL_MAX_SHRINKS):
        t = angle[searching][:, None]
        proposal = centre + (x[searching] - centre) * np.cos(t) + nu[searching] * np.sin(t)
        value, _ = _evaluate(log_density, proposal, need_grad=False)
        evaluations += 1
        accept = elliptical_residual(value, proposal, precond) > level[searching]  # NaN: shrink
        done = searching[accept]
        position[done], log_p[done] = proposal[accept], value[accept]
        searching = searching[~accept]
        if len(searching) == 0:
            break
        below = angle[searching] < 0.0
        low[searching] = np.where(below, angle[searching], low[searching])
        high[searching] = np.where(below, high[searching], angle[searching])
        angle[searching] = rng.uniform(low[searching], high[searching])
    moved = np.ones(num_chains, dtype=bool)
    moved[searching] = False  # out of shrinks: stay (valid: the current point is on its slice)
    return (ChainState(position, log_p, None),
            StepInfo(np.ones(num_chains), moved, np.zeros(num_chains, dtype=bool), evaluations))


#: Degrees of freedom of the independence kernel's Student-t: heavy tails, so that a target wider
#: than the fitted Gaussian in some direction is still proposed there (a proposal lighter-tailed
#: than the target makes the tails sticky).
INDEPENDENCE_DOF: float = 5.0
#: The independence kernel proposes from ``t_nu(m, w^2 M)``, ``w`` this factor (wider than the
#: covariance estimate, for the same reason as ``ELLIPTICAL_WIDTH``).
INDEPENDENCE_WIDTH: float = 1.2


def independence_log_proposal(x: np.ndarray, precond: Preconditioner) -> np.ndarray:
    """``log t_nu(x; m, w^2 M)`` up to a constant: ``-(nu + d)/2 log(1 + |L^-1 (x - m)|^2 / (w^2 nu))``;
    ``(C, d) -> (C,)``."""
    u = precond.whiten(x - precond.centre) / INDEPENDENCE_WIDTH
    return -0.5 * (INDEPENDENCE_DOF + x.shape[1]) * np.log1p(np.sum(u**2, axis=1) / INDEPENDENCE_DOF)


def independence_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn,
                      params: KernelParams) -> tuple[ChainState, StepInfo]:
    """One independence Metropolis-Hastings transition of every chain (one batched call).

    Proposes ``y = m + w L z / sqrt(g / nu)`` (``z ~ N(0, I)``, ``g ~ chi^2_nu``) and accepts with
    ``p(y) q(x) / (p(x) q(y))``. ``q`` is evaluated at the current point under the CURRENT
    preconditioner, so the warm-up may change ``(m, M)`` between steps. Random numbers in a fixed
    order: ``z``, ``g``, then the acceptance uniforms.
    """
    x, precond = state.position, params.preconditioner
    z = rng.standard_normal(x.shape)
    g = rng.chisquare(INDEPENDENCE_DOF, size=(x.shape[0], 1))
    proposal = precond.centre + INDEPENDENCE_WIDTH * precond.scale(z / np.sqrt(g / INDEPENDENCE_DOF))
    log_p, _ = _evaluate(log_density, proposal, need_grad=False)
    log_ratio = (log_p - independence_log_proposal(proposal, precond)) - \
        (state.log_density - independence_log_proposal(x, precond))
    return _metropolis_step(rng, state, proposal, log_p, None, log_ratio, 1)


def independence_elliptical_step(rng: np.random.Generator, state: ChainState, log_density: LogDensityFn,
                                 params: KernelParams) -> tuple[ChainState, StepInfo]:
    """``independence_step`` then ``elliptical_step`` (one call, then one per shrink). The
    reported acceptance is the independence step's (the slice step always moves)."""
    jumped, jump = independence_step(rng, state, log_density, params)
    moved, slide = elliptical_step(rng, jumped, log_density, params)
    return moved, jump._replace(num_evaluations=jump.num_evaluations + slide.num_evaluations)


#: The kernels by name. Target acceptance: RWM and MALA from the optimal-scaling results of
#: Roberts, Gelman & Gilks (1997) and Roberts & Rosenthal (1998); HMC as Stan's default. HMC's
#: step is jittered by +-10% at every iteration so that no fixed trajectory length resonates with
#: the target.
KERNEL_TABLE: dict[str, Kernel] = {
    "rwm": Kernel(rwm_init, rwm_step, 0.234, lambda dim: 2.38 / np.sqrt(dim), needs_gradient=False),
    "mala": Kernel(gradient_init, mala_step, 0.574, lambda dim: 1.65 * dim ** (-1.0 / 3.0)),
    "hmc": Kernel(gradient_init, hmc_step, 0.8, lambda dim: dim ** (-0.25), step_jitter=(0.9, 1.1),
                  uses_trajectory=True),
    # No step size: the slice shrinks its own bracket; only the Gaussian (mean, metric) adapts.
    "elliptical": Kernel(rwm_init, elliptical_step, 1.0, lambda dim: 1.0, needs_gradient=False, tunes_step=False),
    # No step size either: the proposal is the fitted (m, M) itself.
    "independence": Kernel(rwm_init, independence_step, 1.0, lambda dim: 1.0, needs_gradient=False,
                           tunes_step=False),
    "independence_elliptical": Kernel(rwm_init, independence_elliptical_step, 1.0, lambda dim: 1.0,
                                      needs_gradient=False, tunes_step=False),
}
KERNELS: tuple[str, ...] = tuple(KERNEL_TABLE)
TARGET_ACCEPT: dict[str, float] = {name: k.target_accept for name, k in KERNEL_TABLE.items()}


def get_kernel(name: str) -> Kernel:
    """The kernel called ``name``; ValueError naming the ``kernel`` field otherwise."""
    if not isinstance(name, str) or name not in KERNEL_TABLE:
        raise ValueError(f"kernel: expected one of {KERNELS}, got {name!r}")
    return KERNEL_TABLE[name]


def num_leapfrog_steps(kernel: Kernel, step: float, trajectory_length: float, cap: int) -> int:
    """``clip(round(trajectory_length / step), 1, cap)`` for HMC, 1 for the other kernels."""
    return int(np.clip(round(trajectory_length / step), 1, cap)) if kernel.uses_trajectory else 1


def step_sizes(kernel: Kernel, step: float, num_chains: int, rng: np.random.Generator) -> np.ndarray:
    """Per-chain step sizes ``(C,)``: ``step`` times the kernel's random jitter factor, if any."""
    steps = np.full(num_chains, step)
    if kernel.step_jitter is not None:
        steps = steps * rng.uniform(*kernel.step_jitter, size=num_chains)
    return steps
