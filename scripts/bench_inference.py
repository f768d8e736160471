#!/usr/bin/env python3
"""Benchmark: IRD posterior sampling on latent_raw (d = 50), batched chains vs one weight per call.

For each method (MaxEnt-Z, Sample-Z) it times ``sample_posterior`` (1000 samples, default sampler
settings) on a 15x15 training map with T = 30, and prints wall time, batched log-density calls,
weight evaluations, acceptance rate, split R-hat (rank-normalised, max over coordinates), bulk
ESS (min over coordinates), step size and leapfrog steps.

The naive reference does the SAME log-posterior(+gradient) work one weight vector per MDP call:
it times ``--naive-calls`` such calls on the run's own draws and extrapolates to the number of
weight evaluations the batched run made (``--full-naive`` runs all of them instead; slow).

    python scripts/bench_inference.py [--seed 0] [--beta 1.0] [--samples 1000] [--methods maxent_z sample_z]
    python scripts/bench_inference.py --proxy-study   # Sample-Z sensitivity to the number of proxies
    python scripts/bench_inference.py --levers        # sampler levers at the experiments' beta 50, 64 samples

Time to convergence: each method is also run with ``until_converged=RunUntil()`` (chains extended
until split R-hat <= 1.05 and bulk ESS >= max(400, samples / 2); ``--skip-run-until`` to skip),
and one line per method compares it with the fixed-length run.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time

# The MCMC hot path is single-threaded numpy; multithreaded BLAS only oversubscribes small
# machines (measured: a (16, 50) x (50, 1000) product 40x slower on a loaded 2-core box).
# Set OPENBLAS_NUM_THREADS yourself to override.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from ird_core import posterior  # noqa: E402
from ird_core.experiments.progress import step_progress  # noqa: E402
from ird_core.posterior import RunUntil  # noqa: E402
from ird_core.worlds import lavaland  # noqa: E402

#: Wall-time target for one posterior on this 2-core machine, as stated in the README's benchmarks.
TARGET_SECONDS = 10.0


def naive_seconds_per_weight(model: posterior.PosteriorModel, weights: np.ndarray, kernel: str) -> float:
    """Seconds per weight of the sampler's evaluation done one ``(1, d)`` weight per call."""
    start = time.process_time()
    for w in weights:
        if kernel == "rwm":
            model.log_density(w[None])
        else:
            model.log_density_and_grad(w[None])
    return (time.process_time() - start) / len(weights)


def proxy_study(instance: lavaland.LavalandInstance, beta: float, seed: int) -> None:
    """How Sample-Z log-posterior differences between posterior-typical weights move with N."""
    mdp = lavaland.train_mdp(instance)
    draws = posterior.sample_posterior(instance.proxy_weights, mdp, beta, "maxent_z", 256, seed).samples
    reference = posterior.log_posterior(draws, instance.proxy_weights, mdp, beta, "sample_z",
                                        seed=seed + 1, num_proxy_samples=6400)
    reference = reference - reference.mean()
    print(f"Sample-Z log-posterior differences between 256 MaxEnt-Z posterior draws vs N = 6400 proxies "
          f"(beta {beta:g}):")
    print(f"{'N':>6} {'rms error (nats)':>17} {'sd of differences':>18}")
    for n in (25, 50, 100, 200, 400, 800, 1600):
        values = posterior.log_posterior(draws, instance.proxy_weights, mdp, beta, "sample_z", seed=seed + 1,
                                         num_proxy_samples=n)
        values = values - values.mean()
        print(f"{n:>6} {np.sqrt(np.mean((values - reference) ** 2)):>17.3f} {reference.std():>18.3f}")


#: ``before=True`` in a lever's overrides: the experiments' settings before they moved to 1000
#: proxies, i.e. 100 proxies, the sampler's default check blocks (``max(n0, 50)`` iterations) and,
#: in d = 50, these HMC settings (100 warm-up iterations, at most 32 leapfrog steps, the sampler's
#: default trajectory length).
_D50_BEFORE = dict(warmup=100, max_leapfrog=32, warmup_max_leapfrog=0, trajectory_length=0.0)
_B = dict(before=True)

#: The levers measured by ``--levers`` (Sample-Z at the experiments' beta). Each is
#: ``(label, method, overrides, newton_start_only)``; every run uses the experiments' default
#: sampler settings of its method for the condition's dimension
#: (``ird_core.experiments.SamplerSettings.for_dim``: run until R-hat <= 1.05 and ESS >= 32,
#: or the iteration cap), without the give-up rule (the levers compare samplers, not stopping
#: rules), with the lever's ``overrides`` of those settings; ``num_proxy_samples`` in the overrides
#: replaces the experiments' ``TrialSpec.num_proxy_samples`` instead, and ``before`` (see
#: ``_D50_BEFORE``) starts from the settings the experiments used with 100 proxies.
LEVERS = (
    ("hmc, Newton start (before)", "sample_z", dict(_B, kernel="hmc", num_chains=4), True),
    ("hmc, mode + profile start", "sample_z", dict(_B, kernel="hmc", num_chains=4), False),
    ("hmc, 16 chains", "sample_z", dict(_B, kernel="hmc", num_chains=16), False),
    ("hmc, long trajectories", "sample_z", dict(_B, kernel="hmc", num_chains=8, warmup=600, max_leapfrog=128,
                                                max_iterations=1000, warmup_max_leapfrog=64,
                                                trajectory_length=3.0), False),
    ("hmc, 1000 proxies", "sample_z", dict(_B, kernel="hmc", num_chains=4, num_proxy_samples=1000), False),
    ("hmc, 1000 proxies, traj 2.5", "sample_z", dict(kernel="hmc", num_chains=4), False),  # the default
    ("hmc, 1000 proxies, 150 warm-up", "sample_z", dict(kernel="hmc", num_chains=4, warmup=150), False),
    ("hmc, 1000 proxies, 8 chains", "sample_z", dict(kernel="hmc", num_chains=8), False),
    ("elliptical slice", "sample_z", dict(_B, kernel="elliptical", num_chains=8), False),
    ("independence + slice", "sample_z", dict(_B, kernel="independence_elliptical", num_chains=8), False),
    ("hmc, MaxEnt-Z", "maxent_z", dict(kernel="hmc", num_chains=4), False),
)


def levers(conditions: list[str], seeds: int, beta: float, samples: int, only: "list[str] | None" = None) -> None:
    """Per condition and lever: converged runs (R-hat <= 1.1), median R-hat, mean CPU seconds,
    mean bulk ESS and ESS per CPU second, with the ratio to the first lever of the same method."""
    import math
    import warnings
    from unittest import mock

    from ird_core import experiments
    from ird_core.posterior import laplace

    print(f"levers at beta {beta:g}, {samples} samples, Sample-Z with 100 proxies (and in d = 50 the HMC settings "
          f"used with them) up to the '1000 proxies' levers, seeds 0-{seeds - 1}:")
    print(f"{'condition':<18} {'lever':<30} {'R-hat<=1.1':>10} {'med R-hat':>9} {'CPU s':>6} {'ESS':>6} "
          f"{'ESS/s':>7} {'vs first':>8}")
    for condition in conditions:
        first: dict[str, float] = {}
        for label, method, overrides, newton_only in LEVERS:
            if only and not any(word in label for word in only):
                continue
            rows = []
            for seed in range(seeds):
                spec = experiments.TrialSpec(condition, seed)
                fields = dict(overrides)
                before = fields.pop("before", False)
                proxies = fields.pop("num_proxy_samples", 100 if before else spec.num_proxy_samples)
                inst = lavaland.make_instance(condition, seed, size=15, horizon=30, obs_dim=50)
                obs = posterior.proxy_observations(inst, proxies if method == "sample_z" else None, seed + 100, 1.0)
                base = spec.sampler(method)
                settings = base.for_dim(obs[0].dim)
                if before:  # default check blocks and, for the d = 50 settings (not the small ones), _D50_BEFORE
                    settings = dataclasses.replace(settings, check_every=0, **(_D50_BEFORE if settings is base else {}))
                settings = dataclasses.replace(settings, give_up_after=0, **fields)
                stall = math.inf if newton_only else laplace._NEWTON_STALL
                with mock.patch.object(laplace, "_NEWTON_STALL", stall), warnings.catch_warnings():
                    warnings.simplefilter("ignore", RuntimeWarning)  # the table reports R-hat
                    cpu = time.process_time()
                    post = posterior.sample_joint_posterior(obs, beta, method, samples, seed, **settings.options())
                    rows.append((post.r_hat_max, time.process_time() - cpu, post.ess_min))
            r_hat, cpu, ess = (np.array(v) for v in zip(*rows))
            rate = float(np.mean(ess) / np.mean(cpu))
            first.setdefault(method, rate)
            print(f"{condition:<18} {label:<30} {int(np.sum(r_hat <= 1.1)):>5}/{seeds:<4} {np.median(r_hat):>9.3f} "
                  f"{np.mean(cpu):>6.1f} {np.mean(ess):>6.0f} {rate:>7.1f} {rate / first[method]:>7.1f}x", flush=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--beta", type=float, default=1.0)
    parser.add_argument("--samples", type=int, default=1000)
    parser.add_argument("--size", type=int, default=15)
    parser.add_argument("--horizon", type=int, default=30)
    parser.add_argument("--methods", nargs="+", default=list(posterior.METHODS), choices=posterior.METHODS)
    parser.add_argument("--naive-calls", type=int, default=200)
    parser.add_argument("--full-naive", action="store_true")
    parser.add_argument("--proxy-study", action="store_true")
    parser.add_argument("--warmup", type=int, default=None, help="warm-up iterations (default: the library's)")
    parser.add_argument("--skip-run-until", action="store_true", help="skip the time-to-convergence runs")
    parser.add_argument("--levers", nargs="*", default=None, metavar="CONDITION",
                        help="compare the sampler levers at the experiments' settings (beta 50, 64 samples) on "
                             "these conditions (default latent_raw side_effects) and exit")
    parser.add_argument("--lever-seeds", type=int, default=3)
    parser.add_argument("--lever-labels", nargs="+", default=None, metavar="WORDS",
                        help="only the levers whose label contains one of these (e.g. 'slice' 'MaxEnt')")
    args = parser.parse_args(argv)
    if args.levers is not None:
        levers(args.levers or ["latent_raw", "side_effects"], args.lever_seeds, 50.0, 64, args.lever_labels)
        return 0

    instance = lavaland.make_instance("latent_raw", args.seed, size=args.size, horizon=args.horizon)
    mdp = lavaland.train_mdp(instance)
    print(f"latent_raw seed {args.seed}: {args.size}x{args.size}, T = {args.horizon}, d = {instance.num_features}, "
          f"beta = {args.beta:g}, {args.samples} samples; {os.cpu_count()} CPUs, load average "
          f"{os.getloadavg()[0]:.2f}")
    if args.proxy_study:
        proxy_study(instance, args.beta, args.seed)
        return 0

    rows = []
    for method in args.methods:
        start, cpu_start = time.perf_counter(), time.process_time()
        with step_progress(f"{method} MCMC") as progress:
            post = posterior.sample_posterior(instance.proxy_weights, mdp, args.beta, method, args.samples,
                                              args.seed, warmup=args.warmup, progress=progress)
        seconds, cpu = time.perf_counter() - start, time.process_time() - cpu_start
        model = posterior.make_posterior_model(instance.proxy_weights, mdp, args.beta, method, seed=args.seed)
        per_call = post.num_chains * (2 if method == "sample_z" and post.kernel != "rwm" else 1)
        weight_evals = post.num_evaluations * per_call
        pool = post.samples[np.linspace(0, len(post.samples) - 1, min(args.naive_calls, len(post.samples))).astype(int)]
        if args.full_naive:
            pool = post.samples[np.arange(post.num_evaluations * post.num_chains) % len(post.samples)]
        naive = naive_seconds_per_weight(model, pool, post.kernel) * post.num_evaluations * post.num_chains
        rows.append((method, seconds, cpu, post, weight_evals, naive))
    until_rows = []
    for method in [] if args.skip_run_until else args.methods:
        start, cpu_start = time.perf_counter(), time.process_time()
        with step_progress(f"{method} MCMC until converged") as progress:
            post = posterior.sample_posterior(instance.proxy_weights, mdp, args.beta, method, args.samples,
                                              args.seed, warmup=args.warmup, until_converged=RunUntil(),
                                              progress=progress)
        until_rows.append((method, time.perf_counter() - start, time.process_time() - cpu_start, post))

    print()
    print(f"{'method':<9} {'kernel':<6} {'wall s':>7} {'CPU s':>6} {'calls':>6} {'weight evals':>12} {'accept':>6} {'R-hat':>6} "
          f"{'ESS':>6} {'step':>6} {'L':>3} {'chains':>6} {'warmup':>6} {'thin':>4} {'naive CPU s':>11} {'speed-up':>8}")
    for method, seconds, cpu, post, weight_evals, naive in rows:
        steps = max(1, int(np.clip(round(posterior.DEFAULT_TRAJECTORY_LENGTH / post.step_size), 1,
                                   posterior.DEFAULT_MAX_LEAPFROG[method]))) if post.kernel == "hmc" else 1
        print(f"{method:<9} {post.kernel:<6} {seconds:>7.1f} {cpu:>6.1f} {post.num_evaluations:>6d} {weight_evals:>12d} "
              f"{post.acceptance_rate:>6.2f} {post.r_hat_max:>6.3f} {post.ess_min:>6.0f} {post.step_size:>6.3f} "
              f"{steps:>3d} {post.num_chains:>6d} {post.warmup:>6d} {post.thin:>4d} {naive:>11.1f} "
              f"{naive / cpu:>7.1f}x")
    fixed = {method: (seconds, cpu, post) for method, seconds, cpu, post, *_ in rows}
    for method, seconds, cpu, post in until_rows:
        base_s, base_cpu, base = fixed[method]
        print(f"time to convergence ({method}, R-hat <= {post.run_until.r_hat:g}, ESS >= "
              f"{post.run_until.required_ess(args.samples):.0f}): {seconds:.1f} s wall, {cpu:.1f} s CPU, "
              f"{post.iterations} iterations per chain, R-hat {post.r_hat_max:.3f}, ESS {post.ess_min:.0f}, "
              f"{post.stop_reason}; fixed-length run {base_s:.1f} s wall, {base_cpu:.1f} s CPU, {base.iterations} "
              f"iterations, R-hat {base.r_hat_max:.3f}, ESS {base.ess_min:.0f}")
    at_target_size = (args.size, args.horizon, args.samples) == (15, 30, 1000)
    for method, seconds, *_ in rows if at_target_size else []:
        verdict = "met" if seconds < TARGET_SECONDS else "MISSED"
        print(f"target: {method} wall time < {TARGET_SECONDS:g} s (15x15, T = 30, 1000 samples): {verdict}")
    print("calls: batched log-density(+gradient) calls of the sampler (warm-up included; the Laplace "
          "approximation's few calls are in the time but not counted).")
    print("naive: the same sampler evaluations, one weight vector per MDP call "
          + ("(all run)" if args.full_naive else f"(extrapolated from {args.naive_calls} timed calls)")
          + "; speed-up = naive CPU / batched CPU (CPU time: other jobs on a shared machine inflate wall time).")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
