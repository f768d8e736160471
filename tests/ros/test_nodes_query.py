"""/ird/query and /ird/answer over real DDS (world + inference nodes, 8x8, T = 12, side_effects):
the options are legal, distinct paths whose features and information gain the library reproduces,
an answer moves the posterior towards the chosen option, bad answers change nothing, a second
answer during a re-sampling is refused as busy (never lost), and a new world forgets the evidence."""

from __future__ import annotations

from typing import Any, Iterator

import numpy as np
import pytest
from _query_world import SAMPLER_ARGS, SIZE, Probe, node_args, world_args

from ird_core.designer import queries as core_queries
from ird_msgs.msg import RewardPosterior
from ird_msgs.srv import AnswerQuery, GenerateWorld, ProposeQuery
from ird_ros import conversions as conv
from ird_ros.bags import rounds as qr
from ird_ros.graph import names
from ird_ros.testing import DomainLease, running_nodes

ANSWER_BETA = 1.0  # the inference node's answer_beta (graph.yaml)


@pytest.fixture(scope="module")
def probe(ros_domain: DomainLease, ros_ctx: Any) -> Iterator[Probe]:
    with running_nodes(ros_domain, ("world", node_args("ird_ros.nodes.world", world_args(3))),
                       ("inference", node_args("ird_ros.nodes.inference", SAMPLER_ARGS))) as procs:
        p = Probe(ros_ctx, procs)
        yield p
        p.node.destroy_node()


def _samples(msg: RewardPosterior) -> np.ndarray:
    return conv.posterior_from_msg(msg).samples


def _cells(path: Any) -> np.ndarray:
    return np.array(conv.path_to_cells(path, height=SIZE, width=SIZE), dtype=np.int64)


def _margin(samples: np.ndarray, features: np.ndarray, chosen: int) -> float:
    """Mean over the samples of w . (f_chosen - f_other) (two options)."""
    return float((samples @ (features[chosen] - features[1 - chosen])).mean())


def test_query_contract_and_answers(probe: Probe) -> None:
    train, test, proxy = probe.world()
    post0 = probe.infer(train, proxy).posterior
    resp = probe.query(proxy, num_options=2, strategy="info_gain", seed=1)
    assert resp.success, resp.message
    q, d = len(resp.options), len(resp.feature_names)
    assert q == 2 and tuple(resp.feature_names) == tuple(post0.feature_names)
    features = np.asarray(resp.option_features, dtype=np.float64).reshape(q, d)
    test_features = conv.feature_grid_from_msg(test).features.astype(np.float64)
    start = np.array([proxy.test_start_row, proxy.test_start_col])
    for k, path in enumerate(resp.options):
        cells = _cells(path)
        assert cells.shape == (proxy.test_horizon + 1, 2)  # horizon 0 = the proxy's test horizon
        assert np.array_equal(cells[0], start)
        assert np.all(np.abs(np.diff(cells, axis=0)).sum(axis=1) <= 1)  # stay or a 4-neighbour move
        assert np.allclose(features[k], test_features[cells[:, 0], cells[:, 1]].sum(axis=0))
    assert not np.array_equal(features[0], features[1])  # distinct options
    gain = core_queries.information_gain(features, _samples(post0), ANSWER_BETA)
    assert resp.information_gain == pytest.approx(gain, rel=1e-9, abs=1e-12)
    assert resp.information_gain > 0.0

    # The proposal is on /ird/queries.
    probe.spin_until(lambda: any(r.query_id == resp.query_id for r in probe.records), "the proposal record")
    proposed = [r for r in probe.records if r.query_id == resp.query_id]
    assert [r.event for r in proposed] == ["proposed"] and proposed[0].chosen == -1

    # Answer the option the posterior now favours less: the mean margin must grow towards it.
    chosen = int(_margin(_samples(post0), features, 0) > 0)
    before = _margin(_samples(post0), features, chosen)
    answered = probe.answer(resp.query_id, chosen, beta=5.0)
    assert answered.success, answered.message
    after = _margin(_samples(answered.posterior), features, chosen)
    assert after > before, (before, after)
    probe.spin_until(lambda: np.array_equal(_samples(probe.posteriors[-1]), _samples(answered.posterior)),
                     "the re-sampled posterior on /ird/posterior")
    probe.spin_until(lambda: any(r.query_id == resp.query_id and r.event == "answered" for r in probe.records),
                     "the answer record")
    record = [r for r in probe.records if r.query_id == resp.query_id and r.event == "answered"][0]
    assert (record.chosen, record.beta, record.answered_by, record.num_answers) == (chosen, 5.0, "client", 1)

    # Bad answers fail naming the field and change nothing.
    n_records, n_posteriors = len(probe.records), len(probe.posteriors)
    open_resp = probe.query(proxy, num_options=2, strategy="random", seed=2)
    assert open_resp.success, open_resp.message
    for query_id, chosen_, beta, field, text in (
            (resp.query_id, 0, 0.0, "query_id", "already answered"),
            (open_resp.query_id + 100, 0, 0.0, "query_id", "unknown"),
            (open_resp.query_id, 2, 0.0, "chosen", "out of range"),
            (open_resp.query_id, 0, -1.0, "beta", ">= 0"),
            (open_resp.query_id, 0, float("nan"), "beta", ">= 0")):
        bad = probe.answer(query_id, chosen_, beta)
        assert not bad.success and bad.message.startswith(f"{field}:") and text in bad.message, bad.message
    probe.spin_until(lambda: len(probe.records) >= n_records + 1, "the second proposal record")
    good = probe.answer(open_resp.query_id, 1)
    assert good.success, good.message
    probe.spin_until(lambda: len(probe.records) >= n_records + 2, "the second answer record")
    events = [qr.event_from_msg(r) for r in probe.records[n_records:]]
    assert [(e.query_id, e.event) for e in events] == [(open_resp.query_id, "proposed"),
                                                       (open_resp.query_id, "answered")]
    assert events[1].num_answers == 2 and events[1].beta == ANSWER_BETA  # beta 0 = the node's answer_beta
    probe.spin_until(lambda: len(probe.posteriors) >= n_posteriors + 1, "the second re-sampled posterior")
    assert len(probe.posteriors) == n_posteriors + 1  # the bad answers published nothing


def test_answer_during_resampling_is_refused_as_busy_never_lost(probe: Probe) -> None:
    train, _, proxy = probe.world()
    probe.infer(train, proxy, seed=11)
    ids = []
    for seed in (3, 4):
        resp = probe.query(proxy, num_options=2, strategy="random", seed=seed)
        assert resp.success, resp.message
        ids.append(resp.query_id)
    client = probe.clients[names.SRV_ANSWER]
    futures = [client.call_async(AnswerQuery.Request(query_id=i, chosen=0, answered_by="client")) for i in ids]
    probe.spin_until(lambda: all(f.done() for f in futures), "both answers", timeout=120.0)
    first, second = (f.result() for f in futures)
    assert first.success, first.message
    if not second.success:  # refused while the first was re-sampled: nothing changed, answer again
        assert second.message.startswith("busy"), second.message
        second = probe.answer(ids[1], 0)
        assert second.success, second.message
    probe.spin_until(lambda: len([r for r in probe.records if r.event == "answered" and r.query_id in ids]) == 2,
                     "both answer records")
    answers = [r for r in probe.records if r.event == "answered" and r.query_id in ids]
    assert sorted(r.num_answers for r in answers) == [1, 2]


def test_bad_queries_name_the_field(probe: Probe) -> None:
    _, _, proxy = probe.world()
    for kw, field in ((dict(num_options=1), "num_options"), (dict(num_options=9), "num_options"),
                      (dict(strategy="best"), "strategy")):
        resp = probe.query(proxy, **kw)
        assert not resp.success and resp.message.startswith(f"{field}:"), resp.message
    resp = probe.call(names.SRV_QUERY, ProposeQuery.Request(start_row=SIZE, start_col=0))
    assert not resp.success and resp.message.startswith("start"), resp.message
    wrong = conv.feature_grid_to_msg(np.zeros((SIZE, SIZE, 2), np.float32), ("a", "b"))
    resp = probe.call(names.SRV_QUERY, ProposeQuery.Request(map=wrong, start_row=0, start_col=0, horizon=3))
    assert not resp.success and resp.message.startswith("map.layers:"), resp.message


def test_a_new_world_forgets_the_evidence(probe: Probe) -> None:
    train, _, proxy = probe.world()
    probe.infer(train, proxy, seed=21)
    old = probe.query(proxy, num_options=2, strategy="random", seed=5)
    assert old.success, old.message
    generated = probe.call(names.SRV_GENERATE, GenerateWorld.Request(condition="side_effects", seed=4))
    assert generated.success, generated.message
    train2, _, proxy2 = probe.world(stamp_after=proxy.header.stamp)

    def forgotten() -> bool:  # the inference node got the new world's proxy
        return probe.query(proxy2).message.startswith("evidence:")
    probe.spin_until(forgotten, "the inference node to forget the old world", timeout=60.0)
    stale = probe.answer(old.query_id, 0)
    assert not stale.success and stale.message.startswith("query_id:") and "forgotten" in stale.message
    probe.infer(train2, proxy2, seed=22)
    fresh = probe.query(proxy2, num_options=2, strategy="random", seed=6)
    assert fresh.success, fresh.message
    answered = probe.answer(fresh.query_id, 1)
    assert answered.success, answered.message
    probe.spin_until(lambda: any(r.query_id == fresh.query_id and r.event == "answered" for r in probe.records),
                     "the answer record")
    record = [r for r in probe.records if r.query_id == fresh.query_id and r.event == "answered"][0]
    assert record.num_answers == 1  # the old world's answers are not in the new evidence
