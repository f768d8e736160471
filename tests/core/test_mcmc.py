"""Batched MCMC kernels, warm-up adaptation and convergence diagnostics (ird_core.mcmc)."""

from __future__ import annotations

import numpy as np
import pytest

from ird_core import mcmc
from ird_core.mcmc import elliptical_slice
from ird_core.mcmc import kernels as mcmc_kernels


def ar1(rng: np.random.Generator, rho: float, chains: int, n: int, dim: int) -> np.ndarray:
    """Stationary AR(1) chains with unit marginal variance; (C, n, d)."""
    x = np.empty((chains, n, dim))
    x[:, 0] = rng.standard_normal((chains, dim))
    noise = np.sqrt(1.0 - rho**2) * rng.standard_normal((chains, n, dim))
    for t in range(1, n):
        x[:, t] = rho * x[:, t - 1] + noise[:, t]
    return x


# ------------------------------------------------------------------------------ diagnostics


def test_iid_normal_draws_r_hat_one_and_ess_n() -> None:
    draws = np.random.default_rng(0).standard_normal((4, 1000, 20))
    assert np.all(np.abs(mcmc.split_r_hat(draws) - 1.0) < 0.01)
    assert np.all(np.abs(mcmc.rank_normalized_r_hat(draws) - 1.0) < 0.01)
    ess = mcmc.effective_sample_size(draws)
    assert abs(ess.mean() / 4000 - 1.0) < 0.05
    assert np.all(np.abs(ess / 4000 - 1.0) < 0.2)
    bulk = mcmc.bulk_effective_sample_size(draws)
    assert abs(bulk.mean() / 4000 - 1.0) < 0.05


@pytest.mark.parametrize("rho", [0.5, 0.9])
def test_ar1_ess_matches_theory(rho: float) -> None:
    draws = ar1(np.random.default_rng(1), rho, chains=4, n=5000, dim=20)
    expected = draws.shape[0] * draws.shape[1] * (1 - rho) / (1 + rho)
    ess = mcmc.effective_sample_size(draws)
    assert abs(ess.mean() / expected - 1.0) < 0.1, (ess.mean(), expected)
    assert np.all(np.abs(ess / expected - 1.0) < 0.3)
    # Stationary and mixed: R-hat close to 1.
    assert mcmc.rank_normalized_r_hat(draws).max() < 1.02


def test_antithetic_chain_ess_above_n_is_capped() -> None:
    # rho < 0: ESS > N (antithetic); capped at N log10(N) like Stan.
    draws = ar1(np.random.default_rng(2), -0.5, chains=2, n=2000, dim=5)
    ess = mcmc.effective_sample_size(draws)
    assert np.all(ess > 4000) and np.all(ess <= 4000 * np.log10(4000))


def test_chains_with_different_means_have_large_r_hat() -> None:
    rng = np.random.default_rng(3)
    draws = rng.standard_normal((4, 500, 3)) + np.array([0.0, 0.0, 1.0, 2.0])[:, None, None]
    assert np.all(mcmc.split_r_hat(draws) > 1.1)
    assert np.all(mcmc.rank_normalized_r_hat(draws) > 1.1)


def test_drifting_chain_caught_by_splitting() -> None:
    # Each chain drifts from -1 to 1: the chain means agree, but the halves do not.
    rng = np.random.default_rng(4)
    drift = np.linspace(-1.5, 1.5, 1000)[None, :, None]
    draws = rng.standard_normal((4, 1000, 2)) * 0.3 + drift
    assert np.all(mcmc.split_r_hat(draws) > 1.5)


def test_folded_r_hat_catches_different_scales() -> None:
    # Same location, different spread: classic (bulk) R-hat misses it, the folded one does not.
    rng = np.random.default_rng(5)
    draws = rng.standard_normal((4, 1000, 2)) * np.array([1.0, 1.0, 1.0, 4.0])[:, None, None]
    assert np.all(mcmc.split_r_hat(draws) < 1.05)
    assert np.all(mcmc.rank_normalized_r_hat(draws) > 1.1)


def test_constant_coordinate() -> None:
    draws = np.ones((3, 10, 2))
    draws[:, :, 1] = np.random.default_rng(0).standard_normal((3, 10))
    assert mcmc.split_r_hat(draws)[0] == 1.0
    assert np.isnan(mcmc.effective_sample_size(draws)[0])


def test_rank_normalize_is_monotone_and_normal() -> None:
    x = np.random.default_rng(6).exponential(size=(2, 500, 1))
    z = mcmc.rank_normalize(x)
    order = np.argsort(x.ravel())
    assert np.all(np.diff(z.ravel()[order]) > 0)
    assert abs(z.mean()) < 1e-12 and abs(z.std() - 1.0) < 0.02


def test_split_chains_shape() -> None:
    x = np.arange(2 * 7 * 3, dtype=float).reshape(2, 7, 3)
    halves = mcmc.split_chains(x)
    assert halves.shape == (4, 3, 3)
    np.testing.assert_array_equal(halves[0], x[0, :3])
    np.testing.assert_array_equal(halves[2], x[0, 4:])


@pytest.mark.parametrize("bad", [np.ones((2, 3, 1)), np.ones(5), np.full((2, 10, 1), np.nan)])
def test_diagnostics_reject_bad_draws(bad: np.ndarray) -> None:
    with pytest.raises(ValueError, match="draws"):
        mcmc.split_r_hat(bad)


# ------------------------------------------------------------------------------ adaptation


def test_dual_averaging_finds_target_step() -> None:
    # Acceptance exp(-h): target 0.5 is reached at h = log 2.
    adapt = mcmc.DualAveraging.start(0.01, 0.5)
    for _ in range(400):
        adapt = adapt.update(float(np.exp(-adapt.step)))
    assert abs(adapt.final_step - np.log(2.0)) < 0.02


def test_warmup_windows_schedule() -> None:
    assert mcmc.warmup_windows(10) == []
    for warmup in (30, 60, 100, 300, 1000):
        windows = mcmc.warmup_windows(warmup)
        assert windows[0][0] >= 0.15 * warmup - 1
        assert windows[-1][1] <= warmup - 10
        assert all(a[1] == b[0] for a, b in zip(windows, windows[1:]))
        lengths = [e - s for s, e in windows]
        assert all(length >= 10 for length in lengths)



@pytest.mark.parametrize("warmup", [0, 10, 29, 30, 60, 100, 300, 1000])
def test_warmup_schedule_follows_the_windows(warmup: int) -> None:
    windows = mcmc.warmup_windows(warmup)
    schedule = mcmc.warmup_schedule(warmup)
    assert len(schedule) == warmup
    in_window = [any(s <= it < e for s, e in windows) for it in range(warmup)]
    assert [stage.collect for stage in schedule] == in_window
    assert [it + 1 for it, stage in enumerate(schedule) if stage.window_end] == [e for _, e in windows]
    # Short HMC trajectories exactly until the final buffer (throughout when there are no windows).
    final_buffer = windows[-1][1] if windows else warmup
    assert [stage.short for stage in schedule] == [it < final_buffer for it in range(warmup)]
    fixed = mcmc.warmup_schedule(warmup, adapt_preconditioner=False)
    assert all(stage.short and not stage.collect and not stage.window_end for stage in fixed)


def test_estimate_preconditioner_recovers_covariance() -> None:
    rng = np.random.default_rng(7)
    a = rng.standard_normal((5, 5))
    cov = a @ a.T + 0.5 * np.eye(5)
    draws = rng.multivariate_normal(np.zeros(5), cov, size=(8, 2000))
    est = mcmc.estimate_preconditioner(draws, "dense")
    np.testing.assert_allclose(est.cov, cov, rtol=0.1, atol=0.1 * np.abs(cov).max())
    diag = mcmc.estimate_preconditioner(draws, "diag")
    np.testing.assert_allclose(np.diag(diag.cov), np.diag(cov), rtol=0.1)
    assert np.count_nonzero(diag.cov - np.diag(np.diag(diag.cov))) == 0


def test_estimate_preconditioner_shrinks_few_draws() -> None:
    # 10 draws in 20 dimensions: the raw covariance is singular, the estimate is not.
    draws = np.random.default_rng(8).standard_normal((2, 5, 20))
    est = mcmc.estimate_preconditioner(draws, "dense")
    assert np.all(np.linalg.eigvalsh(est.cov) > 0)


# ------------------------------------------------------------------------------ samplers


def gaussian_target(mean: np.ndarray, cov: np.ndarray):
    precision = np.linalg.inv(cov)

    def log_density(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r = x - mean
        return -0.5 * np.einsum("ki,ij,kj->k", r, precision, r), -r @ precision

    return log_density


@pytest.mark.parametrize("kernel", mcmc.KERNELS)
def test_kernels_sample_a_correlated_gaussian(kernel: str) -> None:
    mean = np.array([1.0, -2.0, 0.5])
    cov = np.array([[1.0, 0.6, 0.0], [0.6, 1.0, 0.2], [0.0, 0.2, 0.25]])
    assert np.all(np.linalg.eigvalsh(cov) > 0.05)
    initial = np.random.default_rng(9).standard_normal((16, 3)) * 3.0
    result = mcmc.sample_chains(gaussian_target(mean, cov), initial, 200, kernel=kernel, warmup=200,
                                thin=2 if kernel == "rwm" else 1, seed=0)
    draws = result.draws
    assert draws.shape == (16, 200, 3)
    ess = mcmc.effective_sample_size(draws)
    flat = draws.reshape(-1, 3)
    sd = np.sqrt(np.diag(cov))
    assert np.all(np.abs(flat.mean(axis=0) - mean) <= 4 * sd / np.sqrt(ess))
    # Variance error: sd of a variance estimate is ~ var * sqrt(2 / ESS).
    assert np.all(np.abs(flat.var(axis=0) - sd**2) <= 4 * sd**2 * np.sqrt(2 / ess))
    assert mcmc.rank_normalized_r_hat(draws).max() < 1.05
    if kernel.startswith("independence"):  # no step to tune: the fitted t proposal itself is accepted often
        assert result.acceptance_rate.mean() > 0.5
    else:
        assert abs(result.acceptance_rate.mean() - mcmc.TARGET_ACCEPT[kernel]) < 0.15


def test_sampler_is_deterministic_per_seed() -> None:
    target = gaussian_target(np.zeros(2), np.eye(2))
    initial = np.random.default_rng(0).standard_normal((4, 2))
    a = mcmc.sample_chains(target, initial, 20, warmup=30, seed=5)
    b = mcmc.sample_chains(target, initial, 20, warmup=30, seed=5)
    c = mcmc.sample_chains(target, initial, 20, warmup=30, seed=6)
    np.testing.assert_array_equal(a.draws, b.draws)
    assert not np.array_equal(a.draws, c.draws)


def test_progress_callback_counts_every_step() -> None:
    seen: list[tuple[int, int]] = []
    target = gaussian_target(np.zeros(2), np.eye(2))
    mcmc.sample_chains(target, np.zeros((2, 2)) + 0.1, 5, warmup=7, thin=2, seed=0,
                       progress=lambda step, total: seen.append((step, total)))
    assert seen == [(i, 17) for i in range(1, 18)]


@pytest.mark.parametrize("kwargs, field", [
    ({"kernel": "nuts"}, "kernel"),
    ({"preconditioner": "full"}, "preconditioner"),
    ({"warmup": -1}, "warmup"),
    ({"thin": 0}, "thin"),
    ({"seed": -3}, "seed"),
    ({"target_accept": 1.5}, "target_accept"),
    ({"num_draws": 0}, "num_draws"),
    ({"initial": np.zeros((1, 2))}, "initial"),
])
def test_sampler_rejects_bad_arguments(kwargs: dict, field: str) -> None:
    args = {"initial": np.zeros((3, 2)), "num_draws": 5} | kwargs
    initial, num_draws = args.pop("initial"), args.pop("num_draws")
    with pytest.raises(ValueError, match=field):
        mcmc.sample_chains(gaussian_target(np.zeros(2), np.eye(2)), initial, num_draws, **args)


def test_gradient_kernels_need_a_gradient() -> None:
    def no_grad(x: np.ndarray) -> tuple[np.ndarray, None]:
        return -0.5 * np.sum(x**2, axis=1), None

    with pytest.raises(ValueError, match="gradient"):
        mcmc.sample_chains(no_grad, np.zeros((2, 2)), 5, kernel="mala", warmup=0)
    result = mcmc.sample_chains(no_grad, np.zeros((2, 2)), 5, kernel="rwm", warmup=0)
    assert result.draws.shape == (2, 5, 2)



# ------------------------------------------------------------------------------ kernels


def test_kernel_table_is_the_single_list_of_kernels() -> None:
    assert mcmc.KERNELS == tuple(mcmc.KERNEL_TABLE)
    assert mcmc.TARGET_ACCEPT == {name: k.target_accept for name, k in mcmc.KERNEL_TABLE.items()}
    for name, kernel in mcmc.KERNEL_TABLE.items():
        assert mcmc_kernels.get_kernel(name) is kernel
    with pytest.raises(ValueError, match="kernel"):
        mcmc_kernels.get_kernel("nuts")


@pytest.mark.parametrize("kernel", mcmc.KERNELS)
def test_one_kernel_step_leaves_the_target_invariant(kernel: str) -> None:
    # Exact draws of N(mean, cov) stay N(mean, cov) after one transition of any kernel, even with
    # a large step and a mismatched preconditioner: 40 000 chains make it a sharp moment test.
    mean, cov = np.array([1.0, -1.0]), np.array([[1.0, 0.8], [0.8, 2.0]])
    rng = np.random.default_rng(4)
    start = rng.multivariate_normal(mean, cov, size=40_000)
    k = mcmc.KERNEL_TABLE[kernel]
    target = gaussian_target(mean, cov)
    state = k.init(start, target)
    params = mcmc.KernelParams(np.full(len(start), 1.2), mcmc.Preconditioner(np.diag([1.0, 0.5])), 3)
    state, info = k.step(rng, state, target, params)
    assert state.position.shape == start.shape and state.log_density.shape == (len(start),)
    assert (state.gradient is None) == (not k.needs_gradient)
    np.testing.assert_allclose(state.log_density, target(state.position)[0])
    if kernel == "elliptical":  # never rejects; one call per shrink of its bracket
        assert info.is_accepted.all() and not np.any(np.all(state.position == start, axis=1))
        assert 1 <= info.num_evaluations <= elliptical_slice.ELLIPTICAL_MAX_SHRINKS
    elif kernel == "independence_elliptical":  # one independence call, then the slice's shrinks
        assert 0.05 < info.is_accepted.mean() < 0.95 and not np.any(np.all(state.position == start, axis=1))
        assert 2 <= info.num_evaluations <= 1 + elliptical_slice.ELLIPTICAL_MAX_SHRINKS
    else:
        assert 0.05 < info.is_accepted.mean() < 0.95  # the step moves the chains
        assert info.num_evaluations == (3 if kernel == "hmc" else 1)
    n = len(start)
    assert np.all(np.abs(state.position.mean(axis=0) - mean) < 5 * np.sqrt(np.diag(cov) / n))
    # sd of a sample variance ~ var sqrt(2 / n); moved and unmoved chains are correlated, so
    # the start's own error is removed by comparing with it.
    drift = np.cov(state.position.T) - np.cov(start.T)
    assert np.all(np.abs(drift) < 5 * np.sqrt(2 / n) * np.sqrt(np.outer(np.diag(cov), np.diag(cov))))


def test_step_info_flags_divergent_transitions() -> None:
    stiff = gaussian_target(np.zeros(2), np.diag([1.0, 1e-4]))
    k = mcmc.KERNEL_TABLE["hmc"]
    state = k.init(np.full((6, 2), 0.01), stiff)
    rng = np.random.default_rng(0)
    _, wild = k.step(rng, state, stiff, mcmc.KernelParams(np.full(6, 5.0), mcmc.Preconditioner.identity(2), 10))
    assert np.all(wild.is_divergent) and not np.any(wild.is_accepted)
    _, tame = k.step(rng, state, stiff, mcmc.KernelParams(np.full(6, 1e-3), mcmc.Preconditioner.identity(2), 10))
    assert not np.any(tame.is_divergent)


def test_gradient_kernel_refuses_a_state_without_gradient() -> None:
    target = gaussian_target(np.zeros(2), np.eye(2))
    state = mcmc.KERNEL_TABLE["rwm"].init(np.zeros((2, 2)), target)
    params = mcmc.KernelParams(np.full(2, 0.1), mcmc.Preconditioner.identity(2))
    for kernel in ("mala", "hmc"):
        with pytest.raises(ValueError, match="state"):
            mcmc.KERNEL_TABLE[kernel].step(np.random.default_rng(0), state, target, params)


def test_sampler_counts_divergences_per_chain() -> None:
    result = mcmc.sample_chains(gaussian_target(np.zeros(2), np.eye(2)), np.zeros((3, 2)) + 0.1, 20,
                                kernel="hmc", warmup=40, seed=1)
    assert result.num_divergent is not None and result.num_divergent.shape == (3,)
    assert np.all(result.num_divergent == 0)
