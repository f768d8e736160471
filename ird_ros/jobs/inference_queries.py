"""The inference node's evidence of the current world and its query bookkeeping (no ROS;
docs/spec.md section 7).

:class:`WorldEvidence` holds what the posterior is conditioned on: the proxy observation of the
latest successful ``/ird/infer`` (its validated job) and every answer taken since, with the
latest posterior (the warm start of the next re-sampling) and the open queries. The job carries
the observation model its posterior was sampled with (:attr:`WorldEvidence.observation_model`);
every re-sampling of this evidence uses that model, never the node's current default.

Lifetime (what "the current world" means):

- a successful ``/ird/infer`` starts new evidence: its proxy, no answers, no open queries;
- a ``/world/proxy`` of a new world generation (a header stamp not seen before) forgets the
  evidence, unless the evidence's training map carries that same stamp (the client inferred on
  the new world's own map before this node received its proxy);
- query ids are unique for the node's lifetime; ids of forgotten worlds are refused as such.

Answers are taken one at a time: while a re-sampling runs (:attr:`WorldEvidence.resampling`) a
second answer is refused with ``busy`` (nothing changes; the caller answers again after the
next posterior). :attr:`WorldEvidence.epoch` changes whenever the evidence is replaced, so a
re-sampling that finishes after its world was forgotten is dropped, never mixed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from ird_core import posterior as core_inference
from ird_core.checks import check_real
from ird_core.designer import queries as core_queries
from ird_core.mdp import GridMDP
from ird_core.vocabulary import QueryStrategy
from ird_ros.jobs.inference import InferenceJob

if TYPE_CHECKING:  # the options are nav_msgs/Path messages, built by the node; no ROS import here
    from nav_msgs.msg import Path

__all__ = ["QueryJob", "ProposalRecord", "OpenQuery", "WorldEvidence", "run_query", "resample_seed"]


@dataclass(frozen=True)
class QueryJob:
    """A validated /ird/query request, as the worker process gets it (``propose_query``'s arguments)."""

    query_mdp: GridMDP
    samples: np.ndarray
    beta: float
    num_options: int
    strategy: QueryStrategy
    seed: int


def run_query(job: QueryJob) -> core_queries.Query:
    """The worker-process job of /ird/query (raises ``NotEnoughCandidates`` naming num_options)."""
    return core_queries.propose_query(job.query_mdp, job.samples, job.beta, job.num_options, job.strategy, job.seed)


def resample_seed(seed: int, num_answers: int) -> int:
    """Seed of the re-sampling after ``num_answers`` answers: distinct per round, uint32."""
    return (int(seed) + 7919 * int(num_answers)) % 2**32


@dataclass(frozen=True)
class ProposalRecord:
    """What every ``/ird/queries`` record of a query repeats: the fields of its proposal.

    Attributes:
        strategy: how the question was picked.
        options: one nav_msgs/Path per option (poses at cell centres).
        feature_names: the d feature names (the posterior's).
        option_features: (q, d) feature counts of the options.
        information_gain: expected information gain of the answer, nats.
    """

    strategy: QueryStrategy
    options: tuple[Path, ...]
    feature_names: tuple[str, ...]
    option_features: np.ndarray
    information_gain: float


@dataclass
class OpenQuery:
    """A proposed query of the current evidence and how the record shows it."""

    query_id: int
    query: core_queries.Query
    feature_names: tuple[str, ...]
    record: ProposalRecord
    answered: bool = False


@dataclass
class WorldEvidence:
    """The current world's evidence (see the module doc). All methods are called on the node's
    executor thread, so no locking."""

    job: InferenceJob | None = None  # the job of the proxy observation; None = no evidence
    feature_names: tuple[str, ...] = ()
    world_stamp: tuple[int, int] | None = None  # training map's header stamp (sec, nanosec)
    posterior: core_inference.Posterior | None = None
    answers: list[core_inference.ChoiceObservation] = field(default_factory=list)
    queries: dict[int, OpenQuery] = field(default_factory=dict)
    forgotten: set[int] = field(default_factory=set)
    epoch: int = 0
    next_id: int = 1
    resampling: bool = False
    last_proxy_stamp: tuple[int, int] | None = None

    @property
    def observation_model(self) -> core_inference.ObservationModel | None:
        """The observation model of the evidence's posterior (``None``: no evidence)."""
        return None if self.job is None else self.job.observation_model

    def reset(self, job: InferenceJob, posterior: core_inference.Posterior, feature_names: tuple[str, ...],
              world_stamp: tuple[int, int]) -> None:
        """New evidence: the proxy of ``job`` (its posterior ``posterior``), no answers."""
        self._retire()
        self.job, self.posterior, self.feature_names, self.world_stamp = job, posterior, feature_names, world_stamp

    def forget(self) -> None:
        """No evidence (a new world)."""
        self._retire()
        self.job, self.posterior, self.feature_names, self.world_stamp = None, None, (), None

    def _retire(self) -> None:
        self.epoch += 1
        self.forgotten.update(self.queries)
        self.queries = {}
        self.answers = []
        self.resampling = False

    def on_proxy(self, stamp: tuple[int, int]) -> bool:
        """A /world/proxy arrived; True if the evidence was forgotten (a new world generation)."""
        new_generation = stamp != self.last_proxy_stamp
        self.last_proxy_stamp = stamp
        if new_generation and self.job is not None and stamp != self.world_stamp:
            self.forget()
            return True
        return False

    def add_query(self, query: core_queries.Query, record: ProposalRecord) -> int:
        """Register a proposal; returns its id."""
        qid = self.next_id
        self.next_id += 1
        self.queries[qid] = OpenQuery(qid, query, self.feature_names, record)
        return qid

    def check_answer(self, query_id: int, chosen: int, beta: float, default_beta: float) -> tuple[OpenQuery, float]:
        """The open query and the answer's beta, or ``ValueError`` naming the field (nothing changes)."""
        if query_id in self.forgotten:
            raise ValueError(f"query_id: query {query_id} belongs to a forgotten world (a new world or "
                             "/ird/infer replaced the evidence)")
        open_query = self.queries.get(query_id)
        if open_query is None:
            raise ValueError(f"query_id: unknown query {query_id}")
        if open_query.answered:
            raise ValueError(f"query_id: query {query_id} was already answered")
        q = open_query.query.num_options
        if not 0 <= chosen < q:
            raise ValueError(f"chosen: {chosen} is out of range for {q} options (0..{q - 1})")
        if not math.isfinite(beta) or beta < 0.0:
            raise ValueError(f"beta: must be finite and >= 0 (0 = the node's answer_beta), got {beta!r}")
        answer_beta = float(default_beta) if beta == 0.0 else float(beta)
        check_real("beta", answer_beta, positive=False)  # the range every beta is held to (ird_core.checks)
        return open_query, answer_beta

    def choice(self, open_query: OpenQuery, chosen: int, beta: float) -> core_inference.ChoiceObservation:
        return core_inference.ChoiceObservation(open_query.query.option_features, int(chosen), float(beta))

    def commit(self, open_query: OpenQuery, choice: core_inference.ChoiceObservation,
               posterior: core_inference.Posterior) -> None:
        """Take the answer: it joins the evidence and ``posterior`` becomes the current one."""
        open_query.answered = True
        self.answers.append(choice)
        self.posterior = posterior
