"""World files: a user's own maps, terrains, proxy and training worlds, as YAML plus PNG images.

A world file becomes an :class:`ird_core.worlds.lavaland.LavalandInstance` (condition
:data:`ird_core.worlds.lavaland.FILE_CONDITION`), so inference, planning, rendering, experiments and Rob
need no special case. The format reuses the Nav2 ``map_server`` map YAML conventions where they
apply: ``image`` paths are relative to the YAML file, ``resolution`` (metres per cell) and
``origin: [x, y, yaw]`` are optional (defaults 1.0 and [0, 0, 0]; the yaw must be 0), and the
image's top row is the map's highest row (row 0 = the image's bottom row). Example
(``worlds/figure1.yaml``)::

    name: figure1
    resolution: 1.0
    origin: [0.0, 0.0, 0.0]
    terrains:                       # the legend, in feature order
      - {name: dirt,   colour: [139, 90, 43],  true_reward: 0.1}
      - {name: grass,  colour: [60, 154, 60],  true_reward: -0.2}
      - {name: target, colour: [255, 212, 0],  true_reward: 1.0}
      - {name: lava,   colour: [224, 32, 27],  true_reward: -10.0}
    features: {type: indicator}
    proxy: [0.1, -0.2, 1.0, 0.0]    # one proxy for every training world without its own
    training_worlds:
      - {image: figure1_train.png, start: [1, 1], horizon: 14}
    test_world: {image: figure1_test.png, start: [1, 1], horizon: 14}

Keys:

* ``terrains`` (required): list of ``name`` (unique), ``colour`` (``[r, g, b]`` 0-255, or one
  grey value 0-255 for greyscale images; unique), optional ``true_reward`` (all terrains or
  none; used only for evaluation and the simulated designer). Every pixel of every image must
  have a legend colour (exact match; PNG, PGM or PPM, any mode PIL converts to RGB).
* ``features``: how each terrain looks to the robot, i.e. the IRD hypothesis features.
  ``{type: indicator}`` (default): one indicator per terrain, in legend order.
  ``{type: vectors, names: [...]}``: each terrain gives ``features: [...]`` of that length
  (e.g. two sensors that disagree on lava). ``{type: gaussian, ...}``: each cell's features are
  one draw from its terrain's Gaussian; either ``dim`` + ``lavaland_seed`` (the observation
  model, classifier and observation draws of ``lavaland.make_instance(condition,
  lavaland_seed, obs_dim=dim)``; terrains among dirt, grass, target, lava), or per terrain
  ``mean: [D values]`` and ``covariance`` (a variance, D variances, or a D x D matrix) plus
  ``observation_seed`` (int, default 0). Draws are made for the training worlds in order,
  then the test world, from one stream; so a file world is fully determined by its YAML and
  images (no .npy of features) and the exported Lavaland latent instances round-trip exactly.
* ``proxy_features``: ``hypothesis`` (default: the proxy is linear in the features above) or
  ``classifier`` (gaussian only, terrains dirt, grass, target, lava: the proxy is linear in the
  class probabilities [dirt, grass, target] of the designer's QDA classifier, fitted on the safe
  terrains' Gaussians with ``classifier_seed``, default the Lavaland stream of
  ``lavaland_seed``).
* ``seed`` (optional int >= 0): ``instance.seed`` (experiments derive sampler seeds from it);
  default ``lavaland_seed`` or ``observation_seed``, else 0.
* ``proxy``: the proxy weights (one per proxy feature) for every training world that gives no
  ``proxy`` of its own; ``proxy_intercept`` (optional, default 0) a constant per-cell term.
* ``training_worlds`` (required, >= 1): ``image``, ``start: [row, col]``, ``horizon`` (T >= 1
  moves), optional ``proxy``. Each is one ``ProxyObservation`` (docs/spec.md section 7,
  :func:`ird_core.posterior.proxy_observations`): the first is the instance's ``train_*``,
  the others ``extra_training_worlds``.
* ``test_world`` (required): ``image``, ``start``, ``horizon``.

Labels: a terrain named like a Lavaland terrain keeps its :class:`ird_core.worlds.terrain.Terrain`
value (so ``touches_lava``, ``reaches_target`` and the render colours apply); other names get
labels 5, 6, ... in legend order, and ``instance.terrain_names`` is ``TERRAIN_NAMES`` plus them.

Every key is checked: an unknown key is refused with the closest known key as a hint
(``horizn: unknown key (did you mean 'horizon'?)``); ``name``, terrain and feature names are
printable strings of at most :data:`~ird_core.worlds.file_values.MAX_NAME_LENGTH` characters.
``image`` paths stay inside the YAML file's folder (:mod:`ird_core.worlds.file_images`).

Limits (:mod:`ird_core.worlds.file_values`): the YAML is read safely within a file size, a
nesting depth and a node count with aliases expanded (:mod:`ird_core.worlds.safe_yaml`); each
image is at most ``MAX_MAP_SIDE`` (1000) cells per side, checked from its header before
decoding; ``H*W*d`` (features) and ``H*W*p`` (proxy features) at most ``MAX_MAP_VALUES`` (the
nodes' ``max_map_values``); every horizon in [1, ``MAX_HORIZON``] (the nodes' ``max_horizon``)
and ``(T + 1) * H * W`` at most ``MAX_PLAN_WORK`` (the planner's ``max_plan_work`` for one
sample); the origin's yaw 0 (the grids are axis-aligned) and ``resolution`` in
``RESOLUTION_RANGE``; at most ``MAX_TERRAINS`` terrains, ``MAX_FEATURES`` features and
``MAX_TRAINING_WORLDS`` training worlds; feature values within
:data:`ird_core.checks.MAX_ABS_FEATURE`, proxy weights and true rewards within
:data:`ird_core.checks.MAX_ABS_WEIGHT` (a true reward is a per-cell weight: it scales the
returns the evaluation and the simulated designer compute as a weight does); seeds in
[0, 2**32 - 1]. So a world that loads is one the graph's services accept with their default
limits.

Every error is a ValueError ``"<file>: <key>: <problem>, got <value>"`` naming the offending
value, raised while loading, before anything is planned or published. What loads but looks
wrong is in ``WorldFile.warnings`` for the programs to print: a test start on a terrain no
training world shows (e.g. lava), on which the designer's proxy says nothing.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from ird_core.checks import MAX_ABS_FEATURE, MAX_ABS_WEIGHT
from ird_core.worlds import lavaland
from ird_core.worlds.file_export import export_instance, write_image
from ird_core.worlds.file_images import read_image
from ird_core.worlds.file_values import (MAX_FEATURES, MAX_HORIZON, MAX_MAP_VALUES, MAX_PLAN_WORK, MAX_SEED,
                                         MAX_TERRAINS, MAX_TRAINING_WORLDS, RESOLUTION_RANGE, FileErrors,
                                         check_keys, read_colour, read_int, read_name, read_vector)
from ird_core.worlds.observations import ObservationModel, TerrainClassifier, fit_classifier, make_observation_model
from ird_core.worlds.safe_yaml import read_yaml
from ird_core.worlds.terrain import SAFE_TERRAINS, TERRAIN_NAMES, Terrain

__all__ = ["FEATURE_TYPES", "PROXY_FEATURES", "WorldFile", "load_world_file", "load_world", "export_instance",
           "write_image"]

FEATURE_TYPES: tuple[str, ...] = ("indicator", "vectors", "gaussian")
PROXY_FEATURES: tuple[str, ...] = ("hypothesis", "classifier")
# make_instance's SeedSequence children: observation model, classifier, observations.
_SEQ_MODEL, _SEQ_CLASSIFIER, _SEQ_OBSERVATIONS, _NUM_SEQ = 4, 5, 6, 9
_LATENT_TERRAINS: tuple[str, ...] = tuple(TERRAIN_NAMES[t] for t in (*SAFE_TERRAINS, Terrain.LAVA))
# The keys of each mapping (an unknown key is refused).
TOP_KEYS = ("name", "resolution", "origin", "terrains", "features", "proxy_features", "seed", "proxy",
            "proxy_intercept", "training_worlds", "test_world")
TERRAIN_KEYS = ("name", "colour", "true_reward", "features", "mean", "covariance")
FEATURES_KEYS = ("type", "names", "dim", "lavaland_seed", "observation_seed", "classifier_seed")
TRAINING_WORLD_KEYS = ("image", "start", "horizon", "proxy")
TEST_WORLD_KEYS = ("image", "start", "horizon")


@dataclasses.dataclass(frozen=True)
class WorldFile:
    """A loaded world file: the instance plus the map_server metadata.

    Attributes:
        path: the YAML file; name: its ``name`` (default the file stem);
        resolution: metres per cell; origin: (x, y, yaw) of cell (0, 0)'s corner;
        instance: the :class:`ird_core.worlds.lavaland.LavalandInstance`;
        warnings: ``"<file>: <key>: <what>"`` lines about what loaded but looks wrong.
    """

    path: Path
    name: str
    resolution: float
    origin: tuple[float, float, float]
    instance: lavaland.LavalandInstance
    warnings: tuple[str, ...] = ()


def _legend(ctx: FileErrors, raw: Any) -> tuple[list[dict], list[int], tuple[str, ...], np.ndarray | None]:
    """-> (entries, label per entry, terrain_names, true reward per label or None)."""
    if not isinstance(raw, list) or not 1 <= len(raw) <= MAX_TERRAINS:
        raise ctx.fail("terrains", f"must be a list of 1 to {MAX_TERRAINS} {{name, colour}}", raw)
    names: list[str] = []
    colours: set[tuple[int, int, int]] = set()
    for i, entry in enumerate(raw):
        check_keys(ctx, entry, TERRAIN_KEYS, f"terrains[{i}].")
        name = read_name(ctx, ctx.get(entry, "name", f"terrains[{i}]."), f"terrains[{i}].name")
        if name in names:
            raise ctx.fail(f"terrains[{i}].name", "must be a unique non-empty string", name)
        colour = read_colour(ctx, ctx.get(entry, "colour", f"terrains[{i}]."), f"terrains[{i}].colour")
        if colour in colours:
            raise ctx.fail(f"terrains[{i}].colour", "is used by another terrain", entry["colour"])
        names.append(name)
        colours.add(colour)
    custom = [n for n in names if n not in TERRAIN_NAMES]
    terrain_names = TERRAIN_NAMES + tuple(custom)
    labels = [terrain_names.index(n) for n in names]
    given = ["true_reward" in entry for entry in raw]
    if any(given) and not all(given):
        i = given.index(False)
        raise ctx.fail(f"terrains[{i}].true_reward", "missing (give a true reward for every terrain or none)", None)
    reward = None
    if all(given):
        reward = np.concatenate([lavaland.TRUE_TERRAIN_REWARD, np.zeros(len(custom))])
        for i, (entry, label) in enumerate(zip(raw, labels)):
            reward[label] = read_vector(ctx, [entry["true_reward"]], f"terrains[{i}].true_reward", 1,
                                        MAX_ABS_WEIGHT)[0]
        reward.setflags(write=False)
    return raw, labels, terrain_names, reward


def _gaussians(ctx: FileErrors, spec: dict, legend: list[dict], labels: list[int], num_labels: int):
    """-> (means (L, D), cholesky (L, D, D) per label (NaN where unused), model or None, rng seed)."""
    if "lavaland_seed" in spec:
        seed = read_int(ctx, spec["lavaland_seed"], "features.lavaland_seed", 0, MAX_SEED)
        dim = read_int(ctx, ctx.get(spec, "dim", "features."), "features.dim", 3, MAX_FEATURES)
        for i, entry in enumerate(legend):
            if entry["name"] not in _LATENT_TERRAINS:
                raise ctx.fail(f"terrains[{i}].name", f"lavaland_seed models only {list(_LATENT_TERRAINS)}", entry["name"])
        seqs = np.random.SeedSequence(seed).spawn(_NUM_SEQ)
        model = make_observation_model(dim, np.random.default_rng(seqs[_SEQ_MODEL]))
        means = np.full((num_labels, dim), np.nan)
        chol = np.full((num_labels, dim, dim), np.nan)
        means[: len(_LATENT_TERRAINS)], chol[: len(_LATENT_TERRAINS)] = model.means, model.cholesky
        return means, chol, model, seqs[_SEQ_OBSERVATIONS], seqs[_SEQ_CLASSIFIER], seed
    obs_seed = read_int(ctx, spec.get("observation_seed", 0), "features.observation_seed", 0, MAX_SEED)
    dim = None
    means = chol = None
    for i, entry in enumerate(legend):
        mean = read_vector(ctx, ctx.get(entry, "mean", f"terrains[{i}]."), f"terrains[{i}].mean", dim,
                           MAX_ABS_FEATURE)
        if mean.size > MAX_FEATURES:
            raise ctx.fail(f"terrains[{i}].mean", f"must have at most {MAX_FEATURES} values", entry["mean"])
        if means is None:
            dim = mean.size
            means, chol = np.full((num_labels, dim), np.nan), np.full((num_labels, dim, dim), np.nan)
        key = f"terrains[{i}].covariance"
        raw = ctx.get(entry, "covariance", f"terrains[{i}].")
        try:
            cov = np.asarray(raw, dtype=np.float64)
        except (TypeError, ValueError):
            raise ctx.fail(key, "must be a variance, D variances or a D x D matrix", raw) from None
        cov = cov * np.eye(dim) if cov.ndim == 0 else np.diag(cov) if cov.ndim == 1 else cov
        if cov.shape != (dim, dim) or not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T):
            raise ctx.fail(key, f"must be a variance, {dim} variances or a symmetric {dim}x{dim} matrix", raw)
        try:
            chol[labels[i]] = np.linalg.cholesky(cov)
        except np.linalg.LinAlgError:
            raise ctx.fail(key, "must be positive definite", raw) from None
        means[labels[i]] = mean
    model = None
    if sorted(e["name"] for e in legend) == sorted(_LATENT_TERRAINS):
        k = len(_LATENT_TERRAINS)
        model = ObservationModel(means=means[:k], covariances=chol[:k] @ np.swapaxes(chol[:k], 1, 2))
    classifier_seed = read_int(ctx, spec.get("classifier_seed", 0), "features.classifier_seed", 0, MAX_SEED)
    return means, chol, model, np.random.SeedSequence(obs_seed), classifier_seed, obs_seed


def _sample(means: np.ndarray, chol: np.ndarray, labels: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One draw per cell from its label's Gaussian (as observations.sample_observations, any labels)."""
    noise = rng.standard_normal(labels.shape + (means.shape[1],))
    out = np.empty_like(noise)
    for k in np.unique(labels):  # a few terrains, each vectorised over its cells
        mask = labels == k
        out[mask] = means[k] + noise[mask] @ chol[k].T
    return out


class _Worlds(NamedTuple):
    """The training worlds then the test world: their keys and mappings, label maps, starts, horizons."""

    keyed: list[tuple[str, Any]]
    maps: list[np.ndarray]
    starts: list[tuple[int, int]]
    horizons: list[int]


def _read_worlds(ctx: FileErrors, doc: dict, legend: list[dict], labels: list[int]) -> _Worlds:
    """``training_worlds`` then ``test_world``: images of one size, starts on the map, horizons >= 1."""
    raw_worlds = ctx.get(doc, "training_worlds", "")
    if not isinstance(raw_worlds, list) or not 1 <= len(raw_worlds) <= MAX_TRAINING_WORLDS:
        raise ctx.fail("training_worlds", f"must be a list of 1 to {MAX_TRAINING_WORLDS} worlds", raw_worlds)
    keyed = [(f"training_worlds[{i}]", w) for i, w in enumerate(raw_worlds)]
    keyed.append(("test_world", ctx.get(doc, "test_world", "")))
    out = _Worlds(keyed, [], [], [])
    for key, world in keyed:
        check_keys(ctx, world, TEST_WORLD_KEYS if key == "test_world" else TRAINING_WORLD_KEYS, f"{key}.")
        image_key = f"{key}.image"
        grid = read_image(ctx, ctx.path.parent, ctx.get(world, "image", f"{key}."), image_key, legend, labels)
        if out.maps and grid.shape != out.maps[0].shape:
            raise ctx.fail(image_key, f"{world['image']} is {grid.shape[1]}x{grid.shape[0]} (W x H) but "
                           f"{keyed[0][1]['image']} is {out.maps[0].shape[1]}x{out.maps[0].shape[0]}", world["image"])
        start = ctx.get(world, "start", f"{key}.")
        if (not isinstance(start, list) or len(start) != 2
                or not all(isinstance(v, int) and not isinstance(v, bool) for v in start)):
            raise ctx.fail(f"{key}.start", "must be [row, col] integers", start)
        if not (0 <= start[0] < grid.shape[0] and 0 <= start[1] < grid.shape[1]):
            raise ctx.fail(f"{key}.start", f"is off the {grid.shape[0]}x{grid.shape[1]} (H x W) map", start)
        out.maps.append(grid)
        out.starts.append((start[0], start[1]))
        horizon = read_int(ctx, ctx.get(world, "horizon", f"{key}."), f"{key}.horizon", 1, MAX_HORIZON)
        work = (horizon + 1) * grid.size
        if work > MAX_PLAN_WORK:
            raise ctx.fail(f"{key}.horizon", f"(T + 1) x H x W = {horizon + 1} x {grid.shape[0]} x {grid.shape[1]} = "
                           f"{work} exceeds the limit {MAX_PLAN_WORK} (the planner's max_plan_work)", horizon)
        out.horizons.append(horizon)
    return out


def _check_map_values(ctx: FileErrors, key: str, grid: np.ndarray, depth: int, what: str) -> None:
    """``H*W*depth`` at most ``MAX_MAP_VALUES``, checked before the maps are built."""
    if grid.size * depth > MAX_MAP_VALUES:
        raise ctx.fail(key, f"H x W x {what} = {grid.shape[0]} x {grid.shape[1]} x {depth} = {grid.size * depth} "
                       f"values exceed the limit {MAX_MAP_VALUES} (the nodes' max_map_values)", depth)


def _feature_kinds(ctx: FileErrors, doc: dict) -> tuple[dict, str, str]:
    """``features`` (its mapping and type) and ``proxy_features``, checked."""
    spec = check_keys(ctx, doc.get("features", {"type": "indicator"}), FEATURES_KEYS, "features.")
    if spec.get("type", "indicator") not in FEATURE_TYPES:
        raise ctx.fail("features.type", f"must be one of {list(FEATURE_TYPES)}", spec)
    kind = spec.get("type", "indicator")
    proxy_kind = doc.get("proxy_features", "hypothesis")
    if proxy_kind not in PROXY_FEATURES or (proxy_kind == "classifier" and kind != "gaussian"):
        raise ctx.fail("proxy_features", f"must be one of {list(PROXY_FEATURES)} (classifier needs gaussian features)",
                       proxy_kind)
    return spec, kind, proxy_kind


def _label_table(ctx: FileErrors, spec: dict, kind: str, legend: list[dict], labels: list[int], num_labels: int
                 ) -> tuple[tuple[str, ...], np.ndarray]:
    """Feature names and the ``(labels, d)`` feature table of ``indicator`` or ``table`` features."""
    if kind == "indicator":
        table = np.zeros((num_labels, len(legend)))
        table[labels, np.arange(len(legend))] = 1.0
        return tuple(e["name"] for e in legend), table
    names = ctx.get(spec, "names", "features.")
    if not isinstance(names, list) or not 1 <= len(names) <= MAX_FEATURES or len(set(map(str, names))) != len(names):
        raise ctx.fail("features.names", f"must be a list of 1 to {MAX_FEATURES} unique names", names)
    for i, n in enumerate(names):
        read_name(ctx, n, f"features.names[{i}]")
    table = np.zeros((num_labels, len(names)))
    for i, entry in enumerate(legend):
        table[labels[i]] = read_vector(ctx, ctx.get(entry, "features", f"terrains[{i}]."), f"terrains[{i}].features",
                                       len(names), MAX_ABS_FEATURE)
    return tuple(names), table


class _Features(NamedTuple):
    """Every world's ``(H, W, d)`` features, their names, and for gaussian features the
    observation model, the classifier's seed and the file's default seed."""

    maps: list[np.ndarray]
    names: tuple[str, ...]
    model: "ObservationModel | None"
    classifier_seed: Any
    seed: int


def _features(ctx: FileErrors, spec: dict, kind: str, legend: list[dict], labels: list[int], num_labels: int,
              worlds: _Worlds) -> _Features:
    """The hypothesis features of every map (training worlds, then test); their size checked first."""
    maps, key = worlds.maps, worlds.keyed[0][0] + ".image"
    if kind == "gaussian":
        means, chol, model, obs_seq, clf_seed, seed = _gaussians(ctx, spec, legend, labels, num_labels)
        _check_map_values(ctx, key, maps[0], means.shape[1], "features")
        rng = np.random.default_rng(obs_seq)
        features = [_sample(means, chol, grid, rng) for grid in maps]  # training worlds, then test
        for (world_key, _), grid in zip(worlds.keyed, features):
            if np.max(np.abs(grid)) > MAX_ABS_FEATURE:
                raise ctx.fail(world_key, f"a Gaussian draw exceeds the feature limit {MAX_ABS_FEATURE:g} (means or "
                               "variances too large)", float(np.max(np.abs(grid))))
        return _Features(features, tuple(f"obs_{i:02d}" for i in range(means.shape[1])), model, clf_seed, seed)
    names, table = _label_table(ctx, spec, kind, legend, labels, num_labels)
    _check_map_values(ctx, key, maps[0], len(names), "features")
    return _Features([table[grid] for grid in maps], names, None, None, 0)


def _proxy_space(ctx: FileErrors, proxy_kind: str, features: _Features, legend: list[dict]
                 ) -> tuple["TerrainClassifier | None", tuple[str, ...], list[np.ndarray]]:
    """The classifier (or None), the proxy's feature names and every map's proxy features."""
    if proxy_kind != "classifier":
        return None, features.names, features.maps
    if features.model is None:
        raise ctx.fail("proxy_features", f"classifier needs gaussian terrains exactly {list(_LATENT_TERRAINS)}",
                       [e["name"] for e in legend])
    names = tuple(f"clf_{TERRAIN_NAMES[t]}" for t in SAFE_TERRAINS)
    _check_map_values(ctx, "proxy_features", features.maps[0][..., 0], len(names), "proxy features")
    classifier = fit_classifier(features.model, np.random.default_rng(features.classifier_seed))
    return classifier, names, [classifier.predict_proba(f) for f in features.maps]


def _proxies(ctx: FileErrors, doc: dict, keyed: list[tuple[str, Any]], num_proxy_features: int) -> list[np.ndarray]:
    """Each training world's proxy weights: its own ``proxy``, else the top-level one."""
    default_proxy = doc.get("proxy")
    proxies = []
    for key, world in keyed[:-1]:
        if "proxy" in world:
            proxies.append(read_vector(ctx, world["proxy"], f"{key}.proxy", num_proxy_features, MAX_ABS_WEIGHT))
        elif default_proxy is not None:
            proxies.append(read_vector(ctx, default_proxy, "proxy", num_proxy_features, MAX_ABS_WEIGHT))
        else:
            raise ValueError(f"{ctx.path}: {key}.proxy: missing required key (or give a top-level proxy)")
    return proxies


def _geometry(ctx: FileErrors, doc: dict) -> tuple[float, tuple[float, float, float]]:
    """``resolution`` (in ``RESOLUTION_RANGE``) and ``origin`` ``[x, y, yaw]`` (yaw 0)."""
    resolution = doc.get("resolution", 1.0)
    low, high = RESOLUTION_RANGE
    if isinstance(resolution, bool) or not isinstance(resolution, (int, float)) or not low <= resolution <= high:
        raise ctx.fail("resolution", f"must be a number in [{low:g}, {high:g}] (metres per cell)", resolution)
    origin = read_vector(ctx, doc.get("origin", [0.0, 0.0, 0.0]), "origin", 3)
    if origin[2] != 0.0:
        raise ctx.fail("origin", "the yaw must be 0 (the grids are axis-aligned)", doc["origin"])
    return float(resolution), (float(origin[0]), float(origin[1]), 0.0)


def _unseen_start(ctx: FileErrors, worlds: _Worlds, terrain_names: tuple[str, ...]) -> tuple[str, ...]:
    """A warning when the test start is on a terrain no training world shows."""
    seen = set(np.unique(np.concatenate([m.ravel() for m in worlds.maps[:-1]])).tolist())
    label = int(worlds.maps[-1][worlds.starts[-1]])
    if label in seen:
        return ()
    return (f"{ctx.path}: test_world.start: {list(worlds.starts[-1])} is on {terrain_names[label]}, a terrain no "
            "training world shows (the proxy says nothing about it, and Rob starts on it)",)


def load_world_file(path: str | os.PathLike) -> WorldFile:
    """Load and validate a world file (see the module docstring); ValueError on any bad value."""
    path = Path(path)
    ctx = FileErrors(path)
    doc = read_yaml(ctx)
    check_keys(ctx, doc, TOP_KEYS, "")
    resolution, origin = _geometry(ctx, doc)
    name = read_name(ctx, doc["name"], "name") if "name" in doc else path.stem
    legend, labels, terrain_names, true_reward = _legend(ctx, ctx.get(doc, "terrains", ""))
    worlds = _read_worlds(ctx, doc, legend, labels)
    spec, kind, proxy_kind = _feature_kinds(ctx, doc)
    features = _features(ctx, spec, kind, legend, labels, len(terrain_names), worlds)
    classifier, proxy_names, proxy_maps = _proxy_space(ctx, proxy_kind, features, legend)
    proxies = _proxies(ctx, doc, worlds.keyed, len(proxy_names))
    seed = read_int(ctx, doc.get("seed", features.seed), "seed", 0, MAX_SEED)
    intercept = doc.get("proxy_intercept", 0.0)
    if (isinstance(intercept, bool) or not isinstance(intercept, (int, float)) or not np.isfinite(intercept)
            or abs(intercept) > MAX_ABS_WEIGHT):
        raise ctx.fail("proxy_intercept", f"must be a finite number of magnitude at most {MAX_ABS_WEIGHT:g}", intercept)
    maps, starts, horizons, feature_maps = worlds.maps, worlds.starts, worlds.horizons, features.maps
    extra = tuple(lavaland.TrainingWorld(maps[i], feature_maps[i], proxy_maps[i], starts[i], horizons[i], proxies[i])
                  for i in range(1, len(worlds.keyed) - 1))
    instance = lavaland.LavalandInstance(
        condition=lavaland.FILE_CONDITION, seed=seed,
        train_labels=maps[0], test_labels=maps[-1], train_start=starts[0], test_start=starts[-1],
        train_horizon=horizons[0], test_horizon=horizons[-1], feature_names=features.names,
        train_features=feature_maps[0], test_features=feature_maps[-1], proxy_feature_names=proxy_names,
        proxy_train_features=proxy_maps[0], proxy_test_features=proxy_maps[-1], proxy_weights=proxies[0],
        proxy_intercept=float(intercept), classifier=classifier, observation_model=features.model,
        terrain_names=terrain_names, true_terrain_reward=true_reward, extra_training_worlds=extra,
    )
    return WorldFile(path, name, resolution, origin, instance, _unseen_start(ctx, worlds, terrain_names))


def load_world(path: str | os.PathLike) -> lavaland.LavalandInstance:
    """The instance of a world file (:func:`load_world_file` without the metadata)."""
    return load_world_file(path).instance
