"""The world node: generates a Lavaland instance and publishes its maps and proxy (latched).

Run: ``python -m ird_ros.world --ros-args --params-file msgs_config/params/graph.yaml``

Publishes (reliable, transient local, depth 1; all messages of one generation carry the same
header stamp, so subscribers can pair them):

- ``/world/train_features`` (FeatureGrid): the training map in the IRD hypothesis space
  (``instance.train_features``, layers ``instance.feature_names``).
- ``/world/test_features`` (FeatureGrid): what Rob's sensors report on the test map: the
  indicators (side_effects), the two sensors' indicators (reward_hacking, lava reads as grass /
  target) or the raw observations (latent conditions).
- ``/world/train_proxy_features`` (FeatureGrid): the training map in the proxy's feature space
  (the classifier's class probabilities for latent_classifier; identical to
  ``/world/train_features`` otherwise). Published in every condition, so a late joiner never
  gets a stale classifier map from an earlier generation.
- ``/world/terrain`` (TerrainGrid): ground-truth terrain of the test map, one-hot probabilities.
- ``/world/proxy`` (ProxyReward): condition, seed, the proxy's feature names and weights, the
  training start/horizon, the test (deployment) start/horizon, and the true terrain rewards.
  Published last: a received proxy means the whole generation is out.

Serves ``/world/generate`` (GenerateWorld): regenerate with a new condition (empty = keep the
current one) and seed, republish everything, and update the ``condition`` / ``seed`` parameters
to the world now published. An unknown condition gets ``success: false`` naming ``condition``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from rclpy.node import Node

from ird_core import lavaland
from ird_core.terrain import TERRAIN_NAMES
from ird_msgs.msg import FeatureGrid, ProxyReward, TerrainGrid
from ird_msgs.srv import GenerateWorld
from ird_ros import conversions as conv
from ird_ros import names
from ird_ros.node_main import declare, run_node, exit_process

__all__ = ["WorldNode", "main"]


class WorldNode(Node):
    def __init__(self, **kwargs: Any) -> None:
        super().__init__(names.NODE_WORLD, **kwargs)
        self.condition = declare(
            self, "condition", "latent_raw", "Lavaland condition of the world generated at start-up",
            choices=lavaland.CONDITIONS)
        self.seed = declare(self, "seed", 0, "Seed of the world generated at start-up (maps, proxy)",
                            min_value=0, max_value=2**32 - 1)
        self.height = declare(self, "height", 15, "Map height H in cells (rows)", min_value=3, max_value=1000)
        self.width = declare(self, "width", 15, "Map width W in cells (columns)", min_value=3, max_value=1000)
        self.horizon = declare(self, "horizon", lavaland.DEFAULT_HORIZON,
                               "Horizon T (moves) of the training and the test MDP", min_value=1,
                               max_value=10000)
        self.obs_dim = declare(self, "obs_dim", 50, "Observation dimension of the latent conditions",
                               min_value=3, max_value=10000)
        self.resolution = declare(self, "resolution", 1.0, "Map resolution in metres per cell",
                                  min_value=1e-6, max_value=1e6)
        qos = names.latched_qos()
        self._pubs = {
            names.TOPIC_TRAIN_FEATURES: self.create_publisher(FeatureGrid, names.TOPIC_TRAIN_FEATURES, qos),
            names.TOPIC_TEST_FEATURES: self.create_publisher(FeatureGrid, names.TOPIC_TEST_FEATURES, qos),
            names.TOPIC_TRAIN_PROXY_FEATURES: self.create_publisher(
                FeatureGrid, names.TOPIC_TRAIN_PROXY_FEATURES, qos),
            names.TOPIC_TERRAIN: self.create_publisher(TerrainGrid, names.TOPIC_TERRAIN, qos),
            names.TOPIC_PROXY: self.create_publisher(ProxyReward, names.TOPIC_PROXY, qos),
        }
        self.instance: lavaland.LavalandInstance | None = None
        self.generate(self.condition, self.seed)
        self.create_service(GenerateWorld, names.SRV_GENERATE, self._on_generate)
        self.get_logger().info(
            f"published {self.condition} seed {self.seed} {self.height}x{self.width} T={self.horizon}")

    # ------------------------------------------------------------------ generation

    def generate(self, condition: str, seed: int) -> lavaland.LavalandInstance:
        """Make and publish a new instance (raises ``ValueError`` naming a bad argument)."""
        if condition not in lavaland.CONDITIONS:
            raise ValueError(f"condition: must be one of {list(lavaland.CONDITIONS)}, got {condition!r}")
        instance = lavaland.make_instance(
            condition, int(seed), size=(self.height, self.width), horizon=self.horizon, obs_dim=self.obs_dim)
        self.instance = instance
        self.condition, self.seed = condition, int(seed)
        self._publish(instance)
        return instance

    def _publish(self, inst: lavaland.LavalandInstance) -> None:
        stamp = self.get_clock().now().to_msg()
        geometry = dict(resolution=self.resolution, origin=(0.0, 0.0), stamp=stamp)
        msgs: list[tuple[str, Any]] = [
            (names.TOPIC_TRAIN_FEATURES, conv.feature_grid_to_msg(inst.train_features, inst.feature_names, **geometry)),
            (names.TOPIC_TEST_FEATURES, conv.feature_grid_to_msg(inst.test_features, inst.feature_names, **geometry)),
            (names.TOPIC_TRAIN_PROXY_FEATURES,
             conv.feature_grid_to_msg(inst.proxy_train_features, inst.proxy_feature_names, **geometry)),
            (names.TOPIC_TERRAIN, conv.terrain_grid_to_msg(
                inst.test_labels, TERRAIN_NAMES,
                probabilities=(inst.test_labels[..., None] == np.arange(len(TERRAIN_NAMES))).astype(np.float32),
                **geometry)),
            (names.TOPIC_PROXY, self._proxy_msg(inst, stamp)),
        ]
        for topic, msg in msgs:  # the proxy last: it marks a complete generation
            self._pubs[topic].publish(msg)

    def _proxy_msg(self, inst: lavaland.LavalandInstance, stamp: Any) -> ProxyReward:
        msg = ProxyReward()
        msg.header = conv.make_header(stamp)
        msg.condition = inst.condition
        msg.seed = int(inst.seed)
        msg.feature_names = list(inst.proxy_feature_names)
        msg.weights = conv.weights_to_flat(inst.proxy_weights, field="ProxyReward.weights")
        msg.start_row, msg.start_col = (int(v) for v in inst.train_start)
        msg.horizon = int(inst.train_horizon)
        msg.test_start_row, msg.test_start_col = (int(v) for v in inst.test_start)
        msg.test_horizon = int(inst.test_horizon)
        msg.terrain_names = list(TERRAIN_NAMES)
        msg.true_terrain_rewards = [float(v) for v in lavaland.TRUE_TERRAIN_REWARD]
        return msg

    # ------------------------------------------------------------------ service

    def _on_generate(self, request: GenerateWorld.Request, response: GenerateWorld.Response) -> GenerateWorld.Response:
        condition = request.condition or self.condition
        try:
            inst = self.generate(condition, int(request.seed))
        except ValueError as exc:
            response.success, response.message = False, str(exc)
            self.get_logger().warning(f"/world/generate rejected: {exc}")
            return response
        from rclpy.parameter import Parameter

        self.set_parameters([
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
