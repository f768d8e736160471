"""Posteriors with creases (the Sample-Z likelihood at large beta): the elliptical slice kernel,
the Laplace start when Newton stalls, and the profile rescaling of its covariance."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from _quadrature import quadrature_moments
from scipy.optimize import minimize

from ird_core import mcmc
from ird_core import posterior as I
from ird_core.mdp import GridMDP
from ird_core.posterior import laplace
from ird_core.posterior.evidence import make_joint_model
from ird_core.worlds import lavaland

#: The designer model the creased cases were found with: unit temperature (the prior is given as 1).
UNIT = I.MAXENT_OBSERVATION_MODEL

# A 2-d target with creases: a correlated product of Laplace densities, mode at (1, -1).
_MIX = np.array([[1.0, 0.0], [0.7, 1.0]])
_SCALE = np.array([3.0, 1.5])


def _laplace_target(x: np.ndarray) -> tuple[np.ndarray, None]:
    u = (x - np.array([1.0, -1.0])) @ _MIX.T
    return -np.sum(_SCALE * np.abs(u), axis=1), None


def test_elliptical_kernel_samples_a_creased_target() -> None:
    want_mean, want_cov = quadrature_moments(lambda x: _laplace_target(x)[0])
    initial = np.random.default_rng(3).standard_normal((16, 2)) * 2.0
    result = mcmc.sample_chains(_laplace_target, initial, 400, kernel="elliptical", warmup=200, seed=2)
    draws = result.draws
    assert mcmc.rank_normalized_r_hat(draws).max() < 1.05
    ess = mcmc.effective_sample_size(draws)
    sd = np.sqrt(np.diag(want_cov))
    mean_err = np.abs(draws.reshape(-1, 2).mean(axis=0) - want_mean)
    assert np.all(mean_err <= 4 * sd / np.sqrt(ess)), (mean_err, sd / np.sqrt(ess))
    centred = draws - want_mean
    for i, j in [(0, 0), (1, 1), (0, 1)]:
        product = centred[..., i] * centred[..., j]
        err = abs(product.mean() - want_cov[i, j])
        assert err <= 4 * product.std() / np.sqrt(mcmc.effective_sample_size(product)[0]), (i, j, err)
    # No step size: acceptance is 1 by construction and the step is never tuned.
    assert np.all(result.acceptance_rate == 1.0) and result.step_size == 1.0
    # The adapted Gaussian is centred on the draws (the warm-up estimates the mean as well).
    assert np.all(np.abs(result.preconditioner.centre - want_mean) < 0.5)


def test_estimated_preconditioner_carries_the_pooled_mean() -> None:
    draws = np.random.default_rng(0).standard_normal((4, 200, 3)) + np.array([1.0, -2.0, 0.5])
    for kind in mcmc.PRECONDITIONERS:
        pre = mcmc.estimate_preconditioner(draws, kind)
        np.testing.assert_allclose(pre.centre, draws.reshape(-1, 3).mean(axis=0), rtol=1e-12)
    assert np.array_equal(mcmc.Preconditioner.identity(3).centre, np.zeros(3))


@pytest.mark.parametrize("kernel", ["elliptical", "independence_elliptical"])
def test_elliptical_posterior_matches_quadrature_in_2d(kernel: str) -> None:
    # The sampler's Sample-Z posterior, drawn with a gradient-free kernel.
    rng = np.random.default_rng(11)
    mdp = GridMDP(rng.normal(size=(2, 3, 2)), (0, 1), 3)
    proxy, samples = np.array([0.8, -0.5]), rng.normal(size=(20, 2))
    model = I.make_posterior_model(proxy, mdp, 10.0, "sample_z", 1.0, samples)
    want_mean, want_cov = quadrature_moments(model.log_density)
    chains, per_chain = 16, 125
    post = I.sample_posterior(proxy, mdp, 10.0, "sample_z", chains * per_chain, seed=1, prior_sigma=1.0,
                              proxy_samples=samples, num_chains=chains, kernel=kernel)
    assert post.converged and post.kernel == kernel
    draws = post.samples.reshape(per_chain, chains, 2).transpose(1, 0, 2)
    ess = mcmc.effective_sample_size(draws)
    sd = np.sqrt(np.diag(want_cov))
    assert np.all(np.abs(draws.reshape(-1, 2).mean(axis=0) - want_mean) <= 4 * sd / np.sqrt(ess))
    np.testing.assert_allclose(np.cov(draws.reshape(-1, 2).T), want_cov, rtol=0.3, atol=0.05 * sd.max() ** 2)


# ------------------------------------------------------------------------------ Laplace start


def _creased_model(condition: str, size: int, horizon: int, beta: float, seed: int):
    inst = lavaland.make_instance(condition, seed, size=size, horizon=horizon, obs_dim=4)
    return make_joint_model(I.proxy_observations(inst, 20, 3, 1.0, UNIT), beta, "sample_z", 1.0, observation_model=UNIT)


# Cases where damped Newton stalls on a crease (found by search under the unit-temperature designer
# with a unit prior, UNIT; each checked below).
STALLING = [("side_effects", 5, 6, 500.0, 0), ("side_effects", 5, 6, 500.0, 1), ("latent_raw", 15, 30, 50.0, 1)]


@pytest.mark.parametrize("condition, size, horizon, beta, seed", STALLING)
def test_laplace_start_finds_the_mode_past_a_stalled_newton(condition: str, size: int, horizon: int,
                                                            beta: float, seed: int,
                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    model = _creased_model(condition, size, horizon, beta, seed)
    mode, cov = laplace.laplace_approximation(model)
    with monkeypatch.context() as patch:
        patch.setattr(laplace, "_NEWTON_STALL", np.inf)  # Newton alone
        newton, _ = laplace.laplace_approximation(model)
    value = float(model.log_density(mode[None])[0])
    assert value > float(model.log_density(newton[None])[0]) + 0.1  # Newton had stalled

    def negative(w: np.ndarray) -> tuple[float, np.ndarray]:
        v, g = model.log_density_and_grad(w[None])
        return -float(v[0]), -g[0]

    # A local maximum: neither a fresh L-BFGS run nor 2000 nearby points do better.
    assert -minimize(negative, mode, jac=True, method="L-BFGS-B").fun <= value + 1e-6
    nearby = mode + 0.05 * np.random.default_rng(0).standard_normal((2000, model.dim))
    assert model.log_density(nearby).max() <= value + 1e-9
    assert np.all(np.linalg.eigvalsh(cov) > 0)


def test_smooth_posteriors_keep_the_newton_laplace_start(monkeypatch: pytest.MonkeyPatch) -> None:
    # MaxEnt-Z is smooth and log-concave: Newton converges and nothing else runs.
    inst = lavaland.make_instance("latent_raw", 1, size=15, horizon=30, obs_dim=4)
    model = make_joint_model(I.proxy_observations(inst, None, 3, 1.0), 50.0, "maxent_z", 1.0)
    calls: list[str] = []
    monkeypatch.setattr(laplace, "_quasi_newton_mode", lambda *a: calls.append("lbfgs"))
    monkeypatch.setattr(laplace, "_profile_widths", lambda *a: calls.append("profile"))
    laplace.laplace_approximation(model)
    assert calls == []


class _Quadratic:
    """A Gaussian log density with covariance ``cov`` around ``mean`` (the model interface the
    profile needs)."""

    def __init__(self, mean: np.ndarray, cov: np.ndarray) -> None:
        self.mean, self.precision = mean, np.linalg.inv(cov)

    def log_density(self, x: np.ndarray) -> np.ndarray:
        r = x - self.mean
        return -0.5 * np.einsum("ki,ij,kj->k", r, self.precision, r)


def test_profile_keeps_an_exact_gaussian_and_corrects_an_overstated_one() -> None:
    mean = np.array([0.3, -1.0, 2.0])
    a = np.array([[1.0, 0.4, 0.0], [0.0, 0.5, 0.2], [0.3, 0.0, 0.2]])
    cov = a @ a.T + 0.05 * np.eye(3)
    model = _Quadratic(mean, cov)
    np.testing.assert_allclose(laplace._profile_widths(model, mean, cov), cov, rtol=1e-12, atol=1e-14)
    # Axes overstated by 2^5 in sd (1024 in variance) are found exactly: widths are powers of 2.
    eigval, eigvec = np.linalg.eigh(cov)
    inflated = (eigvec * (eigval * 4.0 ** np.array([5, 0, 3]))) @ eigvec.T
    np.testing.assert_allclose(laplace._profile_widths(model, mean, inflated), cov, rtol=1e-9, atol=1e-12)


def test_profile_narrows_a_crease() -> None:
    # Along a crease of slope s the log density drops 1 nat within 1 / s, whatever a Hessian says.
    slope = np.array([400.0, 1.0])

    class Crease:
        def log_density(self, x: np.ndarray) -> np.ndarray:
            return -np.abs(x) @ slope

    width = np.sqrt(np.diag(laplace._profile_widths(Crease(), np.zeros(2), np.eye(2))))
    # Read at the largest 2^-k with drop s 2^-k <= 3 nats, as a Gaussian: 2^-k sqrt(0.5 / (s 2^-k)).
    assert 0.85 / slope[0] < width[0] <= 1.25 / slope[0]
    np.testing.assert_allclose(width[1], np.sqrt(0.5), rtol=1e-12)  # slope 1: read at the full axis


def test_the_mode_start_lets_short_chains_converge_on_a_creased_posterior(monkeypatch: pytest.MonkeyPatch) -> None:
    # latent_raw at 15x15, T = 30, beta 50 (4-d observations, so the test stays fast): from the
    # L-BFGS mode with profiled widths, 4 short chains of either kernel pass R-hat; from the
    # stalled Newton point the elliptical chains do not (seeded, so the values are fixed).
    inst = lavaland.make_instance("latent_raw", 1, size=15, horizon=30, obs_dim=4)
    observations = I.proxy_observations(inst, 20, 3, 1.0, UNIT)
    settings = dict(num_chains=4, warmup=100, thin=4, max_leapfrog=32, observation_model=UNIT)

    def r_hat(kernel: str) -> float:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            return I.sample_joint_posterior(observations, 50.0, "sample_z", 64, 0, 1.0, kernel=kernel,
                                            **settings).r_hat_max

    assert r_hat("hmc") <= 1.05 and r_hat("elliptical") <= 1.1
    monkeypatch.setattr(laplace, "_NEWTON_STALL", np.inf)
    assert r_hat("elliptical") > 1.2
