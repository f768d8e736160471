"""The pot_of_gold condition (docs/spec.md sections 5 and 7): gold and lava only at test, their shares,
the arbitrary proxy weights, outcomes on hand-made paths, pairing with the other conditions,
rendering, and the paper's four conditions unchanged by the new terrain."""

from __future__ import annotations

import hashlib
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from matplotlib.colors import to_rgb

from ird_core import render
from ird_core.worlds import evaluation
from ird_core.worlds import lavaland as L
from ird_core.worlds.terrain import TERRAIN_COLORS, TEST_MAP, Terrain, place_gold, sample_terrain, terrain_fractions

SEEDS = range(12)


@pytest.fixture(scope="module")
def gold_instances() -> dict[int, L.LavalandInstance]:
    return {s: L.make_instance("pot_of_gold", s) for s in SEEDS}


def test_gold_and_lava_never_in_training_and_indicators_match(gold_instances: dict) -> None:
    for inst in gold_instances.values():
        assert inst.feature_names == ("dirt", "grass", "target", "lava", "gold")
        assert inst.proxy_feature_names == inst.feature_names
        assert not np.any(np.isin(inst.train_labels, (Terrain.LAVA, Terrain.GOLD)))
        assert np.all(inst.train_features[..., 3:] == 0.0)
        for k in range(5):
            assert np.array_equal(inst.test_features[..., k] == 1.0, inst.test_labels == k)
        assert np.all(inst.test_features.sum(axis=-1) == 1.0)


def test_test_maps_hold_about_five_percent_lava_and_three_percent_gold(gold_instances: dict) -> None:
    cells = 15 * 15
    shares = np.array([terrain_fractions(inst.test_labels) for inst in gold_instances.values()])
    # Gold: exactly round(0.03 N) cells on every map (7 of 225).
    assert np.all(shares[:, Terrain.GOLD] * cells == round(L.GOLD_SHARE * cells))
    # Lava: the map distribution's 5% (the MCMC's per-map and mean tolerances).
    assert np.all(np.abs(shares[:, Terrain.LAVA] - 0.05) <= 0.03)
    assert abs(shares[:, Terrain.LAVA].mean() - 0.05) <= 0.01
    assert np.all(shares[:, Terrain.TARGET] * cells == 1)
    small = [L.make_instance("pot_of_gold", s, size=8, horizon=12) for s in range(5)]
    assert all(np.sum(i.test_labels == Terrain.GOLD) == 2 for i in small)  # round(1.92)


def test_pot_of_gold_is_the_paired_test_map_with_gold_on_dirt_or_grass(gold_instances: dict) -> None:
    for s, inst in gold_instances.items():
        base = L.make_instance("side_effects", s)
        assert np.array_equal(inst.train_labels, base.train_labels)
        assert (inst.train_start, inst.test_start) == (base.train_start, base.test_start)
        gold = inst.test_labels == Terrain.GOLD
        assert np.array_equal(inst.test_labels[~gold], base.test_labels[~gold])
        assert np.all(np.isin(base.test_labels[gold], (Terrain.DIRT, Terrain.GRASS)))
        assert inst.test_labels[inst.test_start] not in (Terrain.LAVA, Terrain.GOLD, Terrain.TARGET)


def test_proxy_is_intended_on_safe_terrain_and_arbitrary_on_lava_and_gold(gold_instances: dict) -> None:
    lava, gold = [], []
    for s, inst in gold_instances.items():
        w = inst.proxy_weights
        assert np.array_equal(w[:3], L.INTENDED_SAFE_REWARD)
        assert L.LAVA_PROXY_RANGE[0] <= w[3] <= L.LAVA_PROXY_RANGE[1]
        assert L.GOLD_PROXY_RANGE[0] <= w[4] <= L.GOLD_PROXY_RANGE[1]
        # The lava weight is side_effects' (same proxy stream), the gold weight a new draw.
        assert w[3] == L.make_instance("side_effects", s).proxy_weights[3]
        lava.append(w[3])
        gold.append(w[4])
    assert len(set(gold)) == len(gold) and len(set(lava)) == len(lava)
    assert min(gold) < 0 < max(gold)  # 12 draws of U(-1, 1): both signs (probability 1 - 2^-11)


def test_true_reward_of_gold_is_well_above_the_target() -> None:
    assert L.TRUE_TERRAIN_REWARD[Terrain.GOLD] >= 2 * L.TRUE_TERRAIN_REWARD[Terrain.TARGET]
    assert L.TRUE_TERRAIN_REWARD.shape == (len(Terrain),)


def test_outcomes_on_a_hand_made_path() -> None:
    labels = np.array([[Terrain.DIRT, Terrain.GOLD, Terrain.GRASS],
                       [Terrain.LAVA, Terrain.TARGET, Terrain.DIRT],
                       [Terrain.DIRT, Terrain.GRASS, Terrain.GOLD]], dtype=np.int8)
    # Start (0, 0) dirt, gold, gold again (stay), target, lava: T + 1 = 5 cells, start included.
    path = [(0, 0), (0, 1), (0, 1), (1, 1), (1, 0)]
    assert evaluation.true_return(labels, path) == pytest.approx(0.1 + 3.0 + 3.0 + 1.0 - 10.0, abs=1e-12)
    assert evaluation.reaches_gold(labels, path) and evaluation.touches_lava(labels, path) and evaluation.reaches_target(labels, path)
    safe = [(0, 0), (0, 0), (0, 0)]
    assert not evaluation.reaches_gold(labels, safe) and not evaluation.touches_lava(labels, safe)
    assert evaluation.reaches_gold(labels, [(1, 2), (2, 2)])
    with pytest.raises(ValueError, match="cells"):
        evaluation.reaches_gold(labels, [(3, 0)])


def test_place_gold_counts_and_errors() -> None:
    labels = sample_terrain(TEST_MAP, 4)
    out = place_gold(labels, 0.03, 1, exclude=(0, 0))
    changed = out != labels
    assert np.all(out[changed] == Terrain.GOLD) and changed.sum() == 7
    assert np.all(np.isin(labels[changed], (Terrain.DIRT, Terrain.GRASS)))
    assert np.array_equal(out, place_gold(labels, 0.03, 1, exclude=(0, 0)))
    assert not np.any(labels == Terrain.GOLD)  # input untouched
    assert np.sum(place_gold(np.zeros((3, 3), np.int8), 0.01, 0) == Terrain.GOLD) == 1  # at least one
    with pytest.raises(ValueError, match="share"):
        place_gold(labels, 0.0, 0)
    with pytest.raises(ValueError, match="exclude"):
        place_gold(labels, 0.03, 0, exclude=(99, 0))
    with pytest.raises(ValueError, match="share"):
        place_gold(np.full((3, 3), Terrain.LAVA, np.int8), 0.5, 0)


def test_make_instance_accepts_pot_of_gold_but_the_paper_conditions_stay_four() -> None:
    assert L.CONDITIONS == ("side_effects", "reward_hacking", "latent_raw", "latent_classifier")
    assert L.ALL_CONDITIONS == L.CONDITIONS + ("pot_of_gold",)
    a = L.make_instance("pot_of_gold", 3, size=3, horizon=3)
    b = L.make_instance("pot_of_gold", 3, size=3, horizon=3)
    assert np.array_equal(a.test_features, b.test_features) and np.array_equal(a.proxy_weights, b.proxy_weights)
    assert np.sum(a.test_labels == Terrain.GOLD) == 1
    with pytest.raises(ValueError, match="condition"):
        L.make_instance("pot_of_lead", 0)


def test_gold_has_its_own_colour_and_legend_entry(tmp_path: Path, gold_instances: dict) -> None:
    inst = gold_instances[0]
    assert len(set(TERRAIN_COLORS)) == len(TERRAIN_COLORS) == len(Terrain)
    path = tmp_path / "gold.png"
    render.save_mission_figure(path, inst.train_labels, inst.test_labels, {}, title="gold",
                               test_start=inst.test_start)
    image = mpimg.imread(path)[..., :3]
    gold = np.all(np.abs(image - np.array(to_rgb(TERRAIN_COLORS[Terrain.GOLD]))) <= 2.5 / 255, axis=-1)
    assert gold.any()
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    figure = Figure()
    FigureCanvasAgg(figure)
    ax = figure.subplots()
    render.draw_terrain(ax, inst.test_labels)
    assert "gold" in [t.get_text() for t in ax.get_legend().get_texts()]
    render.draw_terrain(ax, inst.train_labels)
    assert "gold" not in [t.get_text() for t in ax.get_legend().get_texts()]


# Fingerprints of the paper's four conditions (8x8, T = 12, obs_dim 10), recorded from the code
# before the gold terrain existed: labels hash, (train start, test start), index-weighted sums of
# the test, train and proxy-test features, and the first proxy weights.
FINGERPRINTS = {
    ("side_effects", 0): ("7fc9619142f2cc14", (5, 1, 6, 5), 191.0, 125.0, 63.0, [0.1, -0.2, 1.0, -0.38924450014955836]),
    ("side_effects", 1): ("3edb3e6a91b210c1", (4, 2, 2, 0), 203.0, 131.0, 64.0, [0.1, -0.2, 1.0, -0.4126808565523994]),
    ("reward_hacking", 0): ("7fc9619142f2cc14", (5, 1, 6, 5), 376.0, 256.0, 51.0, [0.030537774992522082, -0.004729915954436281, 0.6180396658643161, 0.06946222500747792]),
    ("reward_hacking", 1): ("3edb3e6a91b210c1", (4, 2, 2, 0), 393.0, 248.0, 47.0, [0.029365957172380032, -0.125399363503626, 0.5281925308244695, 0.07063404282761997]),
    ("latent_raw", 0): ("7fc9619142f2cc14", (5, 1, 6, 5), 512.4748276188266, 340.2831936704912, 149.75077740932193, [0.06220484637807508, -0.05850220055312151, -0.058887775411918, -0.01751558830082358]),
    ("latent_raw", 1): ("3edb3e6a91b210c1", (4, 2, 2, 0), 657.7708967747444, 405.9751318079342, 173.96211146925302, [0.026909517816821844, -0.02668215910657141, 0.032828440761037345, -0.0690571647627349]),
    ("latent_classifier", 0): ("7fc9619142f2cc14", (5, 1, 6, 5), 512.4748276188266, 340.2831936704912, 27.78576357294317, [0.1, -0.2, 1.0]),
    ("latent_classifier", 1): ("3edb3e6a91b210c1", (4, 2, 2, 0), 657.7708967747444, 405.9751318079342, 23.246107516921803, [0.1, -0.2, 1.0]),
}


def _weighted_sum(array: np.ndarray, modulus: int) -> float:
    return float((array * (np.arange(array.size).reshape(array.shape) % modulus)).sum())


@pytest.mark.parametrize(("condition", "seed"), sorted(FINGERPRINTS))
def test_paper_conditions_are_unchanged_by_the_gold_terrain(condition: str, seed: int) -> None:
    labels_hash, starts, test_sum, train_sum, proxy_sum, weights = FINGERPRINTS[condition, seed]
    inst = L.make_instance(condition, seed, size=8, horizon=12, obs_dim=10)
    got = hashlib.sha256(inst.train_labels.astype(np.int8).tobytes()
                         + inst.test_labels.astype(np.int8).tobytes()).hexdigest()[:16]
    assert got == labels_hash
    assert (*inst.train_start, *inst.test_start) == starts
    assert _weighted_sum(inst.test_features, 7) == pytest.approx(test_sum, rel=1e-10)
    assert _weighted_sum(inst.train_features, 5) == pytest.approx(train_sum, rel=1e-10)
    assert _weighted_sum(inst.proxy_test_features, 3) == pytest.approx(proxy_sum, rel=1e-10)
    assert np.allclose(inst.proxy_weights[: len(weights)], weights, rtol=1e-10, atol=0)
    assert not np.any(inst.test_labels == Terrain.GOLD)
    if condition == "side_effects":
        assert inst.feature_names == ("dirt", "grass", "target", "lava")
