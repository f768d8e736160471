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

#: With a time budget, the iterations of the first run that always complete before the budget
#: is first checked: the library's default fixed-length run (``DEFAULT_MIN_ITERATIONS``: 120
#: MaxEnt-Z, 100 Sample-Z), so a small request's first check is always that run's.
_FIRST_UNCUT: int = 120

#: With a time budget the chains advance in sub-blocks of about this many wall seconds
#: (measured on the previous block) and the budget is checked after each, in the first run
#: too: a run that asks for many samples per chain stops within about this much of its budget.
_BUDGET_STRIDE_S: float = 0.5


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
    (wall seconds of the whole call, from before the model is built) is only a safety stop and
    makes the result machine-dependent when it is hit. It is checked after the warm-up and the
    first ``min(n0, 120)`` iterations, then every ``_BUDGET_STRIDE_S`` (0.5 s) of sampling, in
    the first run as in the extension (so it holds for any number of samples); the draws are
    the same sub-blocks or not. Either way the posterior says so (``converged`` False,
    ``stop_reason``); a budget spent before every chain has ``ceil(num_samples / C)`` draws is
    a ``ValueError`` naming ``num_samples`` (there is nothing to return).

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
    ``(C, n, d)`` states (all of them while ``n < first``), with its R-hat (NaN below 4 draws)
    and bulk ESS (NaN below 8)."""
    window = states[:, max(0, n - max(first, -(-n // 2))):]
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


def _kept_draws(window: int, per_chain: int, evenly: bool) -> tuple[np.ndarray, int]:
    """Indices of the ``per_chain`` draws kept from a window of ``window`` iterations, and the thinning."""
    if evenly:
        return np.round(np.linspace(0, window - 1, per_chain)).astype(np.int64), 1
    thin = window // per_chain
    return window - 1 - thin * np.arange(per_chain - 1, -1, -1), thin


def _with_total(progress: "Callable[[int, int], None] | None", done: int, total: int
                ) -> "Callable[[int, int], None] | None":
    """A block's ``progress(i, step)`` reported as ``progress(done + i, total)``."""
    return None if progress is None else (lambda i, _t: progress(done + i, total))


class _Chains:
    """The post-warm-up chains as they grow: their states in pieces, exact accepted counts,
    evaluations, the first run's result and the latest one (whose continuation extends them)."""

    def __init__(self, head: mcmc.MCMCResult, iterations: int, seconds: float) -> None:
        self.pieces, self.n, self.head, self.last = [head.draws], iterations, head, head
        self.accepted = np.rint(head.acceptance_rate * iterations)
        self.evaluations = head.num_evaluations
        self.seconds_per_iteration = seconds / max(iterations, 1)

    def extend(self, target: mcmc.LogDensityFn, step: int, progress: "Callable[[int, int], None] | None") -> None:
        t0 = time.monotonic()
        self.last = mcmc.continue_chains(target, self.last.continuation, step, progress=progress)
        self.seconds_per_iteration = (time.monotonic() - t0) / step
        self.pieces.append(self.last.draws)
        self.accepted += np.rint(self.last.acceptance_rate * step)
        self.evaluations += self.last.num_evaluations
        self.n += step

    def states(self) -> np.ndarray:
        if len(self.pieces) > 1:
            self.pieces = [np.concatenate(self.pieces, axis=1)]
        return self.pieces[0]


def _spent(rule: RunUntil, started: float) -> bool:
    return rule.time_budget_s is not None and time.monotonic() - started >= rule.time_budget_s


def _advance(chains: _Chains, target: mcmc.LogDensityFn, until: int, rule: RunUntil, started: float,
             progress: "Callable[[int, int], None] | None", done: int) -> None:
    """Extend the chains to ``until`` iterations: in one block without a time budget; with one,
    in sub-blocks of about ``_BUDGET_STRIDE_S`` seconds, stopping early once the budget is spent
    (the draws do not depend on the sub-blocks: ``continue_chains`` continues the same stream)."""
    while chains.n < until and not _spent(rule, started):
        step = until - chains.n
        if rule.time_budget_s is not None:
            step = min(step, max(1, int(_BUDGET_STRIDE_S / max(chains.seconds_per_iteration, 1e-9))))
        chains.extend(target, step, _with_total(progress, done + chains.n, done + until))


def run_until(target: mcmc.LogDensityFn, starts: np.ndarray, first: int, per_chain: int, evenly: bool,
              rule: RunUntil, num_samples: int, started: float, chains: dict) -> SamplerRun:
    """Run ``first`` post-warm-up iterations, then extend the same chains until ``rule`` passes
    on the window or a bound stops them (``RunUntil``); keep ``per_chain`` draws of the window.

    ``chains``: ``mcmc.sample_chains``' keywords (``progress`` included). ``evenly`` picks the
    kept draws as the warm start does (``linspace`` over the window), else as integer thinning
    ending at the last iteration, so the first check reproduces the fixed-length run's draws
    exactly. With a time budget the first run too is checked against it (after its first
    ``_FIRST_UNCUT`` iterations, then every sub-block); a budget spent before the chains hold
    ``per_chain`` draws each leaves nothing to return.

    Raises:
        ValueError: naming ``num_samples`` when the time budget ran out before ``per_chain``
            iterations per chain.
    """
    progress = chains.pop("progress")
    warmup = chains["warmup"]
    head = first if rule.time_budget_s is None else min(first, _FIRST_UNCUT)
    t0 = time.monotonic()
    result = mcmc.sample_chains(target, starts, head, thin=1, progress=_with_total(progress, 0, warmup + first),
                                **chains)
    run = _Chains(result, head, time.monotonic() - t0)
    need = rule.required_ess(num_samples)
    cap, block = max(rule.max_iterations, first), rule.check_every or max(first, _MIN_BLOCK)
    check_at = first
    while True:
        _advance(run, target, check_at, rule, started, progress, warmup)
        n = run.n
        if n < per_chain:
            raise ValueError(f"num_samples: the time budget of {rule.time_budget_s:g} s ran out after {n} "
                             f"iterations per chain, fewer than the {per_chain} that {num_samples} samples from "
                             f"{starts.shape[0]} chains need: ask for fewer samples")
        window, r_hat, ess = _window_diagnostics(run.states(), n, first)
        reason = _stop_reason(rule, r_hat, ess, need, n, cap, started)
        if reason:
            break
        check_at = n + min(block, cap - n)
    kept, thin = _kept_draws(window.shape[1], per_chain, evenly)
    acceptance = float((run.accepted / n).mean())
    last = run.head if n <= head else run.last  # the fixed-length run's own result when it was not extended
    return SamplerRun(window[:, kept], r_hat, ess, acceptance, last, run.evaluations, thin, n, reason)
