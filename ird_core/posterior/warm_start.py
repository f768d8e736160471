"""Warm start of the posterior sampler (docs/spec.md section 7): chains that start from a previous
posterior's draws after more evidence was appended, without a Laplace step.

The previous draws are importance-weighted by the new choice terms (closed form, no MDP pass);
``num_chains`` distinct draws picked with those weights start the chains, and the weighted
covariance is the initial metric, re-adapted in a short warm-up
(``ird_core.posterior.sampler.DEFAULT_WARM_WARMUP``, one metric window); the step size is re-tuned
from the sampler's heuristic start.
"""

from __future__ import annotations

import numpy as np

from ird_core.posterior.evidence import PosteriorModel
from ird_core.posterior.likelihoods import choice_log_likelihood
from ird_core.posterior.result import Posterior

__all__ = ["warm_start"]


def warm_start(initial: object, model: PosteriorModel, num_chains: int, rng: np.random.Generator
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Starting points ``(C, d)``, metric factor ``(d, d)`` and centre ``(d,)`` (the weighted
    mean, for the elliptical kernel) from a previous ``Posterior``.

    The previous draws are importance-weighted by the choice terms they were not conditioned on
    (the model's choices after the first ``initial.num_choices``: evidence is appended), which
    costs no MDP pass; ``C`` distinct draws are picked with those weights, and their weighted
    covariance is the initial metric when the weights' effective sample size exceeds ``2 d``
    (else the previous metric). Only efficiency depends on this: the chains are valid from any
    start, and R-hat checks them.
    """
    dim = model.dim
    if not isinstance(initial, Posterior):
        raise ValueError(f"initial: expected a Posterior, got {type(initial).__name__}")
    samples = initial.samples
    if samples.ndim != 2 or samples.shape[1] != dim or not np.all(np.isfinite(samples)):
        raise ValueError(f"initial: expected finite samples of shape (K, {dim}), got {samples.shape}")
    if len(samples) < num_chains:
        raise ValueError(f"initial: needs at least num_chains = {num_chains} samples, got {len(samples)}")
    log_w = np.zeros(len(samples))
    for choice in model.choices[initial.num_choices:]:
        log_w += choice_log_likelihood(samples, choice.option_features, choice.chosen, choice.beta)
    w = np.exp(log_w - log_w.max())
    w /= w.sum()
    starts = samples[rng.choice(len(samples), num_chains, replace=False, p=w)]
    centre = w @ samples
    if 1.0 / np.sum(w**2) > 2 * dim:
        centred = samples - centre
        cov = (centred * w[:, None]).T @ centred
        return starts, np.linalg.cholesky(cov + 1e-9 * np.trace(cov) / dim * np.eye(dim)), centre
    if initial.metric is not None and initial.metric.shape == (dim, dim):
        return starts, initial.metric, centre
    cov = np.atleast_2d(np.cov(samples, rowvar=False))
    return starts, np.linalg.cholesky(cov + 1e-9 * np.trace(cov) / dim * np.eye(dim)), centre
