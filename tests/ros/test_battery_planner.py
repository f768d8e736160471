"""Hostile requests against a running planner node (/ird/plan): each is answered ``success: false``
naming the field (and, for a size or work, the limit) before any work starts, and the node keeps
serving (a valid plan afterwards succeeds). Small limits are set through parameters."""

from __future__ import annotations

import array
import math
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np
import pytest

from ird_core.worlds import lavaland
from ird_msgs.msg import FeatureGrid
from ird_msgs.srv import PlanPath
from ird_ros import conversions as conv
from ird_ros.client import CallStatus, IrdClient, plan_request
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.runtime.guard import MAX_MESSAGE
from ird_ros.testing import NodeProcess, spawn_node_process

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
LIMITS = {"max_map_values": 2000, "max_plan_work": 100000, "time_limit": 2.0}
SIZE, HORIZON = 5, 6


@pytest.fixture(scope="module")
def node(ros_domain: DomainLease) -> Iterator[NodeProcess]:
    args = ["-m", "ird_ros.nodes.planner", "--ros-args", "--params-file", PARAMS]
    for key, value in LIMITS.items():
        args += ["-p", f"{key}:={value}"]
    with spawn_node_process(args, domain=ros_domain, name="planner", ready_text="planner ready") as proc:
        yield proc
    assert proc.returncode == 0, proc.describe()


@pytest.fixture(scope="module")
def ird(ros_ctx: Any, node: NodeProcess) -> Iterator[IrdClient]:
    with IrdClient(context=ros_ctx, node_name="battery_planner_client", processes=[node]) as client:
        client.wait_ready(30.0, services=(names.SRV_PLAN,))
        yield client


@pytest.fixture(scope="module")
def world() -> lavaland.LavalandInstance:
    return lavaland.make_instance("side_effects", 3, size=SIZE, horizon=HORIZON)


def _valid(world: lavaland.LavalandInstance, mode: str = "per_step", samples: int = 8) -> PlanPath.Request:
    weights = np.random.default_rng(0).normal(size=(samples, len(world.feature_names)))
    grid = conv.feature_grid_to_msg(world.test_features.astype(np.float32), world.feature_names)
    return plan_request(world.test_start, HORIZON, mode, "none", weights=weights[:1] if mode == "literal" else weights,
                        grid=grid)


def _declared(height: int, width: int, layers: int, values: int = 0) -> FeatureGrid:
    msg = FeatureGrid(layers=[f"f{i}" for i in range(layers)])
    msg.info.height, msg.info.width, msg.info.resolution = height, width, 1.0
    msg.data = array.array("f", bytes(4 * values))
    return msg


def _set(**fields: Any) -> Callable[[Any], None]:
    return lambda req: [setattr(req, k, v) for k, v in fields.items()] and None


PLAN: list[tuple[str, Callable[[Any], None], str, str]] = [
    ("map data beyond max_map_values", lambda r: setattr(r, "map", _declared(1, 2001, 1, 2001)), "map.data",
     "max_map_values=2000"),
    ("map declares 1e10 values", lambda r: setattr(r, "map", _declared(100000, 100000, 4)), "map.data",
     "max_map_values=2000"),
    ("map values 1e30", lambda r: setattr(r.map, "data", array.array("f", [1e30] * (SIZE * SIZE * 4))), "map.data",
     ""),
    ("1000 samples beyond the work", lambda r: setattr(r, "weights", [0.5] * (1000 * 4)), "weights",
     "max_plan_work=1e+05"),
    ("100000 samples beyond the work", lambda r: setattr(r, "weights", array.array("d", bytes(8 * 400000))),
     "weights", "max_plan_work=1e+05"),
    ("weights not a multiple of d", _set(weights=[0.5] * 7), "weights", ""),
    ("weights NaN", _set(weights=[math.nan] * 8), "weights", ""),
    ("weights 1e308", _set(weights=[1e308] * 8), "weights", ""),
    ("reference_features 100000 values", _set(baseline="training_features", reference_features=[0.0] * 100000),
     "reference_features", ""),
    ("horizon beyond max_horizon", _set(horizon=1001), "horizon", "max_horizon=1000"),
    ("a mode of 100000 characters", _set(mode="m" * 100000), "mode", ""),
    ("an unknown baseline", _set(baseline="median"), "baseline", ""),
    ("a label of 1000 characters", _set(label="l" * 1000), "label", "256"),
    ("start off the map", _set(start_col=99), "start_col", ""),
    ("literal with two weight vectors", _set(mode="literal"), "weights", ""),
    ("no weights and no posterior", _set(weights=[]), "weights", ""),
    ("no map and no perceived map", lambda r: setattr(r, "map", FeatureGrid()), "map", ""),
]


@pytest.mark.parametrize("case,corrupt,field,limit", PLAN, ids=[c[0] for c in PLAN])
def test_hostile_plan_is_refused_and_the_node_serves_on(case: str, corrupt: Callable, field: str, limit: str,
                                                       ird: IrdClient, node: NodeProcess,
                                                       world: lavaland.LavalandInstance) -> None:
    request = _valid(world)
    corrupt(request)
    result = ird.plan(request, timeout=60.0)
    assert result.status is CallStatus.REFUSED, (result.status, result.message)
    assert result.field == field, result.message
    assert limit in result.message and len(result.message) <= MAX_MESSAGE + 40, result.message
    for mode in ("literal", "per_step"):
        valid = ird.plan(_valid(world, mode), timeout=60.0)
        assert valid.ok, valid.message
    assert node.alive()
