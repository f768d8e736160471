"""The simulated designer node over real DDS (world + inference + designer, 8x8, T = 12):
every proposal of a mission gets exactly one answer, the one ``SimulatedDesigner(beta, seed)``
gives on the options' true returns (``evaluation.true_return`` on the world's terrain), recorded
on /ird/queries; a proxy-choice query ("proxies") is answered on the true returns of each proxy's
plan on the TRAINING map (``proxy_queries.proxy_option_returns``); a designer killed with a query
open leaves the inference node serving, and a respawned one answers the open query from the
latched history."""

from __future__ import annotations

import signal
from typing import Any, Iterator

import numpy as np
import pytest
from _query_world import SAMPLER_ARGS, Probe, node_args, world_args
from nav_msgs.msg import OccupancyGrid

from ird_core.designer import proxy_queries
from ird_core.designer.queries import SimulatedDesigner
from ird_core.vocabulary import QueryEvent
from ird_core.worlds import evaluation
from ird_ros import conversions as conv
from ird_ros.bags import rounds as qr
from ird_ros.graph import names
from ird_msgs.srv import ProposeQuery
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess, running_nodes, spawn_node_process
from ird_ros.web.page_state import option_letter

DESIGNER_BETA, DESIGNER_SEED = 2.0, 9
DESIGNER_ARGS = ["-p", "mode:=simulated", "-p", f"beta:={DESIGNER_BETA}", "-p", f"seed:={DESIGNER_SEED}"]
ROUNDS = 3


class Mission(Probe):
    """The probe after /ird/infer on the world: proposes and watches /ird/queries."""

    def __init__(self, ctx: Any, procs: list[NodeProcess]) -> None:
        super().__init__(ctx, procs, name="designer_test_probe")
        world = self.world()
        self.proxy = world.proxy
        self.infer(world, seed=3)
        self.labels = conv.terrain_grid_from_msg(self.ird.latest(names.TOPIC_TERRAIN, timeout=60.0)).classes
        self.ird.subscribe(names.TOPIC_RISK_MAP)

    @property
    def risk_maps(self) -> list[OccupancyGrid]:
        return self.ird.received(names.TOPIC_RISK_MAP)

    def propose(self, seed: int) -> int:
        response = self.query(self.proxy, num_options=2, strategy="random", seed=seed)
        assert response.ok, response.message
        return response.unwrap().query_id

    def answers(self, query_id: int) -> list[qr.QueryRecordData]:
        return [e for e in self.events() if e.query_id == query_id and e.event == QueryEvent.ANSWERED]

    def events(self) -> list[qr.QueryRecordData]:
        return [qr.event_from_msg(r) for r in self.records]

    def wait_answered(self, query_id: int) -> qr.QueryRecordData:
        self.spin_until(lambda: bool(self.answers(query_id)), f"an answer to query {query_id}")
        return self.answers(query_id)[0]

    def expected_choices(self, proposals: list[qr.QueryRecordData]) -> list[int]:
        """What SimulatedDesigner(beta, seed) answers, in order, on evaluation.true_return of the options."""
        designer = SimulatedDesigner(DESIGNER_BETA, DESIGNER_SEED)
        return [designer.answer(np.array([evaluation.true_return(self.labels, cells) for cells in p.options]))
                for p in proposals]


@pytest.fixture
def mission(ros_domain: DomainLease, ros_ctx: Any) -> Iterator[Mission]:
    with running_nodes(ros_domain, ("world", node_args("ird_ros.nodes.world", world_args(5))),
                       ("inference", node_args("ird_ros.nodes.inference", SAMPLER_ARGS)),
                       ("planner", node_args("ird_ros.nodes.planner", []))) as procs:
        m = Mission(ros_ctx, procs)
        yield m
        m.close()


def _designer(ros_domain: DomainLease) -> NodeProcess:
    return spawn_node_process(node_args("ird_ros.nodes.designer", DESIGNER_ARGS), domain=ros_domain, name="designer",
                              ready_text="designer ready")


def test_simulated_designer_answers_a_whole_mission(mission: Mission, ros_domain: DomainLease) -> None:
    with _designer(ros_domain) as designer:
        mission.procs.append(designer)
        ids = []
        mission.spin_until(lambda: bool(mission.risk_maps), "the planner's risk map of /ird/infer's posterior")
        for r in range(ROUNDS):
            ids.append(mission.propose(seed=r))
            risk_maps = len(mission.risk_maps)
            answer = mission.wait_answered(ids[-1])
            assert answer.answered_by == "simulated" and answer.num_answers == r + 1
            # The planner reacts to every re-sampled posterior with a new risk map.
            mission.spin_until(lambda n=risk_maps: len(mission.risk_maps) > n, "a risk map of the re-sampled posterior")
        events = mission.events()
        proposals = [e for e in events if e.event == QueryEvent.PROPOSED]
        rounds = qr.rounds_from_events(events)
        assert [r.query_id for r in rounds] == ids and [p.query_id for p in proposals] == ids
        assert all(r.answer is not None for r in rounds)
        assert len([e for e in events if e.event == QueryEvent.ANSWERED]) == ROUNDS  # one answer per proposal
        assert [r.chosen for r in rounds] == mission.expected_choices(proposals)
        mission.procs.remove(designer)
    assert designer.returncode == 0, designer.describe()


def test_respawned_designer_answers_the_open_query(mission: Mission, ros_domain: DomainLease) -> None:
    with _designer(ros_domain) as designer:
        mission.procs.append(designer)
        first = mission.propose(seed=11)
        mission.wait_answered(first)
        mission.procs.remove(designer)
        designer.proc.send_signal(signal.SIGKILL)
        designer.proc.wait(30.0)
    # The inference node keeps serving with no designer: the query stays open.
    second = mission.propose(seed=12)
    assert mission.answers(second) == []
    with _designer(ros_domain) as again:
        mission.procs.append(again)
        answer = mission.wait_answered(second)
        assert answer.answered_by == "simulated" and answer.num_answers == 2
        # A fresh designer (same seed): its first choice, on the open query only; the answered
        # first query of the history is not answered again.
        proposal = [e for e in mission.events() if e.query_id == second and e.event == QueryEvent.PROPOSED]
        assert answer.chosen == mission.expected_choices(proposal)[0]
        assert f"query {first}:" not in again.output() and len(mission.answers(first)) == 1
        mission.procs.remove(again)


def test_designer_killed_while_answering_loses_nothing(mission: Mission, ros_domain: DomainLease) -> None:
    """SIGKILL right after the designer sent (or was about to send) its answer: the respawned
    designer and the inference node together give the query exactly one answer."""
    with _designer(ros_domain) as designer:
        mission.procs.append(designer)
        first = mission.propose(seed=21)
        designer.wait_for_output(f"query {first}:", timeout=60.0)
        mission.procs.remove(designer)
        designer.proc.send_signal(signal.SIGKILL)
        designer.proc.wait(30.0)
    with _designer(ros_domain) as again:
        mission.procs.append(again)
        mission.wait_answered(first)
        second = mission.propose(seed=22)
        answer = mission.wait_answered(second)
        assert answer.num_answers == 2
        assert len(mission.answers(first)) == 1 and len(mission.answers(second)) == 1
        mission.procs.remove(again)


def test_simulated_designer_answers_a_proxies_query_on_the_training_map(mission: Mission,
                                                                        ros_domain: DomainLease) -> None:
    """The options are proxies' plans on the training map: the designer judges them there (as
    ``proxy_queries.simulated_proxy_answer``), not on the test map Rob drives."""
    train = conv.feature_grid_from_msg(mission.ird.latest(names.TOPIC_TRAIN_FEATURES, timeout=60.0))
    assert train.layers == ("dirt", "grass", "target", "lava")  # side_effects: one indicator per terrain
    train_labels = np.argmax(train.features, axis=-1)
    with _designer(ros_domain) as designer:
        mission.procs.append(designer)
        result = mission.ird.propose_query(ProposeQuery.Request(num_options=3, strategy="random", seed=4),
                                           kind="proxies", timeout=120.0)
        assert result.ok, result.message
        query = result.unwrap()
        assert query.kind == "proxies" and query.option_proxies.shape[0] == 3
        answer = mission.wait_answered(query.query_id)
        assert answer.kind == "proxies" and answer.answered_by == "simulated" and answer.num_answers == 1
        proposal = [e for e in mission.events() if e.query_id == query.query_id and e.event == QueryEvent.PROPOSED][0]
        asked = proxy_queries.ProxyQuery(proposal.option_proxies, proposal.option_features, proposal.options,
                                         proposal.information_gain, proposal.strategy.value, 3)
        returns = proxy_queries.proxy_option_returns(asked, train_labels)
        # A fresh designer (same seed): its first choice, Boltzmann on the training-map returns.
        assert answer.chosen == SimulatedDesigner(DESIGNER_BETA, DESIGNER_SEED).answer(returns)
        logged = designer.wait_for_output(f"query {query.query_id}: proxies options, true returns", timeout=30.0)
        # options by letter, as the page names them (issue 43)
        by_letter = ", ".join(f"{option_letter(k)} {r:.3f}" for k, r in enumerate(returns))
        assert f"true returns {by_letter}; answering Option {option_letter(answer.chosen)}" in logged, logged
        test_returns = [evaluation.true_return(mission.labels, cells) for cells in proposal.options]
        assert not np.allclose(returns, test_returns), "the test map would give the same returns: a weak check"
        mission.procs.remove(designer)
