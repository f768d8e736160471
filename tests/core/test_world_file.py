"""World files (ird_core.worlds.world_file): validation, Lavaland round trip, several training worlds."""

from __future__ import annotations

import copy
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from ird_core import planning, posterior
from ird_core.mdp import GridMDP
from ird_core.worlds import evaluation, lavaland, world_file
from ird_core.worlds.terrain import TERRAIN_NAMES, Terrain

WORLDS = Path(__file__).resolve().parents[2] / "worlds"
COLOURS = {0: [139, 90, 43], 1: [60, 154, 60], 2: [255, 212, 0], 3: [224, 32, 27]}
# Three training-world maps (dirt/grass/target) and a test map with lava, 4 x 5, row 0 at the bottom.
TRAIN = np.array([[0, 0, 0, 0, 2], [0, 1, 1, 0, 0], [0, 1, 1, 1, 0], [0, 0, 0, 0, 0]], dtype=np.int8)
TEST = np.array([[0, 3, 3, 0, 2], [0, 1, 1, 0, 0], [0, 0, 1, 1, 0], [0, 0, 0, 0, 0]], dtype=np.int8)


def _base(tmp_path: Path) -> dict:
    world_file.write_image(TRAIN, COLOURS, tmp_path / "train.png")
    world_file.write_image(TEST, COLOURS, tmp_path / "test.png")
    world_file.write_image(np.zeros((4, 6), dtype=np.int8), COLOURS, tmp_path / "wide.png")
    odd = np.asarray(Image.open(tmp_path / "train.png")).copy()
    odd[0, 2] = [1, 2, 3]
    Image.fromarray(odd).save(tmp_path / "odd.png")
    return {
        "terrains": [{"name": TERRAIN_NAMES[t], "colour": COLOURS[t], "true_reward": float(r)}
                     for t, r in zip(range(4), lavaland.TRUE_TERRAIN_REWARD)],
        "features": {"type": "indicator"},
        "proxy": [0.1, -0.2, 1.0, 0.0],
        "training_worlds": [{"image": "train.png", "start": [0, 0], "horizon": 6},
                            {"image": "train.png", "start": [3, 0], "horizon": 5, "proxy": [0.2, -0.4, 1.0, 0.0]}],
        "test_world": {"image": "test.png", "start": [0, 0], "horizon": 6},
    }


def _write(tmp_path: Path, doc: dict, name: str = "world.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


def _drop(doc: dict, *keys) -> None:
    target = doc
    for key in keys[:-1]:
        target = target[key]
    del target[keys[-1]]


def _set(doc: dict, value, *keys) -> None:
    target = doc
    for key in keys[:-1]:
        target = target[key]
    target[keys[-1]] = value


# (edit of the base document, text the message must contain: the key and the value)
BAD_FILES = [
    (lambda d: _drop(d, "terrains"), ["terrains: missing"]),
    (lambda d: _drop(d, "training_worlds"), ["training_worlds: missing"]),
    (lambda d: _drop(d, "test_world"), ["test_world: missing"]),
    (lambda d: _drop(d, "training_worlds", 0, "horizon"), ["training_worlds[0].horizon: missing"]),
    (lambda d: _drop(d, "test_world", "start"), ["test_world.start: missing"]),
    (lambda d: _drop(d, "terrains", 1, "colour"), ["terrains[1].colour: missing"]),
    (lambda d: _drop(d, "proxy"), ["training_worlds[0].proxy: missing"]),
    (lambda d: _set(d, [], "training_worlds"), ["training_worlds", "[]"]),
    (lambda d: _set(d, "wide.png", "test_world", "image"), ["test_world.image", "wide.png", "6x4"]),
    (lambda d: _set(d, "odd.png", "training_worlds", 1, "image"),
     ["training_worlds[1].image", "odd.png", "[1, 2, 3]", "row 3, col 2"]),
    (lambda d: _set(d, "nowhere.png", "training_worlds", 0, "image"), ["training_worlds[0].image", "nowhere.png"]),
    (lambda d: _set(d, [4, 0], "test_world", "start"), ["test_world.start", "[4, 0]", "off the 4x5"]),
    (lambda d: _set(d, [0, -1], "training_worlds", 1, "start"), ["training_worlds[1].start", "[0, -1]"]),
    (lambda d: _set(d, [1], "test_world", "start"), ["test_world.start", "[1]"]),
    (lambda d: _set(d, 0, "training_worlds", 0, "horizon"), ["training_worlds[0].horizon", "got 0"]),
    (lambda d: _set(d, -3, "test_world", "horizon"), ["test_world.horizon", "got -3"]),
    (lambda d: _set(d, 2.5, "test_world", "horizon"), ["test_world.horizon", "got 2.5"]),
    (lambda d: _set(d, [0.1, -0.2, 1.0], "proxy"), ["proxy", "4 finite numbers", "[0.1, -0.2, 1.0]"]),
    (lambda d: _set(d, [1.0] * 5, "training_worlds", 1, "proxy"), ["training_worlds[1].proxy", "[1.0, 1.0, 1.0, 1.0, 1.0]"]),
    (lambda d: _set(d, COLOURS[0], "terrains", 2, "colour"), ["terrains[2].colour", "another terrain"]),
    (lambda d: _set(d, [300, 0, 0], "terrains", 2, "colour"), ["terrains[2].colour", "[300, 0, 0]"]),
    (lambda d: _set(d, "dirt", "terrains", 3, "name"), ["terrains[3].name", "'dirt'"]),
    (lambda d: _drop(d, "terrains", 2, "true_reward"), ["terrains[2].true_reward: missing"]),
    (lambda d: _set(d, 1e300, "terrains", 3, "true_reward"),
     ["terrains[3].true_reward: has a value of magnitude above the limit 10000"]),
    (lambda d: _set(d, {"type": "fancy"}, "features"), ["features.type", "fancy"]),
    (lambda d: _set(d, "classifier", "proxy_features"), ["proxy_features", "classifier"]),
    (lambda d: _set(d, {"type": "vectors", "names": ["a", "a"]}, "features"), ["features.names", "['a', 'a']"]),
    (lambda d: _set(d, {"type": "vectors", "names": ["a", "b"]}, "features"), ["terrains[0].features: missing"]),
    (lambda d: _set(d, {"type": "gaussian", "dim": 4, "lavaland_seed": -1}, "features"),
     ["features.lavaland_seed", "got -1"]),
    (lambda d: _set(d, {"type": "gaussian", "dim": 4}, "features"), ["terrains[0].mean: missing"]),
    (lambda d: _set(d, 0.0, "resolution"), ["resolution", "got 0.0"]),
    (lambda d: _set(d, [0.0, 0.0], "origin"), ["origin", "[0.0, 0.0]"]),
    # every key is known, every value typed and within the services' limits
    (lambda d: _set(d, 6, "training_worlds", 0, "horizn"), ["training_worlds[0].horizn", "did you mean 'horizon'?"]),
    (lambda d: _set(d, [1.0] * 4, "proxyy"), ["proxyy: unknown key", "did you mean 'proxy'?"]),
    (lambda d: _set(d, [1.0] * 4, "test_world", "proxy"), ["test_world.proxy: unknown key", "image, start, horizon"]),
    (lambda d: _set(d, 1, "terrains", 0, "colur"), ["terrains[0].colur", "did you mean 'colour'?"]),
    (lambda d: _set(d, {"type": "indicator", "dims": 3}, "features"), ["features.dims", "did you mean 'dim'?"]),
    (lambda d: _set(d, "bad\nname", "name"), ["name:", "printable string", "'bad\\nname'"]),
    (lambda d: _set(d, ["a"], "name"), ["name:", "printable string", "['a']"]),
    (lambda d: _set(d, "x" * 65, "name"), ["name:", "1 to 64 characters"]),
    (lambda d: _set(d, [0.0, 0.0, 0.5], "origin"), ["origin", "yaw must be 0", "[0.0, 0.0, 0.5]"]),
    (lambda d: _set(d, 1e9, "resolution"), ["resolution", "[1e-06, 1e+06]", "1000000000.0"]),
    (lambda d: _set(d, 1001, "test_world", "horizon"), ["test_world.horizon", "in [1, 1000]", "got 1001"]),
    (lambda d: _set(d, 2**32, "seed"), ["seed", "4294967295", "got 4294967296"]),
    (lambda d: _set(d, [1e5, 0.0, 0.0, 0.0], "proxy"), ["proxy", "limit 10000", "100000.0"]),
    (lambda d: _set(d, 1e5, "proxy_intercept"), ["proxy_intercept", "10000", "100000.0"]),
    (lambda d: _set(d, [], "terrains"), ["terrains", "1 to 64"]),
    (lambda d: _set(d, [d["training_worlds"][0]] * 17, "training_worlds"), ["training_worlds", "1 to 16"]),
    (lambda d: _set(d, ["dirt"], "terrains", 0), ["terrains[0]", "must be a mapping", "['dirt']"]),
]


@pytest.mark.parametrize("edit, expected", BAD_FILES)
def test_bad_files_name_the_file_key_and_value(tmp_path: Path, edit, expected: list[str]) -> None:
    doc = _base(tmp_path)
    edit(doc)
    path = _write(tmp_path, doc)
    with pytest.raises(ValueError) as info:
        world_file.load_world_file(path)
    message = str(info.value)
    assert message.startswith(f"{path}: "), message
    for text in expected:
        assert text in message, (text, message)


def test_the_base_file_loads_with_row_0_at_the_bottom(tmp_path: Path) -> None:
    wf = world_file.load_world_file(_write(tmp_path, _base(tmp_path)))
    inst = wf.instance
    assert inst.condition == lavaland.FILE_CONDITION and wf.name == "world" and wf.resolution == 1.0
    np.testing.assert_array_equal(inst.train_labels, TRAIN)
    np.testing.assert_array_equal(inst.test_labels, TEST)
    # The image's top pixel row is the map's highest row.
    top = np.asarray(Image.open(tmp_path / "test.png").convert("RGB"))[0]
    np.testing.assert_array_equal(top, [COLOURS[t] for t in TEST[-1]])
    np.testing.assert_array_equal(inst.test_features, np.eye(4)[TEST])
    assert inst.feature_names == TERRAIN_NAMES[:4] and inst.terrain_names == TERRAIN_NAMES
    np.testing.assert_array_equal(inst.true_terrain_reward, lavaland.TRUE_TERRAIN_REWARD)
    (extra,) = inst.extra_training_worlds
    assert extra.start == (3, 0) and extra.horizon == 5
    np.testing.assert_array_equal(extra.proxy_weights, [0.2, -0.4, 1.0, 0.0])


def test_grey_images_custom_terrains_and_vectors(tmp_path: Path) -> None:
    grey = np.array([[10, 10, 200], [10, 90, 90], [10, 10, 10]], dtype=np.uint8)  # top row first
    Image.fromarray(grey).save(tmp_path / "grey.pgm")
    doc = {"terrains": [{"name": "road", "colour": 10, "features": [1.0, 0.0]},
                        {"name": "mud", "colour": 90, "features": [0.5, 0.5]},
                        {"name": "target", "colour": 200, "features": [0.0, 1.0]}],
           "features": {"type": "vectors", "names": ["smooth", "goal"]}, "proxy": [0.1, 1.0],
           "training_worlds": [{"image": "grey.pgm", "start": [0, 0], "horizon": 3}],
           "test_world": {"image": "grey.pgm", "start": [0, 1], "horizon": 3}}
    inst = world_file.load_world(_write(tmp_path, doc))
    assert inst.terrain_names == TERRAIN_NAMES + ("road", "mud") and inst.true_terrain_reward is None
    road, mud = 5, 6
    np.testing.assert_array_equal(inst.train_labels, [[road] * 3, [road, mud, mud], [road, road, Terrain.TARGET]])
    np.testing.assert_array_equal(inst.train_features[1, 1], [0.5, 0.5])
    np.testing.assert_array_equal(inst.train_features[2, 2], [0.0, 1.0])


def test_hand_written_gaussians_draw_from_their_terrain(tmp_path: Path) -> None:
    doc = _base(tmp_path)
    doc["features"] = {"type": "gaussian", "observation_seed": 5}
    for i, entry in enumerate(doc["terrains"]):
        entry["mean"] = [10.0 * i, -3.0 * i]
        entry["covariance"] = [[1e-8, 0.0], [0.0, 1e-8]] if i else 1e-8
    doc["proxy"] = [0.0, 1.0]
    del doc["training_worlds"][1]["proxy"]
    inst = world_file.load_world(_write(tmp_path, doc))
    means = np.array([[10.0 * i, -3.0 * i] for i in range(4)])
    np.testing.assert_allclose(inst.test_features, means[TEST], atol=1e-3)
    assert inst.observation_model is not None
    # The same seed gives the same draws; the classifier proxy works on hand-written Gaussians.
    again = world_file.load_world(_write(tmp_path, doc))
    np.testing.assert_array_equal(again.train_features, inst.train_features)
    for entry in doc["terrains"]:
        entry["covariance"] = 1.0
    doc["proxy_features"], doc["proxy"] = "classifier", [0.1, -0.2, 1.0]
    clf = world_file.load_world(_write(tmp_path, doc))
    assert clf.proxy_feature_names == ("clf_dirt", "clf_grass", "clf_target")
    np.testing.assert_allclose(clf.proxy_train_features.sum(axis=-1), 1.0)
    doc["terrains"][3]["covariance"] = [[1.0, 2.0], [2.0, 1.0]]
    with pytest.raises(ValueError, match=re.escape("terrains[3].covariance: must be positive definite")):
        world_file.load_world(_write(tmp_path, doc))


def _plans(inst: lavaland.LavalandInstance, samples: np.ndarray):
    literal = planning.plan_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights[None], "literal")
    reference = posterior.proxy_feature_expectations(inst) / (inst.train_horizon + 1)
    ird = planning.plan_path(lavaland.test_mdp(inst), samples, "per_step", "training_features", reference)
    return literal.cells, ird.cells


@pytest.mark.parametrize("name", ["../escape", "sub/dir", "back\\slash", ".", "..", "", "x" * 65, "tab\there"])
def test_an_export_name_that_is_not_a_file_stem_is_refused_before_anything_is_written(tmp_path: Path,
                                                                                       name: str) -> None:
    """``--name ../../evil`` wrote the world outside ``--out`` (found by a hostile-input pass)."""
    out = tmp_path / "out" / "deeper"
    instance = lavaland.make_instance("side_effects", 0, size=5, horizon=5)
    with pytest.raises(ValueError, match="^name: must be a file stem"):
        world_file.export_instance(instance, out, name)
    assert not (tmp_path / "out").exists() and sorted(p.name for p in tmp_path.iterdir()) == []
    assert world_file.export_instance(instance, out, "x" * 64).parent == out


def test_an_export_directory_that_cannot_be_a_folder_is_refused_naming_it(tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    instance = lavaland.make_instance("side_effects", 0, size=5, horizon=5)
    for out in (blocker, blocker / "sub"):
        with pytest.raises(ValueError, match=f"^directory: cannot make the folder {re.escape(str(out))}: "):
            world_file.export_instance(instance, out, "w")
    assert blocker.read_text() == "kept"

def test_the_export_command_names_its_flags(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from ird_core.worlds import export

    blocker = tmp_path / "a_file"
    blocker.write_text("kept")
    base = ["--condition", "side_effects", "--size", "5", "--horizon", "5"]
    for argv, message in ((["--out", str(blocker)], f"--out: cannot make the folder {blocker}: "),
                          (["--out", str(tmp_path / "w"), "--name", "../evil"], "--name: must be a file stem")):
        with pytest.raises(SystemExit) as stop:
            export.main([*base, *argv])
        err = capsys.readouterr().err
        assert stop.value.code == 2 and f"error: {message}" in err, err
    assert blocker.read_text() == "kept" and not (tmp_path / "evil.yaml").exists()
    assert export.main([*base, "--out", str(tmp_path / "w")]) == 0
    assert capsys.readouterr().out == f"{tmp_path / 'w' / 'side_effects_0.yaml'}\n"

@pytest.mark.parametrize("condition", lavaland.ALL_CONDITIONS)
def test_lavaland_round_trip(tmp_path: Path, condition: str) -> None:
    original = lavaland.make_instance(condition, 11, size=6, horizon=6, obs_dim=4)
    path = world_file.export_instance(original, tmp_path, condition)
    loaded = world_file.load_world(path)
    for name in ("train_labels", "test_labels", "train_features", "test_features", "proxy_train_features",
                 "proxy_test_features", "proxy_weights", "true_terrain_reward"):
        np.testing.assert_array_equal(getattr(loaded, name), getattr(original, name), err_msg=name)
    for name in ("train_start", "test_start", "train_horizon", "test_horizon", "feature_names",
                 "proxy_feature_names", "proxy_intercept", "seed"):
        assert getattr(loaded, name) == getattr(original, name), name
    assert (loaded.classifier is None) == (original.classifier is None)
    options = dict(num_chains=4, warmup=20, thin=1)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # short chains: only equality matters
        before = posterior.sample_posterior(original.proxy_weights, lavaland.train_mdp(original), 5.0, "maxent_z",
                                            40, 3, proxy_features=posterior.proxy_feature_expectations(original),
                                            **options)
        after = posterior.sample_joint_posterior(posterior.proxy_observations(loaded), 5.0, "maxent_z", 40, 3,
                                                 **options)
    np.testing.assert_array_equal(after.samples, before.samples)
    assert _plans(loaded, after.samples) == _plans(original, before.samples)


def test_proxy_observations_of_a_lavaland_instance_carry_sample_z_counts() -> None:
    inst = lavaland.make_instance("latent_classifier", 2, size=5, horizon=5, obs_dim=4)
    (obs,) = posterior.proxy_observations(inst, num_proxy_samples=30, seed=9, prior_sigma=0.5)
    np.testing.assert_array_equal(obs.proxy_features, posterior.proxy_feature_expectations(inst))
    np.testing.assert_array_equal(obs.proxy_sample_features, posterior.proxy_prior_features(inst, 30, 9, 0.5))
    assert posterior.proxy_observations(inst)[0].proxy_sample_features is None


@pytest.mark.parametrize("method", ["maxent_z", "sample_z"])
def test_two_training_worlds_enter_the_joint_posterior(method: str) -> None:
    inst = world_file.load_world(WORLDS / "two_training_worlds.yaml")
    (second,) = inst.extra_training_worlds
    assert not (inst.train_labels == Terrain.GRASS).any() and (second.labels == Terrain.GRASS).any()
    observations = posterior.proxy_observations(inst)
    by_hand = [posterior.ProxyObservation(inst.proxy_weights, GridMDP(inst.train_features, inst.train_start,
                                                                      inst.train_horizon)),
               posterior.ProxyObservation(second.proxy_weights, GridMDP(second.features, second.start,
                                                                        second.horizon))]
    rng = np.random.default_rng(0)
    weights = rng.standard_normal((16, inst.num_features))
    beta, kw = 4.0, dict(seed=1, num_proxy_samples=50)
    joint = posterior.joint_log_posterior(weights, observations, beta, method, **kw)
    np.testing.assert_allclose(joint, posterior.joint_log_posterior(weights, by_hand, beta, method, **kw), rtol=1e-12)
    # Independent evidence: joint = posterior(world 1) + posterior(world 2) - prior.
    single = [posterior.joint_log_posterior(weights, [o], beta, method, **kw) for o in observations]
    sigma = posterior.calibrated_prior_sigma(posterior.CALIBRATED_TEMPERATURE)  # the default prior
    prior = posterior.log_prior(weights, sigma)
    np.testing.assert_allclose(joint - joint[0], (single[0] + single[1] - prior) - (single[0] + single[1] - prior)[0],
                               rtol=1e-9, atol=1e-9)
    # The first world has no grass: its likelihood ignores the grass weight; the second's does not.
    shifted = weights.copy()
    shifted[:, TERRAIN_NAMES.index("grass")] += 1.0
    first = [posterior.joint_log_posterior(w, observations[:1], beta, method, **kw) - posterior.log_prior(w, sigma)
             for w in (weights, shifted)]
    np.testing.assert_allclose(first[1] - first[1][0], first[0] - first[0][0], atol=1e-9)
    both = [posterior.joint_log_posterior(w, observations, beta, method, **kw) - posterior.log_prior(w, sigma)
            for w in (weights, shifted)]
    assert np.max(np.abs((both[1] - both[1][0]) - (both[0] - both[0][0]))) > 1e-3


def test_two_training_worlds_sample_as_the_joint_posterior() -> None:
    inst = world_file.load_world(WORLDS / "two_training_worlds.yaml")
    options = dict(num_chains=4, warmup=20, thin=1)
    observations = posterior.proxy_observations(inst)
    second = inst.extra_training_worlds[0]
    by_hand = observations[:1] + [posterior.ProxyObservation(
        second.proxy_weights, GridMDP(second.features, second.start, second.horizon))]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        a = posterior.sample_joint_posterior(observations, 5.0, "maxent_z", 40, 7, **options)
        b = posterior.sample_joint_posterior(by_hand, 5.0, "maxent_z", 40, 7, **options)
    np.testing.assert_array_equal(a.samples, b.samples)
    assert a.num_proxies == 2


@pytest.mark.parametrize("name", ["figure1", "pot_of_gold", "two_training_worlds"])
def test_shipped_examples_load_and_match_their_generator(tmp_path: Path, name: str) -> None:
    inst = world_file.load_world(WORLDS / f"{name}.yaml")
    assert inst.true_terrain_reward is not None
    literal = planning.plan_path(lavaland.test_mdp(inst, proxy=True), inst.proxy_weights[None], "literal")
    if name != "two_training_worlds":  # the scenes put lava on the proxy's shortcut
        assert evaluation.touches_lava(inst.test_labels, literal.cells)
    assert evaluation.reaches_target(inst.test_labels, literal.cells)
    # The committed PNGs are what worlds/make_examples.py draws.
    for png in WORLDS.glob(f"{name}_*.png"):
        assert png.stat().st_size > 0
    doc = yaml.safe_load((WORLDS / f"{name}.yaml").read_text())
    edited = copy.deepcopy(doc)
    edited["test_world"]["horizon"] = 0
    for world in edited["training_worlds"] + [edited["test_world"]]:
        (tmp_path / world["image"]).write_bytes((WORLDS / world["image"]).read_bytes())
    with pytest.raises(ValueError, match=re.escape("test_world.horizon")):
        world_file.load_world(_write(tmp_path, edited))


def test_lavaland_instances_keep_their_defaults() -> None:
    inst = lavaland.make_instance("side_effects", 0, size=5, horizon=4)
    assert inst.terrain_names == TERRAIN_NAMES and inst.extra_training_worlds == ()
    assert inst.true_terrain_reward is lavaland.TRUE_TERRAIN_REWARD
    cells = [inst.test_start]
    assert evaluation.true_return(inst.test_labels, cells) == evaluation.true_return(
        inst.test_labels, cells, inst.true_terrain_reward)
