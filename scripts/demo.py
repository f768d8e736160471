"""PLACEHOLDER for the Lavaland demo (run it with: bash scripts/demo.sh).

The real demo (written later, replacing this file) starts the ROS graph -- world,
perception, inference, planner, rob, recorder -- in a private domain, asks for a world,
runs IRD inference and the literal and risk-averse plans, lets Rob drive them, records a
bag and prints lava/target rates. None of those nodes exist yet.

What this placeholder does: checks that the foundation works (rclpy, the generated
ird_msgs, ird_ros.conversions, a node in this run's private domain) and says what is
missing. It exits 0 when the foundation is healthy.
"""

from __future__ import annotations

import os
import sys

MISSING = """\
Missing before this becomes the IRD demo:
  - ird_core: Lavaland worlds, IRD inference, risk-averse planning (in progress)
  - ird_ros nodes: world, perception, inference, planner, rob, recorder
  - the launcher that starts them with msgs_config/params/graph.yaml and prints results"""


def main() -> int:
    import numpy as np
    import rclpy

    from ird_ros import conversions as conv

    grid = conv.feature_grid_to_msg(np.zeros((15, 15, 4), np.float32), ["dirt", "grass", "target", "lava"])
    rclpy.init()
    try:
        node = rclpy.create_node("ird_demo_placeholder")
        node.get_logger().info(
            f"foundation OK: ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID')}, "
            f"FeatureGrid {grid.info.height}x{grid.info.width}x{len(grid.layers)} built"
        )
        node.destroy_node()
    finally:
        rclpy.try_shutdown()
    print("scripts/demo.py is a PLACEHOLDER: the Lavaland demo is not written yet.")
    print(MISSING)
    return 0


if __name__ == "__main__":
    sys.exit(main())
