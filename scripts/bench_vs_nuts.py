#!/usr/bin/env python3
"""Benchmark: the project's posterior sampler against NumPyro's NUTS on the same IRD log posterior.

    python scripts/bench_vs_nuts.py [--instances small d50] [--methods maxent_z sample_z]
                                    [--repeats 3] [--draws 256] [--nuts-warmup 200] [--install]

Needs jax and numpyro, optional benchmark-only dependencies that the project's set-up does not
install (``requirements-bench.txt``). Without them the script prints the command that installs
them (``INSTALL_COMMAND``: pip with ``requirements.txt`` as constraints, so no pin of the venv
moves) and exits 2; ``--install`` runs that command first.

Instances (``INSTANCES``): Lavaland ``latent_raw`` (d = 50) and ``side_effects`` (d = 4) at
15x15, T = 30, seed 0, with the experiments' observation model, beta (50) and, for Sample-Z, the
library's default 1000 fixed proxies (``posterior.proxy_observations``, built once, outside
both timings).

Ours: ``posterior.sample_joint_posterior`` with the experiments' sampler recipe for the method
and dimension (``TrialSpec(...).sampler(method).for_dim(d)``: chains, warm-up, kernel, leapfrog
caps), as a fixed-length run of ``--draws`` iterations per chain after warm-up with every
iteration kept (``thin=1``, no run-until-converged), so both samplers' ESS is taken on the same
number of draws. Its time is the whole call: Laplace start, warm-up, sampling, diagnostics.

NUTS: numpyro's functional ``hmc(potential_fn, algo="NUTS")`` with its defaults (target
acceptance 0.8, tree depth 10, heuristic-free dual averaging) and a dense mass matrix, on the log
posterior written in JAX (float64; ``scripts/lib/nuts_reference.py``), the same number of chains
and draws per chain, ``--nuts-warmup`` warm-up iterations per chain, chains one after another
from numpyro's default start. Its three jitted functions are compiled once per instance by a
throwaway chain (compilation excluded); warm-up and sampling are timed separately.

Before timing, JAX's log density and gradient are checked against the library's
(``PosteriorModel.log_density_and_grad``) at six weights; the script exits 3 if they differ by
more than ``VALUE_RTOL`` / the method's ``GRAD_RTOL``.

ESS (bulk, min over coordinates) and R-hat (rank, max) are ArviZ's on both samplers' draws.
Ratios: ours' ESS per second (total wall time) over NUTS's, total and sampling phase alone.
Repeats are interleaved (ours, NUTS, ours, NUTS, ...) with seeds ``--seed + r``; the table gives
the median absolute numbers and the min / median ratios. Single-thread fairness:
``OPENBLAS_NUM_THREADS=1`` and ``XLA_FLAGS`` with XLA's Eigen thread pool off (set them
yourself to override).
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.util
import os
import shlex
import subprocess
import sys
import time
import warnings
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("XLA_FLAGS", "--xla_cpu_multi_thread_eigen=false intra_op_parallelism_threads=1")

import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: The optional dependencies and the one command that installs them (exit code 2 when missing).
NEEDED = ("jax", "numpyro")
INSTALL_ARGS = [sys.executable, "-m", "pip", "install", "-r", str(ROOT / "requirements-bench.txt"),
                "-c", str(ROOT / "requirements.txt")]
INSTALL_COMMAND = shlex.join(INSTALL_ARGS)
EXIT_MISSING = 2
EXIT_DISAGREE = 3
#: Agreement of JAX's log posterior with the library's: value (relative, all methods) and gradient
#: (relative norm; Sample-Z's library gradient takes ``H(w) w`` as a forward difference, ~1e-6).
VALUE_RTOL = 1e-8
GRAD_RTOL = {"maxent_z": 1e-8, "sample_z": 1e-5}
#: Goals of issue 31: ours / NUTS in ESS per second, total, and against NUTS's sampling phase alone.
GOAL_TOTAL = 10.0
GOAL_SAMPLING = 2.0
#: name -> (condition, obs_dim): the instances (15x15, T = 30, seed 0).
INSTANCES = {"small": ("side_effects", 50), "d50": ("latent_raw", 50)}
METHODS = ("maxent_z", "sample_z")


def parse_args(argv: "list[str] | None" = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--instances", nargs="+", default=list(INSTANCES), choices=list(INSTANCES))
    parser.add_argument("--methods", nargs="+", default=list(METHODS), choices=METHODS)
    parser.add_argument("--repeats", type=int, default=3, help="interleaved repeats (seeds --seed + r)")
    parser.add_argument("--draws", type=int, default=256, help="draws per chain after warm-up, both samplers")
    parser.add_argument("--nuts-warmup", type=int, default=200, help="NUTS warm-up iterations per chain")
    parser.add_argument("--nuts-mass", choices=("dense", "diag"), default="dense")
    parser.add_argument("--beta", type=float, default=50.0, help="the proxies' rationality (experiments: 50)")
    parser.add_argument("--size", type=int, default=15)
    parser.add_argument("--horizon", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--check-only", action="store_true", help="only check JAX against the library")
    parser.add_argument("--install", action="store_true", help=f"install jax and numpyro first: {INSTALL_COMMAND}")
    args = parser.parse_args(argv)
    for name in ("repeats", "draws", "nuts_warmup"):
        if getattr(args, name) < 1:
            parser.error(f"--{name.replace('_', '-')} must be >= 1")
    return args


def missing_dependencies() -> list[str]:
    """The optional modules (``NEEDED``) that do not import."""
    return [name for name in NEEDED if importlib.util.find_spec(name) is None]


def ensure_dependencies(install: bool, run=subprocess.call) -> "int | None":
    """None when jax and numpyro are there (installed first with ``install``), else the exit code
    ``EXIT_MISSING`` after printing the command that installs them."""
    missing = missing_dependencies()
    if missing and install:
        print(f"installing {', '.join(missing)}: {INSTALL_COMMAND}", flush=True)
        if run(list(INSTALL_ARGS)) == 0:
            importlib.invalidate_caches()
            missing = missing_dependencies()
    if not missing:
        return None
    print(f"bench_vs_nuts: {' and '.join(missing)} not installed (optional, benchmark only; not part of the "
          f"project's set-up). Install them with\n    {INSTALL_COMMAND}\nor run this script with --install.",
          file=sys.stderr)
    return EXIT_MISSING


@dataclasses.dataclass
class Measure:
    """One sampler run: wall seconds (warm-up, sampling), ArviZ's bulk ESS (min) and R-hat (max)."""

    warmup: float
    sampling: float
    ess: float
    r_hat: float
    extra: str = ""

    @property
    def total(self) -> float:
        return self.warmup + self.sampling


def ratios(ours: Measure, nuts: Measure) -> tuple[float, float]:
    """Ours' ESS per second (total) over NUTS's total, and over NUTS's sampling phase alone."""
    rate = ours.ess / ours.total
    return rate / (nuts.ess / nuts.total), rate / (nuts.ess / nuts.sampling)


def min_median(values: "list[float]") -> str:
    return f"{np.min(values):.1f} / {np.median(values):.1f}"


def verdict(values: "list[float]", goal: float) -> str:
    """'met' when the minimum ratio reaches ``goal``, 'met at the median' or 'MISSED' otherwise."""
    if np.min(values) >= goal:
        return "met"
    return "met at the median only" if np.median(values) >= goal else "MISSED"


TABLE_HEADER = ("| instance | Z | chains x draws | ours s (warm-up + sampling) | ours ESS / R-hat | "
                "NUTS s (warm-up + sampling) | NUTS ESS / R-hat | NUTS steps | ESS/s ours / NUTS / NUTS sampling | "
                "ratio total (min / med) | ratio vs NUTS sampling (min / med) |\n|" + "---|" * 11)


def table_row(name: str, method: str, shape: str, pairs: "list[tuple[Measure, Measure]]") -> str:
    """One markdown row: median absolute numbers of the repeats, min / median ratios."""
    med = lambda f: float(np.median([f(p) for p in pairs]))  # noqa: E731
    total, sampling = zip(*(ratios(o, n) for o, n in pairs))
    return (f"| {name} | {method} | {shape} | {med(lambda p: p[0].total):.1f} ({med(lambda p: p[0].warmup):.1f} + "
            f"{med(lambda p: p[0].sampling):.1f}) | {med(lambda p: p[0].ess):.0f} / {med(lambda p: p[0].r_hat):.3f} | "
            f"{med(lambda p: p[1].total):.1f} ({med(lambda p: p[1].warmup):.1f} + {med(lambda p: p[1].sampling):.1f}) | "
            f"{med(lambda p: p[1].ess):.0f} / {med(lambda p: p[1].r_hat):.3f} | {pairs[0][1].extra} | "
            f"{med(lambda p: p[0].ess / p[0].total):.1f} / {med(lambda p: p[1].ess / p[1].total):.1f} / "
            f"{med(lambda p: p[1].ess / p[1].sampling):.1f} | {min_median(total)} | {min_median(sampling)} |")


def goal_lines(results: "dict[tuple[str, str], list[tuple[Measure, Measure]]]") -> list[str]:
    """One line per instance x method: each goal met or missed, with the min / median ratios."""
    lines = []
    for (name, method), pairs in results.items():
        total, sampling = zip(*(ratios(o, n) for o, n in pairs))
        lines.append(f"{name} {method}: >= {GOAL_TOTAL:g}x NUTS ESS/s {verdict(total, GOAL_TOTAL)} "
                     f"({min_median(total)}x); >= {GOAL_SAMPLING:g}x NUTS's sampling phase "
                     f"{verdict(sampling, GOAL_SAMPLING)} ({min_median(sampling)}x)")
    return lines


def diagnostics(draws: np.ndarray) -> tuple[float, float]:
    """ArviZ's bulk ESS (min over coordinates) and rank R-hat (max) of ``(C, n, d)`` draws."""
    import arviz

    data = arviz.convert_to_dataset(draws)
    ess = float(np.min(arviz.ess(data, method="bulk")["x"].values))
    return ess, float(np.max(arviz.rhat(data, method="rank")["x"].values))


def build_case(name: str, method: str, args: argparse.Namespace):
    """The instance's observations, the library's model and the experiments' sampler options."""
    from ird_core import posterior
    from ird_core.experiments import TrialSpec
    from ird_core.worlds import lavaland

    condition, obs_dim = INSTANCES[name]
    inst = lavaland.make_instance(condition, args.seed, size=args.size, horizon=args.horizon, obs_dim=obs_dim)
    spec = TrialSpec(condition, args.seed, size=args.size, horizon=args.horizon, obs_dim=obs_dim, beta=args.beta)
    proxies = spec.num_proxy_samples if method == "sample_z" else None
    observations = posterior.proxy_observations(inst, proxies, args.seed + 100, spec.prior_sigma,
                                                observation_model=spec.observation_model())
    model = posterior.make_joint_model(observations, spec.beta, method, spec.prior_sigma,
                                       observation_model=spec.observation_model())
    options = spec.sampler(method).for_dim(model.dim).options()
    options.update(thin=1, until_converged=None)
    return inst, spec, observations, model, options


def run_ours(spec, observations, method: str, options: dict, draws: int, seed: int) -> Measure:
    """The project's sampler, fixed length, every iteration kept; wall time split at the warm-up's end."""
    from ird_core import posterior
    from ird_core.experiments.progress import step_progress

    chains, warmup = options["num_chains"], options["warmup"]
    marks = {}
    with step_progress(f"ours {method}") as bar, warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the table reports R-hat

        def progress(step: int, total: int) -> None:
            bar(step, total)
            if step == warmup:
                marks["warmup"] = time.perf_counter()

        start = time.perf_counter()
        post = posterior.sample_joint_posterior(observations, spec.beta, method, chains * draws, seed,
                                                spec.prior_sigma, observation_model=spec.observation_model(),
                                                progress=progress, **options)
        end = time.perf_counter()
    split = marks.get("warmup", start)
    samples = post.samples.reshape(draws, chains, -1).transpose(1, 0, 2)  # pool_draws is draw-major
    ess, r_hat = diagnostics(samples)
    return Measure(split - start, end - split, ess, r_hat, f"{post.kernel}")


def run_nuts(runner, chains: int, seed: int, method: str) -> Measure:
    from ird_core.experiments.progress import step_progress

    with step_progress(f"NUTS {method}", unit="chain") as bar:
        run = runner.run(chains, seed, bar)
    ess, r_hat = diagnostics(run.draws)
    return Measure(run.warmup_seconds, run.sampling_seconds, ess, r_hat,
                   f"{run.mean_steps:.0f} (eps {run.step_size:.3g}, {run.divergences} div.)")


def main(argv: "list[str] | None" = None) -> int:
    args = parse_args(argv)
    code = ensure_dependencies(args.install)
    if code is not None:
        return code
    sys.path.insert(0, str(ROOT / "scripts" / "lib"))
    import arviz
    import nuts_reference

    from ird_core import mdp

    mdp.warm_up()
    print(f"versions: {nuts_reference.versions()}, arviz {arviz.__version__}, numpy {np.__version__}; "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.2f}; XLA_FLAGS={os.environ['XLA_FLAGS']!r}, "
          f"OPENBLAS_NUM_THREADS={os.environ['OPENBLAS_NUM_THREADS']}", flush=True)
    results: dict[tuple[str, str], list[tuple[Measure, Measure]]] = {}
    rows = []
    for name in args.instances:
        for method in args.methods:
            inst, spec, observations, model, options = build_case(name, method, args)
            log_density = nuts_reference.log_density_fn(model)
            rng = np.random.default_rng(args.seed)
            points = np.concatenate([inst.proxy_weights + 0.3 * rng.standard_normal((3, model.dim)),
                                     model.prior_sigma * rng.standard_normal((3, model.dim))])
            try:
                v_err, g_err = nuts_reference.check_agreement(model, log_density, points, VALUE_RTOL,
                                                              GRAD_RTOL[method])
            except AssertionError as exc:
                print(f"{name} {method}: {exc}", file=sys.stderr)
                return EXIT_DISAGREE
            print(f"{name} ({INSTANCES[name][0]}, d = {model.dim}) {method}: JAX agrees with the library at 6 weights "
                  f"(value {v_err:.1e} <= {VALUE_RTOL:.0e}, gradient {g_err:.1e} <= {GRAD_RTOL[method]:.0e}); "
                  f"ours: {options}", flush=True)
            if args.check_only:
                continue
            runner = nuts_reference.NutsRunner(log_density, model.dim, args.nuts_warmup, args.draws,
                                               dense_mass=args.nuts_mass == "dense")
            print(f"  NUTS compiled in {runner.compile():.1f} s (excluded)", flush=True)
            pairs = []
            for r in range(args.repeats):
                ours = run_ours(spec, observations, method, options, args.draws, args.seed + r)
                nuts = run_nuts(runner, options["num_chains"], args.seed + r, method)
                pairs.append((ours, nuts))
                total, sampling = ratios(ours, nuts)
                print(f"  repeat {r}: ours {ours.total:.1f} s ({ours.warmup:.1f} + {ours.sampling:.1f}), ESS "
                      f"{ours.ess:.0f}, R-hat {ours.r_hat:.3f}; NUTS {nuts.total:.1f} s ({nuts.warmup:.1f} + "
                      f"{nuts.sampling:.1f}), ESS {nuts.ess:.0f}, R-hat {nuts.r_hat:.3f}, steps {nuts.extra}; "
                      f"ratio {total:.1f}x total, {sampling:.1f}x NUTS sampling", flush=True)
            results[(name, method)] = pairs
            rows.append(table_row(f"{name} ({INSTANCES[name][0]}, d = {model.dim})", method,
                                  f"{options['num_chains']} x {args.draws}", pairs))
    if rows:
        print("\n" + TABLE_HEADER + "\n" + "\n".join(rows) + "\n")
        print("\n".join(goal_lines(results)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
