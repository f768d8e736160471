"""Minimal client of the IRD inference service (/ird/infer): copy it and adapt.

    ird-infer                   # a small generated map (or: .venv/bin/python scripts/call_inference.py)
    ird-infer --from-world      # the world node's training worlds + proxy
    options: --method maxent_z|sample_z  --beta 10  --num-samples 200  --seed 0  --timeout 120
             --proxy-counts optimal|maxent  --designer-temperature 1   (the observation model)
             --risk min|cvar|mean_sd  --risk-level 0.25   (then plan on the posterior: /ird/plan)

Prints the ROS_DOMAIN_ID it searches first; with no graph there within --timeout it says so in one
paragraph (which domain, how to set another) and exits 1.
The inference node must be running in the same ROS domain (ROS_DOMAIN_ID), e.g. started with
``scripts/launch_graph.py --nodes inference`` (or the whole graph for --from-world; with
``--world FILE`` the request holds every training world of the file).
Prints the posterior (docs/spec.md section 3): per feature the proxy weight, posterior mean and
std; then the sampler's diagnostics (acceptance rate, largest split R-hat, smallest ESS) and the
observation model used. With ``--risk``, it then asks ``/ird/plan`` (the planner node must run
too) for a per-step plan with the posterior's samples on the request's own training map, from its
start over its horizon (a demo: a robot plans on its test map), and prints the plan and the risk
measure it used (docs/spec.md section 4).
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import numpy as np

from ird_core.posterior import METHODS
from ird_core.vocabulary import PROXY_COUNTS, RISK_MEASURES
from ird_ros import conversions
from ird_ros.client import ClientTimeout, IrdClient, infer_request, plan_request
from ird_ros.graph.domains import domain_banner


def generated_request(seed: int) -> Any:
    """A 6x6 training map with indicator features (dirt, grass, target) and a designer's proxy."""
    rng = np.random.default_rng(seed)
    terrain = rng.choice(3, size=(6, 6), p=[0.65, 0.3, 0.05])  # 0 dirt, 1 grass, 2 target
    terrain[5, 5] = 2                                          # at least one target
    features = np.eye(3, dtype=np.float32)[terrain]            # (H, W, d) one-hot
    training_map = conversions.feature_grid_to_msg(features, ["dirt", "grass", "target"])
    proxy_weights = [0.1, -0.2, 1.0]                           # what the designer wrote down
    return infer_request(training_map, (0, 0), 10, proxy_weights, beta=0.0, method="", num_samples=0, seed=0)


#: The largest value of the request's ``uint32`` fields (num_samples, seed).
_UINT32_MAX = 2**32 - 1


def _whole(low: int):
    """argparse type: an integer in ``[low, 2^32 - 1]`` (the request's uint32 fields)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = low - 1
        if not low <= value <= _UINT32_MAX:
            raise argparse.ArgumentTypeError(f"expected an integer in [{low}, {_UINT32_MAX}], got {text!r}")
        return value
    return parse


def _real(low: float, positive: bool = False, zero_or_in: "tuple[float, float] | None" = None):
    """argparse type: a finite number ``>= low`` (``> low`` if ``positive``), or with
    ``zero_or_in`` 0 or a number in that closed range."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = float("nan")
        if zero_or_in is not None:
            ok = value == 0.0 or zero_or_in[0] <= value <= zero_or_in[1]
            want = f"0 or a number in [{zero_or_in[0]:g}, {zero_or_in[1]:g}]"
        else:
            ok = math.isfinite(value) and (value > low if positive else value >= low)
            want = f"a finite number {'>' if positive else '>='} {low:g}"
        if not ok:
            raise argparse.ArgumentTypeError(f"expected {want}, got {text!r}")
        return value
    return parse


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The options, each checked before the client looks for a graph (argparse exits with status
    2 naming the option)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--from-world", action="store_true", help="use the world node's request (/world/infer_request)")
    parser.add_argument("--method", default="maxent_z", choices=METHODS, help="the posterior's approximation")
    parser.add_argument("--beta", type=_real(0.0), default=10.0, help="designer rationality (default 10)")
    parser.add_argument("--num-samples", type=_whole(1), default=200, help="posterior samples (default 200)")
    parser.add_argument("--seed", type=_whole(0), default=0, help="sampler seed (and the generated map's)")
    parser.add_argument("--proxy-counts", default="", choices=("", *PROXY_COUNTS),
                        help="observation model: the proxy's optimal-path or MaxEnt counts (default: the node's)")
    parser.add_argument("--designer-temperature", type=_real(0.0, zero_or_in=(0.001, 1000.0)), default=0.0,
                        help="MaxEnt designer's temperature in [0.001, 1000] (default 0: the node's)")
    parser.add_argument("--risk", default=None, choices=("", *RISK_MEASURES),
                        help="then plan on the posterior with this risk measure (\"\": the planner's default)")
    parser.add_argument("--risk-level", type=_real(0.0), default=0.0,
                        help="cvar's alpha in (0, 1] or mean_sd's lambda in [0, 100] (default 0: none)")
    parser.add_argument("--timeout", type=_real(0.0, positive=True), default=120.0,
                        help="seconds for discovery and for the answer (default 120); with no graph in "
                             "ROS_DOMAIN_ID by then, exit 1 naming the domain")
    return parser.parse_args(argv)


def print_posterior(post: conversions.PosteriorData) -> None:
    """Per feature the proxy weight, posterior mean and std; then the sampler's diagnostics."""
    mean, std = post.samples.mean(axis=0), post.samples.std(axis=0)
    print(f"{post.method}, beta={post.beta:g}, sigma={post.prior_sigma:g}: "
          f"{post.samples.shape[0]} samples from {post.num_chains} chains")
    print(f"{'feature':<12} {'proxy':>8} {'mean':>8} {'std':>8}")
    for name, w, m, s in zip(post.feature_names, post.proxy_weights, mean, std):
        print(f"{name:<12} {w:>8.3f} {m:>8.3f} {s:>8.3f}")
    print(f"acceptance {post.acceptance_rate:.2f}, R-hat max {post.r_hat_max:.3f}, "
          f"ESS min {post.ess_min:.0f}" + ("" if post.converged else "  (NOT converged: R-hat > 1.1)"))
    print(f"observation model: {post.proxy_counts or '?'} proxy counts"
          + (f", designer temperature {post.designer_temperature:g}" if post.proxy_counts == "maxent" else ""))


def plan_on(ird: IrdClient, request: Any, post: conversions.PosteriorData, args: argparse.Namespace) -> int:
    """``/ird/plan`` per step on ``request``'s training map with the samples; print it; 0 or 1."""
    plan = ird.plan(plan_request((request.start_row, request.start_col), request.horizon, "per_step", "none",
                                 weights=post.samples, grid=request.training_map, label="call_inference",
                                 risk=args.risk, risk_level=args.risk_level), timeout=args.timeout)
    if not plan.ok:
        print(f"the planner refused the request: {plan.message}", file=sys.stderr)
        return 1
    response = plan.response
    level = f" {response.risk_level:g}" if response.risk != "min" else ""
    print(f"plan ({response.risk}{level}): objective {response.objective:.4g}, cells "
          + " ".join(f"({r},{c})" for r, c in plan.unwrap().cells))
    return 0


def not_found(exc: ClientTimeout, domain_id: int) -> str:
    """One paragraph: what was not found, in which domain, and how to point this client elsewhere."""
    return (f"call_inference: no IRD graph answered in ROS_DOMAIN_ID={domain_id}: {' '.join(str(exc).split())} "
            "Start one in this domain (scripts/launch_graph.py --domain-id "
            f"{domain_id}), or use the domain a running graph printed: export ROS_DOMAIN_ID=N; "
            "source scripts/lib/ros_env.sh && ird_ros_env")


def main(argv: list[str] | None = None) -> int:
    """Ask /ird/infer once and print the posterior; 1 if the graph is not found or refuses."""
    args = parse_args(argv)
    with IrdClient(node_name="call_inference") as ird:  # this client's own sockets stay on loopback too
        print(domain_banner(ird.domain_id, "searched for the graph"), flush=True)
        try:
            request = ird.world_infer_request(timeout=args.timeout) if args.from_world else generated_request(args.seed)
            request.beta, request.method = args.beta, args.method
            request.num_samples, request.seed = args.num_samples, args.seed
            request.prior_sigma = 0.0  # 0 = the node's default
            request.proxy_counts, request.designer_temperature = args.proxy_counts, args.designer_temperature
            result = ird.infer(request, timeout=args.timeout)
            if result.ok:
                print_posterior(result.unwrap())
                return 0 if args.risk is None else plan_on(ird, request, result.unwrap(), args)
        except ClientTimeout as exc:
            print(not_found(exc, ird.domain_id), file=sys.stderr)
            return 1
        except KeyboardInterrupt:
            print("call_inference: interrupted", file=sys.stderr)
            return 130
    print(f"inference refused the request: {result.message}", file=sys.stderr)
    return 1


if __name__ == "__main__":
    sys.exit(main())
