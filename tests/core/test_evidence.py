"""The joint IRD posterior (docs/spec.md section 7): several training MDPs and answered queries.

Ground truth is brute-force enumeration of every trajectory (``ird_core.mdp.enumeration``) and a 2-d
grid quadrature of the brute-force density.
"""

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
from ird_core.mdp import GridMDP
from ird_core.mdp.enumeration import (
    all_trajectories,
    brute_feature_expectations,
    brute_log_partition,
    trajectory_features,
)

#: The default (calibrated) designer's temperature: the library's behaviour counts are MaxEnt at it.
TAU = I.DEFAULT_OBSERVATION_MODEL.temperature


def tiny_mdp(seed: int, d: int = 3, shape: tuple[int, int] = (2, 3), horizon: int = 2) -> GridMDP:
    rng = np.random.default_rng(seed)
    start = (int(rng.integers(shape[0])), int(rng.integers(shape[1])))
    return GridMDP(rng.normal(size=shape + (d,)), start, horizon)


def random_options(mdp: GridMDP, q: int, rng: np.random.Generator) -> np.ndarray:
    """Feature counts ``(q, d)`` of ``q`` distinct random trajectories of ``mdp``."""
    phi = trajectory_features(mdp, all_trajectories(mdp))
    return phi[rng.choice(len(phi), q, replace=False)]


def brute_joint(weights: np.ndarray, observations: list, beta: float, method: str, sigma: float,
                proxy_samples: np.ndarray) -> np.ndarray:
    """docs/spec.md section 7 written out with enumeration: prior + proxy terms + choice terms; the
    designer's behaviour at the default temperature TAU."""
    total = -0.5 * np.sum(weights**2, axis=1) / sigma**2
    for obs in observations:
        if isinstance(obs, I.ChoiceObservation):
            scores = obs.beta * weights @ obs.option_features.T
            total = total + scores[:, obs.chosen] - logsumexp(scores, axis=1)
            continue
        mdp = obs.train_mdp
        phi = brute_feature_expectations(mdp, obs.proxy_weights[None] / TAU)[0]
        if method == "maxent_z":
            total = total + beta * (weights @ phi - brute_log_partition(mdp, weights))
        else:
            own = np.sum(weights * brute_feature_expectations(mdp, weights / TAU), axis=1)
            phi_i = brute_feature_expectations(mdp, proxy_samples / TAU)  # the same w_i in every MDP
            scores = np.concatenate([own[:, None], weights @ phi_i.T], axis=1)
            total = total + beta * weights @ phi - logsumexp(beta * scores, axis=1)
    return total


def two_worlds_two_answers(seed: int, d: int = 3) -> tuple[list, np.ndarray]:
    rng = np.random.default_rng(seed)
    first, second = tiny_mdp(seed, d), tiny_mdp(seed + 1000, d, shape=(3, 2))
    observations = [
        I.ProxyObservation(rng.normal(size=d), first),
        I.ChoiceObservation(random_options(first, 2, rng), 1, 1.5),
        I.ProxyObservation(rng.normal(size=d), second),
        I.ChoiceObservation(random_options(second, 3, rng), 0, 0.7),
    ]
    return observations, rng.normal(size=(6, d))


# ------------------------------------------------------------------------------ exact values


@pytest.mark.parametrize("method", I.METHODS)
@pytest.mark.parametrize("seed", range(3))
def test_joint_log_posterior_differences_match_enumeration(method: str, seed: int) -> None:
    observations, samples = two_worlds_two_answers(seed)
    rng = np.random.default_rng(50 + seed)
    weights = np.concatenate([rng.normal(size=(5, 3)), 10.0 * rng.normal(size=(2, 3))])
    for beta, sigma in [(0.8, 1.0), (4.0, 0.5), (0.0, 2.0)]:
        got = I.joint_log_posterior(weights, observations, beta, method, sigma, samples)
        want = brute_joint(weights, observations, beta, method, sigma, samples)
        np.testing.assert_allclose(got - got[0], want - want[0], rtol=0, atol=1e-8 * max(1.0, np.abs(want).max()))


@pytest.mark.parametrize("method", I.METHODS)
def test_joint_gradient_matches_finite_differences(method: str) -> None:
    observations, samples = two_worlds_two_answers(7)
    weights = np.random.default_rng(7).normal(size=(4, 3))
    grad = I.joint_log_posterior_grad(weights, observations, 2.0, method, 1.0, samples)
    eps = 1e-5
    for j in range(3):
        e = np.zeros(3)
        e[j] = eps
        fd = (I.joint_log_posterior(weights + e, observations, 2.0, method, 1.0, samples)
              - I.joint_log_posterior(weights - e, observations, 2.0, method, 1.0, samples)) / (2 * eps)
        np.testing.assert_allclose(grad[:, j], fd, rtol=1e-4, atol=1e-5)


def test_choice_term_gradient_is_exact() -> None:
    rng = np.random.default_rng(3)
    weights, options = rng.normal(size=(5, 4)), rng.normal(size=(3, 4))
    value, grad = I.choice_log_likelihood_and_grad(weights, options, 2, 1.7)
    np.testing.assert_allclose(value, I.choice_log_likelihood(weights, options, 2, 1.7), rtol=1e-14)
    p = np.exp(1.7 * weights @ options.T - logsumexp(1.7 * weights @ options.T, axis=1, keepdims=True))
    np.testing.assert_allclose(grad, 1.7 * (options[2] - p @ options), rtol=1e-12, atol=1e-14)


def test_proxies_sharing_a_training_mdp_share_its_pass() -> None:
    # Grouping by MDP object is an optimisation only: a copy of the MDP gives the same density.
    mdp = tiny_mdp(4)
    copy = GridMDP(mdp.features.copy(), mdp.start, mdp.horizon)
    rng = np.random.default_rng(4)
    a, b, weights = rng.normal(size=3), rng.normal(size=3), rng.normal(size=(5, 3))
    for method in I.METHODS:
        shared = I.joint_log_posterior(weights, [I.ProxyObservation(a, mdp), I.ProxyObservation(b, mdp)],
                                       1.3, method, seed=2, num_proxy_samples=9)
        separate = I.joint_log_posterior(weights, [I.ProxyObservation(a, mdp), I.ProxyObservation(b, copy)],
                                         1.3, method, seed=2, num_proxy_samples=9)
        np.testing.assert_allclose(shared, separate, rtol=1e-13)


def test_default_proxy_samples_are_shared_seeded_prior_draws() -> None:
    observations, _ = two_worlds_two_answers(5)
    weights = np.random.default_rng(5).normal(size=(4, 3))
    a = I.joint_log_posterior(weights, observations, 1.0, "sample_z", 0.7, seed=6, num_proxy_samples=25)
    b = I.joint_log_posterior(weights, observations, 1.0, "sample_z", 0.7, I.proxy_prior_samples(25, 3, 0.7, 6))
    np.testing.assert_allclose(a, b, rtol=1e-13)


def test_supplied_proxy_sample_features_override_the_shared_samples() -> None:
    mdp = tiny_mdp(6)
    rng = np.random.default_rng(6)
    proxy, samples, weights = rng.normal(size=3), rng.normal(size=(8, 3)), rng.normal(size=(4, 3))
    phi_i = brute_feature_expectations(mdp, samples / TAU)
    a = I.joint_log_posterior(weights, [I.ProxyObservation(proxy, mdp)], 1.0, "sample_z", 1.0, samples)
    b = I.joint_log_posterior(weights, [I.ProxyObservation(proxy, mdp, proxy_sample_features=phi_i)],
                              1.0, "sample_z", 1.0, 5.0 * samples)
    np.testing.assert_allclose(a, b, rtol=1e-10)


# ------------------------------------------------------------------------------ one proxy == section 3


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), beta=st.floats(0.0, 10.0), sigma=st.floats(0.3, 3.0),
       method=st.sampled_from(I.METHODS), supplied=st.booleans())
def test_one_proxy_observation_is_the_single_proxy_posterior(seed: int, beta: float, sigma: float, method: str,
                                                             supplied: bool) -> None:
    rng = np.random.default_rng(seed)
    mdp = tiny_mdp(seed % 997, shape=(2, 2), horizon=2)
    proxy, samples, weights = rng.normal(size=3), rng.normal(size=(6, 3)), 2.0 * rng.normal(size=(5, 3))
    extra = {"proxy_features": rng.normal(size=3), "proxy_sample_features": rng.normal(size=(4, 3))} \
        if supplied else {}
    observation = I.ProxyObservation(proxy, mdp, extra.get("proxy_features"), extra.get("proxy_sample_features"))
    single = I.log_posterior(weights, proxy, mdp, beta, method, sigma, samples, **extra)
    joint = I.joint_log_posterior(weights, [observation], beta, method, sigma, samples)
    np.testing.assert_allclose(joint, single, rtol=1e-12, atol=1e-12)
    single_grad = I.log_posterior_grad(weights, proxy, mdp, beta, method, sigma, samples, **extra)
    joint_grad = I.joint_log_posterior_grad(weights, [observation], beta, method, sigma, samples)
    np.testing.assert_allclose(joint_grad, single_grad, rtol=1e-12, atol=1e-12)


def test_one_proxy_observation_samples_like_sample_posterior() -> None:
    mdp = tiny_mdp(8)
    proxy = np.array([0.4, -0.3, 0.2])
    for method in I.METHODS:
        a = I.sample_posterior(proxy, mdp, 2.0, method, 200, seed=5, num_proxy_samples=30)
        b = I.sample_joint_posterior([I.ProxyObservation(proxy, mdp)], 2.0, method, 200, 5, num_proxy_samples=30)
        np.testing.assert_array_equal(a.samples, b.samples)
        assert (b.num_proxies, b.num_choices, b.warm_started) == (1, 0, False)
        np.testing.assert_array_equal(b.proxy_weights, proxy)


# ------------------------------------------------------------------------------ Proposition 1


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 2**31 - 1), beta=st.floats(0.0, 8.0), shift=st.floats(-5.0, 5.0),
       method=st.sampled_from(I.METHODS))
def test_proposition_1_holds_for_the_joint_posterior(seed: int, beta: float, shift: float, method: str) -> None:
    # A constant c added to every cell's features adds (T + 1) w . c to every path's return in
    # each MDP. Options are paths of T + 1 states, so their counts move by (T + 1) c too and
    # every choice term is unchanged; the proxy terms are unchanged by section 3's argument.
    rng = np.random.default_rng(seed)
    first, second = tiny_mdp(seed % 991, d=2), tiny_mdp(seed % 983 + 1, d=2, shape=(3, 2), horizon=3)
    c = shift * rng.normal(size=2)
    proxies, samples = rng.normal(size=(2, 2)), rng.normal(size=(5, 2))
    options = [random_options(first, 2, rng), random_options(second, 3, rng)]
    weights = rng.normal(size=(6, 2))

    def observations(offset: np.ndarray) -> list:
        worlds = [m.with_features(m.features + offset) for m in (first, second)]
        return [I.ProxyObservation(proxies[0], worlds[0]), I.ProxyObservation(proxies[1], worlds[1]),
                I.ChoiceObservation(options[0] + (first.horizon + 1) * offset, 0, 1.2),
                I.ChoiceObservation(options[1] + (second.horizon + 1) * offset, 2, 0.6)]

    a = I.joint_log_posterior(weights, observations(np.zeros(2)), beta, method, 1.0, samples)
    b = I.joint_log_posterior(weights, observations(c), beta, method, 1.0, samples)
    magnitude = 1.0 + (1.0 + beta) * np.abs(weights).max() * (4.0 + np.abs(c).max()) * 8
    np.testing.assert_allclose(a - a[0], b - b[0], rtol=0, atol=1e-9 * magnitude)


def test_choices_between_paths_of_unequal_length_are_not_shift_invariant() -> None:
    # Guard: the invariance rests on equal option lengths.
    options = np.array([[1.0, 0.0], [0.0, 1.0]])
    c = np.array([1.0, 1.0])
    weights = np.random.default_rng(0).normal(size=(4, 2))
    a = I.joint_log_posterior(weights, [I.ChoiceObservation(options, 0, 1.0)], 0.0, "maxent_z")
    b = I.joint_log_posterior(weights, [I.ChoiceObservation(options + np.array([[3.0], [2.0]]) * c, 0, 1.0)],
                              0.0, "maxent_z")
    assert np.abs((a - a[0]) - (b - b[0])).max() > 1e-3


# ------------------------------------------------------------------------------ sampling


def brute_quadrature_moments(observations: list, beta: float, method: str, samples: np.ndarray
                             ) -> tuple[np.ndarray, np.ndarray]:
    """Mean (2,) and covariance (2, 2) of the brute-force 2-d joint posterior on a dense grid."""
    return quadrature_moments(lambda pts: brute_joint(pts, observations, beta, method, 1.0, samples))


def assert_moments(post: I.Posterior, chains: int, want_mean: np.ndarray, want_cov: np.ndarray) -> None:
    per_chain = post.num_samples // chains
    draws = post.samples.reshape(per_chain, chains, 2).transpose(1, 0, 2)  # draw-major pooling
    ess = mcmc.effective_sample_size(draws)
    sd = np.sqrt(np.diag(want_cov))
    mean_err = np.abs(draws.reshape(-1, 2).mean(axis=0) - want_mean)
    assert np.all(mean_err <= 4 * sd / np.sqrt(ess)), (mean_err, sd / np.sqrt(ess))
    centred = draws - want_mean
    for i in range(2):  # each variance is the mean of a squared centred draw: its own ESS and sd
        square = centred[..., i] ** 2
        err = abs(square.mean() - want_cov[i, i])
        assert err <= 4 * square.std() / np.sqrt(mcmc.effective_sample_size(square)[0]), (i, err)


def joint_2d(seed: int) -> tuple[list, np.ndarray]:
    rng = np.random.default_rng(seed)
    first, second = tiny_mdp(seed, d=2), tiny_mdp(seed + 1, d=2, shape=(3, 2))
    observations = [I.ProxyObservation(np.array([0.8, -0.5]), first),
                    I.ProxyObservation(np.array([0.3, 0.4]), second),
                    I.ChoiceObservation(random_options(first, 2, rng), 0, 1.0),
                    I.ChoiceObservation(random_options(second, 2, rng), 1, 2.0)]
    return observations, rng.normal(size=(20, 2))


@pytest.mark.parametrize("method", I.METHODS)
def test_joint_sampler_matches_quadrature_in_2d(method: str) -> None:
    observations, samples = joint_2d(21)
    want_mean, want_cov = brute_quadrature_moments(observations, 1.5, method, samples)
    chains = 16
    post = I.sample_joint_posterior(observations, 1.5, method, chains * 125, 1, 1.0, samples,
                                    num_chains=chains)
    assert post.converged and (post.num_proxies, post.num_choices) == (2, 2)
    assert_moments(post, chains, want_mean, want_cov)


@pytest.mark.parametrize("method", I.METHODS)
def test_warm_started_resample_after_an_answer_matches_quadrature(method: str) -> None:
    observations, samples = joint_2d(22)
    chains = 16
    before = I.sample_joint_posterior(observations[:3], 1.5, method, chains * 125, 1, 1.0, samples,
                                      num_chains=chains)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no R-hat warning
        after = I.sample_joint_posterior(observations, 1.5, method, chains * 125, 2, 1.0, samples,
                                         num_chains=chains, initial=before)
    assert after.warm_started and after.converged and after.r_hat_max <= I.R_HAT_CONVERGED
    assert after.warmup == I.DEFAULT_WARM_WARMUP[method] and np.all(np.isnan(after.mode))
    assert after.metric is not None and after.metric.shape == (2, 2)
    want_mean, want_cov = brute_quadrature_moments(observations, 1.5, method, samples)
    assert_moments(after, chains, want_mean, want_cov)
    again = I.sample_joint_posterior(observations, 1.5, method, chains * 125, 2, 1.0, samples,
                                     num_chains=chains, initial=before)
    np.testing.assert_array_equal(after.samples, again.samples)


def test_choices_only_posterior_needs_no_mdp() -> None:
    options = np.array([[2.0, 0.0], [0.0, 2.0]])
    post = I.sample_joint_posterior([I.ChoiceObservation(options, 0, 3.0)], 1.0, "sample_z", 400, 0)
    assert post.num_proxies == 0 and post.proxy_weights.shape == (0,) and post.converged
    assert post.mean[0] > post.mean[1]  # the chosen option's feature is preferred


# ------------------------------------------------------------------------------ arguments


@pytest.mark.parametrize("make, field", [
    (lambda m: I.ProxyObservation(np.ones(2), m), "proxy_weights"),
    (lambda m: I.ProxyObservation(np.array([1.0, np.nan, 0.0]), m), "proxy_weights"),
    (lambda m: I.ProxyObservation(np.ones(3), "map"), "train_mdp"),
    (lambda m: I.ProxyObservation(np.ones(5), m, proxy_features=np.ones(4)), "proxy_features"),
    (lambda m: I.ProxyObservation(np.ones(3), m, proxy_sample_features=np.ones((4, 2))), "proxy_sample_features"),
    (lambda m: I.ChoiceObservation(np.ones((1, 3)), 0, 1.0), "option_features"),
    (lambda m: I.ChoiceObservation(np.ones(3), 0, 1.0), "option_features"),
    (lambda m: I.ChoiceObservation(np.full((2, 3), np.inf), 0, 1.0), "option_features"),
    (lambda m: I.ChoiceObservation(np.ones((2, 3)), 2, 1.0), "chosen"),
    (lambda m: I.ChoiceObservation(np.ones((2, 3)), -1, 1.0), "chosen"),
    (lambda m: I.ChoiceObservation(np.ones((2, 3)), 1.0, 1.0), "chosen"),
    (lambda m: I.ChoiceObservation(np.ones((2, 3)), 0, -1.0), "beta"),
    (lambda m: I.ChoiceObservation(np.ones((2, 3)), 0, float("nan")), "beta"),
])
def test_bad_observations_name_the_field(make, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        make(tiny_mdp(0))


def test_observations_are_frozen_read_only_copies() -> None:
    features = np.ones((2, 3))
    choice = I.ChoiceObservation(features, 1, 2.0)
    features[0, 0] = 5.0
    assert choice.option_features[0, 0] == 1.0 and not choice.option_features.flags.writeable
    with pytest.raises(AttributeError):
        choice.chosen = 0  # type: ignore[misc]


@pytest.mark.parametrize("observations, field", [
    ([], "observations"),
    ("proxy", "observations"),
    ([np.ones(3)], r"observations\[0\]"),
    ([I.ChoiceObservation(np.ones((2, 3)), 0, 1.0), I.ChoiceObservation(np.ones((2, 4)), 0, 1.0)],
     r"observations\[1\]"),
])
def test_bad_observation_lists_name_the_field(observations, field: str) -> None:
    with pytest.raises(ValueError, match=field):
        I.sample_joint_posterior(observations, 1.0, "maxent_z", 10, 0)


def test_weights_of_the_wrong_dimension_are_refused() -> None:
    with pytest.raises(ValueError, match="observations"):
        I.joint_log_posterior(np.ones((2, 4)), [I.ChoiceObservation(np.ones((2, 3)), 0, 1.0)], 1.0, "maxent_z")


def test_bad_initial_is_refused() -> None:
    observations, _ = two_worlds_two_answers(1)
    with pytest.raises(ValueError, match="initial"):
        I.sample_joint_posterior(observations, 1.0, "maxent_z", 10, 0, initial=np.ones((5, 3)))
