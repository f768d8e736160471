"""The IRD log posterior in JAX and NumPyro's NUTS on it (for scripts/bench_vs_nuts.py only).

Imported only when jax and numpyro are installed (``requirements-bench.txt``); nothing in
``ird_core`` or the tests' no-jax part imports it.

The log posterior is written from a :class:`ird_core.posterior.PosteriorModel` (so it holds the
very ``phi~(w~)`` and Sample-Z ``phi_i`` the project's sampler uses), for the settings the
benchmark runs: proxy terms only (no choice terms), unit-temperature MaxEnt counts with
Sample-Z's own term (``ObservationModel()``):

- prior ``-|w|^2 / (2 sigma^2)``;
- MaxEnt-Z: ``beta (w . phi~ - log Z(w))``, ``log Z`` by log-space soft value iteration over
  the grid (``V[T] = r``, ``V[t] = r + logsumexp over the stay + 4 in-grid successors of
  V[t + 1]``, ``log Z = V[0][start]``), as ``ird_core.mdp.log_partition``;
- Sample-Z: ``beta w . phi~ - logsumexp([beta w . phi(w)] + [beta w . phi_i]_i)`` with
  ``phi(w) = grad log Z(w)`` (the MaxEnt feature expectations), as
  ``ird_core.posterior.sample_z_log_likelihood``.

Gradients are JAX's (exact; the library's Sample-Z gradient takes ``H(w) w`` as a forward
difference along the ray, relative error ~1e-6, hence the looser gradient tolerance there).

NUTS is numpyro's functional ``hmc(potential_fn, algo="NUTS")``: the initialisation, the warm-up
loop and the sampling loop are each one ``jax.jit`` (``lax.scan`` over ``sample_kernel``),
compiled once by a throwaway chain and then reused for every chain and repeat (numpyro's
``MCMC`` re-jits its ``fori_collect`` per call, which would put compilation into every chain).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

import jax

jax.config.update("jax_enable_x64", True)

import jax.numpy as jnp  # noqa: E402
from jax import lax  # noqa: E402
from numpyro.infer.hmc import hmc  # noqa: E402

from ird_core.mdp.grid import MOVES  # noqa: E402
from ird_core.posterior import PosteriorModel  # noqa: E402

__all__ = ["log_density_fn", "check_agreement", "NutsRunner", "NutsRun", "versions"]


def versions() -> dict[str, str]:
    import numpyro
    return {"jax": jax.__version__, "jaxlib": jax.lib.__version__ if hasattr(jax.lib, "__version__")
            else __import__("jaxlib").__version__, "numpyro": numpyro.__version__}


def _log_partition_fn(features: np.ndarray, start: tuple[int, int], horizon: int):
    """``w (d,) -> log Z(w)`` for one grid MDP (log-space soft value iteration)."""
    feats = jnp.asarray(features)
    height, width = features.shape[:2]
    row, col = start

    def neighbour_lse(values):
        padded = jnp.pad(values, 1, constant_values=-jnp.inf)
        views = jnp.stack([padded[1 + dr: 1 + dr + height, 1 + dc: 1 + dc + width] for dr, dc in MOVES])
        return jax.nn.logsumexp(views, axis=0)

    def log_z(w):
        rewards = feats @ w

        def step(values, _):
            return rewards + neighbour_lse(values), None

        values, _ = lax.scan(step, rewards, None, length=horizon)
        return values[row, col]

    return log_z


def log_density_fn(model: PosteriorModel):
    """The model's unnormalised log posterior as a JAX function ``w (d,) -> scalar``."""
    if model.choices:
        raise ValueError("the JAX reference has no choice terms")
    obs = model.observation
    if obs.optimal or obs.temperature != 1.0 or not obs.own_term:
        raise ValueError("the JAX reference is written for ObservationModel() (unit-temperature MaxEnt, own term)")
    beta, sigma = float(model.beta), float(model.prior_sigma)
    terms = []
    for term in model.proxy_terms:
        mdp = term.train_mdp
        log_z = _log_partition_fn(np.asarray(mdp.features), mdp.start, mdp.horizon)
        phi_i = None if term.sample_features is None else jnp.asarray(term.sample_features)
        terms.append((log_z, jnp.asarray(term.proxy_features), phi_i))
    sample_z = model.method == "sample_z"

    def log_density(w):
        total = -0.5 * jnp.sum(w * w) / sigma**2
        for log_z, phi, phi_i in terms:
            if sample_z:
                own = jax.grad(log_z)(w)
                scores = beta * jnp.concatenate([jnp.dot(w, own)[None], phi_i @ w])
                total = total + beta * jnp.dot(w, phi) - jax.nn.logsumexp(scores)
            else:
                total = total + beta * (jnp.dot(w, phi) - log_z(w))
        return total

    return log_density


def check_agreement(model: PosteriorModel, log_density, weights: np.ndarray, value_rtol: float,
                    grad_rtol: float) -> tuple[float, float]:
    """The largest relative differences (value, gradient) between JAX and the library at
    ``weights`` ``(K, d)``; raises ``AssertionError`` when either exceeds its tolerance.

    Value: ``|a - b| / max(1, |b|)``; gradient: ``||g_a - g_b|| / max(1, ||g_b||)`` per weight."""
    lib_value, lib_grad = model.log_density_and_grad(np.asarray(weights, dtype=np.float64))
    value_and_grad = jax.jit(jax.value_and_grad(log_density))
    v_err = g_err = 0.0
    for k, w in enumerate(weights):
        v, g = value_and_grad(jnp.asarray(w))
        v_err = max(v_err, abs(float(v) - lib_value[k]) / max(1.0, abs(lib_value[k])))
        g_err = max(g_err, float(np.linalg.norm(np.asarray(g) - lib_grad[k]) / max(1.0, np.linalg.norm(lib_grad[k]))))
    if not (v_err <= value_rtol and g_err <= grad_rtol):
        raise AssertionError(f"JAX and the library disagree: value {v_err:.2e} (tolerance {value_rtol:.0e}), "
                             f"gradient {g_err:.2e} (tolerance {grad_rtol:.0e})")
    return v_err, g_err


@dataclass
class NutsRun:
    """One NUTS run: ``draws`` ``(C, n, d)``, wall seconds of the warm-up and sampling phases
    (all chains), mean tree size (leapfrog steps per iteration) in sampling, divergences."""

    draws: np.ndarray
    warmup_seconds: float
    sampling_seconds: float
    mean_steps: float
    divergences: int
    step_size: float


class NutsRunner:
    """NUTS on ``log_density`` with fixed warm-up and draw counts, compiled once.

    Args:
        log_density: ``w (d,) -> scalar`` (JAX).
        dim: ``d``.
        num_warmup, num_draws: iterations per chain.
        dense_mass: adapt a dense (True) or diagonal mass matrix.
        target_accept: the dual averaging's target (numpyro's default 0.8).
        max_tree_depth: NUTS's cap (numpyro's default 10).
    """

    def __init__(self, log_density, dim: int, num_warmup: int, num_draws: int, dense_mass: bool = True,
                 target_accept: float = 0.8, max_tree_depth: int = 10) -> None:
        self.dim, self.num_warmup, self.num_draws = dim, num_warmup, num_draws
        init_kernel, sample_kernel = hmc(lambda z: -log_density(z), algo="NUTS")

        def init(z0, key):
            return init_kernel(z0, num_warmup, dense_mass=dense_mass, target_accept_prob=target_accept,
                               max_tree_depth=max_tree_depth, rng_key=key)

        def warm(state):
            return lax.fori_loop(0, num_warmup, lambda _, s: sample_kernel(s), state)

        def sample(state):
            def step(s, _):
                s = sample_kernel(s)
                return s, (s.z, s.num_steps, s.diverging)
            return lax.scan(step, state, None, length=num_draws)

        self._init, self._warm, self._sample = jax.jit(init), jax.jit(warm), jax.jit(sample)
        self.compile_seconds = float("nan")

    def compile(self, seed: int = 12345) -> float:
        """One throwaway chain (compiles the three functions); returns its wall seconds."""
        start = time.perf_counter()
        self._chain(np.zeros(self.dim), jax.random.key(seed))
        self.compile_seconds = time.perf_counter() - start
        return self.compile_seconds

    def _chain(self, z0: np.ndarray, key) -> tuple:
        t0 = time.perf_counter()
        state = self._init(jnp.asarray(z0), key)
        state = jax.block_until_ready(self._warm(state))
        t1 = time.perf_counter()
        state, (z, steps, div) = jax.block_until_ready(self._sample(state))
        t2 = time.perf_counter()
        return np.asarray(z), np.asarray(steps), np.asarray(div), t1 - t0, t2 - t1, float(state.adapt_state.step_size)

    def run(self, num_chains: int, seed: int, progress=None) -> NutsRun:
        """``num_chains`` chains one after another from numpyro's default start (uniform in
        ``[-2, 2]^d``, ``init_to_uniform``), each with its own warm-up."""
        keys = jax.random.split(jax.random.key(seed), num_chains)
        rng = np.random.default_rng(seed)
        out = []
        for c in range(num_chains):
            out.append(self._chain(rng.uniform(-2.0, 2.0, self.dim), keys[c]))
            if progress is not None:
                progress(c + 1, num_chains)
        draws = np.stack([o[0] for o in out])
        steps = np.concatenate([o[1] for o in out])
        return NutsRun(draws, sum(o[3] for o in out), sum(o[4] for o in out), float(steps.mean()),
                       int(sum(o[2].sum() for o in out)), float(np.mean([o[5] for o in out])))
