"""Writing world files (:mod:`ird_core.worlds.world_file`'s format): label maps as PNG images,
and a generated Lavaland instance as a YAML file plus its PNGs that loads back to the same
instance (the latent conditions store their ``lavaland_seed``, not their draws)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import yaml
from PIL import Image

from ird_core.output_paths import make_output_folder
from ird_core.vocabulary import Condition
from ird_core.worlds import lavaland
from ird_core.worlds.file_values import MAX_NAME_LENGTH
from ird_core.worlds.terrain import NUM_TERRAINS, SAFE_TERRAINS, TERRAIN_COLORS, TERRAIN_NAMES, Terrain

__all__ = ["write_image", "export_instance"]

_LATENT_TERRAINS: tuple[str, ...] = tuple(TERRAIN_NAMES[t] for t in (*SAFE_TERRAINS, Terrain.LAVA))


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

    Raises:
        ValueError: naming ``name`` unless it is a plain file stem (printable, 1 to
            ``MAX_NAME_LENGTH`` characters, no path separator, not ``.`` or ``..``: the files stay in
            ``directory``), or ``instance.condition`` for an instance Lavaland did not generate;
            before anything is written. Naming ``directory`` when it cannot be made a folder.
    """
    separators = {"/", "\\", os.sep, os.altsep} - {None}
    if (not isinstance(name, str) or not name or len(name) > MAX_NAME_LENGTH or not name.isprintable()
            or any(sep in name for sep in separators) or name in (".", "..")):
        raise ValueError(f"name: must be a file stem of 1 to {MAX_NAME_LENGTH} printable characters without a "
                         f"path separator (the files stay in the output directory), got {name!r}")
    condition = instance.condition
    if condition not in lavaland.ALL_CONDITIONS:
        raise ValueError(f"instance.condition: only generated Lavaland instances can be exported, got {condition!r}")
    directory = Path(directory)
    make_output_folder(directory, "directory")
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
