"""Requests of the IRD services, built from numpy arrays and plain values (docs/spec.md section 6).

Each builder fills the fields a caller chooses and leaves the rest at the message's default, which
the nodes read as "the node's default" or "the latest published" (an empty ``map``: the latest
perceived test map; empty ``weights``: the latest posterior's samples, or the proxy for
``literal``). The nodes validate every field; the builders only convert.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

import numpy as np

if TYPE_CHECKING:
    from ird_msgs.msg import FeatureGrid
    from ird_msgs.srv import InferReward, PlanPath, ProposeQuery

__all__ = ["infer_request", "plan_request", "query_request"]


def infer_request(
    training_map: "FeatureGrid",
    start: tuple[int, int],
    horizon: int,
    proxy_weights: Sequence[float] | np.ndarray,
    *,
    beta: float,
    method: str,
    num_samples: int,
    seed: int,
    prior_sigma: float = 0.0,
    proxy_map: "FeatureGrid | None" = None,
    proxy_counts: str = "",
    designer_temperature: float = 0.0,
) -> "InferReward.Request":
    """An ``/ird/infer`` request: the proxy ``proxy_weights`` designed on ``training_map`` from
    ``start`` over ``horizon`` moves (docs/spec.md section 3); ``prior_sigma`` 0 = the node's
    default; ``proxy_map`` the map the proxy is defined on (latent_classifier), if any; the
    observation model ``proxy_counts`` ("optimal" or "maxent"; "" = the node's) and
    ``designer_temperature`` (MaxEnt's; 0 = the node's)."""
    from ird_msgs.srv import InferReward

    request = InferReward.Request()
    request.training_map = training_map
    request.start_row, request.start_col = (int(v) for v in start)
    request.horizon = int(horizon)
    request.proxy_weights = np.asarray(proxy_weights, dtype=np.float64).ravel().tolist()
    if proxy_map is not None:
        request.proxy_map = proxy_map
    request.beta, request.method = float(beta), str(method)
    request.num_samples, request.seed, request.prior_sigma = int(num_samples), int(seed), float(prior_sigma)
    request.proxy_counts, request.designer_temperature = str(proxy_counts), float(designer_temperature)
    return request


def plan_request(
    start: tuple[int, int],
    horizon: int,
    mode: str,
    baseline: str,
    *,
    weights: np.ndarray | Sequence[float] = (),
    reference_features: np.ndarray | Sequence[float] = (),
    grid: "FeatureGrid | None" = None,
    label: str = "",
    risk: str = "",
    risk_level: float = 0.0,
) -> "PlanPath.Request":
    """A ``/ird/plan`` request (docs/spec.md section 4): ``weights`` (K, d) or flat K*d values
    (empty: the latest posterior, or the proxy for ``literal``), ``reference_features`` the
    ``training_features`` baseline's f_ref (empty: the node's), ``grid`` the test map (None: the
    latest perceived one), ``risk`` the measure over the samples ("min", "cvar", "mean_sd"; "" =
    the planner's) at ``risk_level`` (cvar's alpha, mean_sd's lambda; 0 = none / the planner's)."""
    from ird_msgs.srv import PlanPath

    request = PlanPath.Request()
    if grid is not None:
        request.map = grid
    request.start_row, request.start_col = (int(v) for v in start)
    request.horizon = int(horizon)
    request.mode, request.baseline, request.label = str(mode), str(baseline), label
    request.risk, request.risk_level = str(risk), float(risk_level)
    request.weights = np.asarray(weights, dtype=np.float64).ravel().tolist()
    request.reference_features = np.asarray(reference_features, dtype=np.float64).ravel().tolist()
    return request


def query_request(
    start: tuple[int, int],
    *,
    horizon: int = 0,
    num_options: int = 0,
    strategy: str = "",
    seed: int = 0,
    grid: "FeatureGrid | None" = None,
) -> "ProposeQuery.Request":
    """A ``/ird/query`` request (docs/spec.md section 7): options from ``start``; 0 and "" mean the
    node's defaults (the proxy's test horizon, 2 options, ``info_gain``); ``grid`` None = the latest
    perceived test map."""
    from ird_msgs.srv import ProposeQuery

    request = ProposeQuery.Request(start_row=int(start[0]), start_col=int(start[1]), horizon=int(horizon),
                                   num_options=int(num_options), strategy=str(strategy), seed=int(seed))
    if grid is not None:
        request.map = grid
    return request

