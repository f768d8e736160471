#!/usr/bin/env python3
"""Benchmark: our convergence diagnostics (``ird_core.mcmc.diagnostics``) against arviz-stats 0.8.

For each size of the run-until loop (``C`` chains in {4, 8}, ``N`` draws in {16, 64, 256, 1024},
``d`` coordinates in {4, 50}) it times one check, i.e. the rank-normalised split R-hat plus the
bulk ESS of ``(C, N, d)`` AR(1) draws, with ours and with arviz-stats' numpy-only array interface
(``arviz_stats.base.array_stats``), the two interleaved (their order alternating) in the same
run, and prints the min and median ms per call, their ratio (arviz-stats / ours) and how far the
numbers are apart (max |R-hat difference|, max relative bulk-ESS difference). Rely on the ratios
on a busy machine: both sides see the same load.

    python scripts/bench_diagnostics.py [--repeats 15] [--seed 0]
    python scripts/bench_diagnostics.py --decisions 0 1 2   # plus real posterior draws (below)

``--decisions SEEDS``: on Lavaland posteriors (MaxEnt-Z at the experiments' settings: beta 50,
64 samples, 4 chains in d = 50; and 8 chains in d = 4) the run-until loop is run to its cap
(every window recorded, never stopping), then both implementations judge every window: the
iteration at which R-hat <= 1.05 and bulk ESS >= 32 first hold, with each, and the sampler's
wall time per block of 16 iterations beside one check's time.

Needs arviz-stats (``pip install arviz-stats==0.8.0``, numpy and scipy only); without it the
script prints that command and exits 2.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from typing import Callable, Sequence

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402
from scipy.signal import lfilter  # noqa: E402

from ird_core.mcmc import diagnostics  # noqa: E402

INSTALL = "pip install arviz-stats==0.8.0"
CHAINS, DRAWS, DIMS = (4, 8), (16, 64, 256, 1024), (4, 50)
#: The run-until loop's thresholds in the experiments (RUN_UNTIL_R_HAT, ESS of 64 samples / 2).
R_HAT_OK, ESS_OK, BLOCK = 1.05, 32.0, 16

Check = Callable[[np.ndarray], "tuple[np.ndarray, np.ndarray]"]


def load_arviz_stats() -> "object | None":
    """arviz-stats' numpy array interface, or None when it is not installed."""
    try:
        from arviz_stats.base import array_stats
    except ImportError:
        return None
    return array_stats


def ours(draws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One run-until check with ``ird_core.mcmc.diagnostics``: ``(R-hat, bulk ESS)``, each ``(d,)``."""
    return diagnostics.rank_normalized_r_hat(draws), diagnostics.bulk_effective_sample_size(draws)


def arviz_check(array_stats: object) -> Check:
    """The same check with arviz-stats' array interface on ``(C, N, d)`` draws."""
    def check(draws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return (np.asarray(array_stats.rhat(draws, chain_axis=0, draw_axis=1, method="rank")),
                np.asarray(array_stats.ess(draws, chain_axis=0, draw_axis=1, method="bulk")))
    return check


def ar1_draws(rng: np.random.Generator, chains: int, n: int, dim: int, rho: float = 0.7) -> np.ndarray:
    """Stationary AR(1) chains with unit variance, ``(chains, n, dim)``."""
    noise = np.sqrt(1.0 - rho**2) * rng.standard_normal((chains, n + 100, dim))
    return lfilter([1.0], [1.0, -rho], noise, axis=1)[:, 100:]


def time_interleaved(funcs: Sequence[Check], draws: np.ndarray, repeats: int) -> list[list[float]]:
    """Seconds per call of each function, ``repeats`` times, interleaved, alternating the order."""
    times: list[list[float]] = [[] for _ in funcs]
    for f in funcs:  # warm-up (first-call imports and caches)
        f(draws)
    for r in range(repeats):
        order = range(len(funcs)) if r % 2 == 0 else reversed(range(len(funcs)))
        for i in order:
            t0 = time.perf_counter()
            funcs[i](draws)
            times[i].append(time.perf_counter() - t0)
    return times


def differences(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]) -> tuple[float, float]:
    """Max |R-hat difference| and max relative bulk-ESS difference of two checks."""
    return (float(np.max(np.abs(a[0] - b[0]))), float(np.max(np.abs(a[1] - b[1]) / np.abs(b[1]))))


def format_table(rows: Sequence[dict]) -> str:
    """The timing table: one row per size, ms per call (min and median), ratio, differences."""
    head = (f"{'C':>2} {'N':>5} {'d':>3} | {'ours min':>8} {'med':>7} | {'azs min':>8} {'med':>7} | "
            f"{'ratio min':>9} {'med':>5} | {'max dR':>8} {'max dESS':>8}")
    lines = [head, "-" * len(head)]
    for r in rows:
        lines.append(f"{r['C']:>2} {r['N']:>5} {r['d']:>3} | {1e3 * r['ours_min']:>8.2f} "
                     f"{1e3 * r['ours_med']:>7.2f} | {1e3 * r['azs_min']:>8.2f} {1e3 * r['azs_med']:>7.2f} | "
                     f"{r['azs_min'] / r['ours_min']:>9.1f} {r['azs_med'] / r['ours_med']:>5.1f} | "
                     f"{r['dr']:>8.1e} {r['dess']:>8.1e}")
    lines.append("ms per check (R-hat + bulk ESS); ratio = arviz-stats / ours, same run; "
                 "dR = max |R-hat difference|, dESS = max relative bulk-ESS difference")
    return "\n".join(lines)


def timing_rows(check: Check, repeats: int, seed: int) -> list[dict]:
    """One row per (C, N, d) of the run-until loop's sizes."""
    rng = np.random.default_rng(seed)
    rows = []
    for c in CHAINS:
        for n in DRAWS:
            for d in DIMS:
                draws = ar1_draws(rng, c, n, d)
                (t_ours, t_azs) = time_interleaved([ours, check], draws, repeats)
                dr, dess = differences(check(draws), ours(draws))
                rows.append(dict(C=c, N=n, d=d, ours_min=min(t_ours), ours_med=statistics.median(t_ours),
                                 azs_min=min(t_azs), azs_med=statistics.median(t_azs), dr=dr, dess=dess))
    return rows


def bit_identical(check: Check, seed: int) -> bool:
    """Whether repeated calls (and a copy of the input) give the same bytes."""
    draws = ar1_draws(np.random.default_rng(seed), 4, 256, 50)
    first = check(draws)
    return all(np.array_equal(a, b) for _ in range(5) for a, b in zip(first, check(draws.copy())))


def first_pass(checks: Sequence[tuple[int, tuple[np.ndarray, np.ndarray]]]) -> "int | None":
    """The first iteration whose check passes (R-hat <= 1.05, bulk ESS >= 32, no NaN), or None."""
    for n, (r_hat, ess) in checks:
        if np.max(r_hat) <= R_HAT_OK and not np.any(np.isnan(ess)) and np.min(ess) >= ESS_OK:
            return n
    return None


def record_windows(condition: str, seed: int, dim: int, chains: int, cap: int
                   ) -> tuple[list[tuple[int, np.ndarray]], list[float]]:
    """Run the run-until loop to ``cap`` on a Lavaland MaxEnt-Z posterior, never stopping; return
    every ``(iteration, window)`` it checked and the sampler's wall seconds of each block."""
    from ird_core import posterior
    from ird_core.posterior import run_until
    from ird_core.worlds import lavaland

    instance = lavaland.make_instance(condition, seed, obs_dim=dim)
    mdp = lavaland.train_mdp(instance)
    windows: list[tuple[int, np.ndarray]] = []
    stamps: list[float] = []
    real = run_until._window_diagnostics

    def recording(states: np.ndarray, n: int, first: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        stamps.append(time.perf_counter())
        window, _, ess = real(states, n, first)
        windows.append((n, window.copy()))
        stamps.append(time.perf_counter())
        return window, np.full(states.shape[2], np.inf), ess  # never converged: on to the cap

    rule = posterior.RunUntil(r_hat=R_HAT_OK, min_ess=0.0, ess_per_sample=0.5, max_iterations=cap,
                              check_every=BLOCK)
    run_until._window_diagnostics = recording
    try:
        posterior.sample_posterior(instance.proxy_weights, mdp, 50.0, "maxent_z", 64, seed, num_chains=chains,
                                   warmup=50, thin=4, max_leapfrog=16, until_converged=rule)
    finally:
        run_until._window_diagnostics = real
    # Sampler seconds of each block of BLOCK iterations: from one check's end to the next's start.
    blocks = [stamps[i + 1] - stamps[i] for i in range(1, len(stamps) - 1, 2)]
    return windows, blocks


def decisions(check: Check, seeds: Sequence[int], cap: int) -> None:
    """Print, per posterior, the first passing iteration with each implementation, in how many
    windows their verdicts differ, and the seconds of all blocks and of all checks to the cap."""
    print(f"\nRun-until decisions (R-hat <= {R_HAT_OK}, bulk ESS >= {ESS_OK:g}, checks every {BLOCK} "
          f"iterations, cap {cap}); Lavaland latent_raw, MaxEnt-Z, beta 50, 64 samples")
    print(f"{'d':>3} {'C':>2} {'seed':>4} | {'pass ours':>9} {'pass azs':>8} {'differ':>7} | {'max dR':>8} "
          f"{'max dESS':>8} | {'blocks s':>8} {'checks ours s':>13} {'checks azs s':>12}")
    for dim, chains in ((50, 4), (4, 8)):
        for seed in seeds:
            windows, blocks = record_windows("latent_raw", seed, dim, chains, cap)
            a, b, t_ours, t_azs = [], [], 0.0, 0.0
            for n, w in windows:
                (ta,), (tb,) = time_interleaved([ours, check], w, 1)
                t_ours, t_azs = t_ours + ta, t_azs + tb
                a.append((n, ours(w)))
                b.append((n, check(w)))
            dr = max(differences(y, x)[0] for (_, x), (_, y) in zip(a, b))
            dess = max(differences(y, x)[1] for (_, x), (_, y) in zip(a, b) if np.all(np.isfinite(x[1])))
            differ = sum((first_pass([x]) is None) != (first_pass([y]) is None) for x, y in zip(a, b))
            print(f"{dim:>3} {chains:>2} {seed:>4} | {str(first_pass(a)):>9} {str(first_pass(b)):>8} "
                  f"{f'{differ}/{len(a)}':>7} | {dr:>8.1e} {dess:>8.1e} | {sum(blocks):>8.2f} {t_ours:>13.2f} "
                  f"{t_azs:>12.2f}")
    print("differ: windows whose verdict (pass/fail) differs; blocks s: the sampler's seconds for all blocks "
          "of 16 iterations to the cap; checks s: one check of every window, with each implementation")


def main(argv: "list[str] | None" = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--repeats", type=int, default=15)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--decisions", type=int, nargs="*", default=None, metavar="SEED")
    parser.add_argument("--cap", type=int, default=400, help="iteration cap of the --decisions runs")
    args = parser.parse_args(argv)
    array_stats = load_arviz_stats()
    if array_stats is None:
        print(f"arviz-stats is not installed; to run this benchmark: {INSTALL}")
        return 2
    check = arviz_check(array_stats)
    print(f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}; {args.repeats} interleaved repeats")
    print(format_table(timing_rows(check, args.repeats, args.seed)))
    print(f"arviz-stats bit-identical over repeated calls: {bit_identical(check, args.seed)}")
    if args.decisions is not None:
        decisions(check, args.decisions or [0, 1, 2], args.cap)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
