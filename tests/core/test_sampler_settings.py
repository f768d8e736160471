"""ird_core.posterior.SamplerSettings: the one record of the sampler's keyword settings."""

from __future__ import annotations

import dataclasses
import inspect

from ird_core import posterior
from ird_core.posterior.settings import NONE_IS_DEFAULT


def test_none_is_passed_only_where_it_is_the_samplers_default() -> None:
    parameters = inspect.signature(posterior.sample_joint_posterior).parameters
    for field in dataclasses.fields(posterior.SamplerSettings):
        assert field.name in parameters
        assert (parameters[field.name].default is None) == (field.name in NONE_IS_DEFAULT), field.name


def test_an_empty_record_is_the_samplers_defaults() -> None:
    assert posterior.SamplerSettings().kwargs() == {name: None for name in NONE_IS_DEFAULT}


def test_set_fields_are_passed() -> None:
    rule = posterior.RunUntil(max_iterations=10)
    kwargs = posterior.SamplerSettings(num_chains=3, kernel="hmc", num_proxy_samples=7, until_converged=rule).kwargs()
    assert kwargs["num_chains"] == 3 and kwargs["kernel"] == "hmc" and kwargs["num_proxy_samples"] == 7
    assert kwargs["until_converged"] is rule
