"""Run until converged (docs/spec.md section 3): extend a fixed-length run's chains in blocks with
the frozen kernel and metric (``mcmc.continue_chains``) until split R-hat and bulk ESS pass on the
latest half of the post-warm-up draws, or the iteration cap (deterministic), the futility rule
(deterministic) or the time budget (a safety stop) ends the run; see :class:`RunUntil`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, NamedTuple

import numpy as np

from ird_core import mcmc
from ird_core.checks import check_int, check_real

__all__ = ["RunUntil", "GIVE_UP_R_HAT", "SamplerRun", "run_until"]

#: ``RunUntil.give_up_after``'s threshold: a window R-hat this far above 1 after that many
#: iterations marks a run that will not converge within its budget (docs/benchmarks.md).
GIVE_UP_R_HAT: float = 1.4

#: Smallest block by which ``RunUntil`` extends the chains unless its ``check_every`` says
#: otherwise (diagnostics cost little, but a block of a few iterations would re-test nearly the
#: same draws).
_MIN_BLOCK: int = 50


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
            small blocks save that; each check costs one diagnostic.
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


class SamplerRun(NamedTuple):
    """The post-warm-up outcome the sampler turns into a ``Posterior``: ``kept`` ``(C, k, d)``
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


def _window_diagnostics(states: np.ndarray, n: int, first: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The diagnostic window, the latest ``max(first, ceil(n / 2))`` of ``n`` iterations of
    ``(C, n, d)`` states, with its R-hat (NaN below 4 draws) and bulk ESS (NaN below 8)."""
    window = states[:, n - max(first, -(-n // 2)):]
    w = window.shape[1]
    r_hat = mcmc.rank_normalized_r_hat(window) if w >= 4 else np.full(states.shape[2], np.nan)
    ess = mcmc.bulk_effective_sample_size(window) if w >= 8 else np.full(states.shape[2], np.nan)
    return window, r_hat, ess


def _stop_reason(rule: RunUntil, r_hat: np.ndarray, ess: np.ndarray, need: float, n: int, cap: int,
                 started: float) -> str:
    """Why the run stops after ``n`` iterations (``""``: extend it), checked in this order."""
    if np.max(r_hat) <= rule.r_hat and np.nanmin(ess, initial=np.inf) >= need and not np.any(np.isnan(ess)):
        return "converged"
    if rule.give_up_after and n >= rule.give_up_after and np.max(r_hat) > GIVE_UP_R_HAT:
        return "futile"
    if n >= cap:
        return "max_iterations"
    if rule.time_budget_s is not None and time.monotonic() - started >= rule.time_budget_s:
        return "time_budget"
    return ""


def _block_progress(progress: "Callable[[int, int], None] | None", done: int, step: int
                    ) -> "Callable[[int, int], None] | None":
    """A block's ``progress(i, step)`` reported as ``progress(done + i, done + step)``."""
    return None if progress is None else (lambda i, _t: progress(done + i, done + step))


def _kept_draws(window: int, per_chain: int, evenly: bool) -> tuple[np.ndarray, int]:
    """Indices of the ``per_chain`` draws kept from a window of ``window`` iterations, and the thinning."""
    if evenly:
        return np.round(np.linspace(0, window - 1, per_chain)).astype(np.int64), 1
    thin = window // per_chain
    return window - 1 - thin * np.arange(per_chain - 1, -1, -1), thin


def run_until(target: mcmc.LogDensityFn, starts: np.ndarray, first: int, per_chain: int, evenly: bool,
              rule: RunUntil, num_samples: int, started: float, chains: dict) -> SamplerRun:
    """Run ``first`` post-warm-up iterations, then extend the same chains until ``rule`` passes
    on the window or a bound stops them (``RunUntil``); keep ``per_chain`` draws of the window.

    ``chains``: ``mcmc.sample_chains``' keywords (``progress`` included). ``evenly`` picks the
    kept draws as the warm start does (``linspace`` over the window), else as integer thinning
    ending at the last iteration, so the first check reproduces the fixed-length run's draws
    exactly.
    """
    progress = chains.pop("progress")
    result = mcmc.sample_chains(target, starts, first, thin=1, progress=progress, **chains)
    states, accepted, evaluations = result.draws, result.acceptance_rate * first, result.num_evaluations
    n, last, need = first, result, rule.required_ess(num_samples)
    cap, block = max(rule.max_iterations, first), rule.check_every or max(first, _MIN_BLOCK)
    while True:
        window, r_hat, ess = _window_diagnostics(states, n, first)
        reason = _stop_reason(rule, r_hat, ess, need, n, cap, started)
        if reason:
            break
        step = min(block, cap - n)
        last = mcmc.continue_chains(target, last.continuation, step,
                                    progress=_block_progress(progress, chains["warmup"] + n, step))
        states = np.concatenate([states, last.draws], axis=1)
        accepted, evaluations, n = accepted + last.acceptance_rate * step, evaluations + last.num_evaluations, n + step
    kept, thin = _kept_draws(window.shape[1], per_chain, evenly)
    acceptance = float(result.acceptance_rate.mean()) if n == first else float((accepted / n).mean())
    return SamplerRun(window[:, kept], r_hat, ess, acceptance, last, evaluations, thin, n, reason)
