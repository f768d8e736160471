"""ird_ros.conversions: good input round-trips exactly; each kind of bad input raises a
ValueError whose message starts with the offending field."""

from __future__ import annotations

import array
import re
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from ird_msgs.msg import FeatureGrid, RewardPosterior, TerrainGrid
from ird_ros import conversions as conv

LAYERS4 = ["dirt", "grass", "target", "lava"]


def raises_field(field: str, match: str = ""):
    """pytest.raises(ValueError) whose message starts with ``field:`` (and contains ``match``)."""
    return pytest.raises(ValueError, match=rf"^{re.escape(field)}: .*{match}")


# --------------------------------------------------------------------------- FeatureGrid


@settings(max_examples=40, deadline=None)
@given(
    hnp.arrays(
        np.float32,
        hnp.array_shapes(min_dims=3, max_dims=3, min_side=1, max_side=6),
        elements=st.floats(width=32, allow_nan=False, allow_infinity=False),
    )
)
def test_feature_grid_roundtrip_exact(features: np.ndarray) -> None:
    layers = [f"l{k}" for k in range(features.shape[2])]
    msg = conv.feature_grid_to_msg(features, layers, resolution=0.25, origin=(1.5, -2.0))
    assert isinstance(msg.data, array.array) and msg.data.typecode == "f"
    back = conv.feature_grid_from_msg(msg)
    assert back.features.dtype == np.float32
    assert back.features.shape == features.shape
    assert np.array_equal(back.features.view(np.uint32), features.view(np.uint32))  # bit-exact
    assert back.layers == tuple(layers)
    assert (back.resolution, back.origin, back.frame_id) == (0.25, (1.5, -2.0), "map")
    assert (msg.info.height, msg.info.width) == features.shape[:2]


def test_feature_grid_index_convention() -> None:
    """data index (row*W + col)*d + k; row 0 is the bottom row."""
    h, w, d = 3, 4, 2
    features = np.arange(h * w * d, dtype=np.float32).reshape(h, w, d)
    msg = conv.feature_grid_to_msg(features, ["a", "b"])
    row, col, k = 2, 1, 1
    assert msg.data[(row * w + col) * d + k] == features[row, col, k]


def test_feature_grid_result_outlives_message() -> None:
    msg = conv.feature_grid_to_msg(np.ones((2, 2, 1), np.float32), ["a"])
    grid = conv.feature_grid_from_msg(msg)
    msg.data = array.array("f", [5.0] * 4)
    grid.features[0, 0, 0] = 3.0  # writable, independent copy
    assert grid.features[1, 1, 0] == 1.0


def _grid_msg(h: int = 15, w: int = 15, d: int = 20) -> FeatureGrid:
    return conv.feature_grid_to_msg(np.zeros((h, w, d), np.float32), [f"f{k}" for k in range(d)])


def test_feature_grid_from_msg_rejects_short_data() -> None:
    msg = _grid_msg()
    msg.data = msg.data[:-1]
    with pytest.raises(ValueError) as err:
        conv.feature_grid_from_msg(msg)
    assert str(err.value) == "FeatureGrid.data: expected 4500 values (H=15 x W=15 x d=20), got 4499"


def test_feature_grid_from_msg_names_the_callers_field() -> None:
    msg = _grid_msg(2, 2, 1)
    msg.data = array.array("f", [0.0] * 5)
    with raises_field("training_map.data", "expected 4 values"):
        conv.feature_grid_from_msg(msg, field="training_map")


@pytest.mark.parametrize(
    "mutate, field, match",
    [
        (lambda m: m.data.__setitem__(3, float("nan")), "FeatureGrid.data", "non-finite"),
        (lambda m: m.data.__setitem__(0, float("inf")), "FeatureGrid.data", "non-finite"),
        (lambda m: setattr(m, "layers", []), "FeatureGrid.layers", "must not be empty"),
        (lambda m: setattr(m, "layers", ["a", "a"]), "FeatureGrid.layers", "duplicate"),
        (lambda m: setattr(m, "layers", ["a", ""]), "FeatureGrid.layers", "non-empty"),
        (lambda m: setattr(m.info, "width", 0), "FeatureGrid.info.width", "> 0"),
        (lambda m: setattr(m.info, "height", 0), "FeatureGrid.info.height", "> 0"),
        (lambda m: setattr(m.info, "resolution", 0.0), "FeatureGrid.info.resolution", "> 0"),
        (lambda m: setattr(m.info, "resolution", float("nan")), "FeatureGrid.info.resolution", "> 0"),
        (lambda m: setattr(m.info.origin.position, "x", float("inf")), "FeatureGrid.info.origin", "finite"),
        (lambda m: setattr(m, "layers", ["a", "b", "c"]), "FeatureGrid.data", "expected 36 values"),
    ],
)
def test_feature_grid_from_msg_rejects(mutate, field: str, match: str) -> None:
    msg = conv.feature_grid_to_msg(np.zeros((3, 4, 2), np.float32), ["a", "b"])
    mutate(msg)
    with raises_field(field, match):
        conv.feature_grid_from_msg(msg)


@pytest.mark.parametrize(
    "features, layers, kwargs, field, match",
    [
        (np.zeros((3, 4), np.float32), ["a"], {}, "FeatureGrid.data", r"\(H, W, d\)"),
        (np.zeros((0, 4, 1), np.float32), ["a"], {}, "FeatureGrid.info.height", "> 0"),
        (np.zeros((3, 0, 1), np.float32), ["a"], {}, "FeatureGrid.info.width", "> 0"),
        (np.zeros((3, 4, 2), np.float32), ["a"], {}, "FeatureGrid.layers", "expected d=2"),
        (np.zeros((3, 4, 0), np.float32), [], {}, "FeatureGrid.layers", "must not be empty"),
        (np.zeros((3, 4, 2), np.float32), ["a", "a"], {}, "FeatureGrid.layers", "duplicate"),
        (np.full((3, 4, 1), np.nan), ["a"], {}, "FeatureGrid.data", "non-finite"),
        (np.full((1, 1, 1), 1e300), ["a"], {}, "FeatureGrid.data", "non-finite"),  # float32 overflow
        (np.array([[["x"]]]), ["a"], {}, "FeatureGrid.data", "numbers"),
        (np.zeros((3, 4, 1), np.float32), ["a"], {"resolution": -1.0}, "info.resolution", "> 0"),
        (np.zeros((3, 4, 1), np.float32), ["a"], {"origin": (0.0,)}, "info.origin", r"\(x, y\)"),
    ],
)
def test_feature_grid_to_msg_rejects(features, layers, kwargs, field: str, match: str) -> None:
    with raises_field(field, match):
        conv.feature_grid_to_msg(features, layers, **kwargs)


# --------------------------------------------------------------------------- TerrainGrid


def _terrain(h: int = 4, w: int = 5, seed: int = 0):
    rng = np.random.default_rng(seed)
    classes = rng.integers(0, 4, size=(h, w)).astype(np.uint8)
    classes[1, 2] = conv.UNKNOWN_CLASS
    probs = rng.dirichlet(np.ones(4), size=(h, w)).astype(np.float32)
    novelty = rng.exponential(size=(h, w)).astype(np.float32)
    return classes, probs, novelty


def test_terrain_grid_roundtrip_exact() -> None:
    classes, probs, novelty = _terrain()
    msg = conv.terrain_grid_to_msg(classes, LAYERS4, probabilities=probs, novelty=novelty, resolution=2.0)
    back = conv.terrain_grid_from_msg(msg)
    assert back.classes.dtype == np.uint8 and np.array_equal(back.classes, classes)
    assert back.probabilities is not None and np.array_equal(back.probabilities.view(np.uint32), probs.view(np.uint32))
    assert back.novelty is not None and np.array_equal(back.novelty.view(np.uint32), novelty.view(np.uint32))
    assert back.class_names == tuple(LAYERS4)
    assert back.resolution == 2.0
    assert TerrainGrid.UNKNOWN == conv.UNKNOWN_CLASS == 255


def test_terrain_grid_optional_fields_stay_empty() -> None:
    classes, _, _ = _terrain()
    msg = conv.terrain_grid_to_msg(classes, LAYERS4)
    assert len(msg.probabilities) == 0 and len(msg.novelty) == 0
    back = conv.terrain_grid_from_msg(msg)
    assert back.probabilities is None and back.novelty is None


@pytest.mark.parametrize(
    "kwargs, field, match",
    [
        ({"classes": np.zeros((4,), np.uint8)}, "TerrainGrid.classes", r"\(H, W\)"),
        ({"classes": np.zeros((0, 3), np.uint8)}, "TerrainGrid.info.height", "> 0"),
        ({"classes": np.zeros((3, 0), np.uint8)}, "TerrainGrid.info.width", "> 0"),
        ({"classes": np.full((4, 5), 4, np.uint8)}, "TerrainGrid.classes", r"\[0, 4\) or 255"),
        ({"classes": np.full((4, 5), -1)}, "TerrainGrid.classes", r"\[0, 4\) or 255"),
        ({"classes": np.zeros((4, 5), np.float32)}, "TerrainGrid.classes", "integers"),
        ({"class_names": []}, "TerrainGrid.class_names", "must not be empty"),
        ({"class_names": ["dirt", "dirt", "a", "b"]}, "TerrainGrid.class_names", "duplicate"),
        ({"probabilities": np.zeros((4, 5, 3), np.float32)}, "TerrainGrid.probabilities", "shape"),
        ({"probabilities": np.full((4, 5, 4), np.nan, np.float32)}, "TerrainGrid.probabilities", "non-finite"),
        ({"probabilities": np.full((4, 5, 4), 1.5, np.float32)}, "TerrainGrid.probabilities", r"\[0, 1\]"),
        ({"novelty": np.zeros((5, 4), np.float32)}, "TerrainGrid.novelty", "shape"),
        ({"novelty": np.full((4, 5), -0.5, np.float32)}, "TerrainGrid.novelty", ">= 0"),
        ({"novelty": np.full((4, 5), np.inf, np.float32)}, "TerrainGrid.novelty", "non-finite"),
    ],
)
def test_terrain_grid_to_msg_rejects(kwargs, field: str, match: str) -> None:
    classes, _, _ = _terrain()
    args = {"classes": classes, "class_names": LAYERS4, **kwargs}
    with raises_field(field, match):
        conv.terrain_grid_to_msg(args.pop("classes"), args.pop("class_names"), **args)


@pytest.mark.parametrize(
    "mutate, field, match",
    [
        (lambda m: setattr(m, "classes", m.classes[:-1]), "TerrainGrid.classes", "expected 20 values"),
        (lambda m: m.classes.__setitem__(0, 7), "TerrainGrid.classes", r"\[0, 4\) or 255"),
        (lambda m: setattr(m, "probabilities", m.probabilities[:-2]), "TerrainGrid.probabilities", "expected 80"),
        (lambda m: m.probabilities.__setitem__(5, float("nan")), "TerrainGrid.probabilities", "non-finite"),
        (lambda m: setattr(m, "novelty", m.novelty[:3]), "TerrainGrid.novelty", "expected 20"),
        (lambda m: m.novelty.__setitem__(0, -1.0), "TerrainGrid.novelty", ">= 0"),
        (lambda m: setattr(m, "class_names", ["a", "a", "b", "c"]), "TerrainGrid.class_names", "duplicate"),
        (lambda m: setattr(m.info, "width", 0), "TerrainGrid.info.width", "> 0"),
    ],
)
def test_terrain_grid_from_msg_rejects(mutate, field: str, match: str) -> None:
    classes, probs, novelty = _terrain()
    msg = conv.terrain_grid_to_msg(classes, LAYERS4, probabilities=probs, novelty=novelty)
    mutate(msg)
    with raises_field(field, match):
        conv.terrain_grid_from_msg(msg)


# --------------------------------------------------------------------------- OccupancyGrid


def test_occupancy_grid_roundtrip() -> None:
    costs = np.random.default_rng(0).integers(-1, 101, size=(5, 7)).astype(np.int8)
    msg = conv.occupancy_grid_to_msg(costs, resolution=0.25, origin=(1.0, -1.0))
    assert (msg.info.height, msg.info.width, msg.info.resolution) == (5, 7, 0.25)
    assert msg.header.frame_id == "map" and msg.data[2 * 7 + 3] == costs[2, 3]
    back = conv.occupancy_grid_from_msg(msg)
    assert back.dtype == np.int8 and np.array_equal(back, costs)


@pytest.mark.parametrize(
    "costs, field, match",
    [
        (np.zeros(5, np.int8), "OccupancyGrid.data", r"\(H, W\)"),
        (np.zeros((0, 5), np.int8), "OccupancyGrid.info.height", "> 0"),
        (np.zeros((5, 0), np.int8), "OccupancyGrid.info.width", "> 0"),
        (np.full((2, 2), 101), "OccupancyGrid.data", "0..100 or -1"),
        (np.full((2, 2), -2), "OccupancyGrid.data", "0..100 or -1"),
        (np.full((2, 2), 0.5), "OccupancyGrid.data", "integers"),
    ],
)
def test_occupancy_grid_to_msg_rejects(costs, field: str, match: str) -> None:
    with raises_field(field, match):
        conv.occupancy_grid_to_msg(costs)


def test_occupancy_grid_from_msg_rejects() -> None:
    msg = conv.occupancy_grid_to_msg(np.zeros((3, 3), np.int8))
    msg.data = msg.data[:-1]
    with raises_field("risk_map.data", "expected 9 values"):
        conv.occupancy_grid_from_msg(msg, field="risk_map")
    msg.data = array.array("b", [0] * 8 + [120])
    with raises_field("OccupancyGrid.data", "0..100 or -1"):
        conv.occupancy_grid_from_msg(msg)


# --------------------------------------------------------------------------- weights


@settings(max_examples=40, deadline=None)
@given(
    hnp.arrays(
        np.float64,
        hnp.array_shapes(min_dims=2, max_dims=2, min_side=1, max_side=8),
        elements=st.floats(allow_nan=False, allow_infinity=False),
    )
)
def test_weights_roundtrip_exact(weights: np.ndarray) -> None:
    flat = conv.weights_to_flat(weights)
    assert isinstance(flat, array.array) and flat.typecode == "d" and len(flat) == weights.size
    back = conv.weights_from_flat(flat, weights.shape[1])
    assert back.dtype == np.float64 and np.array_equal(back, weights)


def test_weights_from_list_and_single_vector() -> None:
    assert conv.weights_from_flat([1.0, 2.0, 3.0], 3).shape == (1, 3)
    assert list(conv.weights_to_flat(np.array([1.0, 2.0]))) == [1.0, 2.0]


@pytest.mark.parametrize(
    "flat, d, match",
    [
        ([1.0] * 7, 3, "length 7 is not a multiple of d=3"),
        ([], 3, "must not be empty"),
        ([1.0, float("nan"), 2.0], 3, "non-finite"),
        ([1.0, float("-inf"), 2.0], 3, "non-finite"),
        ([1.0, 2.0], 0, "d must be > 0"),
    ],
)
def test_weights_from_flat_rejects(flat, d: int, match: str) -> None:
    with raises_field("weights", match):
        conv.weights_from_flat(array.array("d", flat), d)
    with raises_field("PlanPath.weights", match):
        conv.weights_from_flat(flat, d, field="PlanPath.weights")


@pytest.mark.parametrize(
    "weights, match",
    [
        (np.zeros((2, 2, 2)), r"\(K, d\)"),
        (np.zeros((0, 3)), "must not be empty"),
        (np.array([[1.0, np.nan]]), "non-finite"),
        (np.array(["a"]), "numbers"),
    ],
)
def test_weights_to_flat_rejects(weights, match: str) -> None:
    with raises_field("weights", match):
        conv.weights_to_flat(weights)


# --------------------------------------------------------------------------- RewardPosterior


def _posterior(**overrides):
    base = dict(
        samples=np.random.default_rng(0).normal(size=(50, 3)),
        method="maxent_z",
        beta=10.0,
        acceptance_rate=0.35,
        r_hat_max=1.02,
        ess_min=321.5,
        prior_sigma=1.0,
        num_chains=4,
        seed=17,
    )
    base.update(overrides)
    return SimpleNamespace(**base)


def test_posterior_roundtrip_exact() -> None:
    post = _posterior()
    proxy = np.array([0.1, -0.2, 1.0])
    msg = conv.posterior_to_msg(post, feature_names=["dirt", "grass", "target"], proxy_weights=proxy)
    assert msg.num_samples == 50 and msg.converged
    back = conv.posterior_from_msg(msg)
    assert np.array_equal(back.samples, post.samples)
    assert np.array_equal(back.proxy_weights, proxy)
    assert back.feature_names == ("dirt", "grass", "target")
    for name in ("method", "beta", "acceptance_rate", "r_hat_max", "ess_min", "prior_sigma", "num_chains", "seed"):
        assert getattr(back, name) == getattr(post, name), name
    # PosteriorData quacks like ird_core's Posterior: it converts back to the same message.
    again = conv.posterior_to_msg(back, feature_names=back.feature_names, proxy_weights=back.proxy_weights)
    assert again == msg


def test_posterior_proxy_on_its_own_map_has_p_weights() -> None:
    """latent_classifier: the proxy has p weights (proxy_map layers), the samples d."""
    msg = conv.posterior_to_msg(_posterior(), feature_names=["a", "b", "c"], proxy_weights=[1.0, -0.2])
    back = conv.posterior_from_msg(msg)
    assert back.samples.shape == (50, 3) and list(back.proxy_weights) == [1.0, -0.2]


@pytest.mark.parametrize("r_hat, converged", [(1.1, True), (1.1000001, False), (float("nan"), False)])
def test_posterior_converged_flag(r_hat: float, converged: bool) -> None:
    msg = conv.posterior_to_msg(_posterior(r_hat_max=r_hat), feature_names=["a", "b", "c"], proxy_weights=[0, 0, 1])
    assert msg.converged is converged


@pytest.mark.parametrize(
    "overrides, kwargs, field, match",
    [
        ({"samples": np.zeros((5, 2))}, {}, "RewardPosterior.samples", r"\(K>=1, d=3\)"),
        ({"samples": np.zeros((0, 3))}, {}, "RewardPosterior.samples", r"\(K>=1, d=3\)"),
        ({"samples": np.full((5, 3), np.nan)}, {}, "RewardPosterior.samples", "non-finite"),
        ({}, {"proxy_weights": []}, "RewardPosterior.proxy_weights", "must not be empty"),
        ({}, {"proxy_weights": [1.0, np.inf, 2.0]}, "RewardPosterior.proxy_weights", "non-finite"),
        ({}, {"feature_names": ["a", "a", "b"]}, "RewardPosterior.feature_names", "duplicate"),
        ({}, {"feature_names": []}, "RewardPosterior.feature_names", "must not be empty"),
        ({"method": "exact_z"}, {}, "RewardPosterior.method", "maxent_z"),
        ({"beta": -1.0}, {}, "RewardPosterior.beta", ">= 0"),
        ({"beta": float("nan")}, {}, "RewardPosterior.beta", ">= 0"),
        ({"prior_sigma": 0.0}, {}, "RewardPosterior.prior_sigma", "> 0"),
        ({"acceptance_rate": 1.5}, {}, "RewardPosterior.acceptance_rate", r"\[0, 1\]"),
        ({"r_hat_max": float("inf")}, {}, "RewardPosterior.r_hat_max", "NaN"),
        ({"ess_min": -3.0}, {}, "RewardPosterior.ess_min", ">= 0"),
        ({"num_chains": 0}, {}, "RewardPosterior.num_chains", "> 0"),
        ({"seed": -1}, {}, "RewardPosterior.seed", "uint32"),
        ({"seed": 2**32}, {}, "RewardPosterior.seed", "uint32"),
    ],
)
def test_posterior_to_msg_rejects(overrides, kwargs, field: str, match: str) -> None:
    args = {"feature_names": ["a", "b", "c"], "proxy_weights": [0.0, 0.0, 1.0], **kwargs}
    with raises_field(field, match):
        conv.posterior_to_msg(_posterior(**overrides), **args)


@pytest.mark.parametrize(
    "mutate, field, match",
    [
        (lambda m: setattr(m, "samples", m.samples[:-1]), "RewardPosterior.samples", "not a multiple of d=3"),
        (lambda m: setattr(m, "samples", m.samples[:-3]), "RewardPosterior.num_samples", "is 50 but"),
        (lambda m: m.samples.__setitem__(4, float("nan")), "RewardPosterior.samples", "non-finite"),
        (lambda m: setattr(m, "proxy_weights", []), "RewardPosterior.proxy_weights", "must not be empty"),
        (lambda m: m.proxy_weights.__setitem__(0, float("nan")), "RewardPosterior.proxy_weights", "non-finite"),
        (lambda m: setattr(m, "method", "magic"), "RewardPosterior.method", "sample_z"),
        (lambda m: setattr(m, "beta", -2.0), "RewardPosterior.beta", ">= 0"),
        (lambda m: setattr(m, "feature_names", []), "RewardPosterior.feature_names", "must not be empty"),
    ],
)
def test_posterior_from_msg_rejects(mutate, field: str, match: str) -> None:
    msg = conv.posterior_to_msg(_posterior(), feature_names=["a", "b", "c"], proxy_weights=[0.0, 0.0, 1.0])
    mutate(msg)
    with raises_field(field, match):
        conv.posterior_from_msg(msg)


def test_posterior_from_empty_message_rejected() -> None:
    with raises_field("RewardPosterior.feature_names"):
        conv.posterior_from_msg(RewardPosterior())


# --------------------------------------------------------------------------- Path


def test_path_roundtrip_and_cell_centres() -> None:
    cells = [(0, 0), (0, 1), (1, 1), (1, 1), (2, 1), (14, 14)]
    path = conv.cells_to_path(cells, resolution=0.5, origin=(-1.0, 2.0), height=15, width=15)
    assert path.header.frame_id == "map" and len(path.poses) == len(cells)
    pose = path.poses[2].pose
    assert (pose.position.x, pose.position.y) == (-1.0 + 1.5 * 0.5, 2.0 + 1.5 * 0.5)
    assert pose.orientation.w == 1.0
    assert conv.path_to_cells(path, resolution=0.5, origin=(-1.0, 2.0), height=15, width=15) == cells
    assert conv.cell_center(2, 3, 2.0, (10.0, 20.0)) == (17.0, 25.0)


def test_path_from_numpy_cells() -> None:
    cells = np.array([[3, 4], [3, 5]], dtype=np.uint32)
    assert conv.path_to_cells(conv.cells_to_path(cells)) == [(3, 4), (3, 5)]


@pytest.mark.parametrize(
    "cells, kwargs, field, match",
    [
        ([], {}, "Path.poses", "at least one cell"),
        ([(0, 0, 1)], {}, "Path.poses", r"\(N, 2\)"),
        ([(-1, 0)], {}, "Path.poses", "negative"),
        ([(0, 0), (15, 0)], {"height": 15, "width": 15}, "Path.poses", "row off the map"),
        ([(0, 15)], {"height": 15, "width": 15}, "Path.poses", "col off the map"),
        ([(0.5, 1.0)], {}, "Path.poses", "integer"),
        ([(0, 0)], {"resolution": 0.0}, "Path.resolution", "> 0"),
    ],
)
def test_cells_to_path_rejects(cells, kwargs, field: str, match: str) -> None:
    with raises_field(field, match):
        conv.cells_to_path(cells, **kwargs)


def test_path_to_cells_rejects() -> None:
    path = conv.cells_to_path([(0, 0), (0, 1)])
    with raises_field("Path.poses[1]", "off the map"):
        conv.path_to_cells(path, width=1)
    path.poses[1].pose.position.x += 0.3
    with raises_field("Path.poses[1]", "not at a cell centre"):
        conv.path_to_cells(path)
    path.poses[0].pose.position.y = float("nan")
    with raises_field("plan.poses[0]", "non-finite"):
        conv.path_to_cells(path, field="plan")
    path.poses = []
    with raises_field("Path.poses", "at least one pose"):
        conv.path_to_cells(path)


# --------------------------------------------------------------------------- map info


def test_make_map_info_rejects() -> None:
    with raises_field("info.height", "> 0"):
        conv.make_map_info(0, 3)
    with raises_field("info.width", "> 0"):
        conv.make_map_info(3, 0)
    info = conv.make_map_info(2, 3, 0.5, (1.0, 2.0))
    assert (info.height, info.width, info.resolution) == (2, 3, 0.5)
    assert (info.origin.position.x, info.origin.position.y, info.origin.orientation.w) == (1.0, 2.0, 1.0)
