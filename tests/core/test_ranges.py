"""The ranges of ird_core.checks: out-of-range numbers are refused up front by name, by the
node-facing checks and the library functions alike, and a plan's objective is always finite."""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

# The tiny MDP, good arguments and sampler call of the posterior checks' own test.
from test_posterior_checks import GOOD, MDP, _sample

from ird_core import checks, planning, posterior
from ird_core.mdp import GridMDP

# The values of the reliability report (issue: "messages that do not name the field"), and the
# edges of each range.
OUT_OF_RANGE = [
    ("proxy_weights", np.array([1e308, 0.0])), ("proxy_weights", np.array([0.0, -2 * checks.MAX_ABS_WEIGHT])),
    ("beta", 1e308), ("beta", checks.BETA_RANGE[1] * 1.5),
    ("prior_sigma", 1e-300), ("prior_sigma", 1e308), ("prior_sigma", checks.PRIOR_SIGMA_RANGE[0] / 2),
]


@pytest.mark.parametrize("field,value", OUT_OF_RANGE, ids=[f"{f}={v!r}" for f, v in OUT_OF_RANGE])
def test_out_of_range_posterior_arguments_are_named(field: str, value: object) -> None:
    args = {**GOOD, field: value}
    with pytest.raises(ValueError) as checked:
        checks.check_posterior_arguments(args["proxy_weights"], 2, args["beta"], args["method"],
                                         args["num_samples"], args["prior_sigma"])
    assert str(checked.value).startswith(field + ":")
    with pytest.raises(ValueError) as sampled:
        _sample(args)
    assert str(sampled.value) == str(checked.value)


@pytest.mark.parametrize("field,value", [("beta", checks.BETA_RANGE[1]), ("prior_sigma", checks.PRIOR_SIGMA_RANGE[0]),
                                         ("prior_sigma", checks.PRIOR_SIGMA_RANGE[1])])
def test_range_edges_are_accepted(field: str, value: float) -> None:
    assert checks.check_real(field, value, positive=field == "prior_sigma") == value


@pytest.mark.parametrize("weights,reference,field", [
    (np.array([[1e308, 0.0]]), None, "weights"),
    (np.array([[1e308, -1e308]]), None, "weights"),
    (np.array([[0.5, 0.5]]), np.array([1e30, 0.0]), "reference_features"),
])
@pytest.mark.parametrize("mode", planning.MODES)
def test_huge_plan_weights_are_named(weights: np.ndarray, reference: np.ndarray | None, field: str, mode: str) -> None:
    baseline = "training_features" if reference is not None else "none"
    with pytest.raises(ValueError) as checked:
        planning.check_plan_arguments(mode, baseline, weights, 2, reference)
    assert str(checked.value).startswith(field + ":")
    with pytest.raises(ValueError) as planned:
        planning.plan_path(MDP, weights, mode, baseline, reference)
    assert str(planned.value) == str(checked.value)


def test_huge_map_values_are_named() -> None:
    mdp = GridMDP(np.full((3, 3, 2), 1e30), (0, 0), 2)
    with pytest.raises(ValueError, match="^features:"):
        planning.plan_path(mdp, np.ones((1, 2)), "literal")


@pytest.mark.parametrize("mode", planning.MODES)
def test_objective_is_finite_at_the_edges_of_the_ranges(mode: str) -> None:
    big = checks.MAX_ABS_WEIGHT
    mdp = GridMDP(np.random.default_rng(2).choice([-checks.MAX_ABS_FEATURE, checks.MAX_ABS_FEATURE], (3, 3, 2)),
                  (1, 1), 4)
    weights = np.array([[big, -big]]) if mode == "literal" else np.array([[big, -big], [-big, big]])
    plan = planning.plan_path(mdp, weights, mode, "log_z")
    assert math.isfinite(plan.objective)


def test_plan_size_names_the_weights_and_the_limit() -> None:
    planning.check_plan_size(10, 9, 3, 3, max_work=10 * 10 * 9)
    with pytest.raises(ValueError) as exc:
        planning.check_plan_size(200_000, 1000, 15, 15, max_work=50_000_000)
    assert str(exc.value).startswith("weights: 200000 samples x horizon 1000")
    assert "max_plan_work=5e+07" in str(exc.value)
    assert planning.plan_work(200_000, 1000, 15, 15) == 200_000 * 1001 * 225


@pytest.mark.parametrize("method", posterior.METHODS)
def test_posterior_is_finite_at_the_corners_of_the_ranges(method: str) -> None:
    feature, weight = checks.MAX_ABS_FEATURE, checks.MAX_ABS_WEIGHT
    mdp = GridMDP(np.random.default_rng(1).choice([-feature, feature], (3, 3, 2)), (0, 1), 3)
    for beta in (checks.BETA_RANGE[1], 1.0):
        for sigma in checks.PRIOR_SIGMA_RANGE:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                result = posterior.sample_posterior(np.array([weight, -weight]), mdp, beta, method, 4, 0, sigma,
                                                    num_chains=2, warmup=5, thin=1)
            assert np.all(np.isfinite(result.samples))
