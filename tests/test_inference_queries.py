"""ird_ros.jobs.inference_queries.WorldEvidence (no ROS): when the inference node forgets a world, and how
answers are checked before anything changes."""

from __future__ import annotations

from types import SimpleNamespace as NS

import numpy as np
import pytest

from ird_core.vocabulary import QueryStrategy
from ird_ros.jobs.inference_queries import ProposalRecord, WorldEvidence, resample_seed

OLD, NEW = (10, 0), (20, 0)


def _query(q: int = 2) -> NS:
    return NS(num_options=q, option_features=np.arange(q * 3, dtype=float).reshape(q, 3))


def _record(q: int = 2) -> ProposalRecord:
    return ProposalRecord(QueryStrategy.INFO_GAIN, (), ("a", "b", "c"), np.zeros((q, 3)), 0.0)


def _evidence(world: tuple[int, int]) -> WorldEvidence:
    ev = WorldEvidence()
    ev.on_proxy(OLD)
    ev.reset(job=NS(seed=1), posterior=NS(samples=np.zeros((4, 3))), feature_names=("a", "b", "c"), world_stamp=world)
    return ev


def test_a_new_world_forgets_the_evidence_and_its_queries() -> None:
    ev = _evidence(OLD)
    qid = ev.add_query(_query(), _record())
    epoch = ev.epoch
    assert not ev.on_proxy(OLD)  # the same world again (a late latched copy): kept
    assert ev.on_proxy(NEW) and ev.job is None and ev.posterior is None and ev.epoch > epoch
    with pytest.raises(ValueError, match=f"^query_id: query {qid} belongs to a forgotten world"):
        ev.check_answer(qid, 0, 0.0, 1.0)


def test_evidence_on_the_new_worlds_map_survives_its_late_proxy() -> None:
    ev = _evidence(NEW)  # /ird/infer on the new world's map arrived before the new proxy
    assert not ev.on_proxy(NEW) and ev.job is not None
    assert ev.on_proxy((30, 0)) and ev.job is None  # then another world


def test_reset_starts_new_evidence_and_ids_stay_unique() -> None:
    ev = _evidence(OLD)
    first = ev.add_query(_query(), _record())
    open_query, beta = ev.check_answer(first, 1, 0.0, 2.5)
    assert beta == 2.5  # 0 = the node's default
    ev.commit(open_query, ev.choice(open_query, 1, beta), NS(samples=np.ones((4, 3))))
    assert len(ev.answers) == 1
    ev.reset(job=NS(seed=2), posterior=NS(samples=np.zeros((4, 3))), feature_names=("a", "b", "c"), world_stamp=OLD)
    assert ev.answers == [] and ev.queries == {}
    assert ev.add_query(_query(), _record()) == first + 1


@pytest.mark.parametrize("query_id, chosen, beta, message", [
    (99, 0, 0.0, "^query_id: unknown query 99"),
    (1, 2, 0.0, r"^chosen: 2 is out of range for 2 options \(0..1\)"),
    (1, -1, 0.0, "^chosen: -1 is out of range"),
    (1, 0, -0.5, "^beta: must be finite and >= 0"),
    (1, 0, float("inf"), "^beta: must be finite and >= 0"),
    (1, 0, 1001.0, r"^beta: 1001 is outside the allowed range \[0, 1000\]"),
    (1, 0, 1e308, r"^beta: 1e\+308 is outside the allowed range"),
])
def test_bad_answers_name_the_field_and_change_nothing(query_id: int, chosen: int, beta: float, message: str) -> None:
    ev = _evidence(OLD)
    assert ev.add_query(_query(), _record()) == 1
    with pytest.raises(ValueError, match=message):
        ev.check_answer(query_id, chosen, beta, 1.0)
    assert ev.answers == [] and not ev.queries[1].answered


def test_an_answered_query_cannot_be_answered_again() -> None:
    ev = _evidence(OLD)
    qid = ev.add_query(_query(3), _record(3))
    open_query, beta = ev.check_answer(qid, 2, 4.0, 1.0)
    choice = ev.choice(open_query, 2, beta)
    assert (choice.chosen, choice.beta) == (2, 4.0) and np.array_equal(choice.option_features, _query(3).option_features)
    ev.commit(open_query, choice, NS(samples=np.ones((4, 3))))
    with pytest.raises(ValueError, match=f"^query_id: query {qid} was already answered"):
        ev.check_answer(qid, 0, 0.0, 1.0)


def test_resample_seeds_differ_per_round_and_fit_uint32() -> None:
    seeds = [resample_seed(2**32 - 1, n) for n in range(1, 50)]
    assert len(set(seeds)) == len(seeds) and all(0 <= s < 2**32 for s in seeds)


def test_robs_plan_for_a_query_is_the_planners_scaled_plan() -> None:
    """The inference node's query settings (``plan_settings``) plan as the planner node does by
    default: every sample rescaled on the evidence's training map, then the per-step min with the
    proxy's training_features baseline; so Rob's candidate plan is the planner's plan."""
    from ird_core import planning
    from ird_core.designer.candidates import PlanSettings, query_candidates
    from ird_core.mdp import GridMDP
    from ird_core.planning.sample_scale import normalise_samples
    from ird_ros.jobs.inference_queries import plan_settings
    from ird_ros.jobs.planning import ReferenceJob, reference_features

    rng = np.random.default_rng(2)  # a seed on which the unscaled min plans another path
    train = GridMDP(rng.normal(size=(4, 4, 3)), (0, 0), 4)
    reference = ReferenceJob(train, np.array([1.0, -0.5, 0.2]), train.features)
    settings = plan_settings(reference)
    assert settings.scale_features is train.features
    test = GridMDP(rng.normal(size=(5, 5, 3)), (0, 0), 5)
    samples = rng.normal(size=(6, 3)) * np.array([[0.01], [100.0], [1.0], [3.0], [0.1], [10.0]])
    rob = query_candidates(test, samples, settings, alternatives=0)
    planner = planning.plan_path(test, normalise_samples(samples, train.features), "per_step", "training_features",
                                 reference_features(reference))
    assert [tuple(c) for c in rob.cells[0].tolist()] == [tuple(c) for c in planner.cells]
    unscaled = query_candidates(test, samples, PlanSettings("training_features", reference_features(reference)),
                                alternatives=0)
    assert [tuple(c) for c in unscaled.cells[0].tolist()] != [tuple(c) for c in planner.cells]
    assert plan_settings(None).scale_features is None
