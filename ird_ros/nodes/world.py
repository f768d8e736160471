"""The world node: generates a Lavaland instance (or loads a world file) and publishes its maps
and proxy (latched).

Run: ``python -m ird_ros.nodes.world --ros-args --params-file msgs_config/params/graph.yaml``

Publishes (reliable, transient local, depth 1; all messages of one generation carry the same
header stamp, so subscribers can pair them):

- ``/world/train_features`` (FeatureGrid): what the sensors report on the training map
  (``instance.train_features``, layers ``instance.feature_names``): the paper's hypothesis space.
- ``/world/test_features`` (FeatureGrid): what Rob's sensors report on the test map: the
  indicators (side_effects), the two sensors' indicators (reward_hacking, lava reads as grass /
  target) or the raw observations (latent conditions).
- ``/world/train_proxy_features`` (FeatureGrid): the training map in the proxy's feature space
  (the classifier's class probabilities for latent_classifier; identical to
  ``/world/train_features`` otherwise). Published in every condition, so a late joiner never
  gets a stale classifier map from an earlier generation.
- ``/world/terrain`` (TerrainGrid): ground-truth terrain of the test map, one-hot probabilities.
- ``/world/infer_request`` (``ird_msgs/srv/InferReward_Request``): the /ird/infer request this
  world poses: training map, start, horizon, proxy weights, ``proxy_map`` (when the proxy is
  defined on a classifier's outputs) and ``training_worlds`` (the training worlds after the
  first: a world file's, or a generated Lavaland's with the parameter ``training_worlds`` above 1,
  ``ird_core.worlds.training_worlds``). A client sets beta, method, num_samples, seed and
  calls /ird/infer (``scripts/call_inference.py --from-world`` does). Its ``training_map``
  carries the generation's stamp.
- ``/world/proxy`` (ProxyReward): condition, seed, the proxy's feature names and weights, the
  training start/horizon, the test (deployment) start/horizon, and the true terrain rewards.
  Published last: a received proxy means the whole generation is out.

IRD's hypothesis space (parameters ``hypothesis``, ``rff_features``, ``novelty_feature``,
``novelty_value``: an ``ird_core.hypothesis.HypothesisSpace``, set at configure). The default is
the paper's: the sensors' features, and the topics above are all there is. Any other space
(random Fourier features of the latent observations, the *novel* feature) is applied to each
world by ``HypothesisSpace.apply``, exactly as the experiments apply it (``TrialSpec.hypothesis``,
``--novelty-feature``), and the world then also publishes, with the same stamp, before the proxy:

- ``/world/hypothesis/train_features`` and ``/world/hypothesis/test_features`` (FeatureGrid): the
  training and the test map in that space (layers ``rff_000``, ... and/or ``novel``). The
  planner, the inference node's queries, the live view and the bag analysis look a posterior's
  map up here first.
- ``/world/infer_request`` then carries the training maps in that space, with ``proxy_map`` the
  proxy's own features (the sensors' observations in latent_raw): the posterior lives in the
  hypothesis space while the proxy's behaviour is planned on its own features.

The sensors' topics, ``/world/proxy`` and so perception and the literal plan are unchanged.

World files (parameter ``world_file``, "" = generate Lavaland): the node loads the file with
``ird_core.worlds.world_file.load_world_file`` at start-up (a bad file stops the node before it serves,
with the loader's message naming the file, key and value) and publishes it instead of a
generated world: condition ``file``, the file's ``seed``, terrain classes
``instance.terrain_names`` (one-hot over all of them), the file's true rewards (empty lists
when the file gives none), and the file's resolution and origin (x, y; the yaw must be 0, the
grids are axis-aligned). The first training world is ``/world/train_features``; the others
travel in ``/world/infer_request``.

Serves ``/world/generate`` (GenerateWorld): regenerate with a new condition (empty = keep the
current one) and seed, republish everything, and update the ``condition`` / ``seed`` parameters
to the world now published. An unknown condition gets ``success: false`` naming ``condition``.
With a world file loaded, a Lavaland condition (or empty: the ``condition`` parameter) replaces
the file world by a generated one; condition ``file`` republishes the loaded file world (seed
ignored, the ``condition`` / ``seed`` parameters unchanged; ``success: false`` naming
``condition`` when no world file is set). The handler runs in ``ird_ros.runtime.guard``'s guard:
any other exception is a ``success: false`` answer, and the node keeps serving.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ird_core.hypothesis import DEFAULT_RFF_FEATURES, HYPOTHESES, NOVELTY_VALUES, HypothesisSpace
from ird_core.vocabulary import Condition, parse
from ird_core.worlds import lavaland, world_file
from ird_core.worlds.observations import DEFAULT_DIM
from ird_core.worlds.training_worlds import MAX_TRAINING_WORLDS, with_training_worlds
from ird_msgs.msg import FeatureGrid, ProxyReward, TerrainGrid, TrainingWorld
from ird_msgs.srv import GenerateWorld, InferReward
from ird_ros import conversions as conv
from ird_ros.graph import names
from ird_ros.runtime.node_main import exit_process, run_node
from ird_ros.runtime.lifecycle import ManagedNode
from ird_ros.runtime.node_params import Param
from ird_ros.runtime.offload import service_qos

__all__ = ["WorldNode", "PARAMETERS", "TOPIC_INFER_REQUEST", "infer_request", "with_world_file", "with_hypothesis",
           "with_generated_training_worlds", "main"]

TOPIC_INFER_REQUEST = names.TOPIC_INFER_REQUEST

PARAMETERS: dict[str, Param] = {
    "condition": Param("latent_raw", "Lavaland condition of the world published (set: a new world, as "
                                     "/world/generate makes)", choices=lavaland.ALL_CONDITIONS, runtime=True),
    "seed": Param(0, "Seed of the world published (maps, proxy; set: a new world)", min_value=0,
                  max_value=2**32 - 1, runtime=True),
    "height": Param(lavaland.DEFAULT_SIZE, "Map height H in cells (rows)", min_value=3, max_value=1000),
    "width": Param(lavaland.DEFAULT_SIZE, "Map width W in cells (columns)", min_value=3, max_value=1000),
    "horizon": Param(lavaland.DEFAULT_HORIZON, "Horizon T (moves) of the training and the test MDP",
                     min_value=1, max_value=10000),
    "obs_dim": Param(DEFAULT_DIM, "Observation dimension of the latent conditions", min_value=3,
                     max_value=10000),
    "resolution": Param(1.0, "Map resolution in metres per cell", min_value=1e-6, max_value=1e6),
    "world_file": Param("", "World file (YAML) published at start-up instead of a generated Lavaland; "
                            "\"\" = generate"),
    "hypothesis": Param("linear", "IRD's hypothesis space: linear (the sensors' features, the paper's) or rff "
                                  "(random Fourier features of the latent observations); not linear: also "
                                  "/world/hypothesis/*", choices=HYPOTHESES),
    "rff_features": Param(DEFAULT_RFF_FEATURES, "Random Fourier features D of hypothesis rff", min_value=1,
                          max_value=10000),
    "novelty_feature": Param(False, "Append the hypothesis feature 'novel' (zero in training; on test cells "
                                    "unlike every training cell, the training features' scale)"),
    "novelty_value": Param("feature_scale", "The novel feature's value on novel cells", choices=NOVELTY_VALUES),
    "training_worlds": Param(1, "Training worlds of a generated Lavaland (the first on /world/train_features, the "
                                "others in /world/infer_request's training_worlds)", min_value=1,
                             max_value=MAX_TRAINING_WORLDS),
}


def infer_request(inst: lavaland.LavalandInstance, **geometry: Any) -> InferReward.Request:
    """The /ird/infer request of ``inst``'s training worlds (every one; the sampler settings unset).

    ``geometry``: ``resolution``, ``origin``, ``stamp`` of the grids. The proxy map is sent when
    the proxy has features of its own (a classifier's outputs, as in latent_classifier).
    """
    use_proxy_map = inst.proxy_feature_names != inst.feature_names

    def world(features: np.ndarray, proxy_features: np.ndarray, start: Any, horizon: int,
              weights: np.ndarray, out: Any) -> Any:
        out.training_map = conv.feature_grid_to_msg(features, inst.feature_names, **geometry)
        if use_proxy_map:
            out.proxy_map = conv.feature_grid_to_msg(proxy_features, inst.proxy_feature_names, **geometry)
        out.start_row, out.start_col = (int(v) for v in start)
        out.horizon = int(horizon)
        out.proxy_weights = conv.weights_to_flat(weights, field="proxy_weights")
        return out

    request = world(inst.train_features, inst.proxy_train_features, inst.train_start, inst.train_horizon,
                    inst.proxy_weights, InferReward.Request())
    request.training_worlds = [world(w.features, w.proxy_features, w.start, w.horizon, w.proxy_weights,
                                     TrainingWorld()) for w in inst.extra_training_worlds]
    return request


def _with_parameters(specs: Sequence[Any], nodes: tuple[str, ...], values: Sequence[tuple[str, Any]]) -> list[Any]:
    """Node specs (``ird_ros.graph.NodeSpec``) whose ``nodes`` get ``-p name:=value`` for each of
    ``values`` after the params file (so they override it); the other specs unchanged."""
    args = tuple(arg for name, value in values for arg in ("-p", f"{name}:={value}"))
    return [dataclasses.replace(s, ros_args=tuple(s.ros_args) + args) if s.name in nodes else s for s in specs]


def with_world_file(specs: Sequence[Any], path: str | Path) -> list[Any]:
    """Node specs whose world and perception nodes load the world file ``path``:
    ``-p world_file:=<absolute path>``."""
    return _with_parameters(specs, (names.NODE_WORLD, names.NODE_PERCEPTION), [("world_file", Path(path).resolve())])


def with_hypothesis(specs: Sequence[Any], space: HypothesisSpace) -> list[Any]:
    """Node specs whose world node publishes in the hypothesis space ``space``: its four
    parameters (the launcher's ``--hypothesis``, ``--rff-features``, ``--novelty-feature``)."""
    return _with_parameters(specs, (names.NODE_WORLD,), [
        ("hypothesis", space.kind), ("rff_features", space.rff_features),
        ("novelty_feature", str(space.novelty_feature).lower()), ("novelty_value", space.novelty_value)])


def with_generated_training_worlds(specs: Sequence[Any], count: int) -> list[Any]:
    """Node specs whose world node gives a generated Lavaland ``count`` training worlds
    (``-p training_worlds:=<count>``; the launcher's ``--training-worlds``)."""
    return _with_parameters(specs, (names.NODE_WORLD,), [("training_worlds", int(count))])


class WorldNode(ManagedNode):
    """The world (managed: its first world is made at configure and published at activate)."""

    PARAMETERS = PARAMETERS

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_WORLD, **kwargs)

    def configure(self, p: dict[str, Any]) -> None:
        self.condition, self.seed = p["condition"], p["seed"]
        self.height, self.width, self.horizon = p["height"], p["width"], p["horizon"]
        self.obs_dim, self.resolution = p["obs_dim"], p["resolution"]
        self.training_worlds = int(p["training_worlds"])
        self.space = HypothesisSpace(p["hypothesis"], int(p["rff_features"]), bool(p["novelty_feature"]),
                                     p["novelty_value"])
        self.world_file: world_file.WorldFile | None = None
        if p["world_file"]:
            self.world_file = world_file.load_world_file(p["world_file"])  # ValueError: file, key, value
            if self.world_file.origin[2] != 0.0:
                raise ValueError(f"{self.world_file.path}: origin: the yaw must be 0 (the grids are "
                                 f"axis-aligned), got {list(self.world_file.origin)}")
        qos = names.latched_qos()
        self._pubs = {
            names.TOPIC_TRAIN_FEATURES: self.create_publisher(FeatureGrid, names.TOPIC_TRAIN_FEATURES, qos),
            names.TOPIC_TEST_FEATURES: self.create_publisher(FeatureGrid, names.TOPIC_TEST_FEATURES, qos),
            names.TOPIC_TRAIN_PROXY_FEATURES: self.create_publisher(
                FeatureGrid, names.TOPIC_TRAIN_PROXY_FEATURES, qos),
            names.TOPIC_HYPOTHESIS_TRAIN_FEATURES: self.create_publisher(
                FeatureGrid, names.TOPIC_HYPOTHESIS_TRAIN_FEATURES, qos),
            names.TOPIC_HYPOTHESIS_TEST_FEATURES: self.create_publisher(
                FeatureGrid, names.TOPIC_HYPOTHESIS_TEST_FEATURES, qos),
            names.TOPIC_TERRAIN: self.create_publisher(TerrainGrid, names.TOPIC_TERRAIN, qos),
            TOPIC_INFER_REQUEST: self.create_publisher(InferReward.Request, TOPIC_INFER_REQUEST, qos),
            names.TOPIC_PROXY: self.create_publisher(ProxyReward, names.TOPIC_PROXY, qos),
        }
        self.instance: lavaland.LavalandInstance | None = None
        # made now (a bad condition or world file fails the configure); published at activate
        if self.world_file is not None:
            self.publish_file()
        else:
            self.generate(self.condition, self.seed)
        self.create_service(GenerateWorld, names.SRV_GENERATE, self._on_generate, qos_profile=service_qos())

    def apply_parameters(self, p: dict[str, Any], changed: set[str]) -> None:
        """A new ``condition`` or ``seed`` makes (and, active, publishes) that world, as
        ``/world/generate`` does; ``/world/generate`` sets them to the world it made (no-op here)."""
        condition, seed = p["condition"], int(p["seed"])
        if (condition, seed) == (self.condition, self.seed):
            return
        if condition == lavaland.FILE_CONDITION:
            self.publish_file()
        else:
            self.generate(condition, seed)

    def activate(self) -> None:
        """Publish the current world (a generated one is made again from its condition and seed)."""
        if self.world_file is not None and self.instance is self.world_file.instance:
            self.publish_file()
            self.get_logger().info(f"published world file {self.world_file.path}")
        else:
            self.generate(self.condition, self.seed)
            self.get_logger().info(
                f"published {self.condition} seed {self.seed} {self.height}x{self.width} T={self.horizon}, "
                f"hypothesis space {self.space.describe()}")

    # ------------------------------------------------------------------ generation

    def generate(self, condition: str, seed: int) -> lavaland.LavalandInstance:
        """Make and publish a new instance (raises ``ValueError`` naming a bad argument)."""
        kind = parse(Condition, condition, "condition")
        instance = with_training_worlds(lavaland.make_instance(
            kind, int(seed), size=(self.height, self.width), horizon=self.horizon, obs_dim=self.obs_dim),
            self.training_worlds)
        self.instance = instance
        self.condition, self.seed = kind.value, int(seed)
        self._publish(instance, self.resolution, (0.0, 0.0))
        return instance

    def publish_file(self) -> lavaland.LavalandInstance:
        """Publish the loaded world file (``ValueError`` naming ``condition`` if none is set)."""
        if self.world_file is None:
            raise ValueError(f"condition: {lavaland.FILE_CONDITION!r} needs the world_file parameter, which is empty")
        self.instance = self.world_file.instance
        self._publish(self.instance, self.world_file.resolution, self.world_file.origin[:2])
        return self.instance

    def _publish(self, inst: lavaland.LavalandInstance, resolution: float, origin: tuple[float, ...]) -> None:
        """Publish ``inst`` (the sensors' world) and, in a hypothesis space other than the
        sensors', its maps in that space; the /ird/infer request is always the hypothesis space's."""
        stamp = conv.now_stamp(self)
        geometry = dict(resolution=resolution, origin=origin, stamp=stamp)
        num_terrains = len(inst.terrain_names)
        hyp = self.space.apply(inst)
        in_space: list[tuple[str, Any]] = [] if self.space.is_linear else [
            (names.TOPIC_HYPOTHESIS_TRAIN_FEATURES,
             conv.feature_grid_to_msg(hyp.train_features, hyp.feature_names, **geometry)),
            (names.TOPIC_HYPOTHESIS_TEST_FEATURES,
             conv.feature_grid_to_msg(hyp.test_features, hyp.feature_names, **geometry)),
        ]
        msgs: list[tuple[str, Any]] = [
            (names.TOPIC_TRAIN_FEATURES, conv.feature_grid_to_msg(inst.train_features, inst.feature_names, **geometry)),
            (names.TOPIC_TEST_FEATURES, conv.feature_grid_to_msg(inst.test_features, inst.feature_names, **geometry)),
            (names.TOPIC_TRAIN_PROXY_FEATURES,
             conv.feature_grid_to_msg(inst.proxy_train_features, inst.proxy_feature_names, **geometry)),
            (names.TOPIC_TERRAIN, conv.terrain_grid_to_msg(
                inst.test_labels, inst.terrain_names,
                probabilities=(inst.test_labels[..., None] == np.arange(num_terrains)).astype(np.float32),
                **geometry)),
            *in_space,
            (TOPIC_INFER_REQUEST, infer_request(hyp, **geometry)),
            (names.TOPIC_PROXY, self._proxy_msg(inst, stamp)),
        ]
        for topic, msg in msgs:  # the proxy last: it marks a complete generation
            self._pubs[topic].publish(msg)

    def _proxy_msg(self, inst: lavaland.LavalandInstance, stamp: Any) -> ProxyReward:
        msg = ProxyReward()
        msg.header = conv.make_header(stamp)
        msg.condition = str(inst.condition)
        msg.seed = int(inst.seed)
        msg.feature_names = list(inst.proxy_feature_names)
        msg.weights = conv.weights_to_flat(inst.proxy_weights, field="ProxyReward.weights")
        msg.start_row, msg.start_col = (int(v) for v in inst.train_start)
        msg.horizon = int(inst.train_horizon)
        msg.test_start_row, msg.test_start_col = (int(v) for v in inst.test_start)
        msg.test_horizon = int(inst.test_horizon)
        rewards = inst.true_terrain_reward
        msg.terrain_names = list(inst.terrain_names) if rewards is not None else []
        msg.true_terrain_rewards = [] if rewards is None else [float(v) for v in rewards]
        return msg

    # ------------------------------------------------------------------ service

    def _on_generate(self, request: GenerateWorld.Request, response: GenerateWorld.Response) -> GenerateWorld.Response:
        condition = request.condition or self.condition
        try:
            if condition == lavaland.FILE_CONDITION:
                self.publish_file()
                response.success = True
                response.message = f"republished world file {self.world_file.path}"  # type: ignore[union-attr]
                self.get_logger().info(response.message)
                return response
            inst = self.generate(condition, int(request.seed))
        except ValueError as exc:
            response.success, response.message = False, str(exc)
            self.get_logger().warning(f"/world/generate rejected: {exc}")
            return response
        from rclpy.parameter import Parameter

        # Atomically: set one at a time, the first would be a (condition, seed) pair this node
        # has not published, and apply_parameters would generate and publish that world.
        self.set_parameters_atomically([
            Parameter("condition", Parameter.Type.STRING, inst.condition),
            Parameter("seed", Parameter.Type.INTEGER, int(inst.seed)),
        ])
        response.success = True
        response.message = (f"generated {inst.condition} seed {inst.seed} "
                            f"{self.height}x{self.width} T={self.horizon}")
        self.get_logger().info(response.message)
        return response


def main(args: list[str] | None = None) -> int:
    return run_node(WorldNode, args)


if __name__ == "__main__":
    exit_process(main())
