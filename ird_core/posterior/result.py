"""The posterior sampler's result (docs/spec.md sections 3 and 7): :class:`Posterior`, the pooled
draws and how they were obtained, and its convergence verdict."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ird_core.posterior import run_until as convergence_rules

__all__ = ["R_HAT_CONVERGED", "R_HAT_CAP", "Posterior", "pool_draws"]

#: A run with a larger maximum split R-hat is reported as not converged.
R_HAT_CONVERGED: float = 1.1
#: R-hat values above this are stored as this (``inf`` is not representable in ROS messages).
R_HAT_CAP: float = 1e6


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
    run_until: "convergence_rules.RunUntil | None" = None
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
                 f"given up (R-hat above {convergence_rules.GIVE_UP_R_HAT:g})" if self.stop_reason == "futile" else "stopped")
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
