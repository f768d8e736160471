"""/ird/query and /ird/answer over real DDS (world + inference nodes, 8x8, T = 12, side_effects):
the options are legal, distinct paths whose features and information gain the library reproduces,
an answer moves the posterior towards the chosen option, bad answers change nothing, a second
answer during a re-sampling is refused as busy (never lost), an answer re-samples under the observation
model of the posterior it extends, and a new world forgets the evidence."""

from __future__ import annotations

from typing import Any, Iterator

import numpy as np
import pytest
from _query_world import SAMPLER_ARGS, SIZE, Probe, node_args, world_args

from ird_core import posterior as core_posterior
from ird_core.designer import queries as core_queries
from ird_core.designer.candidates import PlanSettings
from ird_core.mdp import GridMDP
from ird_msgs.srv import ProposeQuery
from ird_ros import conversions as conv
from ird_ros.bags import rounds as qr
from ird_ros.client import CallStatus, infer_request
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import running_nodes

ANSWER_BETA = 1.0  # the inference node's answer_beta (graph.yaml)


@pytest.fixture(scope="module")
def probe(ros_domain: DomainLease, ros_ctx: Any) -> Iterator[Probe]:
    with running_nodes(ros_domain, ("world", node_args("ird_ros.nodes.world", world_args(3))),
                       ("inference", node_args("ird_ros.nodes.inference", SAMPLER_ARGS))) as procs:
        p = Probe(ros_ctx, procs)
        yield p
        p.close()


def _samples(msg: Any) -> np.ndarray:
    return conv.posterior_from_msg(msg).samples


def _margin(samples: np.ndarray, features: np.ndarray, chosen: int) -> float:
    """Mean over the samples of w . (f_chosen - f_other) (two options)."""
    return float((samples @ (features[chosen] - features[1 - chosen])).mean())


def test_query_contract_and_answers(probe: Probe) -> None:
    world = probe.world()
    proxy = world.proxy
    post0 = probe.infer(world)
    result = probe.query(proxy, num_options=2, strategy="info_gain", seed=1)
    assert result.ok, result.message
    resp = result.unwrap()
    q, d = len(resp.options), len(resp.feature_names)
    assert q == 2 and resp.feature_names == post0.feature_names
    features = resp.option_features
    assert features.shape == (q, d)
    test_features = conv.feature_grid_from_msg(world.test).features.astype(np.float64)
    start = np.array([proxy.test_start_row, proxy.test_start_col])
    for k, cells in enumerate(resp.options):
        # The same cells as the poses read back on the map's own bounds.
        path = result.response.options[k]
        assert np.array_equal(cells, np.array(conv.path_to_cells(path, height=SIZE, width=SIZE), dtype=np.int64))
        assert cells.shape == (proxy.test_horizon + 1, 2)  # horizon 0 = the proxy's test horizon
        assert np.array_equal(cells[0], start)
        assert np.all(np.abs(np.diff(cells, axis=0)).sum(axis=1) <= 1)  # stay or a 4-neighbour move
        assert np.allclose(features[k], test_features[cells[:, 0], cells[:, 1]].sum(axis=0))
    assert not np.array_equal(features[0], features[1])  # distinct options
    gain = core_queries.information_gain(features, post0.samples, ANSWER_BETA)
    assert resp.information_gain == pytest.approx(gain, rel=1e-9, abs=1e-12)
    assert resp.information_gain > 0.0

    # The proposal is on /ird/queries.
    probe.spin_until(lambda: any(r.query_id == resp.query_id for r in probe.records), "the proposal record")
    proposed = [r for r in probe.records if r.query_id == resp.query_id]
    assert [r.event for r in proposed] == ["proposed"] and proposed[0].chosen == -1

    # Answer the option the posterior now favours less: the mean margin must grow towards it.
    chosen = int(_margin(post0.samples, features, 0) > 0)
    before = _margin(post0.samples, features, chosen)
    answered = probe.answer(resp.query_id, chosen, beta=5.0)
    assert answered.ok, answered.message
    after = _margin(answered.unwrap().samples, features, chosen)
    assert after > before, (before, after)
    probe.spin_until(lambda: np.array_equal(_samples(probe.posteriors[-1]), answered.unwrap().samples),
                     "the re-sampled posterior on /ird/posterior")
    probe.spin_until(lambda: any(r.query_id == resp.query_id and r.event == "answered" for r in probe.records),
                     "the answer record")
    record = [r for r in probe.records if r.query_id == resp.query_id and r.event == "answered"][0]
    assert (record.chosen, record.beta, record.answered_by, record.num_answers) == (chosen, 5.0, "client", 1)

    # Bad answers fail naming the field and change nothing.
    n_records, n_posteriors = len(probe.records), len(probe.posteriors)
    open_result = probe.query(proxy, num_options=2, strategy="random", seed=2)
    assert open_result.ok, open_result.message
    open_resp = open_result.unwrap()
    for query_id, chosen_, beta, field, text in (
            (resp.query_id, 0, 0.0, "query_id", "already answered"),
            (open_resp.query_id + 100, 0, 0.0, "query_id", "unknown"),
            (open_resp.query_id, 2, 0.0, "chosen", "out of range"),
            (open_resp.query_id, 0, -1.0, "beta", ">= 0"),
            (open_resp.query_id, 0, float("nan"), "beta", ">= 0")):
        bad = probe.answer(query_id, chosen_, beta)
        assert bad.status is CallStatus.REFUSED and bad.field == field, bad
        assert not bad.response.success and bad.message.startswith(f"{field}:") and text in bad.message, bad.message
    probe.spin_until(lambda: len(probe.records) >= n_records + 1, "the second proposal record")
    good = probe.answer(open_resp.query_id, 1)
    assert good.ok, good.message
    probe.spin_until(lambda: len(probe.records) >= n_records + 2, "the second answer record")
    events = [qr.event_from_msg(r) for r in probe.records[n_records:]]
    assert [(e.query_id, e.event) for e in events] == [(open_resp.query_id, "proposed"),
                                                       (open_resp.query_id, "answered")]
    assert events[1].num_answers == 2 and events[1].beta == ANSWER_BETA  # beta 0 = the node's answer_beta
    probe.spin_until(lambda: len(probe.posteriors) >= n_posteriors + 1, "the second re-sampled posterior")
    assert len(probe.posteriors) == n_posteriors + 1  # the bad answers published nothing


def test_the_default_query_is_evoi_for_robs_plan(probe: Probe) -> None:
    """strategy "" is EVOI among the rich candidates of Rob's default plan (the planner's: per
    step, the min over samples rescaled on the training map, the training-features baseline of
    the proxy): the very query the library proposes."""
    world = probe.world()
    proxy = world.proxy
    post0 = probe.infer(world)
    result = probe.query(proxy, num_options=2, strategy="", seed=4)
    assert result.ok, result.message
    resp = result.unwrap()
    assert "evoi" in result.message
    train = GridMDP(conv.feature_grid_from_msg(world.train).features.astype(np.float64),
                    (proxy.start_row, proxy.start_col), proxy.horizon)
    test = GridMDP(conv.feature_grid_from_msg(world.test).features.astype(np.float64),
                   (proxy.test_start_row, proxy.test_start_col), proxy.test_horizon)
    reference = core_posterior.proxy_feature_counts(train, np.asarray(proxy.weights, np.float64), train.features)
    plan = PlanSettings("training_features", reference / (proxy.horizon + 1), train.features)
    expected = core_queries.propose_query(test, post0.samples, ANSWER_BETA, 2, "evoi", 4, plan)
    np.testing.assert_allclose(resp.option_features, expected.option_features, rtol=1e-12, atol=1e-9)
    for cells, want in zip(resp.options, expected.option_cells):
        assert np.array_equal(cells, want)


def test_answer_during_resampling_is_refused_as_busy_never_lost(probe: Probe) -> None:
    world = probe.world()
    proxy = world.proxy
    probe.infer(world, seed=11)
    ids = []
    for seed in (3, 4):
        resp = probe.query(proxy, num_options=2, strategy="random", seed=seed)
        assert resp.ok, resp.message
        ids.append(resp.unwrap().query_id)
    pending = [probe.ird.answer_async(i, 0, answered_by="client") for i in ids]
    probe.spin_until(lambda: all(p.done() for p in pending), "both answers", timeout=120.0)
    first, second = (p.result() for p in pending)
    assert first.ok, first.message
    if not second.ok:  # refused while the first was re-sampled: nothing changed, answer again
        assert second.status is CallStatus.BUSY and second.message.startswith("busy"), second.message
        second = probe.answer(ids[1], 0)
        assert second.ok, second.message
    probe.spin_until(lambda: len([r for r in probe.records if r.event == "answered" and r.query_id in ids]) == 2,
                     "both answer records")
    answers = [r for r in probe.records if r.event == "answered" and r.query_id in ids]
    assert sorted(r.num_answers for r in answers) == [1, 2]


def test_bad_queries_name_the_field(probe: Probe) -> None:
    proxy = probe.world().proxy
    for kw, field in ((dict(num_options=1), "num_options"), (dict(num_options=9), "num_options"),
                      (dict(strategy="best"), "strategy")):
        resp = probe.query(proxy, **kw)
        assert resp.status is CallStatus.REFUSED and resp.field == field, resp
        assert not resp.response.success and resp.message.startswith(f"{field}:"), resp.message
    resp = probe.ird.propose_query(ProposeQuery.Request(start_row=SIZE, start_col=0))
    assert resp.status is CallStatus.REFUSED and resp.message.startswith("start"), resp.message
    wrong = conv.feature_grid_to_msg(np.zeros((SIZE, SIZE, 2), np.float32), ("a", "b"))
    resp = probe.ird.propose_query(ProposeQuery.Request(map=wrong, start_row=0, start_col=0, horizon=3))
    assert resp.status is CallStatus.REFUSED and resp.field == "map.layers", resp
    assert not resp.response.success and resp.message.startswith("map.layers:"), resp.message


def test_an_answer_resamples_with_the_posteriors_observation_model(probe: Probe) -> None:
    """/ird/infer with proxy_counts optimal, then an answer: the re-sampled posterior is, bit for
    bit, sample_joint_posterior of the proxy and the answer under ObservationModel("optimal"),
    warm-started at the first posterior (what the inference jobs document), and says so."""
    import warnings

    from ird_ros.jobs.inference_queries import resample_seed

    world = probe.world()
    proxy = world.proxy
    request = infer_request(world.train, (proxy.start_row, proxy.start_col), proxy.horizon, proxy.weights, beta=2.0,
                            method="maxent_z", num_samples=40, seed=31, proxy_counts="optimal")
    first = probe.ird.infer(request, timeout=120.0)
    assert first.ok and first.unwrap().proxy_counts == "optimal", first.message
    query = probe.query(proxy, num_options=2, strategy="random", seed=7)
    assert query.ok, query.message
    answered = probe.answer(query.unwrap().query_id, 1, beta=5.0)
    assert answered.ok, answered.message
    post = answered.unwrap()
    assert (post.proxy_counts, answered.response.posterior.proxy_counts) == ("optimal", "optimal")

    model = core_posterior.ObservationModel("optimal")
    train = conv.feature_grid_from_msg(world.train).features.astype(np.float64)
    observation = core_posterior.ProxyObservation(np.asarray(proxy.weights, np.float64),
                                                  GridMDP(train, (proxy.start_row, proxy.start_col), proxy.horizon))
    settings = core_posterior.SamplerSettings(num_chains=4, warmup=40, thin=1).kwargs()  # SAMPLER_ARGS
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # short chains
        initial = core_posterior.sample_joint_posterior([observation], 2.0, "maxent_z", 40, 31,
                                                        observation_model=model, **settings)
        assert np.array_equal(initial.samples, first.unwrap().samples)
        settings.pop("warmup")  # a warm start has its own warm-up
        choice = core_posterior.ChoiceObservation(query.unwrap().option_features, 1, 5.0)
        expected = core_posterior.sample_joint_posterior([observation, choice], 2.0, "maxent_z", 40,
                                                         resample_seed(31, 1), initial=initial,
                                                         observation_model=model, **settings)
    assert np.array_equal(post.samples, expected.samples)


def test_a_new_world_forgets_the_evidence(probe: Probe) -> None:
    world = probe.world()
    probe.infer(world, seed=21)
    old_result = probe.query(world.proxy, num_options=2, strategy="random", seed=5)
    assert old_result.ok, old_result.message
    old = old_result.unwrap()
    generated = probe.ird.generate_world("side_effects", 4, timeout=120.0)
    assert generated.ok, generated.message
    world2 = probe.world(other_than=world)
    proxy2 = world2.proxy

    def forgotten() -> bool:  # the inference node got the new world's proxy
        return probe.query(proxy2).message.startswith("evidence:")
    probe.spin_until(forgotten, "the inference node to forget the old world", timeout=60.0)
    stale = probe.answer(old.query_id, 0)
    assert not stale.ok and stale.message.startswith("query_id:") and "forgotten" in stale.message
    probe.infer(world2, seed=22)
    fresh_result = probe.query(proxy2, num_options=2, strategy="random", seed=6)
    assert fresh_result.ok, fresh_result.message
    fresh = fresh_result.unwrap()
    answered = probe.answer(fresh.query_id, 1)
    assert answered.ok, answered.message
    probe.spin_until(lambda: any(r.query_id == fresh.query_id and r.event == "answered" for r in probe.records),
                     "the answer record")
    record = [r for r in probe.records if r.query_id == fresh.query_id and r.event == "answered"][0]
    assert record.num_answers == 1  # the old world's answers are not in the new evidence
