"""The ROS-free halves of the risk measure (/ird/plan, NavigateIrd) and of the observation model
(/ird/infer, /ird/answer): how a request's fields resolve against the node's defaults, that they
are refused exactly when the library refuses them and named as the request names them, that a
re-sampling keeps the model of the posterior it extends, and that the posterior message carries
the model."""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np
import pytest

from ird_core import planning
from ird_core import posterior as core_posterior
from ird_core.mdp import GridMDP
from ird_core.planning.risk_measures import MIN_RISK, Risk
from ird_core.posterior import ObservationModel, SamplerSettings
from ird_msgs.msg import PlanInfo
from ird_ros import conversions as conv
from ird_ros.jobs.inference import InferenceJob, ResampleJob, observation_model, run_inference, run_resample
from ird_ros.jobs.planning import reported_level, request_risk, risk_text
from ird_ros.nodes.designer import plan_dict

LEVELS = [0.0, math.nan, 0.25, 1.0, 1.5, 50.0, -1.0, 101.0]


def _field(exc: BaseException | None) -> str | None:
    return None if exc is None else str(exc).split(":")[0]


def _outcome(call: Any) -> tuple[Any, str | None]:
    try:
        return call(), None
    except ValueError as exc:
        return None, _field(exc)


@pytest.mark.parametrize("mode", ["per_step", "trajectory"])
@pytest.mark.parametrize("measure", ["min", "cvar", "mean_sd", "worst"])
@pytest.mark.parametrize("level", LEVELS)
def test_a_named_risk_is_refused_exactly_when_plan_path_refuses_it(mode: str, measure: str, level: float) -> None:
    """The node checks before queuing what the library would refuse in the worker, naming the same
    field; what it accepts, plan_path plans with the same measure (0 and NaN = no level for min)."""
    rng = np.random.default_rng(0)
    mdp, weights = GridMDP(rng.normal(size=(3, 3, 2)), (1, 1), 2), rng.normal(size=(3, 2))
    checked, node_field = _outcome(lambda: request_risk(measure, level, MIN_RISK, mode))
    library_level = None if measure == "min" and (level == 0.0 or math.isnan(level)) else level
    plan, library_field = _outcome(lambda: planning.plan_path(mdp, weights, mode, "none", risk=measure,
                                                              risk_level=library_level, time_limit=30.0))
    assert node_field == library_field, (node_field, library_field)
    if plan is not None:
        assert plan.risk == checked or (plan.risk.measure == "min" == checked.measure)


@pytest.mark.parametrize("risk,level,default,expected", [
    ("", 0.0, Risk("cvar", 0.25), Risk("cvar", 0.25)),    # the planner's measure and level
    ("", math.nan, Risk("cvar", 0.25), Risk("cvar", 0.25)),
    ("", 0.5, Risk("cvar", 0.25), Risk("cvar", 0.5)),     # the planner's measure, the request's level
    ("", 0.0, MIN_RISK, MIN_RISK),
    ("min", 0.0, Risk("cvar", 0.25), MIN_RISK),           # a named measure ignores the default
    ("mean_sd", 0.0, Risk("cvar", 0.25), Risk("mean_sd", 0.0)),  # lambda 0 is a level, not "unset"
])
def test_an_empty_risk_takes_the_planners_default(risk: str, level: float, default: Risk, expected: Risk) -> None:
    got = request_risk(risk, level, default, "per_step")
    assert got.measure == expected.measure
    assert got.level == expected.level or (math.isnan(got.level) and math.isnan(expected.level))


def test_refusals_use_the_callers_field_names_and_say_what_empty_meant() -> None:
    with pytest.raises(ValueError, match=r"^risk_level: .*'min' risk measure takes no level.*planner's default 'min'"):
        request_risk("", 0.5, MIN_RISK, "per_step")
    with pytest.raises(ValueError, match=r"^risk_measure: expected one of"):
        request_risk("worst", 0.0, MIN_RISK, "per_step", fields=("risk_measure", "risk_level"))
    with pytest.raises(ValueError, match=r"^risk: mean_sd is a per_step risk measure"):
        request_risk("", 0.0, Risk("mean_sd", 1.0), "trajectory")


def test_risk_text_and_the_reported_level() -> None:
    assert risk_text("per_step", "cvar", 0.25) == "per-step CVaR alpha=0.25"
    assert risk_text("trajectory", "min", 0.0) == "trajectory min"
    assert risk_text("per_step", "mean_sd", 1.0) == "per-step mean - 1 sd"
    assert risk_text("literal", "min", 0.0).startswith("literal")
    assert reported_level(MIN_RISK) == 0.0 and reported_level(Risk("cvar", 0.5)) == 0.5
    info = PlanInfo(label="ird", mode="per_step", baseline="none", risk="cvar", risk_level=0.25)
    shown = plan_dict(info)
    assert (shown["text"], shown["risk"], shown["risk_level"]) == ("per-step CVaR alpha=0.25", "cvar", 0.25)


# --------------------------------------------------------------------------- observation model


def test_an_unset_model_is_the_nodes_and_a_set_one_is_the_requests() -> None:
    node = ObservationModel("optimal", 2.0)
    assert observation_model("", 0.0, node) == node
    assert observation_model("maxent", 0.0, node) == ObservationModel("maxent", 2.0)
    assert observation_model("", 0.5, node) == ObservationModel("optimal", 0.5)
    assert observation_model("", 0.0) == ObservationModel()  # the library's defaults


@pytest.mark.parametrize("counts,temperature,field", [
    ("softmax", 0.0, "proxy_counts"), ("", -1.0, "designer_temperature"), ("", math.nan, "designer_temperature"),
    ("", 1e4, "designer_temperature"), ("maxent", 1e-4, "designer_temperature"),
])
def test_a_bad_model_is_refused_naming_the_request_field(counts: str, temperature: float, field: str) -> None:
    with pytest.raises(ValueError) as caught:
        observation_model(counts, temperature)
    assert str(caught.value).startswith(f"{field}: "), caught.value


def _job(model: ObservationModel) -> InferenceJob:
    rng = np.random.default_rng(1)
    mdp = GridMDP(rng.normal(size=(4, 4, 3)), (0, 0), 4)
    return InferenceJob(mdp, None, np.array([0.5, -1.0, 1.0]), 2.0, "maxent_z", 8, 3, 1.0,
                        SamplerSettings(num_chains=4, warmup=20, thin=1), observation_model=model)


def test_a_resampling_uses_the_model_of_the_posterior_it_extends() -> None:
    optimal = ObservationModel("optimal")
    job = _job(optimal)
    choice = core_posterior.ChoiceObservation(np.array([[1.0, 0.0, 2.0], [0.0, 3.0, 1.0]]), 1, 2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # tiny chains
        first = run_inference(job)
        resampled = run_resample(ResampleJob(job, (choice,), first, 99))
        observation = core_posterior.ProxyObservation(job.proxy_weights, job.train_mdp)
        kwargs = job.sampler.kwargs()
        assert np.array_equal(first.samples, core_posterior.sample_joint_posterior(
            [observation], 2.0, "maxent_z", 8, 3, 1.0, observation_model=optimal, **kwargs).samples)
        kwargs.pop("warmup")
        expected = core_posterior.sample_joint_posterior([observation, choice], 2.0, "maxent_z", 8, 99, 1.0, initial=first,
                                                         observation_model=optimal, **kwargs)
        maxent = core_posterior.sample_joint_posterior([observation, choice], 2.0, "maxent_z", 8, 99, 1.0, initial=first,
                                                       observation_model=ObservationModel("maxent"), **kwargs)
    assert np.array_equal(resampled.samples, expected.samples)
    assert not np.array_equal(resampled.samples, maxent.samples)  # the model matters here


def _posterior(**model: Any) -> conv.PosteriorData:
    return conv.PosteriorData(samples=np.arange(6.0).reshape(2, 3), feature_names=("a", "b", "c"),
                              proxy_weights=np.ones(3), method="maxent_z", beta=1.0, prior_sigma=1.0,
                              acceptance_rate=0.5, r_hat_max=1.0, ess_min=10.0, num_chains=2, seed=0, converged=True,
                              **model)


def test_the_posterior_message_carries_the_model() -> None:
    msg = conv.posterior_to_msg(_posterior(), feature_names=("a", "b", "c"), proxy_weights=np.ones(3),
                                observation_model=ObservationModel("maxent", 0.5))
    assert (msg.proxy_counts, msg.designer_temperature) == ("maxent", 0.5)
    back = conv.posterior_from_msg(msg)
    assert (back.proxy_counts, back.designer_temperature) == ("maxent", 0.5)
    again = conv.posterior_to_msg(back, feature_names=back.feature_names, proxy_weights=back.proxy_weights)
    assert (again.proxy_counts, again.designer_temperature) == ("maxent", 0.5)  # PosteriorData passes it on
    unrecorded = conv.posterior_to_msg(_posterior(), feature_names=("a", "b", "c"), proxy_weights=np.ones(3))
    assert (unrecorded.proxy_counts, unrecorded.designer_temperature) == ("", 0.0)


@pytest.mark.parametrize("model,field", [
    (dict(proxy_counts="softmax"), "proxy_counts"), (dict(designer_temperature=-1.0), "designer_temperature"),
    (dict(designer_temperature=math.nan), "designer_temperature"),
])
def test_a_bad_model_in_a_posterior_message_is_named(model: dict[str, Any], field: str) -> None:
    with pytest.raises(ValueError, match=rf"^RewardPosterior\.{field}: "):
        conv.posterior_to_msg(_posterior(**model), feature_names=("a", "b", "c"), proxy_weights=np.ones(3))
    msg = conv.posterior_to_msg(_posterior(), feature_names=("a", "b", "c"), proxy_weights=np.ones(3))
    setattr(msg, field, model[field])
    with pytest.raises(ValueError, match=rf"^RewardPosterior\.{field}: "):
        conv.posterior_from_msg(msg)
