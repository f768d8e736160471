"""Lavaland terrain maps: the map distribution of Section 5 of the IRD paper, sampled by MCMC.

Conventions (docs/spec.md section 1): a map is an ``(H, W)`` array of :class:`Terrain` labels,
cell ``(row, col)``, row 0 is the bottom row.

Map distribution
----------------
The paper samples maps from a distribution whose log-likelihood rewards neighbouring cells
that carry the same terrain, mixed with a quadratic cost for deviating from the target terrain
ratios. We use, over the labels ``l`` of the MCMC terrains (dirt, grass and lava with a share
> 0; targets are placed afterwards)::

    log p(l) = J * #{4-neighbour pairs (i, j) with l_i == l_j}
               - lam * N * sum_k (n_k / N - r_k) ** 2          (+ const)

with ``N = H * W`` cells, ``n_k`` the count of terrain ``k`` and ``r`` the configured shares.

* ``J = neighbour_weight = 1.0``: just above the 2-state Potts critical coupling
  ``ln(1 + sqrt 2) = 0.88``, so the chain coarsens into patches (paths, lawns, lava pools)
  instead of salt-and-pepper noise: neighbours agree far more often than independent labels
  with the same shares would.
* ``lam = ratio_weight = 100.0``: the cost is extensive (scaled by ``N``) like the neighbour
  term; its Gaussian approximation gives a per-terrain share standard deviation of about
  ``1 / sqrt(2 lam N)`` = 0.005 on a 15x15 map. With ``lam = 0`` coarsening lets the shares
  wander freely (some maps almost all one terrain). The tests assert a tolerance of 0.03 per map
  and 0.01 for the mean over 10 seeds.
* No per-label field: a base measure ``sum_i log r[l_i]`` (i.i.d. labels with the target
  shares at ``J = lam = 0``) sounds natural, but with ``J = 1`` it pulls towards the majority
  terrain and shrinks the lava share; without it the residual bias is negligible at
  ``lam = 100``.
* ``sweeps = 100``. On a 3x3 map one flip costs about ``2 lam / N = 22`` in log-probability,
  so the distribution concentrates on the exact shares and the chain barely leaves its initial
  permutation: a property of the target distribution, not a sampler defect. 5x5 maps already
  coarsen.

Sampler: the chain starts from an exact-share random permutation (largest-remainder rounding)
and runs ``sweeps`` systematic sweeps of single-site Metropolis. A sweep updates the two
checkerboard colours in turn: within one colour no two cells are neighbours, so every cell's
neighbour-agreement change is computed for the whole colour at once (vectorised); the ratio term
couples all cells, so the accept/reject decisions of that colour run sequentially over its
cells in a random order with incremental count bookkeeping (a few float operations per cell).
Each single-site update leaves ``p`` invariant, so the whole scheme is an exact MCMC kernel
(the tests compare a long chain on a 3x3 map with exact enumeration). The proposal is a
uniformly random other MCMC terrain (symmetric). ``sweeps`` is a fixed budget: maps are draws after that many sweeps,
not certified equilibrium samples (near the critical coupling coarsening goes on slowly).

Targets: ``num_targets`` cells drawn uniformly without replacement among the non-lava cells,
overwriting their dirt or grass label. The start is chosen afterwards by :func:`choose_start`,
at a Manhattan distance from the nearest target of at least ``(H + W) // 4`` (7 on a 15x15 map)
so that every path has to cross terrain, and at most a caller-given bound (the horizon).

Gold (the pot-of-gold condition only) is not part of the map distribution: :func:`place_gold`
puts it on a finished map, after the start is chosen, on uniformly drawn dirt or grass cells
other than the start (``round(share * H * W)`` of them, at least one), from its own random
stream. Why not an MCMC terrain: the MCMC would grow gold into pools like lava, and a new
label in the chain would change every existing map of a seed; placed afterwards, a
pot-of-gold test map equals the other conditions' test map of the same seed (same lava, same
target, same start) except for the gold cells, so the conditions stay paired by seed.
"""

from __future__ import annotations

import dataclasses
from enum import IntEnum

import numpy as np

from ird_core.style import TERRAIN_COLOR_BY_NAME
from ird_core.vocabulary import TERRAIN_NAMES

__all__ = [
    "Terrain",
    "TERRAIN_NAMES",
    "NUM_TERRAINS",
    "TERRAIN_COLORS",
    "SAFE_TERRAINS",
    "MapConfig",
    "TRAIN_MAP",
    "TEST_MAP",
    "sample_terrain",
    "choose_start",
    "place_gold",
    "terrain_fractions",
    "neighbour_agreement",
    "independent_agreement",
    "as_generator",
]


class Terrain(IntEnum):
    """Cell labels; the values index per-terrain arrays (rewards, colours, Gaussian means)."""

    DIRT = 0
    GRASS = 1
    TARGET = 2
    LAVA = 3
    GOLD = 4


NUM_TERRAINS: int = len(TERRAIN_NAMES)
#: RGB hex per Terrain (pictures, world-file legends): dirt brown, grass green, target yellow,
#: lava red, gold orange; owned by :mod:`ird_core.style` (by name), listed here in label order.
TERRAIN_COLORS: tuple[str, ...] = tuple(TERRAIN_COLOR_BY_NAME[name] for name in TERRAIN_NAMES)
# The terrains the designer saw in training (classifier classes, sensor channels).
SAFE_TERRAINS: tuple[Terrain, ...] = (Terrain.DIRT, Terrain.GRASS, Terrain.TARGET)

# Terrains whose shares the MCMC controls; targets are placed afterwards.
_MCMC_TERRAINS: tuple[Terrain, ...] = (Terrain.DIRT, Terrain.GRASS, Terrain.LAVA)


@dataclasses.dataclass(frozen=True)
class MapConfig:
    """Parameters of the Lavaland map distribution (see the module docstring for the model).

    Attributes:
        height, width: map size in cells, each >= 3.
        dirt, grass, lava: target shares of the MCMC terrains; non-negative, summing to 1.
        num_targets: target cells placed after the MCMC (>= 1).
        neighbour_weight: ``J``, log-likelihood bonus per agreeing 4-neighbour pair (>= 0).
        ratio_weight: ``lam``, weight of the extensive quadratic ratio cost (>= 0).
        sweeps: number of MCMC sweeps over all cells (>= 0).
    """

    height: int = 15
    width: int = 15
    dirt: float = 0.7
    grass: float = 0.3
    lava: float = 0.0
    num_targets: int = 1
    neighbour_weight: float = 1.0
    ratio_weight: float = 100.0
    sweeps: int = 100

    def __post_init__(self) -> None:
        for name in ("height", "width"):
            value = getattr(self, name)
            if not isinstance(value, (int, np.integer)) or value < 3:
                raise ValueError(f"{name} must be an integer >= 3, got {value!r}")
        shares = np.array([self.dirt, self.grass, self.lava], dtype=np.float64)
        for name, value in zip(("dirt", "grass", "lava"), shares):
            if not np.isfinite(value) or value < 0.0:
                raise ValueError(f"{name} must be a finite share >= 0, got {value!r}")
        if abs(shares.sum() - 1.0) > 1e-9:
            raise ValueError(
                f"dirt + grass + lava must sum to 1, got {self.dirt} + {self.grass} + {self.lava}"
            )
        if not isinstance(self.num_targets, (int, np.integer)) or self.num_targets < 1:
            raise ValueError(f"num_targets must be an integer >= 1, got {self.num_targets!r}")
        expected_non_lava = self.height * self.width * (1.0 - self.lava)
        if self.num_targets > expected_non_lava - 1:
            raise ValueError(
                f"num_targets={self.num_targets} leaves no room on a "
                f"{self.height}x{self.width} map with lava share {self.lava}"
            )
        for name in ("neighbour_weight", "ratio_weight"):
            value = getattr(self, name)
            if not np.isfinite(value) or value < 0.0:
                raise ValueError(f"{name} must be finite and >= 0, got {value!r}")
        if not isinstance(self.sweeps, (int, np.integer)) or self.sweeps < 0:
            raise ValueError(f"sweeps must be an integer >= 0, got {self.sweeps!r}")

    @property
    def ratios(self) -> np.ndarray:
        """(NUM_TERRAINS,) target shares indexed by :class:`Terrain` (targets and gold: 0, placed
        afterwards)."""
        out = np.zeros(NUM_TERRAINS)
        out[Terrain.DIRT], out[Terrain.GRASS], out[Terrain.LAVA] = self.dirt, self.grass, self.lava
        return out


# The paper's shares; the team's benchmark size (15x15) is the default.
TRAIN_MAP = MapConfig(dirt=0.7, grass=0.3, lava=0.0)
TEST_MAP = MapConfig(dirt=0.665, grass=0.285, lava=0.05)


def as_generator(seed: int | np.random.Generator) -> np.random.Generator:
    """A numpy Generator from an int seed (a Generator passes through unchanged)."""
    if isinstance(seed, np.random.Generator):
        return seed
    if isinstance(seed, (int, np.integer)) and not isinstance(seed, bool):
        return np.random.default_rng(int(seed))
    raise ValueError(f"seed must be an int or a numpy Generator, got {type(seed).__name__}")


def _exact_counts(shares: np.ndarray, total: int) -> np.ndarray:
    """Largest-remainder rounding of ``shares * total`` to integers summing to ``total``."""
    raw = shares * total
    counts = np.floor(raw).astype(np.int64)
    remainder = total - counts.sum()
    order = np.argsort(-(raw - counts), kind="stable")
    counts[order[:remainder]] += 1
    return counts


def _neighbour_labels(labels: np.ndarray) -> np.ndarray:
    """(4, H, W) labels of the up/down/left/right neighbours; -1 where off the grid."""
    padded = np.pad(labels, 1, constant_values=-1)
    return np.stack(
        [padded[2:, 1:-1], padded[:-2, 1:-1], padded[1:-1, :-2], padded[1:-1, 2:]]
    )


def _metropolis(
    labels: np.ndarray, config: MapConfig, allowed: np.ndarray, rng: np.random.Generator
) -> None:
    """Run ``config.sweeps`` checkerboard-ordered single-site Metropolis sweeps in place.

    ``labels`` (H, W) int64 hold indices into ``allowed`` (the MCMC terrains with share > 0).
    """
    height, width = labels.shape
    num_cells = height * width
    num_allowed = allowed.size
    ratios = config.ratios[allowed]
    coupling = float(config.neighbour_weight)
    lam = float(config.ratio_weight)
    counts = np.bincount(labels.ravel(), minlength=num_allowed).astype(np.float64)
    # Deviation d_k = n_k - N r_k; moving one cell a -> b changes the cost
    # lam/N * sum d^2 by lam/N * (2 (d_b - d_a) + 2).
    deviation = (counts - num_cells * ratios).tolist()
    scale = lam / num_cells
    colours = (np.add.outer(np.arange(height), np.arange(width)) % 2).ravel()
    colour_cells = [np.flatnonzero(colours == c) for c in (0, 1)]
    flat = labels.ravel()  # view: updates write through to ``labels``
    for _ in range(config.sweeps):
        for cells in colour_cells:
            cells = rng.permutation(cells)
            old = flat[cells]
            # Uniform proposal among the other allowed labels (symmetric).
            new = (old + rng.integers(1, num_allowed, size=cells.size)) % num_allowed
            neigh = _neighbour_labels(flat.reshape(height, width)).reshape(4, -1)[:, cells]
            agree_gain = (neigh == new).sum(axis=0) - (neigh == old).sum(axis=0)
            # Everything but the ratio term is fixed while this colour is updated.
            local = coupling * agree_gain
            log_u = np.log(rng.random(cells.size))
            accepted = np.zeros(cells.size, dtype=bool)
            for i, (a, b, gain, lu) in enumerate(
                zip(old.tolist(), new.tolist(), local.tolist(), log_u.tolist())
            ):
                delta = gain - scale * (2.0 * (deviation[b] - deviation[a]) + 2.0)
                if lu < delta:
                    deviation[a] -= 1.0
                    deviation[b] += 1.0
                    accepted[i] = True
            flat[cells[accepted]] = new[accepted]


def sample_terrain(config: MapConfig, seed: int | np.random.Generator) -> np.ndarray:
    """Sample a Lavaland map: MCMC over dirt/grass/lava labels, then place the targets.

    Args:
        config: the map distribution.
        seed: int seed or numpy Generator.

    Returns:
        (H, W) int8 :class:`Terrain` labels, row 0 at the bottom.
    """
    if not isinstance(config, MapConfig):
        raise ValueError(f"config must be a MapConfig, got {type(config).__name__}")
    rng = as_generator(seed)
    height, width = config.height, config.width
    num_cells = height * width
    allowed = np.array([t for t in _MCMC_TERRAINS if config.ratios[t] > 0.0], dtype=np.int64)
    counts = _exact_counts(config.ratios[allowed], num_cells)
    index_labels = rng.permutation(np.repeat(np.arange(allowed.size), counts))
    index_labels = index_labels.reshape(height, width)
    if allowed.size > 1:
        _metropolis(index_labels, config, allowed, rng)
    labels = allowed[index_labels].astype(np.int8)

    free = np.flatnonzero(labels.ravel() != Terrain.LAVA)
    if free.size < config.num_targets + 1:
        raise ValueError(
            f"num_targets={config.num_targets}: only {free.size} non-lava cells were sampled"
        )
    targets = rng.choice(free, size=config.num_targets, replace=False)
    np.put(labels, targets, Terrain.TARGET)
    return labels


def _check_labels(labels: np.ndarray, name: str = "labels") -> np.ndarray:
    labels = np.asarray(labels)
    if labels.ndim != 2 or min(labels.shape) < 1:
        raise ValueError(f"{name} must be a non-empty (H, W) array, got shape {labels.shape}")
    if not np.issubdtype(labels.dtype, np.integer):
        raise ValueError(f"{name} must hold integer Terrain labels, got dtype {labels.dtype}")
    if labels.min() < 0 or labels.max() >= NUM_TERRAINS:
        raise ValueError(f"{name} holds values outside 0..{NUM_TERRAINS - 1}")
    return labels


def choose_start(
    labels: np.ndarray,
    seed: int | np.random.Generator,
    min_distance: int | None = None,
    max_distance: int | None = None,
) -> tuple[int, int]:
    """Choose a start cell: not lava, gold or a target, at some distance from the targets.

    Uniform among the non-lava, non-gold, non-target cells whose Manhattan distance to the nearest target
    lies in ``[min_distance, max_distance]``. If no cell qualifies, ``min_distance`` is relaxed
    (the farthest qualifying distance not above ``max_distance`` is used instead).

    Args:
        labels: (H, W) Terrain labels with at least one target.
        seed: int seed or numpy Generator.
        min_distance: default ``(H + W) // 4``, so that paths must cross terrain.
        max_distance: default unbounded; pass the horizon (or less) so a target is reachable.

    Returns:
        (row, col).
    """
    labels = _check_labels(labels)
    rng = as_generator(seed)
    height, width = labels.shape
    if min_distance is None:
        min_distance = (height + width) // 4
    if max_distance is None:
        max_distance = height + width
    if min_distance < 0:
        raise ValueError(f"min_distance must be >= 0, got {min_distance}")
    if max_distance < 1:
        raise ValueError(f"max_distance must be >= 1, got {max_distance}")
    target_rows, target_cols = np.nonzero(labels == Terrain.TARGET)
    if target_rows.size == 0:
        raise ValueError("labels has no target cell")
    rows, cols = np.indices(labels.shape)
    # (H, W) Manhattan distance to the nearest target, vectorised over targets.
    distance = np.min(
        np.abs(rows[..., None] - target_rows) + np.abs(cols[..., None] - target_cols), axis=-1
    )
    usable = (
        (labels != Terrain.LAVA) & (labels != Terrain.TARGET) & (labels != Terrain.GOLD)
        & (distance <= max_distance)
    )
    if not usable.any():
        raise ValueError(
            f"no non-lava, non-target cell within max_distance={max_distance} of a target"
        )
    eligible = usable & (distance >= min_distance)
    if not eligible.any():
        eligible = usable & (distance == distance[usable].max())
    flat = np.flatnonzero(eligible)
    cell = int(rng.choice(flat))
    return (cell // width, cell % width)


def place_gold(
    labels: np.ndarray,
    share: float,
    seed: int | np.random.Generator,
    exclude: tuple[int, int] | None = None,
) -> np.ndarray:
    """Turn ``max(1, round(share * H * W))`` dirt or grass cells into gold (see the module docstring).

    Args:
        labels: (H, W) Terrain labels.
        share: gold share of all cells, in (0, 1).
        seed: int seed or numpy Generator.
        exclude: a cell that must stay as it is (the start).

    Returns:
        A new (H, W) int8 label array; ``labels`` is not modified.
    """
    labels = _check_labels(labels)
    if not np.isfinite(share) or not 0.0 < share < 1.0:
        raise ValueError(f"share must be in (0, 1), got {share!r}")
    rng = as_generator(seed)
    height, width = labels.shape
    count = max(1, int(round(share * labels.size)))
    eligible = (labels == Terrain.DIRT) | (labels == Terrain.GRASS)
    if exclude is not None:
        row, col = exclude
        if not (0 <= row < height and 0 <= col < width):
            raise ValueError(f"exclude {exclude} is off the {height}x{width} map")
        eligible[row, col] = False
    free = np.flatnonzero(eligible)
    if free.size < count:
        raise ValueError(f"share={share}: {count} gold cells requested, only {free.size} dirt/grass cells")
    out = labels.astype(np.int8, copy=True)
    np.put(out, rng.choice(free, size=count, replace=False), Terrain.GOLD)
    return out


def terrain_fractions(labels: np.ndarray) -> np.ndarray:
    """(NUM_TERRAINS,) share of each :class:`Terrain` among all cells."""
    labels = _check_labels(labels)
    return np.bincount(labels.ravel().astype(np.int64), minlength=NUM_TERRAINS) / labels.size


def neighbour_agreement(labels: np.ndarray) -> float:
    """Fraction of 4-neighbour pairs (each unordered pair once) with equal labels."""
    labels = _check_labels(labels)
    vertical = labels[1:, :] == labels[:-1, :]
    horizontal = labels[:, 1:] == labels[:, :-1]
    return float((vertical.sum() + horizontal.sum()) / (vertical.size + horizontal.size))


def independent_agreement(shares: np.ndarray) -> float:
    """Expected neighbour agreement of i.i.d. labels with the given shares: ``sum_k s_k^2``."""
    shares = np.asarray(shares, dtype=np.float64)
    if shares.ndim != 1 or np.any(shares < 0) or abs(shares.sum() - 1.0) > 1e-9:
        raise ValueError("shares must be a 1-D non-negative vector summing to 1")
    return float(np.sum(shares**2))
