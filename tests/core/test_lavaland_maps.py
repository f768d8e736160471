"""Lavaland map distribution: shares, clumping, the role of each MCMC term, exactness, seeding."""

from __future__ import annotations

import dataclasses
import itertools
import time

import numpy as np
import pytest

from ird_core.worlds import terrain as T
from ird_core.worlds.terrain import TEST_MAP, TRAIN_MAP, MapConfig, Terrain

SEEDS = range(10)
PER_MAP_TOLERANCE = 0.03  # every map's share of dirt/grass/lava vs the config (15x15)
MEAN_TOLERANCE = 0.01  # mean share over SEEDS vs the config


def mcmc_shares(labels: np.ndarray) -> np.ndarray:
    """(4,) shares among the non-target cells: what the MCMC controls (targets come after)."""
    kept = labels[labels != Terrain.TARGET].astype(np.int64)
    return np.bincount(kept, minlength=T.NUM_TERRAINS) / kept.size


@pytest.mark.parametrize("config", [TRAIN_MAP, TEST_MAP], ids=["train", "test"])
def test_shares_match_config(config: MapConfig) -> None:
    shares = np.array([mcmc_shares(T.sample_terrain(config, s)) for s in SEEDS])
    assert np.all(np.abs(shares - config.ratios) <= PER_MAP_TOLERANCE), shares
    assert np.all(np.abs(shares.mean(axis=0) - config.ratios) <= MEAN_TOLERANCE)


@pytest.mark.parametrize("config", [TRAIN_MAP, TEST_MAP], ids=["train", "test"])
def test_neighbour_agreement_far_above_independent_baseline(config: MapConfig) -> None:
    rng = np.random.default_rng(0)
    maps = [T.sample_terrain(config, s) for s in SEEDS]
    agreement = np.mean([T.neighbour_agreement(m) for m in maps])
    # Baseline: the same maps with their cells shuffled (same shares, independent positions);
    # it must match the closed form sum_k s_k^2 and be far below the sampled maps.
    shuffled = np.mean(
        [T.neighbour_agreement(rng.permutation(m.ravel()).reshape(m.shape)) for m in maps for _ in range(5)]
    )
    closed_form = np.mean([T.independent_agreement(T.terrain_fractions(m)) for m in maps])
    assert abs(shuffled - closed_form) < 0.02
    assert agreement > closed_form + 0.15, (agreement, closed_form)


def test_ratio_term_matters() -> None:
    no_ratio = dataclasses.replace(TRAIN_MAP, ratio_weight=0.0)
    with_ratio = np.array([mcmc_shares(T.sample_terrain(TRAIN_MAP, s)) for s in SEEDS])
    without = np.array([mcmc_shares(T.sample_terrain(no_ratio, s)) for s in SEEDS])
    # Without the cost the coarsening drifts towards one terrain; with it, shares hold.
    assert np.mean(np.abs(without[:, Terrain.DIRT] - 0.7)) > 0.1
    assert np.mean(np.abs(with_ratio[:, Terrain.DIRT] - 0.7)) < 0.01


def test_neighbour_term_makes_the_patches() -> None:
    no_coupling = dataclasses.replace(TRAIN_MAP, neighbour_weight=0.0)
    maps = [T.sample_terrain(no_coupling, s) for s in SEEDS]
    agreement = np.mean([T.neighbour_agreement(m) for m in maps])
    baseline = np.mean([T.independent_agreement(T.terrain_fractions(m)) for m in maps])
    assert abs(agreement - baseline) < 0.04


def test_seeded_determinism() -> None:
    a = T.sample_terrain(TEST_MAP, 7)
    assert np.array_equal(a, T.sample_terrain(TEST_MAP, 7))
    assert not np.array_equal(a, T.sample_terrain(TEST_MAP, 8))
    from_generator = T.sample_terrain(TEST_MAP, np.random.default_rng(7))
    assert np.array_equal(from_generator, a)


def test_train_maps_have_no_lava_and_test_maps_do() -> None:
    for s in SEEDS:
        train = T.sample_terrain(TRAIN_MAP, s)
        test = T.sample_terrain(TEST_MAP, s)
        assert train.dtype == np.int8 and train.shape == (15, 15)
        assert not np.any(train == Terrain.LAVA)
        assert np.any(test == Terrain.LAVA)
        assert np.sum(train == Terrain.TARGET) == TRAIN_MAP.num_targets
        assert np.sum(test == Terrain.TARGET) == TEST_MAP.num_targets


@pytest.mark.parametrize("shape", [(3, 3), (3, 7), (8, 5), (25, 25)])
def test_any_size_at_least_3x3(shape: tuple[int, int]) -> None:
    config = dataclasses.replace(TEST_MAP, height=shape[0], width=shape[1])
    start = time.perf_counter()
    labels = T.sample_terrain(config, 1)
    assert time.perf_counter() - start < 1.0
    assert labels.shape == shape
    assert set(np.unique(labels)) <= {0, 1, 2, 3}


def test_mcmc_kernel_is_exact_on_a_tiny_map() -> None:
    """A long chain on 3x3 reproduces the enumerated distribution of the sufficient statistics."""
    config = MapConfig(height=3, width=3, dirt=0.7, grass=0.3, lava=0.0,
                       neighbour_weight=0.8, ratio_weight=3.0, sweeps=1)
    allowed = np.array([Terrain.DIRT, Terrain.GRASS])
    n_cells, ratios = 9, np.array([0.7, 0.3])

    def stats(index_labels: np.ndarray) -> tuple[int, int]:
        grid = index_labels.reshape(3, 3)
        pairs = int((grid[1:] == grid[:-1]).sum() + (grid[:, 1:] == grid[:, :-1]).sum())
        return int((grid == 0).sum()), pairs

    exact: dict[tuple[int, int], float] = {}
    for bits in itertools.product((0, 1), repeat=n_cells):
        labels = np.array(bits)
        dirt, pairs = stats(labels)
        shares = np.array([dirt, n_cells - dirt]) / n_cells
        log_p = 0.8 * pairs - 3.0 * n_cells * np.sum((shares - ratios) ** 2)
        exact[(dirt, pairs)] = exact.get((dirt, pairs), 0.0) + np.exp(log_p)
    total = sum(exact.values())
    exact = {k: v / total for k, v in exact.items()}

    rng = np.random.default_rng(3)
    labels = np.zeros((3, 3), dtype=np.int64)
    counts: dict[tuple[int, int], int] = {}
    burn_in, steps = 200, 12000
    for step in range(burn_in + steps):
        T._metropolis(labels, config, allowed, rng)
        if step >= burn_in:
            key = stats(labels)
            counts[key] = counts.get(key, 0) + 1
    keys = set(exact) | set(counts)
    tv = 0.5 * sum(abs(exact.get(k, 0.0) - counts.get(k, 0) / steps) for k in keys)
    assert tv < 0.03, tv
    # The statistic is sensitive: the distribution without coupling is far from the chain's.
    uncoupled: dict[tuple[int, int], float] = {}
    for bits in itertools.product((0, 1), repeat=n_cells):
        dirt, pairs = stats(np.array(bits))
        shares = np.array([dirt, n_cells - dirt]) / n_cells
        weight = np.exp(-3.0 * n_cells * np.sum((shares - ratios) ** 2))
        uncoupled[(dirt, pairs)] = uncoupled.get((dirt, pairs), 0.0) + weight
    norm = sum(uncoupled.values())
    tv_wrong = 0.5 * sum(abs(uncoupled.get(k, 0.0) / norm - counts.get(k, 0) / steps)
                         for k in set(uncoupled) | set(counts))
    assert tv_wrong > 0.1, tv_wrong


def test_choose_start_is_safe_and_at_a_distance() -> None:
    for s in SEEDS:
        labels = T.sample_terrain(TEST_MAP, s)
        row, col = T.choose_start(labels, s, max_distance=22)
        assert labels[row, col] not in (Terrain.LAVA, Terrain.TARGET)
        targets = np.argwhere(labels == Terrain.TARGET)
        distance = np.min(np.abs(targets - [row, col]).sum(axis=1))
        assert 7 <= distance <= 22
    labels = T.sample_terrain(TEST_MAP, 0)
    assert T.choose_start(labels, 5) == T.choose_start(labels, 5)


def test_choose_start_relaxes_min_distance_when_needed() -> None:
    labels = np.zeros((3, 3), dtype=np.int8)
    labels[1, 1] = Terrain.TARGET
    # Every cell is within distance 2 of the centre; asking for 5 falls back to the farthest.
    row, col = T.choose_start(labels, 0, min_distance=5)
    assert abs(row - 1) + abs(col - 1) == 2


def test_choose_start_errors() -> None:
    with pytest.raises(ValueError, match="target"):
        T.choose_start(np.zeros((3, 3), dtype=np.int8), 0)
    labels = np.full((3, 3), Terrain.LAVA, dtype=np.int8)
    labels[0, 0] = Terrain.TARGET
    with pytest.raises(ValueError, match="max_distance"):
        T.choose_start(labels, 0)


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"height": 2}, "height"),
        ({"width": 0}, "width"),
        ({"dirt": 0.5}, "sum to 1"),
        ({"dirt": -0.1, "grass": 1.1}, "dirt"),
        ({"num_targets": 0}, "num_targets"),
        ({"neighbour_weight": -1.0}, "neighbour_weight"),
        ({"ratio_weight": float("nan")}, "ratio_weight"),
        ({"sweeps": -1}, "sweeps"),
    ],
)
def test_config_errors_name_the_argument(kwargs: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        dataclasses.replace(TRAIN_MAP, **kwargs)


def test_bad_seed_is_rejected() -> None:
    with pytest.raises(ValueError, match="seed"):
        T.sample_terrain(TRAIN_MAP, "seven")  # type: ignore[arg-type]
