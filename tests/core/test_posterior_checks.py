"""checks.check_posterior_arguments: the inference node's up-front checks are sample_posterior's.

Every argument it refuses, ``sample_posterior`` refuses with the same message; what it accepts,
``sample_posterior`` runs on (a tiny grid, a short chain).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from ird_core import checks, posterior
from ird_core.mdp import GridMDP

MDP = GridMDP(np.random.default_rng(1).normal(size=(3, 3, 2)), (0, 1), 2)
GOOD = dict(proxy_weights=np.array([0.3, -0.2]), beta=1.0, method="maxent_z", num_samples=4, prior_sigma=1.0)
BAD = [
    ("method", "maxent"), ("method", ""), ("method", None),
    ("beta", -1.0), ("beta", math.nan), ("beta", math.inf),
    ("num_samples", 0), ("num_samples", 2.5), ("num_samples", True),
    ("prior_sigma", 0.0), ("prior_sigma", -0.5), ("prior_sigma", math.nan),
    ("proxy_weights", np.array([0.3])), ("proxy_weights", np.array([0.3, math.inf])), ("proxy_weights", []),
]


def _sample(args: dict) -> None:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        posterior.sample_posterior(args["proxy_weights"], MDP, args["beta"], args["method"], args["num_samples"],
                                   0, args["prior_sigma"], num_chains=2, warmup=2, thin=1)


@pytest.mark.parametrize("field,value", BAD, ids=[f"{f}={v!r}" for f, v in BAD])
def test_refuses_what_sample_posterior_refuses(field: str, value: object) -> None:
    args = {**GOOD, field: value}
    with pytest.raises(ValueError) as checked:
        checks.check_posterior_arguments(args["proxy_weights"], MDP.num_features, args["beta"], args["method"],
                                            args["num_samples"], args["prior_sigma"])
    assert str(checked.value).startswith(field + ":")
    with pytest.raises(ValueError) as sampled:
        _sample(args)
    assert str(sampled.value) == str(checked.value)


def test_accepts_what_sample_posterior_runs() -> None:
    weights = checks.check_posterior_arguments(GOOD["proxy_weights"], MDP.num_features, GOOD["beta"],
                                                  GOOD["method"], GOOD["num_samples"], GOOD["prior_sigma"])
    assert weights.dtype == np.float64 and np.array_equal(weights, GOOD["proxy_weights"])
    _sample(GOOD)
