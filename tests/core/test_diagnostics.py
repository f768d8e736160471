"""The home-made convergence diagnostics (ird_core.mcmc.diagnostics) against ArviZ, the reference.

ArviZ is a test-only dependency: the core stays numpy/scipy (and does not call arviz-stats, which is
slower per check: scripts/bench_diagnostics.py, docs/dependencies.md). Known, tested differences:

- R-hat, odd chain length: ArviZ drops the middle draw before ranking, we rank every draw, so
  the normal scores (and R-hat) differ slightly; with an even length they are the same numbers.
- Bulk ESS: ArviZ (like Stan) adds the last even-lag autocorrelation ``rho_2K`` (when positive)
  after Geyer's truncation and stops at lag ``N - 3``; we stop at the truncation. For converged
  chains ``tau_arviz - tau_ours`` is therefore one noise-level autocorrelation, never negative.
"""

from __future__ import annotations

import arviz
import numpy as np
import pytest
from scipy.signal import lfilter

from ird_core.mcmc import diagnostics


def ar1(rng: np.random.Generator, rho: float, chains: int, n: int, dim: int) -> np.ndarray:
    """AR(1) chains with unit marginal variance, started near stationarity (|rho|^200 burn-in); (C, n, d)."""
    noise = np.sqrt(1.0 - rho**2) * rng.standard_normal((chains, n + 200, dim))
    return lfilter([1.0], [1.0, -rho], noise, axis=1)[:, 200:]


def converged_draws(name: str, seed: int) -> np.ndarray:
    """Chains from one stationary distribution; (C, N, d), N even."""
    rng = np.random.default_rng(seed)
    return {
        "iid": lambda: rng.standard_normal((4, 1000, 6)),
        "autocorrelated": lambda: ar1(rng, 0.9, 4, 1000, 6),
        "antithetic": lambda: ar1(rng, -0.5, 4, 400, 6),
        "heavy_tails": lambda: rng.standard_t(3, (4, 500, 6)) * 50.0 + 7.0,
        "tiny_scale": lambda: 1e-6 * rng.standard_normal((8, 300, 6)),
    }[name]()


def unconverged_draws(name: str, seed: int) -> np.ndarray:
    """Chains that disagree: in location or in scale; (C, N, d), N even."""
    rng = np.random.default_rng(seed)
    x = rng.standard_normal((4, 500, 6))
    if name == "shifted":
        return x + 0.5 * np.arange(4)[:, None, None]
    return x * np.array([1.0, 1.0, 1.0, 3.0])[:, None, None]


def arviz_r_hat(draws: np.ndarray) -> np.ndarray:
    return arviz.rhat(arviz.convert_to_dataset(draws), method="rank")["x"].values


def arviz_bulk_ess(draws: np.ndarray) -> np.ndarray:
    return arviz.ess(arviz.convert_to_dataset(draws), method="bulk")["x"].values


CONVERGED = ["iid", "autocorrelated", "antithetic", "heavy_tails", "tiny_scale"]
UNCONVERGED = ["shifted", "scaled"]


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", CONVERGED + UNCONVERGED)
def test_rank_normalized_r_hat_equals_arviz(name: str, seed: int) -> None:
    draws = converged_draws(name, seed) if name in CONVERGED else unconverged_draws(name, seed)
    ours = diagnostics.rank_normalized_r_hat(draws)
    np.testing.assert_allclose(ours, arviz_r_hat(draws), rtol=1e-12, atol=0)
    if name in UNCONVERGED:
        assert np.all(ours > 1.05)  # the comparison covers the values that flag non-convergence


def test_rank_normalized_r_hat_odd_length_close_to_arviz() -> None:
    draws = np.random.default_rng(3).standard_normal((3, 201, 6)) + 0.2 * np.arange(3)[:, None, None]
    np.testing.assert_allclose(diagnostics.rank_normalized_r_hat(draws), arviz_r_hat(draws), rtol=1e-3)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", CONVERGED)
def test_bulk_ess_equals_arviz_up_to_the_stan_tail_term(name: str, seed: int) -> None:
    draws = converged_draws(name, seed)
    total = draws.shape[0] * draws.shape[1]
    tau_ours = total / diagnostics.bulk_effective_sample_size(draws)
    tau_arviz = total / arviz_bulk_ess(draws)
    # The only difference is one added autocorrelation rho_2K >= 0, whose sampling sd is
    # about sqrt((1 + 2 sum rho_j^2) / S) <= 0.05 for these chains.
    gap = tau_arviz - tau_ours
    assert np.all(gap >= -1e-9)
    assert np.all(gap <= 0.1)


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("name", UNCONVERGED)
def test_bulk_ess_close_to_arviz_for_chains_that_disagree(name: str, seed: int) -> None:
    draws = unconverged_draws(name, seed)
    np.testing.assert_allclose(diagnostics.bulk_effective_sample_size(draws), arviz_bulk_ess(draws), rtol=0.05)


def test_mcmc_reexports_the_diagnostics() -> None:
    from ird_core import mcmc

    for name in diagnostics.__all__:
        assert getattr(mcmc, name) is getattr(diagnostics, name)
