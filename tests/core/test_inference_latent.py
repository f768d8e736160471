"""IRD on the latent_raw condition (d = 50): convergence and the lava-uncertainty effect.

Slow (about 3 s per seed) but part of the default suite. It uses the sampler's defaults, which
must bring the rank-normalised split R-hat below 1.05: shorter warm-ups and chains than the
defaults leave it near 1.07 on seed 1, so this also guards the defaults.
"""

from __future__ import annotations

import numpy as np
import pytest

from ird_core import posterior
from ird_core.worlds import lavaland
from ird_core.worlds.terrain import Terrain

#: Lava's posterior reward spread must exceed every safe terrain's by at least this factor.
#: Measured on seed 0 (beta 1): about 5x for w . mu_t and 2.3x per cell (per-cell spreads include
#: the within-terrain observation noise, which every terrain shares).
MEAN_SPREAD_FACTOR = 3.0
CELL_SPREAD_FACTOR = 1.8


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_latent_raw_maxent_converges_and_lava_is_uncertain(seed: int) -> None:
    # The unit-temperature designer with a unit prior: under the calibrated default (sigma 5 in
    # d = 50) these chains do not converge (the next test holds that, docs/experiments.md).
    instance = lavaland.make_instance("latent_raw", seed)
    post = posterior.sample_posterior(instance.proxy_weights, lavaland.train_mdp(instance), 1.0, "maxent_z",
                                      1000, seed=seed, prior_sigma=1.0,
                                      observation_model=posterior.MAXENT_OBSERVATION_MODEL)
    assert post.samples.shape == (1000, 50)
    assert post.r_hat_max <= 1.05, post.r_hat_max
    assert post.converged and post.ess_min >= 100

    # Spread of each terrain's reward: w_i . mu_t over the draws ...
    rewards = post.samples @ instance.observation_model.means.T  # (K, 4), indexed by Terrain
    spread = rewards.std(axis=0)
    safe = [Terrain.DIRT, Terrain.GRASS, Terrain.TARGET]
    assert spread[Terrain.LAVA] >= MEAN_SPREAD_FACTOR * spread[safe].max(), spread
    # ... and per cell of the test map, grouped by terrain.
    cell_sd = np.einsum("kd,hwd->khw", post.samples, instance.test_features).std(axis=0)
    by_terrain = {t: cell_sd[instance.test_labels == t].mean() for t in (*safe, Terrain.LAVA)}  # no gold here
    assert by_terrain[Terrain.LAVA] >= CELL_SPREAD_FACTOR * max(by_terrain[t] for t in safe), by_terrain


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="known: the calibrated prior (sigma 5 in d = 50) leaves latent_raw's MaxEnt-Z "
                                       "chains unconverged (docs/experiments.md, 'The calibrated designer')")
def test_latent_raw_maxent_converges_under_the_calibrated_default() -> None:
    """Strict: passes (and so fails the suite) the day the default converges here, so the docs'
    statement of the regression cannot outlive its fix."""
    instance = lavaland.make_instance("latent_raw", 0)
    post = posterior.sample_posterior(instance.proxy_weights, lavaland.train_mdp(instance), 1.0, "maxent_z",
                                      1000, seed=0)
    assert post.r_hat_max <= 1.05, post.r_hat_max
