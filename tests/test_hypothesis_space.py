"""``ird_core.hypothesis.HypothesisSpace``: the one record of IRD's hypothesis space, shared by the
experiments (``TrialSpec``) and the world node. The linear space is the world itself; the others
are the random features and/or the novel feature applied in that order; bad fields are named."""

from __future__ import annotations

import numpy as np
import pytest

from ird_core.experiments import trials
from ird_core.hypothesis import LINEAR, NOVELTY_FEATURE, HypothesisSpace, with_novelty_feature, with_rff_hypothesis
from ird_core.worlds import lavaland


def _raw(condition: str = "latent_raw") -> lavaland.LavalandInstance:
    return lavaland.make_instance(condition, 3, size=6, horizon=6, obs_dim=5)


def test_the_linear_space_is_the_world_itself() -> None:
    inst = _raw()
    assert LINEAR.is_linear and LINEAR == HypothesisSpace()
    assert LINEAR.apply(inst) is inst
    assert not HypothesisSpace("rff").is_linear and not HypothesisSpace(novelty_feature=True).is_linear


def test_random_features_then_the_novel_feature() -> None:
    inst = _raw()
    out = HypothesisSpace("rff", 7, True, "one").apply(inst)
    expected = with_novelty_feature(with_rff_hypothesis(inst, 7), "one")
    assert out.feature_names == expected.feature_names == (*(f"rff_{i:03d}" for i in range(7)), NOVELTY_FEATURE)
    for field in ("train_features", "test_features"):
        np.testing.assert_array_equal(getattr(out, field), getattr(expected, field))
    # Only IRD's features change: the proxy and the sensors' labels are the designer's.
    assert out.proxy_feature_names == inst.proxy_feature_names
    np.testing.assert_array_equal(out.proxy_weights, inst.proxy_weights)
    np.testing.assert_array_equal(out.proxy_test_features, inst.proxy_test_features)
    # Deterministic: the random map is seeded by the instance.
    np.testing.assert_array_equal(HypothesisSpace("rff", 7, True, "one").apply(inst).test_features, out.test_features)


def test_random_features_leave_one_hot_worlds_alone() -> None:
    inst = _raw("side_effects")
    assert HypothesisSpace("rff", 7).apply(inst) is inst


def test_a_trial_uses_its_spec_s_space() -> None:
    spec = trials.TrialSpec("latent_raw", 3, size=6, horizon=6, obs_dim=5, hypothesis="rff", rff_features=7,
                            novelty_feature=True)
    assert spec.hypothesis_space() == HypothesisSpace("rff", 7, True)
    np.testing.assert_array_equal(trials.trial_instance(spec).test_features,
                                  HypothesisSpace("rff", 7, True).apply(_raw()).test_features)


@pytest.mark.parametrize("fields, name", [
    (dict(kind="quadratic"), "hypothesis"),
    (dict(rff_features=0), "rff_features"),
    (dict(rff_features=2.5), "rff_features"),
    (dict(rff_features=True), "rff_features"),
    (dict(novelty_feature="yes"), "novelty_feature"),
    (dict(novelty_value="two"), "novelty_value"),
])
def test_bad_fields_are_named(fields: dict, name: str) -> None:
    with pytest.raises(ValueError, match=name):
        HypothesisSpace(**fields)


def test_describe() -> None:
    assert LINEAR.describe() == "linear"
    assert HypothesisSpace("rff", 50, True).describe() == "rff (D = 50) + novel (feature_scale)"
