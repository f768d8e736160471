"""Running the chains until the diagnostics pass: ``mcmc.continue_chains`` and
``sample_joint_posterior(until_converged=RunUntil(...))``."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from ird_core import mcmc, posterior
from ird_core.posterior import RunUntil
from ird_core.worlds import lavaland

# A 5x5 world whose short run (4 chains, 20 warm-up iterations, 120 after) has split R-hat
# above 1.05 for seed 1 and mixes when run longer (seeds found under the unit-temperature
# designer with a unit prior, which the runs keep).
SHORT = dict(num_chains=4, warmup=20, prior_sigma=1.0, observation_model=posterior.MAXENT_OBSERVATION_MODEL)
SEED_UNMIXED = 1
SEED_MIXED = 0  # the same short run already passes: R-hat <= 1.05, ESS >= 400
NUM_SAMPLES = 12


@pytest.fixture(scope="module")
def world() -> tuple[np.ndarray, object]:
    inst = lavaland.make_instance("side_effects", 4, size=5, horizon=6)
    return inst.proxy_weights, lavaland.train_mdp(inst)


def _sample(world: tuple, seed: int, **kwargs: object) -> posterior.Posterior:
    proxy, mdp = world
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return posterior.sample_posterior(proxy, mdp, 2.0, "maxent_z", NUM_SAMPLES, seed, **{**SHORT, **kwargs})


def _gaussian(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    a = np.array([[2.0, 0.3], [0.3, 0.5]])
    return -0.5 * np.einsum("ij,jk,ik->i", x, a, x), -(x @ a)


@pytest.mark.parametrize("kernel", mcmc.KERNELS)
def test_continuing_equals_a_longer_run(kernel: str) -> None:
    x0 = 3.0 * np.random.default_rng(1).standard_normal((4, 2))
    full = mcmc.sample_chains(_gaussian, x0, 50, kernel=kernel, warmup=40, seed=3)
    head = mcmc.sample_chains(_gaussian, x0, 20, kernel=kernel, warmup=40, seed=3)
    tail = mcmc.continue_chains(_gaussian, head.continuation, 30)
    assert np.array_equal(full.draws, np.concatenate([head.draws, tail.draws], axis=1))
    assert np.array_equal(full.log_density, np.concatenate([head.log_density, tail.log_density], axis=1))
    assert full.num_evaluations == head.num_evaluations + tail.num_evaluations
    assert (tail.step_size, tail.warmup, tail.thin) == (head.step_size, 0, 1)
    # A continuation is a snapshot: continuing from it again gives the same draws, and
    # continuing the continuation extends further along the same stream.
    assert np.array_equal(mcmc.continue_chains(_gaussian, head.continuation, 30).draws, tail.draws)
    more = mcmc.continue_chains(_gaussian, mcmc.continue_chains(_gaussian, head.continuation, 10).continuation, 20)
    assert np.array_equal(more.draws, tail.draws[:, 10:])


def test_continue_chains_rejects_a_bad_length() -> None:
    head = mcmc.sample_chains(_gaussian, np.ones((2, 2)), 5, kernel="hmc", warmup=0, seed=0)
    with pytest.raises(ValueError, match="num_draws"):
        mcmc.continue_chains(_gaussian, head.continuation, 0)


def test_run_until_mixes_a_run_the_short_default_leaves_unmixed(world: tuple) -> None:
    fixed = _sample(world, SEED_UNMIXED)
    assert fixed.r_hat_max > 1.05 and fixed.iterations == 120 and fixed.run_until is None
    rule = RunUntil(r_hat=1.05, min_ess=400.0)
    post = _sample(world, SEED_UNMIXED, until_converged=rule)
    assert post.r_hat_max <= 1.05 and post.ess_min >= 400.0
    assert post.converged and post.stop_reason == "converged" and post.run_until == rule
    assert post.iterations > 120 and post.samples.shape == (NUM_SAMPLES, fixed.samples.shape[1])
    assert np.all(np.isfinite(post.samples))
    assert post.num_evaluations > fixed.num_evaluations
    assert "converged after" in post.diagnosis()
    # Deterministic for a seed (the time budget was not what stopped it).
    again = _sample(world, SEED_UNMIXED, until_converged=rule)
    assert np.array_equal(again.samples, post.samples) and again.iterations == post.iterations
    assert again.r_hat_max == post.r_hat_max and again.ess_min == post.ess_min


def test_required_ess_grows_with_the_samples_asked_for() -> None:
    rule = RunUntil(min_ess=400.0, ess_per_sample=0.5)
    assert rule.required_ess(12) == 400.0 and rule.required_ess(2000) == 1000.0


def test_a_run_converged_at_the_first_check_is_the_fixed_length_run(world: tuple) -> None:
    fixed = _sample(world, SEED_MIXED)
    post = _sample(world, SEED_MIXED, until_converged=RunUntil())
    assert post.stop_reason == "converged" and post.iterations == fixed.iterations == 120
    assert np.array_equal(post.samples, fixed.samples)
    assert np.array_equal(post.r_hat, fixed.r_hat) and np.array_equal(post.ess, fixed.ess)
    assert (post.acceptance_rate, post.num_evaluations, post.thin, post.step_size) == (
        fixed.acceptance_rate, fixed.num_evaluations, fixed.thin, fixed.step_size)


def test_the_iteration_cap_is_honoured_and_reported(world: tuple) -> None:
    with pytest.warns(RuntimeWarning, match="iteration cap 200"):
        proxy, mdp = world
        post = posterior.sample_posterior(proxy, mdp, 2.0, "maxent_z", NUM_SAMPLES, SEED_UNMIXED,
                                          until_converged=RunUntil(max_iterations=200), **SHORT)
    assert post.iterations == 200 and post.stop_reason == "max_iterations"
    assert not post.converged
    assert "not converged: iteration cap 200 reached after 200 iterations per chain" in post.diagnosis()
    # A cap below the first run's length never shortens it.
    short = _sample(world, SEED_UNMIXED, until_converged=RunUntil(max_iterations=10))
    assert short.iterations == 120 and short.stop_reason == "max_iterations"


def test_the_time_budget_is_a_safety_stop(world: tuple) -> None:
    post = _sample(world, SEED_UNMIXED, until_converged=RunUntil(time_budget_s=1e-9))
    assert post.stop_reason == "time_budget" and post.iterations == 120 and not post.converged
    assert "time budget 1e-09 s spent" in post.diagnosis()


def test_warm_start_runs_until_converged(world: tuple) -> None:
    proxy, mdp = world
    first = _sample(world, SEED_MIXED)
    choice = posterior.ChoiceObservation(np.random.default_rng(0).normal(size=(3, mdp.num_features)), 1, 1.0)
    evidence = [posterior.ProxyObservation(proxy, mdp), choice]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        fixed = posterior.sample_joint_posterior(evidence, 2.0, "maxent_z", NUM_SAMPLES, 5, 1.0, initial=first,
                                                 num_chains=4, observation_model=SHORT["observation_model"])
        post = posterior.sample_joint_posterior(evidence, 2.0, "maxent_z", NUM_SAMPLES, 5, 1.0, initial=first,
                                                num_chains=4, observation_model=SHORT["observation_model"], until_converged=RunUntil())
    assert post.warm_started and post.stop_reason == "converged"
    assert post.r_hat_max <= 1.05 and post.ess_min >= 400.0
    if post.iterations == fixed.iterations:  # converged at the first check: the fixed run itself
        assert np.array_equal(post.samples, fixed.samples)


@pytest.mark.parametrize("kwargs, field", [
    (dict(r_hat=0.9), "until_converged.r_hat"),
    (dict(r_hat=float("nan")), "until_converged.r_hat"),
    (dict(min_ess=-1.0), "until_converged.min_ess"),
    (dict(ess_per_sample=float("inf")), "until_converged.ess_per_sample"),
    (dict(max_iterations=0), "until_converged.max_iterations"),
    (dict(time_budget_s=0.0), "until_converged.time_budget_s"),
    (dict(check_every=-1), "until_converged.check_every"),
])
def test_bad_criteria_name_the_field(kwargs: dict, field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field}"):
        RunUntil(**kwargs)


def test_until_converged_must_be_a_run_until(world: tuple) -> None:
    with pytest.raises(ValueError, match="^until_converged"):
        _sample(world, 0, until_converged=1.05)


def test_a_hopeless_run_gives_up_at_its_first_check_past_give_up_after(world: tuple, monkeypatch) -> None:
    from ird_core.posterior import run_until

    monkeypatch.setattr(run_until, "GIVE_UP_R_HAT", 1.0)  # every unconverged check is "hopeless"
    rule = RunUntil(r_hat=1.05, min_ess=400.0, give_up_after=100)
    post = _sample(world, SEED_UNMIXED, until_converged=rule)
    # The first check (120 iterations) is past 100 and not converged: stop there, not at the cap.
    assert post.stop_reason == "futile" and post.iterations == 120 and not post.converged
    assert "given up (R-hat above 1)" in post.diagnosis()
    # Past the first check only: with give_up_after beyond it, the run is extended as usual.
    later = _sample(world, SEED_UNMIXED, until_converged=RunUntil(r_hat=1.05, min_ess=400.0, give_up_after=121))
    assert later.iterations > 120
    # Convergence is tested first: a run that passes at a check never gives up there.
    mixed = _sample(world, SEED_MIXED, until_converged=RunUntil(give_up_after=1))
    assert mixed.stop_reason == "converged" and mixed.iterations == 120


def test_give_up_after_is_validated() -> None:
    with pytest.raises(ValueError, match="give_up_after"):
        RunUntil(give_up_after=-1)


def test_check_every_sets_the_checks_after_the_first(world: tuple) -> None:
    rule = RunUntil(r_hat=1.05, min_ess=400.0)
    default = _sample(world, SEED_UNMIXED, until_converged=rule)
    assert (default.iterations - 120) % 120 == 0  # blocks of max(n0, 50) = 120
    fine = _sample(world, SEED_UNMIXED, until_converged=RunUntil(r_hat=1.05, min_ess=400.0, check_every=7))
    assert fine.converged and fine.iterations > 120 and (fine.iterations - 120) % 7 == 0
    # On this seed the fine schedule stops 118 iterations earlier (722 against 840): the saving
    # check_every is for (not a theorem: a window that passes at 840 need not pass at 839).
    assert fine.iterations < default.iterations - 7
    # The same chains: the first check (120) is the fixed-length run's, whatever the block.
    first = _sample(world, SEED_MIXED, until_converged=RunUntil(check_every=7))
    assert first.iterations == 120 and np.array_equal(first.samples, _sample(world, SEED_MIXED).samples)
