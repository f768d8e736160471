"""A non-linear hypothesis space for the latent conditions that stays linear in its weights:
random Fourier features of an RBF kernel on the cell observations (docs/experiments.md,
"Robot-sized maps").

Why: the paper's latent hypothesis space is linear in the 50-d observations ("the use of linear
reward functions" is the paper's own named limitation). A linear reward extrapolates: lava's
value is tied to the training cells' noise along lava's direction, and the longer the horizon,
the surer the posterior is of the proxy's own extrapolated value of lava (44% lava in latent_raw
at 64x64, T = 120). With ``r(x) = w . z(x)``, ``z(x) = sqrt(2 / D) cos(Omega x + b)``,
``Omega ~ N(0, I / ell^2)`` (``(D, p)``), ``b ~ U(0, 2 pi)`` (``(D,)``) and the prior
``w ~ N(0, sigma^2 I)``, ``r`` is approximately a Gaussian process with the RBF kernel
``sigma^2 exp(-|x - y|^2 / (2 ell^2))`` (Rahimi and Recht 2007: ``E[z(x) . z(y)] = k(x, y)``,
Monte-Carlo error ``O(1 / sqrt D)``). Under a GP, the value at a point far from every training
observation is independent of the values the training behaviour constrains, so it keeps the
prior's spread at any map size and horizon; a training-like point's value is tied to its
neighbours' and shrinks with them. IRD still sees the hypothesis space as linear in ``D``
weights, so the posterior, the samplers and the planners are unchanged.

Choices, each fixed on seeds 500-505 (outside the test seeds 0-49) before the test seeds were
run (docs/experiments.md, "Robot-sized maps"):

- **Length scale** (:func:`median_length_scale`): ``ell = LENGTH_SCALE_FACTOR x`` the median
  Euclidean distance between training observations (every training world's cells; an evenly
  spaced, deterministic subsample of at most :data:`MEDIAN_CELLS` cells), with the factor 2. The
  training observations alone set it: no label, no test cell, no knowledge of lava. Why 2: in
  50-d the observation noise dominates every distance (two cells of one terrain are about 10
  apart, lava about 18 from a safe cell), so at ``ell`` = the median a training-like test cell is
  nearly as uncorrelated with the training cells as lava is; the posterior spread of its value
  (relative to the training baseline) was then as wide as lava's, and the per-step min saw every
  cell as uncertain (seeds 500-505, unscaled samples: one plan in 12 touched lava, none reached a
  target; factors 1.5 and 2: no lava, one target). With the
  exact kernel and noise-free training values, a lava cell keeps 14% of the prior variance
  at factor 2 and a test dirt cell 1% (factor 1: 69% and 9%; factor 4: 2% and 0.3%): factor 2
  keeps lava an order of magnitude less certain than the safe terrain while the safe terrain is
  pinned down.
- **No linear block, no bias column.** A constant per-cell reward changes no fixed-horizon
  behaviour and no plan with the training-features baseline, so a bias column's weight would
  only keep its prior. The observations' own linear features would bring back the linear
  extrapolation the kernel is there to remove: their posterior centres lava on the proxy's
  extrapolated value with a spread that narrows with the horizon.
- **D** (:data:`DEFAULT_RFF_FEATURES` = 100): the MCMC runs in ``D`` dimensions (d = 50 before).
  The kernel's RMS error is 0.06 at D = 100 (0.10 at 50, 0.05 at 400, 0.015 at 1600). Under
  noise-free training values a finite D pins down more than the kernel does (at 15x15, lava keeps
  4% of the prior variance at D = 100, 11% at D = 400 and 14% exactly); the IRD posterior is far
  from noise-free: at D = 100 the posterior sd of lava's value minus dirt's stayed 1.5-3.0 (prior
  sigma 5, seeds 500-505 at 15x15, 500-502 at 32x32), and a lava cell's sd 2-3 times a dirt
  cell's. A posterior at D = 400 was too slow to measure on the shared machine.
- **Seed**: ``Omega`` and ``b`` come from ``SeedSequence([instance seed, RFF_STREAM])``, so both
  latent conditions of a seed (which share the observations) share the map, and a trial stays a
  pure function of its spec.

Only IRD's hypothesis features change, as with ``--novelty-feature``: the designer's proxy, its
features and weights, and so the literal plan, stay the designer's. The proxy's behaviour is
planned on its own features and counted in the new features
(``ird_core.posterior.proxy_feature_expectations``). The indicator conditions are left alone:
on one-hot terrain features a linear reward is already every function of the terrain.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ird_core.worlds import lavaland

__all__ = ["HYPOTHESES", "RFF_CONDITIONS", "DEFAULT_RFF_FEATURES", "LENGTH_SCALE_FACTOR", "MEDIAN_CELLS",
           "RFF_STREAM", "FourierMap", "rbf_kernel", "median_length_scale", "fourier_map", "with_rff_hypothesis",
           "hypothesis_instance"]

#: IRD's hypothesis space in the latent conditions: the paper's linear one, or random Fourier features.
HYPOTHESES: tuple[str, ...] = ("linear", "rff")
#: The conditions whose hypothesis features are continuous observations (the rest are one-hot).
RFF_CONDITIONS: tuple[str, ...] = ("latent_raw", "latent_classifier")
#: Random features ``D`` by default.
DEFAULT_RFF_FEATURES: int = 100
#: ``ell`` = this x the median distance between training observations.
LENGTH_SCALE_FACTOR: float = 2.0
#: At most this many training cells enter the median (an evenly spaced, deterministic subsample).
MEDIAN_CELLS: int = 2048
#: The key of the random map's stream under the instance seed.
RFF_STREAM: int = 4242


@dataclasses.dataclass(frozen=True, eq=False)
class FourierMap:
    """``z(x) = sqrt(2 / D) cos(x Omega^T + b)``: ``(..., p) -> (..., D)``.

    Attributes:
        omega: ``(D, p)`` frequencies, rows ``~ N(0, I / ell^2)``.
        offset: ``(D,)`` phases in ``[0, 2 pi)``.
        length_scale: ``ell`` (recorded; ``omega`` already carries it).

    Raises ``ValueError`` naming the field on a bad shape or value.
    """

    omega: np.ndarray
    offset: np.ndarray
    length_scale: float

    def __post_init__(self) -> None:
        omega = np.array(self.omega, dtype=np.float64)
        offset = np.array(self.offset, dtype=np.float64)
        if omega.ndim != 2 or omega.shape[0] < 1 or omega.shape[1] < 1:
            raise ValueError(f"omega: expected shape (D, p) with D, p >= 1, got {omega.shape}")
        if offset.shape != (omega.shape[0],):
            raise ValueError(f"offset: expected shape ({omega.shape[0]},), got {offset.shape}")
        if not (np.all(np.isfinite(omega)) and np.all(np.isfinite(offset))):
            raise ValueError("omega, offset: must be finite")
        if not (np.isfinite(self.length_scale) and self.length_scale > 0):
            raise ValueError(f"length_scale: must be finite and > 0, got {self.length_scale!r}")
        for array in (omega, offset):
            array.setflags(write=False)
        object.__setattr__(self, "omega", omega)
        object.__setattr__(self, "offset", offset)

    @property
    def num_features(self) -> int:
        return int(self.omega.shape[0])

    @property
    def input_dim(self) -> int:
        return int(self.omega.shape[1])

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """``(..., p)`` observations -> ``(..., D)`` features."""
        x = np.asarray(x, dtype=np.float64)
        if x.ndim < 1 or x.shape[-1] != self.input_dim:
            raise ValueError(f"x: expected shape (..., {self.input_dim}), got {x.shape}")
        return np.sqrt(2.0 / self.num_features) * np.cos(x @ self.omega.T + self.offset)


def rbf_kernel(x: np.ndarray, y: np.ndarray, length_scale: float) -> np.ndarray:
    """``(n, p), (m, p) -> (n, m)``: ``exp(-|x_i - y_j|^2 / (2 ell^2))``."""
    x, y = np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64)
    sq = np.sum(x**2, axis=1)[:, None] + np.sum(y**2, axis=1)[None] - 2.0 * x @ y.T
    return np.exp(-np.maximum(sq, 0.0) / (2.0 * float(length_scale) ** 2))


def _training_cells(worlds: "np.ndarray | list[np.ndarray]") -> np.ndarray:
    """Every training world's ``(H, W, p)`` observations as ``(n, p)``."""
    worlds = worlds if isinstance(worlds, list) else [worlds]
    return np.concatenate([np.asarray(f, dtype=np.float64).reshape(-1, np.shape(f)[-1]) for f in worlds])


def median_length_scale(train_features: "np.ndarray | list[np.ndarray]", factor: float = LENGTH_SCALE_FACTOR,
                        max_cells: int = MEDIAN_CELLS) -> float:
    """``factor x`` the median distance between distinct training observations (module docstring).

    Args:
        train_features: ``(H, W, p)`` or ``(n, p)`` training observations, or a list of them.
        factor: ``> 0``.
        max_cells: at most this many cells (evenly spaced over the concatenated cells) enter.

    Raises ``ValueError`` naming ``train_features`` when fewer than two cells are given or the
    median distance is zero, ``factor`` or ``max_cells`` when out of range.
    """
    if not (np.isfinite(factor) and factor > 0):
        raise ValueError(f"factor: must be finite and > 0, got {factor!r}")
    if isinstance(max_cells, bool) or not isinstance(max_cells, (int, np.integer)) or max_cells < 2:
        raise ValueError(f"max_cells: must be an integer >= 2, got {max_cells!r}")
    cells = _training_cells(train_features)
    if len(cells) < 2:
        raise ValueError("train_features: at least two training cells are needed for the median distance")
    cells = cells[np.unique(np.linspace(0, len(cells) - 1, min(len(cells), int(max_cells))).astype(np.int64))]
    sq = np.sum(cells**2, axis=1)[:, None] + np.sum(cells**2, axis=1)[None] - 2.0 * cells @ cells.T
    median = float(np.median(np.sqrt(np.maximum(sq[np.triu_indices(len(cells), k=1)], 0.0))))
    if not median > 0:
        raise ValueError("train_features: the training observations are all equal (median distance 0)")
    return float(factor) * median


def fourier_map(input_dim: int, num_features: int, length_scale: float,
                seed: "int | np.random.SeedSequence") -> FourierMap:
    """The seeded random map of ``num_features`` features of the RBF kernel with ``length_scale``.

    Raises ``ValueError`` naming ``input_dim``, ``num_features`` or ``length_scale``.
    """
    for name, value in (("input_dim", input_dim), ("num_features", num_features)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
            raise ValueError(f"{name}: must be an integer >= 1, got {value!r}")
    if not (np.isfinite(length_scale) and length_scale > 0):
        raise ValueError(f"length_scale: must be finite and > 0, got {length_scale!r}")
    rng = np.random.default_rng(seed)
    omega = rng.standard_normal((int(num_features), int(input_dim))) / float(length_scale)
    offset = rng.uniform(0.0, 2.0 * np.pi, size=int(num_features))
    return FourierMap(omega, offset, float(length_scale))


def _instance_map(inst: lavaland.LavalandInstance, num_features: int, factor: float) -> FourierMap:
    scale = median_length_scale(list(inst.training_maps), factor)
    return fourier_map(inst.num_features, num_features, scale, np.random.SeedSequence([int(inst.seed), RFF_STREAM]))


def with_rff_hypothesis(inst: lavaland.LavalandInstance, num_features: int = DEFAULT_RFF_FEATURES,
                        factor: float = LENGTH_SCALE_FACTOR) -> lavaland.LavalandInstance:
    """``inst`` with its hypothesis features replaced by ``z(features)`` (module docstring).

    Every training world and the test map go through the same :class:`FourierMap`; the proxy
    (features, weights, names) is untouched. Feature names ``rff_000``, ``rff_001``, ....
    Raises ``ValueError`` naming ``num_features`` or ``feature_names`` (already random features).
    """
    if isinstance(num_features, bool) or not isinstance(num_features, (int, np.integer)) or num_features < 1:
        raise ValueError(f"num_features: must be an integer >= 1, got {num_features!r}")
    if any(name.startswith("rff_") for name in inst.feature_names):
        raise ValueError("feature_names: the instance already has random Fourier features")
    z = _instance_map(inst, int(num_features), factor)
    extra = tuple(dataclasses.replace(world, features=z(world.features)) for world in inst.extra_training_worlds)
    return dataclasses.replace(
        inst, feature_names=tuple(f"rff_{i:03d}" for i in range(z.num_features)),
        train_features=z(inst.train_features), test_features=z(inst.test_features), extra_training_worlds=extra)


def hypothesis_instance(inst: lavaland.LavalandInstance, hypothesis: str,
                        num_features: int = DEFAULT_RFF_FEATURES) -> lavaland.LavalandInstance:
    """``inst`` in the ``hypothesis`` space: ``linear`` as it is; ``rff`` for the latent
    conditions (:data:`RFF_CONDITIONS`), other conditions as they are. ValueError naming
    ``hypothesis``."""
    if hypothesis not in HYPOTHESES:
        raise ValueError(f"hypothesis: must be one of {HYPOTHESES}, got {hypothesis!r}")
    if hypothesis == "linear" or inst.condition not in RFF_CONDITIONS:
        return inst
    return with_rff_hypothesis(inst, num_features)
