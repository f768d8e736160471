"""worlds/lava_detour.yaml (issue 42): lava blocks the straight row to the target, and an 11-move
dirt detour fits the horizon of 14. The literal proxy walks into the lava; IRD with the library's
defaults (the calibrated designer, samples in units of their training spread) takes the detour
and reaches the target without touching lava; the unit-temperature designer with a unit prior
(the defaults before) stays on the start cell."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from ird_core import planning, posterior
from ird_core.worlds import evaluation, lavaland, world_file
from ird_core.worlds.terrain import Terrain

WORLD = Path(__file__).resolve().parents[1] / "worlds" / "lava_detour.yaml"


@pytest.fixture(scope="module")
def inst() -> lavaland.LavalandInstance:
    return world_file.load_world(WORLD)


def ird_plan(inst: lavaland.LavalandInstance, method: str, seed: int, model: posterior.ObservationModel,
             prior_sigma: "float | None", scale: bool) -> planning.Plan:
    observations = posterior.proxy_observations(inst, 1000 if method == "sample_z" else None, seed, prior_sigma,
                                                observation_model=model)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        post = posterior.sample_joint_posterior(observations, 50.0, method, 64, seed, prior_sigma,
                                                observation_model=model)
    samples = post.samples
    if scale:
        samples = planning.normalise_samples(samples, [inst.train_features,
                                                       *(w.features for w in inst.extra_training_worlds)])
    reference = observations[0].proxy_features / (inst.train_horizon + 1)
    return planning.plan_path(lavaland.test_mdp(inst), samples, "per_step", "training_features", reference)


def test_the_world_is_the_one_described(inst: lavaland.LavalandInstance) -> None:
    assert inst.test_labels.shape == (10, 12)
    assert len(inst.extra_training_worlds) == 1
    assert inst.test_horizon == 14
    assert not np.any(inst.train_labels == Terrain.LAVA)
    literal = planning.plan_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights[None], "literal")
    assert evaluation.touches_lava(inst.test_labels, literal.cells)


@pytest.mark.slow
@pytest.mark.parametrize("method", ["maxent_z", "sample_z"])
@pytest.mark.parametrize("seed", range(3))
def test_calibrated_ird_takes_the_detour(inst: lavaland.LavalandInstance, method: str, seed: int) -> None:
    plan = ird_plan(inst, method, seed, posterior.ObservationModel(), None, scale=True)
    assert not evaluation.touches_lava(inst.test_labels, plan.cells)
    assert inst.test_labels[plan.cells[-1]] == Terrain.TARGET
    assert len(set(plan.cells)) == 12  # the 11-move detour, then the target


@pytest.mark.slow
def test_the_unit_temperature_designer_stays_on_the_start(inst: lavaland.LavalandInstance) -> None:
    plan = ird_plan(inst, "maxent_z", 0, posterior.MAXENT_OBSERVATION_MODEL, 1.0, scale=False)
    assert set(plan.cells) == {plan.cells[0]}
