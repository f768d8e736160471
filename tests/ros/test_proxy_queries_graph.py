"""/ird/query's "proxies" kind (Active IRD) over real DDS (world + inference nodes, 8x8, T = 12,
side_effects): the options are proxy rewards whose plans on the TRAINING map, behaviour counts and
information gain the library reproduces; an answer re-samples the posterior and is recorded with
its kind; a bad kind or a path field on a proxy query fails naming the field, and the node keeps
serving."""

from __future__ import annotations

from typing import Any, Iterator

import numpy as np
import pytest
from _query_world import SAMPLER_ARGS, SIZE, Probe, node_args, world_args

from ird_core.designer import proxy_queries as core_proxy_queries
from ird_core.designer import queries as core_queries
from ird_core.mdp import GridMDP
from ird_core.posterior import DEFAULT_OBSERVATION_MODEL
from ird_msgs.srv import ProposeQuery
from ird_ros import conversions as conv
from ird_ros.client import CallStatus
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import running_nodes

ANSWER_BETA = 1.0  # the inference node's answer_beta (graph.yaml)


@pytest.fixture(scope="module")
def probe(ros_domain: DomainLease, ros_ctx: Any) -> Iterator[Probe]:
    with running_nodes(ros_domain, ("world", node_args("ird_ros.nodes.world", world_args(3))),
                       ("inference", node_args("ird_ros.nodes.inference", SAMPLER_ARGS))) as procs:
        p = Probe(ros_ctx, procs, name="proxy_query_test_probe")
        yield p
        p.close()


def _propose(probe: Probe, kind: str, **fields: Any) -> Any:
    return probe.ird.propose_query(ProposeQuery.Request(**fields), kind=kind, timeout=120.0)


def test_proxy_query_contract_and_answer(probe: Probe) -> None:
    world = probe.world()
    proxy = world.proxy
    post0 = probe.infer(world)
    result = _propose(probe, "proxies", num_options=3, strategy="info_gain", seed=1)
    assert result.ok, result.message
    resp, raw = result.unwrap(), result.response
    q, p = len(resp.options), len(raw.proxy_feature_names)
    assert raw.kind == "proxies" and q == 3 and "proxies" in result.message
    assert tuple(raw.proxy_feature_names) == post0.feature_names and p == len(proxy.weights)
    proxies = np.asarray(raw.option_proxies, dtype=np.float64).reshape(q, p)
    train = GridMDP(conv.feature_grid_from_msg(world.train).features.astype(np.float64),
                    (proxy.start_row, proxy.start_col), proxy.horizon)
    # Each option is its proxy's plan on the TRAINING map (cells read back on the map's own bounds).
    plans = core_proxy_queries.proxy_plans(train, None, proxies)
    for k, cells in enumerate(resp.options):
        assert cells.shape == (proxy.horizon + 1, 2)
        assert np.array_equal(cells, plans[k])
        assert np.array_equal(cells, np.array(conv.path_to_cells(raw.options[k], height=SIZE, width=SIZE)))
    # Behaviour counts under the posterior's observation model, and the set's information gain.
    np.testing.assert_allclose(resp.option_features,
                               core_proxy_queries.proxy_behaviour(train, None, proxies, DEFAULT_OBSERVATION_MODEL),
                               rtol=1e-9, atol=1e-9)
    gain = core_queries.information_gain(resp.option_features, post0.samples, ANSWER_BETA)
    assert resp.information_gain == pytest.approx(gain, rel=1e-9, abs=1e-12) and resp.information_gain > 0.0
    # The very query the library proposes from the same posterior.
    expected = core_proxy_queries.propose_proxy_query(train, None, np.asarray(proxy.weights, np.float64),
                                                      post0.samples, ANSWER_BETA, 3, "info_gain", 1)
    np.testing.assert_allclose(proxies, expected.proxies, rtol=0, atol=1e-12)

    probe.spin_until(lambda: any(r.query_id == resp.query_id for r in probe.records), "the proposal record")
    record = [r for r in probe.records if r.query_id == resp.query_id][0]
    assert (record.event, record.kind) == ("proposed", "proxies")
    np.testing.assert_array_equal(np.asarray(record.option_proxies).reshape(q, p), proxies)

    # The answer: a ChoiceObservation over the proxies' behaviour counts; the posterior is re-sampled.
    n_posteriors = len(probe.posteriors)
    answered = probe.answer(resp.query_id, 2, beta=5.0)
    assert answered.ok, answered.message
    post1 = answered.unwrap()
    assert post1.samples.shape == post0.samples.shape and not np.array_equal(post1.samples, post0.samples)
    probe.spin_until(lambda: len(probe.posteriors) > n_posteriors
                     and np.array_equal(conv.posterior_from_msg(probe.posteriors[-1]).samples, post1.samples),
                     "the re-sampled posterior on /ird/posterior")
    probe.spin_until(lambda: any(r.query_id == resp.query_id and r.event == "answered" for r in probe.records),
                     "the answer record")
    done = [r for r in probe.records if r.query_id == resp.query_id and r.event == "answered"][0]
    assert (done.kind, done.chosen, done.beta, done.num_answers) == ("proxies", 2, 5.0, 1)
    # A path query on the same evidence still says "paths" and carries no proxies.
    paths = probe.query(proxy, num_options=2, strategy="random", seed=2)
    assert paths.ok and paths.response.kind == "paths" and len(paths.response.option_proxies) == 0, paths.message


def test_bad_kinds_and_fields_are_refused_and_the_node_keeps_serving(probe: Probe) -> None:
    world = probe.world()
    probe.infer(world, seed=9)
    bad_map = conv.feature_grid_to_msg(np.zeros((SIZE, SIZE, 2), np.float32), ("a", "b"))
    for kind, fields, field in (("nope", {}, "kind"), ("PROXIES", {}, "kind"),
                                ("proxies", dict(map=bad_map), "map"), ("proxies", dict(horizon=3), "horizon"),
                                ("proxies", dict(start_col=1), "start_col"),
                                ("proxies", dict(num_options=9), "num_options"),
                                ("proxies", dict(strategy="best"), "strategy")):
        bad = _propose(probe, kind, **fields)
        assert bad.status is CallStatus.REFUSED and bad.field == field, bad
        assert not bad.response.success and bad.message.startswith(f"{field}:"), bad.message
    good = _propose(probe, "proxies", num_options=2, strategy="random", seed=4)
    assert good.ok and good.response.kind == "proxies", good.message
    paths = probe.query(world.proxy, num_options=2)
    assert paths.ok, paths.message
