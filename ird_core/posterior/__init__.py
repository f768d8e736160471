"""The IRD posterior over true reward weights (docs/spec.md sections 3 and 7).

Modules: ``likelihoods`` (per-term log likelihoods and gradients, proxy feature counts),
``calibration`` (the designer's temperature and the prior's scale, chosen together), ``evidence``
(proxy and choice observations, the joint posterior), ``proxy_terms`` (the one
builder of proxy observations), ``laplace`` (the sampler's start), ``warm_start``,
``run_until`` (extending chains until converged), ``sampler`` (``sample_joint_posterior``),
``result`` (``Posterior``), ``settings`` (``SamplerSettings``, the sampler's keyword record).
"""

from __future__ import annotations

from ird_core.posterior.evidence import (
    ChoiceObservation,
    Observation,
    PosteriorModel,
    ProxyObservation,
    ProxyTerm,
    joint_log_posterior,
    joint_log_posterior_grad,
    log_posterior,
    log_posterior_grad,
    make_joint_model,
    make_posterior_model,
)
from ird_core.posterior.calibration import (
    CALIBRATED_TEMPERATURE,
    PRIOR_RULE,
    feature_scale,
    calibrated_prior_sigma,
    resolve_prior_sigma,
)
from ird_core.posterior.laplace import laplace_approximation
from ird_core.posterior.likelihoods import (
    DEFAULT_NUM_PROXY_SAMPLES,
    METHODS,
    PROXY_BATCH,
    choice_log_likelihood,
    choice_log_likelihood_and_grad,
    log_prior,
    log_prior_grad,
    logsumexp_rows,
    maxent_z_log_likelihood,
    maxent_z_log_likelihood_grad,
    proxy_feature_counts,
    proxy_prior_samples,
    sample_z_log_likelihood,
    sample_z_log_likelihood_and_grad,
    sample_z_log_likelihood_grad,
    sample_z_scores,
)
from ird_core.posterior.observation_model import (
    DEFAULT_OBSERVATION_MODEL,
    MAXENT_OBSERVATION_MODEL,
    ObservationModel,
    behaviour_counts,
)
from ird_core.posterior.proxy_terms import (
    proxy_feature_expectations,
    proxy_observation,
    proxy_observations,
    proxy_prior_features,
)
from ird_core.posterior.result import R_HAT_CONVERGED, Posterior, pool_draws
from ird_core.posterior.run_until import GIVE_UP_R_HAT, RunUntil
from ird_core.posterior.sampler import (
    DEFAULT_INIT_SCALE,
    DEFAULT_KERNEL,
    DEFAULT_MAX_LEAPFROG,
    DEFAULT_MIN_ITERATIONS,
    DEFAULT_NUM_CHAINS,
    DEFAULT_TRAJECTORY_LENGTH,
    DEFAULT_WARM_MIN_ITERATIONS,
    DEFAULT_WARM_WARMUP,
    DEFAULT_WARMUP,
    DEFAULT_WARMUP_MAX_LEAPFROG,
    sample_joint_posterior,
    sample_posterior,
)
from ird_core.posterior.settings import SamplerSettings

__all__ = [
    "METHODS",
    "ObservationModel",
    "CALIBRATED_TEMPERATURE",
    "PRIOR_RULE",
    "feature_scale",
    "calibrated_prior_sigma",
    "resolve_prior_sigma",
    "DEFAULT_OBSERVATION_MODEL",
    "MAXENT_OBSERVATION_MODEL",
    "behaviour_counts",
    "DEFAULT_NUM_PROXY_SAMPLES",
    "PROXY_BATCH",
    "logsumexp_rows",
    "log_prior",
    "log_prior_grad",
    "maxent_z_log_likelihood",
    "maxent_z_log_likelihood_grad",
    "sample_z_scores",
    "sample_z_log_likelihood",
    "sample_z_log_likelihood_grad",
    "sample_z_log_likelihood_and_grad",
    "choice_log_likelihood",
    "choice_log_likelihood_and_grad",
    "proxy_prior_samples",
    "proxy_feature_counts",
    "ProxyObservation",
    "proxy_observation",
    "proxy_observations",
    "proxy_feature_expectations",
    "proxy_prior_features",
    "ChoiceObservation",
    "Observation",
    "ProxyTerm",
    "PosteriorModel",
    "make_joint_model",
    "make_posterior_model",
    "joint_log_posterior",
    "joint_log_posterior_grad",
    "log_posterior",
    "log_posterior_grad",
    "DEFAULT_NUM_CHAINS",
    "DEFAULT_WARMUP",
    "DEFAULT_WARM_WARMUP",
    "DEFAULT_MIN_ITERATIONS",
    "DEFAULT_WARM_MIN_ITERATIONS",
    "DEFAULT_KERNEL",
    "DEFAULT_MAX_LEAPFROG",
    "DEFAULT_TRAJECTORY_LENGTH",
    "DEFAULT_WARMUP_MAX_LEAPFROG",
    "DEFAULT_INIT_SCALE",
    "R_HAT_CONVERGED",
    "GIVE_UP_R_HAT",
    "laplace_approximation",
    "Posterior",
    "RunUntil",
    "SamplerSettings",
    "pool_draws",
    "sample_joint_posterior",
    "sample_posterior",
]
