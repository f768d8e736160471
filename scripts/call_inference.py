#!/usr/bin/env python3
"""Minimal client of the IRD inference service (/ird/infer): copy it and adapt.

    .venv/bin/python scripts/call_inference.py                 # a small generated map
    .venv/bin/python scripts/call_inference.py --from-world    # the world node's training worlds + proxy
    options: --method maxent_z|sample_z  --beta 10  --num-samples 200  --seed 0  --timeout 120

The inference node must be running in the same ROS domain (ROS_DOMAIN_ID), e.g. started with
``scripts/launch_graph.py --nodes inference`` (or the whole graph for --from-world; with
``--world FILE`` the request holds every training world of the file).
Prints the posterior: per feature the proxy weight, posterior mean and std; then the
sampler's diagnostics (acceptance rate, largest split R-hat, smallest ESS).
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import rclpy
from rclpy.node import Node

from ird_core.posterior import METHODS
from ird_msgs.srv import InferReward
from ird_ros import conversions
from ird_ros.client.waits import spin_until
from ird_ros.graph import names
from ird_ros.graph.domains import dds_process_env
from ird_ros.nodes.world import TOPIC_INFER_REQUEST
from ird_ros.runtime.offload import service_qos


def generated_request(seed: int) -> InferReward.Request:
    """A 6x6 training map with indicator features (dirt, grass, target) and a designer's proxy."""
    rng = np.random.default_rng(seed)
    terrain = rng.choice(3, size=(6, 6), p=[0.65, 0.3, 0.05])  # 0 dirt, 1 grass, 2 target
    terrain[5, 5] = 2                                          # at least one target
    features = np.eye(3, dtype=np.float32)[terrain]            # (H, W, d) one-hot
    request = InferReward.Request()
    request.training_map = conversions.feature_grid_to_msg(features, ["dirt", "grass", "target"])
    request.start_row, request.start_col, request.horizon = 0, 0, 10
    request.proxy_weights = [0.1, -0.2, 1.0]                   # what the designer wrote down
    return request


def world_request(node: Node, timeout: float) -> InferReward.Request:
    """The request the world node poses on /world/infer_request (latched: we get the latest):
    training map, start, horizon, proxy weights, proxy_map and every further training world."""
    got: list[InferReward.Request] = []
    qos = names.latched_qos()  # transient local: receives what was published before we joined
    node.create_subscription(InferReward.Request, TOPIC_INFER_REQUEST, got.append, qos)
    spin_until(node, lambda: bool(got), timeout=timeout,
               what=f"{TOPIC_INFER_REQUEST} (is the world node running?)")
    return got[-1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--from-world", action="store_true", help="use the world node's request (/world/infer_request)")
    parser.add_argument("--method", default="maxent_z", choices=METHODS)
    parser.add_argument("--beta", type=float, default=10.0)
    parser.add_argument("--num-samples", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds for discovery and for the answer")
    args = parser.parse_args()

    with dds_process_env():  # this client's own sockets stay on loopback too
        rclpy.init()
    node = rclpy.create_node("call_inference")
    try:
        request = world_request(node, args.timeout) if args.from_world else generated_request(args.seed)
        request.beta = args.beta
        request.method = args.method
        request.num_samples = args.num_samples
        request.seed = args.seed
        request.prior_sigma = 0.0  # 0 = the node's default

        client = node.create_client(InferReward, names.SRV_INFER, qos_profile=service_qos())
        if not client.wait_for_service(timeout_sec=args.timeout):
            print(f"error: {names.SRV_INFER} not available (ROS_DOMAIN_ID right? inference running?)", file=sys.stderr)
            return 1
        future = client.call_async(request)           # never client.call() from a callback
        rclpy.spin_until_future_complete(node, future, timeout_sec=args.timeout)
        if not future.done():
            print(f"error: no answer from {names.SRV_INFER} within {args.timeout:g} s", file=sys.stderr)
            return 1
        response = future.result()
        if not response.success:
            print(f"inference refused the request: {response.message}", file=sys.stderr)
            return 1

        post = conversions.posterior_from_msg(response.posterior)  # samples as (K, d) numpy
        mean, std = post.samples.mean(axis=0), post.samples.std(axis=0)
        print(f"{post.method}, beta={post.beta:g}, sigma={post.prior_sigma:g}: "
              f"{post.samples.shape[0]} samples from {post.num_chains} chains")
        print(f"{'feature':<12} {'proxy':>8} {'mean':>8} {'std':>8}")
        for name, w, m, s in zip(post.feature_names, post.proxy_weights, mean, std):
            print(f"{name:<12} {w:>8.3f} {m:>8.3f} {s:>8.3f}")
        print(f"acceptance {post.acceptance_rate:.2f}, R-hat max {post.r_hat_max:.3f}, "
              f"ESS min {post.ess_min:.0f}" + ("" if post.converged else "  (NOT converged: R-hat > 1.1)"))
        return 0
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
