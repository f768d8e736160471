"""The IRD posterior (ird_core.posterior) against brute-force enumeration and quadrature."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from _quadrature import quadrature_moments
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp

from ird_core import mcmc
from ird_core import posterior as I
from ird_core.mdp import GridMDP, feature_expectations
from ird_core.mdp.enumeration import brute_feature_expectations, brute_log_partition
from ird_core.worlds import lavaland

#: The default (calibrated) designer's temperature: the library's behaviour counts are MaxEnt at it.
TAU = I.DEFAULT_OBSERVATION_MODEL.temperature


def tiny_mdp(seed: int, d: int = 3, shape: tuple[int, int] = (3, 3), horizon: int = 3) -> GridMDP:
    rng = np.random.default_rng(seed)
    start = (int(rng.integers(shape[0])), int(rng.integers(shape[1])))
    return GridMDP(rng.normal(size=shape + (d,)), start, horizon)


def brute_log_posterior(weights: np.ndarray, proxy: np.ndarray, mdp: GridMDP, beta: float, method: str,
                        sigma: float, proxy_samples: np.ndarray) -> np.ndarray:
    """docs/spec.md section 3 with every phi~ and log Z from enumerating all trajectories; the
    designer's behaviour (phi~, the phi_i, the own term) at the default temperature TAU."""
    phi_proxy = brute_feature_expectations(mdp, proxy[None] / TAU)[0]
    prior = -0.5 * np.sum(weights**2, axis=1) / sigma**2
    if method == "maxent_z":
        return beta * (weights @ phi_proxy - brute_log_partition(mdp, weights)) + prior
    own = brute_feature_expectations(mdp, weights / TAU)
    phi_i = brute_feature_expectations(mdp, proxy_samples / TAU)
    scores = np.concatenate([np.sum(weights * own, axis=1)[:, None], weights @ phi_i.T], axis=1)
    return beta * weights @ phi_proxy - logsumexp(beta * scores, axis=1) + prior


# ------------------------------------------------------------------------------ exact values


@pytest.mark.parametrize("method", I.METHODS)
@pytest.mark.parametrize("seed", range(4))
def test_log_posterior_differences_match_enumeration(method: str, seed: int) -> None:
    mdp = tiny_mdp(seed, shape=[(3, 3), (2, 3), (1, 4), (3, 2)][seed], horizon=3 + seed % 2)
    rng = np.random.default_rng(100 + seed)
    proxy = rng.normal(size=3)
    samples = rng.normal(size=(7, 3))
    weights = np.concatenate([rng.normal(size=(5, 3)), 20.0 * rng.normal(size=(2, 3))])
    for beta, sigma in [(0.7, 1.0), (5.0, 0.5), (0.0, 2.0)]:
        got = I.log_posterior(weights, proxy, mdp, beta, method, sigma, samples)
        want = brute_log_posterior(weights, proxy, mdp, beta, method, sigma, samples)
        np.testing.assert_allclose(got - got[0], want - want[0], rtol=0, atol=1e-8 * max(1.0, np.abs(want).max()))


@pytest.mark.parametrize("method", I.METHODS)
def test_gradient_matches_finite_differences(method: str) -> None:
    mdp = tiny_mdp(7)
    rng = np.random.default_rng(7)
    proxy, samples = rng.normal(size=3), rng.normal(size=(6, 3))
    weights = rng.normal(size=(4, 3))
    grad = I.log_posterior_grad(weights, proxy, mdp, 2.0, method, 1.0, samples)
    eps = 1e-5
    for j in range(3):
        e = np.zeros(3)
        e[j] = eps
        fd = (I.log_posterior(weights + e, proxy, mdp, 2.0, method, 1.0, samples)
              - I.log_posterior(weights - e, proxy, mdp, 2.0, method, 1.0, samples)) / (2 * eps)
        np.testing.assert_allclose(grad[:, j], fd, rtol=1e-4, atol=1e-5)


def test_maxent_gradient_formula() -> None:
    mdp = tiny_mdp(8)
    rng = np.random.default_rng(8)
    proxy, weights = rng.normal(size=3), rng.normal(size=(3, 3))
    grad = I.log_posterior_grad(weights, proxy, mdp, 1.5, "maxent_z", 0.5)
    want = (1.5 * (brute_feature_expectations(mdp, proxy[None] / TAU) - brute_feature_expectations(mdp, weights))
            - weights / 0.25)
    np.testing.assert_allclose(grad, want, rtol=1e-8, atol=1e-10)


@pytest.mark.parametrize("beta", [0.0, 1.0, 40.0])
def test_fused_sample_z_value_and_gradient_equal_the_separate_operators(beta: float) -> None:
    # The sampler's hot path evaluates the scores once; it must agree with the two definitions,
    # including when the softmax is nearly one-hot (beta = 40) and the proxies span many BLAS
    # column blocks (N = 3000).
    rng = np.random.default_rng(3)
    weights, own, ray = rng.normal(size=(16, 50)), rng.normal(size=(16, 50)), rng.normal(size=(16, 50))
    proxy, samples = rng.normal(size=50), 3.0 * rng.normal(size=(3000, 50))
    value, grad = I.sample_z_log_likelihood_and_grad(weights, proxy, own, ray, samples, beta)
    np.testing.assert_allclose(value, I.sample_z_log_likelihood(weights, proxy, own, samples, beta),
                               rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(grad, I.sample_z_log_likelihood_grad(weights, proxy, own, ray, samples, beta),
                               rtol=1e-10, atol=1e-9)
    np.testing.assert_allclose(I.sample_z_scores(weights, own, samples, beta)[:, 1:], beta * weights @ samples.T,
                               rtol=1e-12, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), beta=st.floats(0.0, 20.0), scale=st.sampled_from([0.1, 1.0, 5.0]),
       shift=st.floats(-10.0, 10.0), method=st.sampled_from(I.METHODS))
def test_proposition_1_constant_feature_shift(seed: int, beta: float, scale: float, shift: float,
                                              method: str) -> None:
    # Adding a constant vector c to every cell's features adds (T + 1) w . c to every
    # trajectory's return, to log Z and to w . phi~ alike: both posteriors are unchanged.
    rng = np.random.default_rng(seed)
    mdp = tiny_mdp(seed % 1000, d=2, shape=(2, 3), horizon=3)
    c = shift * rng.normal(size=2)
    shifted = mdp.with_features(mdp.features + c)
    proxy, samples = rng.normal(size=2), rng.normal(size=(5, 2))
    weights = scale * rng.normal(size=(6, 2))
    a = I.log_posterior(weights, proxy, mdp, beta, method, 1.0, samples)
    b = I.log_posterior(weights, proxy, shifted, beta, method, 1.0, samples)
    magnitude = 1.0 + beta * np.abs(weights).max() * (np.abs(mdp.features).max() + np.abs(c).max()) * 4
    np.testing.assert_allclose(a - a[0], b - b[0], rtol=0, atol=1e-9 * magnitude)


def test_proposition_1_would_fail_for_a_cell_dependent_shift() -> None:
    # Guard: the property is not vacuous; a non-constant change does move the posterior.
    mdp = tiny_mdp(3, d=2, shape=(2, 3))
    other = mdp.with_features(mdp.features + np.arange(6).reshape(2, 3, 1) * np.array([1.0, 0.0]))
    weights = np.random.default_rng(0).normal(size=(4, 2))
    a = I.log_posterior(weights, np.ones(2), mdp, 1.0, "maxent_z")
    b = I.log_posterior(weights, np.ones(2), other, 1.0, "maxent_z")
    assert np.abs((a - a[0]) - (b - b[0])).max() > 1e-3


def test_supplied_features_override_computation() -> None:
    mdp = tiny_mdp(9)
    rng = np.random.default_rng(9)
    proxy, samples, weights = rng.normal(size=3), rng.normal(size=(4, 3)), rng.normal(size=(3, 3))
    phi = feature_expectations(mdp, proxy[None] / TAU)[0]
    phi_i = feature_expectations(mdp, samples / TAU)
    for method in I.METHODS:
        a = I.log_posterior(weights, proxy, mdp, 1.0, method, 1.0, samples)
        b = I.log_posterior(weights, np.zeros(3), mdp, 1.0, method, 1.0, proxy_features=phi,
                            proxy_sample_features=phi_i)
        np.testing.assert_allclose(a, b, rtol=1e-12)
        c = I.log_posterior(weights, proxy, mdp, 1.0, method, 1.0, samples, proxy_features=phi + 1.0)
        assert not np.allclose(a - a[0], c - c[0])


def test_default_proxy_samples_are_seeded_prior_draws() -> None:
    mdp = tiny_mdp(10)
    weights = np.random.default_rng(10).normal(size=(3, 3))
    a = I.log_posterior(weights, np.ones(3), mdp, 1.0, "sample_z", 0.5, seed=4, num_proxy_samples=30)
    samples = I.proxy_prior_samples(30, 3, 0.5, 4)
    np.testing.assert_allclose(samples, 0.5 * np.random.default_rng(4).standard_normal((30, 3)))
    b = I.log_posterior(weights, np.ones(3), mdp, 1.0, "sample_z", 0.5, samples)
    np.testing.assert_allclose(a, b)
    c = I.log_posterior(weights, np.ones(3), mdp, 1.0, "sample_z", 0.5, seed=5, num_proxy_samples=30)
    assert not np.allclose(a, c)


def test_default_proxy_samples_match_lavaland() -> None:
    instance = lavaland.make_instance("side_effects", 0, size=5, horizon=4)
    mdp = lavaland.train_mdp(instance)
    model = I.make_posterior_model(instance.proxy_weights, mdp, 1.0, "sample_z", seed=3, num_proxy_samples=20)
    np.testing.assert_allclose(model.sample_features, I.proxy_prior_features(instance, 20, 3), atol=1e-10)


# ------------------------------------------------------------------------------ arguments


@pytest.mark.parametrize("kwargs, field", [
    ({"proxy_weights": np.ones(2)}, "proxy_weights"),
    ({"proxy_weights": np.array([1.0, np.nan, 0.0])}, "proxy_weights"),
    ({"train_mdp": "map"}, "train_mdp"),
    ({"beta": -1.0}, "beta"),
    ({"beta": float("inf")}, "beta"),
    ({"beta": float("nan")}, "beta"),
    ({"method": "exact"}, "method"),
    ({"prior_sigma": 0.0}, "prior_sigma"),
    ({"prior_sigma": -1.0}, "prior_sigma"),
    ({"num_samples": 0}, "num_samples"),
    ({"num_samples": 2.5}, "num_samples"),
    ({"seed": -1}, "seed"),
    ({"proxy_samples": np.ones((4, 2))}, "proxy_samples"),
    ({"proxy_features": np.ones(4)}, "proxy_features"),
    ({"proxy_sample_features": np.full((4, 3), np.inf)}, "proxy_sample_features"),
    ({"num_chains": 1}, "num_chains"),
    ({"warmup": -5}, "warmup"),
    ({"thin": 0}, "thin"),
    ({"kernel": "gibbs"}, "kernel"),
    ({"init": "zeros"}, "init"),
    ({"num_proxy_samples": 0}, "num_proxy_samples"),
    ({"trajectory_length": 0.0}, "trajectory_length"),
    ({"trajectory_length": float("nan")}, "trajectory_length"),
    ({"warmup_max_leapfrog": 0}, "warmup_max_leapfrog"),
])
def test_bad_arguments_name_the_field(kwargs: dict, field: str) -> None:
    args = {"proxy_weights": np.ones(3), "train_mdp": tiny_mdp(0), "beta": 1.0, "method": "sample_z",
            "num_samples": 10, "seed": 0} | kwargs
    with pytest.raises(ValueError, match=field):
        I.sample_posterior(**args)


def test_bad_weights_name_the_field() -> None:
    with pytest.raises(ValueError, match="weights"):
        I.log_posterior(np.ones(3), np.ones(3), tiny_mdp(0), 1.0, "maxent_z")
    with pytest.raises(ValueError, match="weights"):
        I.log_posterior(np.full((2, 3), np.nan), np.ones(3), tiny_mdp(0), 1.0, "maxent_z")


# ------------------------------------------------------------------------------ sampling


def posterior_moments(mdp: GridMDP, proxy: np.ndarray, beta: float, method: str, samples: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Mean (2,) and covariance (2, 2) of the exact 2-d posterior on a dense grid.

    A coarse grid over the prior's range locates the mass, then a 241x241 grid over mean +- 8 sd.
    """
    model = I.make_posterior_model(proxy, mdp, beta, method, 1.0, samples)

    return quadrature_moments(model.log_density)


@pytest.mark.parametrize("method", I.METHODS)
@pytest.mark.parametrize("beta", [0.5, 2.0, 10.0])
def test_sampler_matches_quadrature_in_2d(method: str, beta: float) -> None:
    mdp = tiny_mdp(11, d=2, shape=(2, 3), horizon=3)
    rng = np.random.default_rng(11)
    proxy, samples = np.array([0.8, -0.5]), rng.normal(size=(20, 2))
    want_mean, want_cov = posterior_moments(mdp, proxy, beta, method, samples)
    chains, per_chain = 16, 125
    post = I.sample_posterior(proxy, mdp, beta, method, chains * per_chain, seed=1, prior_sigma=1.0,
                              proxy_samples=samples, num_chains=chains)
    assert post.samples.shape == (chains * per_chain, 2) and post.converged
    draws = post.samples.reshape(per_chain, chains, 2).transpose(1, 0, 2)  # draw-major pooling
    sd = np.sqrt(np.diag(want_cov))
    ess = mcmc.effective_sample_size(draws)
    mean_err = np.abs(draws.reshape(-1, 2).mean(axis=0) - want_mean)
    assert np.all(mean_err <= 4 * sd / np.sqrt(ess)), (mean_err, sd / np.sqrt(ess))
    # Each covariance entry is the mean of a product of centred draws: its own ESS and sd.
    centred = draws - want_mean
    for i, j in [(0, 0), (1, 1), (0, 1)]:
        product = centred[..., i] * centred[..., j]
        ess_ij = mcmc.effective_sample_size(product)[0]
        err = abs(product.mean() - want_cov[i, j])
        assert err <= 4 * product.std() / np.sqrt(ess_ij), (i, j, err, product.std() / np.sqrt(ess_ij))


def test_beta_zero_samples_the_prior() -> None:
    post = I.sample_posterior(np.ones(2), tiny_mdp(12, d=2), 0.0, "maxent_z", 2000, seed=0, prior_sigma=2.0)
    assert np.all(np.abs(post.mean) < 4 * 2.0 / np.sqrt(post.ess))
    np.testing.assert_allclose(post.cov, 4.0 * np.eye(2), atol=0.6)


@pytest.mark.filterwarnings("ignore::RuntimeWarning")  # few draws per chain: R-hat is noisy
def test_seeded_determinism() -> None:
    mdp = tiny_mdp(13)
    args = (np.array([0.5, -0.2, 0.1]), mdp, 2.0)
    for method in I.METHODS:
        a = I.sample_posterior(*args, method, 100, seed=3)
        b = I.sample_posterior(*args, method, 100, seed=3)
        c = I.sample_posterior(*args, method, 100, seed=4)
        np.testing.assert_array_equal(a.samples, b.samples)
        assert not np.array_equal(a.samples, c.samples)


def test_posterior_record() -> None:
    mdp = tiny_mdp(14)
    seen: list[tuple[int, int]] = []
    post = I.sample_posterior(np.array([0.5, -0.2, 0.1]), mdp, 2.0, "sample_z", 101, seed=2, num_chains=4,
                              thin=2, warmup=40, progress=lambda s, t: seen.append((s, t)))
    assert post.samples.shape == (101, 3) and post.num_samples == 101
    sigma = 1 / (TAU * I.feature_scale(mdp.features))  # the calibrated prior (posterior.calibration)
    assert (post.method, post.beta, post.prior_sigma, post.seed, post.num_chains) == ("sample_z", 2.0, sigma, 2, 4)
    assert post.num_proxy_samples == I.DEFAULT_NUM_PROXY_SAMPLES and post.kernel == I.DEFAULT_KERNEL
    assert 0.0 < post.acceptance_rate <= 1.0 and post.r_hat.shape == (3,) and post.ess.shape == (3,)
    assert post.r_hat_max == post.r_hat.max() and post.ess_min == post.ess.min()
    assert post.converged == (post.r_hat_max <= 1.1)
    # 26 draws per chain at thin 2 after 40 warm-up steps, one callback per step.
    assert seen[-1] == (40 + 26 * 2, 40 + 26 * 2) and len(seen) == 92
    with pytest.raises(AttributeError):
        post.beta = 3.0  # type: ignore[misc]


def test_unconverged_run_warns() -> None:
    mdp = tiny_mdp(15)
    with pytest.warns(RuntimeWarning, match="R-hat"):
        post = I.sample_posterior(np.array([0.5, -0.2, 0.1]), mdp, 2.0, "maxent_z", 64, seed=0, warmup=0,
                                  thin=1, kernel="rwm", init_scale=100.0)
    assert not post.converged and post.r_hat_max > 1.1


def test_converged_run_does_not_warn() -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        post = I.sample_posterior(np.array([0.5, -0.2, 0.1]), tiny_mdp(16), 1.0, "maxent_z", 400, seed=0)
    assert post.converged


def test_trajectory_options_reach_the_chains() -> None:
    # Same seed: the defaults spelled out give the same run; a longer trajectory costs more
    # leapfrog steps (batched calls), one-step warm-up trajectories fewer, and both change the draws.
    args = dict(proxy_weights=np.array([0.5, -1.0, 0.3]), train_mdp=tiny_mdp(0), beta=2.0, method="maxent_z",
                num_samples=16, seed=3, num_chains=4, warmup=40, max_leapfrog=32, prior_sigma=1 / TAU)
    base = I.sample_posterior(**args)
    same = I.sample_posterior(**args, trajectory_length=I.DEFAULT_TRAJECTORY_LENGTH,
                              warmup_max_leapfrog=I.DEFAULT_WARMUP_MAX_LEAPFROG)
    assert np.array_equal(base.samples, same.samples) and base.num_evaluations == same.num_evaluations
    longer = I.sample_posterior(**args, trajectory_length=3.0)
    capped = I.sample_posterior(**args, warmup_max_leapfrog=1)
    assert longer.num_evaluations > base.num_evaluations > capped.num_evaluations
    assert not np.array_equal(longer.samples, base.samples) and not np.array_equal(capped.samples, base.samples)
