"""The perception node: Rob's terrain classes (and the proxy's features) on the test map.

Run: ``python -m ird_ros.nodes.perception --ros-args --params-file msgs_config/params/graph.yaml``

Subscribes (latched) ``/world/test_features`` and ``/world/proxy`` and processes a pair once
both carry the same header stamp (one world generation). Publishes, latched, with the stamp of
that generation:

- ``/terrain/classes`` (TerrainGrid): per cell the class, class probabilities and novelty.
- ``/terrain/features`` (FeatureGrid): the test map in the proxy's feature space, i.e. the
  features on which the proxy's *literal* plan is made: the classifier's class probabilities
  (layers ``clf_dirt, clf_grass, clf_target``) in latent_classifier, the sensor features
  unchanged in the other conditions (there the proxy is defined on them directly).

What the classes are, per condition (perception reads only what the sensors say):

- side_effects, pot_of_gold: the indicator layers are the classes (dirt, grass, target, lava[, gold]); probabilities
  are the indicators; novelty 0 (the sensors name lava).
- reward_hacking: classes dirt, grass, target from the two sensors. Where they agree the class
  is theirs; where they disagree (lava: grass to sensor 1, target to sensor 2) the class is
  unknown (255); probabilities are the mean of the sensors' indicators; novelty is 1 where the
  sensors disagree, else 0.
- latent_raw and latent_classifier: the designer's safe-terrain classifier (QDA over dirt, grass,
  target; no lava class) applied to the 50-d observations: classes = ``predict``, probabilities =
  ``predict_proba``, novelty = ``novelty`` (chi2 surprise in nats). With the parameter
  ``unknown_novelty`` > 0, cells whose novelty exceeds it are marked unknown (255).
- file (a world file, ``ird_core.worlds.world_file``): with the ``world_file`` parameter set to the
  file the world node publishes, the file's own instance: its classifier if it has one
  (``proxy_features: classifier``; then as latent_classifier, and ``/terrain/features`` = the
  classifier's probabilities); Gaussian features without a classifier get the safe-terrain
  classifier fitted on the file's observation model (seed ``instance.seed``), as latent_raw.
  Perception checks that the received test map equals the file's (float32 tolerance) first.
  Otherwise (indicator or vector features, or no ``world_file``) the layers are the classes,
  as side_effects: ``classify_indicators``. Features outside [0, 1] without a matching
  ``world_file`` are refused (an error naming ``world_file``; nothing published).

Where the classifier comes from: it cannot travel over ROS, so perception rebuilds it from what
``/world/proxy`` says (condition, seed, horizon) and the map itself (size, and ``obs_dim`` = the
number of observation layers): ``ird_core.worlds.lavaland.make_instance("latent_classifier", seed,
...)`` fits exactly the designer's classifier (both latent conditions share the observation
model and the observations, by seed). Before using it, perception checks that the rebuilt
instance's test observations equal the received ones (float32 tolerance): if the world was made
with settings perception cannot reproduce, it logs an error and publishes nothing rather than
classify with the wrong model. (Fitting on data instead would need labelled observations, which
the graph does not carry: the training map's labels are the designer's secret.) Every callback
runs in ``ird_ros.runtime.guard``'s guard: whatever a message raises is logged, never the end of
the node.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ird_core.vocabulary import Condition
from ird_core.worlds import lavaland, world_file
from ird_core.worlds.observations import fit_classifier
from ird_core.worlds.terrain import SAFE_TERRAINS, TERRAIN_NAMES
from ird_msgs.msg import FeatureGrid, ProxyReward, TerrainGrid
from ird_ros import conversions as conv
from ird_ros.graph import names
from ird_ros.runtime.node_main import exit_process, run_node
from ird_ros.runtime.lifecycle import ManagedNode
from ird_ros.runtime.node_params import Param
from ird_ros.stamps import stamp_key

__all__ = ["PerceptionNode", "PARAMETERS", "classify_indicators", "classify_sensors", "main"]

PARAMETERS: dict[str, Param] = {
    "unknown_novelty": Param(0.0, "Latent conditions: cells whose classifier novelty (nats) exceeds this are "
                                  "marked unknown (255); 0 = never", min_value=0.0, runtime=True),
    "world_file": Param("", "The world file the world node publishes (\"\" = none): file worlds with "
                            "Gaussian features take their classifier from it"),
}

_SAFE_NAMES = tuple(TERRAIN_NAMES[t] for t in SAFE_TERRAINS)


def classify_indicators(features: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One sensor of indicators (H, W, C): classes (argmax; 255 where no indicator is on),
    probabilities (the indicators), novelty (zeros)."""
    probs = np.clip(features, 0.0, 1.0).astype(np.float32)
    classes = np.argmax(probs, axis=-1).astype(np.uint8)
    classes[probs.max(axis=-1) <= 0.0] = conv.UNKNOWN_CLASS
    return classes, probs, np.zeros(features.shape[:2], dtype=np.float32)


def classify_sensors(features: np.ndarray, num_sensors: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Several sensors of C indicators each, (H, W, S*C): the agreed class or 255, the mean
    indicator as probabilities, novelty 1 where the sensors disagree."""
    h, w, total = features.shape
    per = total // num_sensors
    sensors = np.clip(features, 0.0, 1.0).reshape(h, w, num_sensors, per)
    votes = np.argmax(sensors, axis=-1)  # (H, W, S)
    agree = np.all(votes == votes[..., :1], axis=-1)
    classes = np.where(agree, votes[..., 0], conv.UNKNOWN_CLASS).astype(np.uint8)
    probs = sensors.mean(axis=2).astype(np.float32)
    return classes, probs, (~agree).astype(np.float32)


class PerceptionNode(ManagedNode):
    """Perception (managed): reads the world while inactive, classifies and publishes while active;
    ``unknown_novelty`` may change at run time (the current map is classified again)."""

    PARAMETERS = PARAMETERS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_PERCEPTION, **kwargs)

    def configure(self, p: dict[str, Any]) -> None:
        self.unknown_novelty = p["unknown_novelty"]
        # A bad file fails the configure, like the world node's.
        self._file_instance = world_file.load_world(p["world_file"]) if p["world_file"] else None
        qos = names.latched_qos()
        self._classes_pub = self.create_publisher(TerrainGrid, names.TOPIC_TERRAIN_CLASSES, qos)
        self._features_pub = self.create_publisher(FeatureGrid, names.TOPIC_TERRAIN_FEATURES, qos)
        self._test_msg: FeatureGrid | None = None
        self._proxy_msg: ProxyReward | None = None
        self._done_stamp: tuple[int, int] | None = None
        self._classifiers: dict[tuple, Any] = {}
        self.create_subscription(FeatureGrid, names.TOPIC_TEST_FEATURES, self._on_test, qos)
        self.create_subscription(ProxyReward, names.TOPIC_PROXY, self._on_proxy, qos)

    def activate(self) -> None:
        self._done_stamp = None  # publish the current map's classification (again)
        self._try_process()

    def apply_parameters(self, p: dict[str, Any], changed: set[str]) -> None:
        self.unknown_novelty = p["unknown_novelty"]
        self._done_stamp = None
        self._try_process()

    def _on_test(self, msg: FeatureGrid) -> None:
        self._test_msg = msg
        self._try_process()

    def _on_proxy(self, msg: ProxyReward) -> None:
        self._proxy_msg = msg
        self._try_process()

    def _try_process(self) -> None:
        test, proxy = self._test_msg, self._proxy_msg
        if test is None or proxy is None or not self.is_active:
            return
        stamp = stamp_key(test.header.stamp)
        if stamp != stamp_key(proxy.header.stamp) or stamp == self._done_stamp:
            return  # not one generation (yet), or already done
        try:
            self._process(test, proxy)
        except ValueError as exc:
            self.get_logger().error(f"cannot perceive the test map: {exc}")
        self._done_stamp = stamp

    def _classifier(self, proxy: ProxyReward, grid: conv.FeatureGridData) -> Any:
        h, w, dim = grid.shape
        key = (int(proxy.seed), h, w, int(proxy.horizon), dim)
        if key not in self._classifiers:
            inst = lavaland.make_instance(Condition.LATENT_CLASSIFIER, int(proxy.seed), size=(h, w),
                                          horizon=int(proxy.horizon), obs_dim=dim)
            if inst.feature_names != grid.layers:
                raise ValueError(f"/world/test_features.layers: expected {dim} observation layers "
                                 f"{inst.feature_names[:2]}..., got {grid.layers[:2]}...")
            if not np.allclose(inst.test_features.astype(np.float32), grid.features, rtol=1e-5, atol=1e-5):
                raise ValueError("/world/test_features.data: the observations differ from the world "
                                 f"rebuilt from seed {proxy.seed}; cannot reproduce the classifier")
            self._classifiers = {key: inst.classifier}  # keep one: worlds change rarely
        return self._classifiers[key]

    def _file_classifier(self, grid: conv.FeatureGridData) -> Any:
        """The classifier of the file world (None: classify the layers as indicators)."""
        inst = self._file_instance
        matches = (inst is not None and inst.feature_names == grid.layers
                   and np.allclose(inst.test_features.astype(np.float32), grid.features, rtol=1e-5, atol=1e-5))
        if not matches:
            if not np.all((grid.features >= 0.0) & (grid.features <= 1.0)):
                raise ValueError("world_file: the test map is not indicators and is not the test map of the "
                                 "parameter's world file; set world_file to the file the world node publishes")
            return None
        assert inst is not None
        if inst.classifier is None and inst.observation_model is not None:
            inst = dataclasses.replace(
                inst, classifier=fit_classifier(inst.observation_model, np.random.default_rng(inst.seed)))
            self._file_instance = inst  # fit once
        return inst.classifier

    def _classify(self, clf: Any, grid: conv.FeatureGridData) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The classifier's classes (unknown past ``unknown_novelty``), probabilities, novelty."""
        obs = grid.features.astype(np.float64)
        probs = clf.predict_proba(obs).astype(np.float32)
        classes = clf.predict(obs).astype(np.uint8)
        novelty = np.maximum(clf.novelty(obs), 0.0).astype(np.float32)
        if self.unknown_novelty > 0:
            classes[novelty > self.unknown_novelty] = conv.UNKNOWN_CLASS
        return classes, probs, novelty

    def _process(self, test: FeatureGrid, proxy: ProxyReward) -> None:
        grid = conv.feature_grid_from_msg(test, field="/world/test_features")
        condition = proxy.condition
        feature_out: tuple[np.ndarray, tuple[str, ...]] = (grid.features, grid.layers)
        if condition in (Condition.SIDE_EFFECTS, Condition.POT_OF_GOLD):  # indicator layers are the classes
            classes, probs, novelty = classify_indicators(grid.features)
            class_names = grid.layers
        elif condition == Condition.REWARD_HACKING:
            classes, probs, novelty = classify_sensors(grid.features, 2)
            class_names = _SAFE_NAMES
        elif condition in (Condition.LATENT_RAW, Condition.LATENT_CLASSIFIER):
            clf = self._classifier(proxy, grid)
            classes, probs, novelty = self._classify(clf, grid)
            class_names = _SAFE_NAMES
            if condition == Condition.LATENT_CLASSIFIER:
                # The proxy's feature space: exactly lavaland's proxy_test_features.
                feature_out = (clf.predict_proba(grid.features.astype(np.float64)), tuple(proxy.feature_names))
        elif condition == lavaland.FILE_CONDITION:
            clf = self._file_classifier(grid)
            if clf is None:
                classes, probs, novelty = classify_indicators(grid.features)
                class_names = grid.layers
            else:
                classes, probs, novelty = self._classify(clf, grid)
                class_names = _SAFE_NAMES
                if tuple(proxy.feature_names) != grid.layers:  # the proxy is on the classifier's outputs
                    feature_out = (clf.predict_proba(grid.features.astype(np.float64)), tuple(proxy.feature_names))
        else:
            raise ValueError(f"/world/proxy.condition: unknown condition {condition!r}")
        geometry = dict(resolution=grid.resolution, origin=grid.origin, stamp=test.header.stamp)
        self._features_pub.publish(conv.feature_grid_to_msg(feature_out[0], feature_out[1], **geometry))
        self._classes_pub.publish(conv.terrain_grid_to_msg(
            classes, class_names, probabilities=np.clip(probs, 0.0, 1.0), novelty=novelty, **geometry))
        known = classes != conv.UNKNOWN_CLASS
        self.get_logger().info(
            f"perceived {condition} seed {proxy.seed}: {int(known.sum())}/{classes.size} cells classified, "
            f"max novelty {float(novelty.max()):.1f}")


def main(args: list[str] | None = None) -> int:
    return run_node(PerceptionNode, args)


if __name__ == "__main__":
    exit_process(main())
