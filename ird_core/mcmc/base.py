"""The shared vocabulary of the MCMC kernels (blackjax's ``base``): the batched target, the
preconditioner, the NamedTuple chain state, step info and parameters, the ``Kernel`` record, and
the Metropolis-Hastings correction every kernel but the slice move ends with.

A target is a function ``log_density(x (C, d)) -> (log p (C,), grad (C, d) | None)`` evaluated on
every chain at once, so each step costs ONE batched call (``L`` calls for HMC with ``L`` leapfrog
steps). The gradient may be any deterministic vector field: MALA and HMC stay exact (the
Metropolis-Hastings correction uses the same field at both ends), only their efficiency depends on
how well it matches ``grad log p``.

Here ``z ~ N(0, I)``, ``M = L L^T`` is a preconditioner (an estimate of the posterior
covariance) and ``h`` a step size. Random numbers are drawn in a fixed order (proposal normals,
then the acceptance uniforms) so that a seed fixes the draws.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np
from scipy.linalg import solve_triangular

__all__ = [
    "LogDensityFn",
    "PRECONDITIONERS",
    "DIVERGENCE_THRESHOLD",
    "Preconditioner",
    "ChainState",
    "StepInfo",
    "KernelParams",
    "Kernel",
    "evaluate",
    "rwm_init",
    "gradient_init",
    "metropolis_accept",
    "metropolis_step",
    "gradient_of",
]

#: ``x (C, d) -> (log p (C,), grad (C, d) or None)``.
LogDensityFn = Callable[[np.ndarray], "tuple[np.ndarray, np.ndarray | None]"]

PRECONDITIONERS: tuple[str, ...] = ("identity", "diag", "dense")
#: A transition whose energy error (minus the log Metropolis-Hastings ratio) exceeds this many nats
#: is flagged divergent, as in Stan and blackjax.
DIVERGENCE_THRESHOLD = 1000.0


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


def evaluate(log_density: LogDensityFn, x: np.ndarray, need_grad: bool
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
    log_p, _ = evaluate(log_density, position, need_grad=False)
    return ChainState(position, log_p, None)


def gradient_init(position: np.ndarray, log_density: LogDensityFn) -> ChainState:
    """State of a gradient kernel (MALA, HMC) at ``position`` ``(C, d)``: one batched call."""
    log_p, grad = evaluate(log_density, position, need_grad=True)
    return ChainState(position, log_p, grad)


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


def metropolis_step(rng: np.random.Generator, state: ChainState, proposal: np.ndarray, log_p: np.ndarray,
                     grad: "np.ndarray | None", log_ratio: np.ndarray, num_evaluations: int
                     ) -> tuple[ChainState, StepInfo]:
    """Accept or reject every chain's proposal ``(C, d)`` given its log MH ratio ``(C,)``."""
    accept, prob = metropolis_accept(log_ratio, rng.random(state.position.shape[0]))
    keep = accept[:, None]
    new = ChainState(np.where(keep, proposal, state.position), np.where(accept, log_p, state.log_density),
                     None if state.gradient is None else np.where(keep, grad, state.gradient))
    divergent = ~(log_ratio > -DIVERGENCE_THRESHOLD)  # NaN counts as divergent
    return new, StepInfo(prob, accept, divergent, num_evaluations)


def gradient_of(state: ChainState, kernel: str) -> np.ndarray:
    if state.gradient is None:
        raise ValueError(f"state: {kernel} needs a gradient, got None (initialise with gradient_init)")
    return state.gradient
