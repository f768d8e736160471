"""World files: a user's own maps, terrains, proxy and training worlds, as YAML plus PNG images.

A world file becomes an :class:`ird_core.worlds.lavaland.LavalandInstance` (condition
:data:`ird_core.worlds.lavaland.FILE_CONDITION`), so inference, planning, rendering, experiments and Rob
need no special case. The format reuses the Nav2 ``map_server`` map YAML conventions where they
apply: ``image`` paths are relative to the YAML file, ``resolution`` (metres per cell) and
``origin: [x, y, yaw]`` are optional (defaults 1.0 and [0, 0, 0]), and the image's top row is the
map's highest row (row 0 = the image's bottom row). Example (``worlds/figure1.yaml``)::

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
  have a legend colour (exact match; PNG or PGM, any mode PIL converts to RGB).
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

Every error is a ValueError ``"<file>: <key>: <problem>"`` naming the offending value, raised
while loading, before anything is planned or published.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml
from PIL import Image

from ird_core.vocabulary import Condition
from ird_core.worlds import lavaland
from ird_core.worlds.file_values import FileErrors, read_colour, read_int, read_vector
from ird_core.worlds.observations import ObservationModel, TerrainClassifier, fit_classifier, make_observation_model
from ird_core.worlds.terrain import NUM_TERRAINS, SAFE_TERRAINS, TERRAIN_COLORS, TERRAIN_NAMES, Terrain

__all__ = ["FEATURE_TYPES", "PROXY_FEATURES", "WorldFile", "load_world_file", "load_world", "export_instance"]

FEATURE_TYPES: tuple[str, ...] = ("indicator", "vectors", "gaussian")
PROXY_FEATURES: tuple[str, ...] = ("hypothesis", "classifier")
# make_instance's SeedSequence children: observation model, classifier, observations.
_SEQ_MODEL, _SEQ_CLASSIFIER, _SEQ_OBSERVATIONS, _NUM_SEQ = 4, 5, 6, 9
_LATENT_TERRAINS: tuple[str, ...] = tuple(TERRAIN_NAMES[t] for t in (*SAFE_TERRAINS, Terrain.LAVA))


@dataclasses.dataclass(frozen=True)
class WorldFile:
    """A loaded world file: the instance plus the map_server metadata.

    Attributes:
        path: the YAML file; name: its ``name`` (default the file stem);
        resolution: metres per cell; origin: (x, y, yaw) of cell (0, 0)'s corner;
        instance: the :class:`ird_core.worlds.lavaland.LavalandInstance`.
    """

    path: Path
    name: str
    resolution: float
    origin: tuple[float, float, float]
    instance: lavaland.LavalandInstance


def _legend(ctx: FileErrors, raw: Any) -> tuple[list[dict], list[int], tuple[str, ...], np.ndarray | None]:
    """-> (entries, label per entry, terrain_names, true reward per label or None)."""
    if not isinstance(raw, list) or not raw:
        raise ctx.fail("terrains", "must be a non-empty list of {name, colour}", raw)
    names: list[str] = []
    colours: set[tuple[int, int, int]] = set()
    for i, entry in enumerate(raw):
        name = ctx.get(entry, "name", f"terrains[{i}].")
        if not isinstance(name, str) or not name or name in names:
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
            reward[label] = read_vector(ctx, [entry["true_reward"]], f"terrains[{i}].true_reward", 1)[0]
        reward.setflags(write=False)
    return raw, labels, terrain_names, reward


def _read_image(ctx: FileErrors, base: Path, value: Any, key: str, legend: list[dict], labels: list[int]) -> np.ndarray:
    """Image file -> (H, W) int8 labels, row 0 = the image's bottom row."""
    if not isinstance(value, str) or not value:
        raise ctx.fail(key, "must be an image file name", value)
    image_path = base / value
    try:
        with Image.open(image_path) as image:
            rgb = np.asarray(image.convert("RGB"), dtype=np.int64)
    except (OSError, ValueError) as exc:
        raise ctx.fail(key, f"cannot read the image ({exc})", value) from None
    codes = (rgb[..., 0] << 16) | (rgb[..., 1] << 8) | rgb[..., 2]
    legend_codes = np.array([(c[0] << 16) | (c[1] << 8) | c[2]
                             for c in (read_colour(ctx, e["colour"], "") for e in legend)])
    order = np.argsort(legend_codes)
    pos = np.clip(np.searchsorted(legend_codes[order], codes), 0, len(order) - 1)
    known = legend_codes[order][pos] == codes
    if not known.all():
        top_row, col = np.argwhere(~known)[0]
        bad = tuple(int(v) for v in rgb[top_row, col])
        raise ctx.fail(key, f"{value}: pixel (row {rgb.shape[0] - 1 - top_row}, col {col}) has colour {list(bad)}, "
                       "which is not in the terrains legend", value)
    return np.asarray(labels, dtype=np.int8)[order][pos][::-1].copy()


def _gaussians(ctx: FileErrors, spec: dict, legend: list[dict], labels: list[int], num_labels: int):
    """-> (means (L, D), cholesky (L, D, D) per label (NaN where unused), model or None, rng seed)."""
    if "lavaland_seed" in spec:
        seed = read_int(ctx, spec["lavaland_seed"], "features.lavaland_seed", 0)
        dim = read_int(ctx, ctx.get(spec, "dim", "features."), "features.dim", 3)
        for i, entry in enumerate(legend):
            if entry["name"] not in _LATENT_TERRAINS:
                raise ctx.fail(f"terrains[{i}].name", f"lavaland_seed models only {list(_LATENT_TERRAINS)}", entry["name"])
        seqs = np.random.SeedSequence(seed).spawn(_NUM_SEQ)
        model = make_observation_model(dim, np.random.default_rng(seqs[_SEQ_MODEL]))
        means = np.full((num_labels, dim), np.nan)
        chol = np.full((num_labels, dim, dim), np.nan)
        means[: len(_LATENT_TERRAINS)], chol[: len(_LATENT_TERRAINS)] = model.means, model.cholesky
        return means, chol, model, seqs[_SEQ_OBSERVATIONS], seqs[_SEQ_CLASSIFIER], seed
    obs_seed = read_int(ctx, spec.get("observation_seed", 0), "features.observation_seed", 0)
    dim = None
    means = chol = None
    for i, entry in enumerate(legend):
        mean = read_vector(ctx, ctx.get(entry, "mean", f"terrains[{i}]."), f"terrains[{i}].mean", dim)
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
    classifier_seed = read_int(ctx, spec.get("classifier_seed", 0), "features.classifier_seed", 0)
    return means, chol, model, np.random.SeedSequence(obs_seed), classifier_seed, obs_seed


def _sample(means: np.ndarray, chol: np.ndarray, labels: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """One draw per cell from its label's Gaussian (as observations.sample_observations, any labels)."""
    noise = rng.standard_normal(labels.shape + (means.shape[1],))
    out = np.empty_like(noise)
    for k in np.unique(labels):  # a few terrains, each vectorised over its cells
        mask = labels == k
        out[mask] = means[k] + noise[mask] @ chol[k].T
    return out


def _read_document(ctx: FileErrors) -> dict:
    """The YAML mapping of the file."""
    try:
        doc = yaml.safe_load(ctx.path.read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise ValueError(f"{ctx.path}: cannot read the world file ({exc})") from None
    if not isinstance(doc, dict):
        raise ctx.fail("(top level)", "must be a mapping of keys", doc)
    return doc


class _Worlds(NamedTuple):
    """The training worlds then the test world: their keys and mappings, label maps, starts, horizons."""

    keyed: list[tuple[str, Any]]
    maps: list[np.ndarray]
    starts: list[tuple[int, int]]
    horizons: list[int]


def _read_worlds(ctx: FileErrors, doc: dict, legend: list[dict], labels: list[int]) -> _Worlds:
    """``training_worlds`` then ``test_world``: images of one size, starts on the map, horizons >= 1."""
    raw_worlds = ctx.get(doc, "training_worlds", "")
    if not isinstance(raw_worlds, list) or not raw_worlds:
        raise ctx.fail("training_worlds", "must be a non-empty list of worlds", raw_worlds)
    keyed = [(f"training_worlds[{i}]", w) for i, w in enumerate(raw_worlds)]
    keyed.append(("test_world", ctx.get(doc, "test_world", "")))
    out = _Worlds(keyed, [], [], [])
    for key, world in keyed:
        if not isinstance(world, dict):
            raise ctx.fail(key, "must be a mapping with image, start, horizon", world)
        image_key = f"{key}.image"
        grid = _read_image(ctx, ctx.path.parent, ctx.get(world, "image", f"{key}."), image_key, legend, labels)
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
        out.horizons.append(read_int(ctx, ctx.get(world, "horizon", f"{key}."), f"{key}.horizon", 1))
    return out


def _feature_kinds(ctx: FileErrors, doc: dict) -> tuple[dict, str, str]:
    """``features`` (its mapping and type) and ``proxy_features``, checked."""
    spec = doc.get("features", {"type": "indicator"})
    if not isinstance(spec, dict) or spec.get("type", "indicator") not in FEATURE_TYPES:
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
    if (not isinstance(names, list) or not names or not all(isinstance(n, str) and n for n in names)
            or len(set(names)) != len(names)):
        raise ctx.fail("features.names", "must be a list of unique non-empty names", names)
    table = np.zeros((num_labels, len(names)))
    for i, entry in enumerate(legend):
        table[labels[i]] = read_vector(ctx, ctx.get(entry, "features", f"terrains[{i}]."), f"terrains[{i}].features",
                                   len(names))
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
              maps: list[np.ndarray]) -> _Features:
    """The hypothesis features of every map (training worlds, then test)."""
    if kind == "gaussian":
        means, chol, model, obs_seq, clf_seed, seed = _gaussians(ctx, spec, legend, labels, num_labels)
        rng = np.random.default_rng(obs_seq)
        features = [_sample(means, chol, grid, rng) for grid in maps]  # training worlds, then test
        return _Features(features, tuple(f"obs_{i:02d}" for i in range(means.shape[1])), model, clf_seed, seed)
    names, table = _label_table(ctx, spec, kind, legend, labels, num_labels)
    return _Features([table[grid] for grid in maps], names, None, None, 0)


def _proxy_space(ctx: FileErrors, proxy_kind: str, features: _Features, legend: list[dict]
                 ) -> tuple["TerrainClassifier | None", tuple[str, ...], list[np.ndarray]]:
    """The classifier (or None), the proxy's feature names and every map's proxy features."""
    if proxy_kind != "classifier":
        return None, features.names, features.maps
    if features.model is None:
        raise ctx.fail("proxy_features", f"classifier needs gaussian terrains exactly {list(_LATENT_TERRAINS)}",
                       [e["name"] for e in legend])
    classifier = fit_classifier(features.model, np.random.default_rng(features.classifier_seed))
    names = tuple(f"clf_{TERRAIN_NAMES[t]}" for t in SAFE_TERRAINS)
    return classifier, names, [classifier.predict_proba(f) for f in features.maps]


def _proxies(ctx: FileErrors, doc: dict, keyed: list[tuple[str, Any]], num_proxy_features: int) -> list[np.ndarray]:
    """Each training world's proxy weights: its own ``proxy``, else the top-level one."""
    default_proxy = doc.get("proxy")
    proxies = []
    for key, world in keyed[:-1]:
        if "proxy" in world:
            proxies.append(read_vector(ctx, world["proxy"], f"{key}.proxy", num_proxy_features))
        elif default_proxy is not None:
            proxies.append(read_vector(ctx, default_proxy, "proxy", num_proxy_features))
        else:
            raise ValueError(f"{ctx.path}: {key}.proxy: missing required key (or give a top-level proxy)")
    return proxies


def load_world_file(path: str | os.PathLike) -> WorldFile:
    """Load and validate a world file (see the module docstring); ValueError on any bad value."""
    path = Path(path)
    ctx = FileErrors(path)
    doc = _read_document(ctx)
    resolution = doc.get("resolution", 1.0)
    if isinstance(resolution, bool) or not isinstance(resolution, (int, float)) or not resolution > 0:
        raise ctx.fail("resolution", "must be a number > 0", resolution)
    origin = read_vector(ctx, doc.get("origin", [0.0, 0.0, 0.0]), "origin", 3)
    name = doc.get("name", path.stem)
    legend, labels, terrain_names, true_reward = _legend(ctx, ctx.get(doc, "terrains", ""))
    worlds = _read_worlds(ctx, doc, legend, labels)
    spec, kind, proxy_kind = _feature_kinds(ctx, doc)
    features = _features(ctx, spec, kind, legend, labels, len(terrain_names), worlds.maps)
    classifier, proxy_names, proxy_maps = _proxy_space(ctx, proxy_kind, features, legend)
    proxies = _proxies(ctx, doc, worlds.keyed, len(proxy_names))
    seed = read_int(ctx, doc.get("seed", features.seed), "seed", 0)
    intercept = doc.get("proxy_intercept", 0.0)
    if isinstance(intercept, bool) or not isinstance(intercept, (int, float)) or not np.isfinite(intercept):
        raise ctx.fail("proxy_intercept", "must be a finite number", intercept)
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
    return WorldFile(path, str(name), float(resolution), tuple(float(v) for v in origin), instance)


def load_world(path: str | os.PathLike) -> lavaland.LavalandInstance:
    """The instance of a world file (:func:`load_world_file` without the metadata)."""
    return load_world_file(path).instance


def _hex_rgb(colour: str) -> list[int]:
    return [int(colour[i: i + 2], 16) for i in (1, 3, 5)]


def write_image(labels: np.ndarray, colours: dict[int, list[int]], path: str | os.PathLike) -> None:
    """(H, W) labels -> an RGB PNG, row 0 at the image's bottom."""
    labels = np.asarray(labels)
    lut = np.zeros((int(labels.max()) + 1, 3), dtype=np.uint8)
    for label, rgb in colours.items():
        if label < lut.shape[0]:
            lut[label] = rgb
    Image.fromarray(lut[labels[::-1]]).save(path)


def export_instance(instance: lavaland.LavalandInstance, directory: str | os.PathLike, name: str,
                    obs_dim: int | None = None) -> Path:
    """Write a generated Lavaland instance as ``<directory>/<name>.yaml`` plus its PNGs.

    Latent conditions store ``lavaland_seed`` (the instance's seed) and ``dim``: loading
    regenerates the same observation model, classifier and observation draws.

    Returns:
        The YAML path.
    """
    condition = instance.condition
    if condition not in lavaland.ALL_CONDITIONS:
        raise ValueError(f"instance.condition: only generated Lavaland instances can be exported, got {condition!r}")
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    present = NUM_TERRAINS if condition == Condition.POT_OF_GOLD else len(_LATENT_TERRAINS)
    colours = {t: _hex_rgb(TERRAIN_COLORS[t]) for t in range(present)}
    terrains: list[dict] = [{"name": TERRAIN_NAMES[t], "colour": colours[t],
                             "true_reward": float(lavaland.TRUE_TERRAIN_REWARD[t])} for t in range(present)]
    if condition in (Condition.SIDE_EFFECTS, Condition.POT_OF_GOLD):
        features: dict = {"type": "indicator"}
    elif condition == Condition.REWARD_HACKING:
        features = {"type": "vectors", "names": list(instance.feature_names)}
        vectors = lavaland._sensor_features(np.arange(present, dtype=np.int8)[None])[0]
        for t, entry in enumerate(terrains):
            entry["features"] = [float(v) for v in vectors[t]]
    else:
        features = {"type": "gaussian", "dim": int(obs_dim or instance.num_features), "lavaland_seed": instance.seed}
    images = {"train": f"{name}_train.png", "test": f"{name}_test.png"}
    write_image(instance.train_labels, colours, directory / images["train"])
    write_image(instance.test_labels, colours, directory / images["test"])
    doc = {
        "name": name, "seed": instance.seed, "resolution": 1.0, "origin": [0.0, 0.0, 0.0], "terrains": terrains, "features": features,
        "proxy_features": "classifier" if instance.classifier is not None else "hypothesis",
        "proxy": [float(v) for v in instance.proxy_weights], "proxy_intercept": float(instance.proxy_intercept),
        "training_worlds": [{"image": images["train"], "start": list(instance.train_start),
                             "horizon": instance.train_horizon}],
        "test_world": {"image": images["test"], "start": list(instance.test_start), "horizon": instance.test_horizon},
    }
    out = directory / f"{name}.yaml"
    out.write_text(f"# Exported from lavaland.make_instance({condition!r}, {instance.seed}).\n"
                   + yaml.safe_dump(doc, sort_keys=False, default_flow_style=None))
    return out
