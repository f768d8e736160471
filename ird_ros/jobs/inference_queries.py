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

Query kinds (``ird_core.vocabulary.QueryKind``): a :class:`QueryJob` proposes paths on a query
map (``ird_core.designer.queries.propose_query``); a :class:`ProxyQueryJob` proposes proxy rewards
for the evidence's own training world (Active IRD, ``ird_core.designer.proxy_queries``:
``propose_proxy_query(train_mdp, proxy_mdp, proxy_weights, samples, beta, num_options, strategy,
seed, observation_model)`` with the evidence job's maps, proxy and observation model;
:func:`proxy_query_job` validates it). Either query's ``option_features`` are what an answer's
``ChoiceObservation`` sees, so ``/ird/answer`` is the same for both.

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
from ird_core.designer import proxy_queries as core_proxy_queries
from ird_core.designer import queries as core_queries
from ird_core.designer.candidates import PlanSettings
from ird_core.mdp import GridMDP
from ird_core.posterior import ObservationModel
from ird_core.vocabulary import QueryKind, QueryStrategy, parse
from ird_ros.jobs.inference import InferenceJob
from ird_ros.jobs.planning import ReferenceJob, reference_features
from ird_ros.jobs.work import check_query_work

if TYPE_CHECKING:  # the options are nav_msgs/Path messages, built by the node; no ROS import here
    from ird_msgs.msg import ProxyReward
    from nav_msgs.msg import Path

    from ird_ros.conversions import FeatureGridData

__all__ = ["QueryJob", "ProxyQueryJob", "ProposalRecord", "OpenQuery", "WorldEvidence", "run_query",
           "proxy_query_job", "proxy_test_mdp", "query_reference", "plan_settings", "resample_seed"]


@dataclass(frozen=True)
class QueryJob:
    """A validated /ird/query request, as the worker process gets it (``propose_query``'s arguments)."""

    query_mdp: GridMDP
    samples: np.ndarray
    beta: float
    num_options: int
    strategy: QueryStrategy
    seed: int
    # Rob's plan on the query map is the planner's default (per step, the min over samples
    # rescaled on the training map, baseline training_features); its reference counts and
    # training map come from this job (None: unscaled, no baseline).
    reference: ReferenceJob | None = None


def plan_settings(reference: ReferenceJob | None) -> PlanSettings:
    """Rob's plan settings when a reference is given: the planner node's defaults, the
    ``training_features`` baseline and every sample rescaled over the training map
    (``sample_scale`` training_spread); without one, the unscaled min with no baseline."""
    if reference is None:
        return PlanSettings()
    return PlanSettings("training_features", reference_features(reference), reference.target_features)


@dataclass(frozen=True)
class ProxyQueryJob:
    """A validated /ird/query request of kind "proxies" (``propose_proxy_query``'s arguments)."""

    train_mdp: GridMDP
    proxy_mdp: GridMDP | None
    proxy_weights: np.ndarray
    samples: np.ndarray
    beta: float
    num_options: int
    strategy: QueryStrategy
    seed: int
    observation_model: ObservationModel
    test_mdp: GridMDP | None = None  # the map Rob will drive, for evoi
    reference: ReferenceJob | None = None  # Rob's baseline there (``plan_settings``)


def run_query(job: "QueryJob | ProxyQueryJob") -> "core_queries.Query | core_proxy_queries.ProxyQuery":
    """The worker-process job of /ird/query (raises ``NotEnoughCandidates`` naming num_options)."""
    if isinstance(job, ProxyQueryJob):
        # The node's work check bounds the candidates (one per sample), not the library's default.
        return core_proxy_queries.propose_proxy_query(
            job.train_mdp, job.proxy_mdp, job.proxy_weights, job.samples, job.beta, job.num_options, job.strategy,
            job.seed, job.observation_model, max_candidates=max(core_proxy_queries.DEFAULT_MAX_CANDIDATES,
                                                                len(job.samples) + 1),
            test_mdp=job.test_mdp, plan=plan_settings(job.reference))
    return core_queries.propose_query(job.query_mdp, job.samples, job.beta, job.num_options, job.strategy, job.seed,
                                      plan_settings(job.reference))


def proxy_query_job(evidence: "WorldEvidence", *, map_empty: bool, start: tuple[int, int], horizon: int,
                    num_options: int, strategy: str, seed: int, beta: float, max_options: int,
                    max_query_work: float, test: GridMDP | None = None) -> ProxyQueryJob:
    """The job of a "proxies" request on ``evidence`` (the node has checked that a posterior exists).

    The options are planned on the evidence's training map, so ``map`` must be empty and
    ``start_row``, ``start_col``, ``horizon`` 0; ``num_options`` 0 = 2 (at most ``max_options``);
    ``strategy`` "" = ``evoi``, which needs ``test`` (the map Rob will drive, :func:`proxy_test_mdp`). The work is ``ird_ros.jobs.work.check_query_work`` on the
    training map (one candidate per sample, each one MDP pass).

    Raises:
        ValueError: naming the field.
    """
    job, posterior = evidence.job, evidence.posterior
    assert job is not None and posterior is not None
    if not map_empty:
        raise ValueError("map: must be empty for kind 'proxies' (the options are planned on the training map)")
    for name, value in zip(("start_row", "start_col"), start):
        if value != 0:
            raise ValueError(f"{name}: must be 0 for kind 'proxies' (the training map's start), got {value}")
    if horizon != 0:
        raise ValueError(f"horizon: must be 0 for kind 'proxies' (the training map's horizon), got {horizon}")
    num_options = num_options or 2
    if not 2 <= num_options <= max_options:
        raise ValueError(f"num_options: must be in [2, max_options={max_options}], got {num_options}")
    chosen = parse(QueryStrategy, strategy or QueryStrategy.EVOI, "strategy")
    if chosen not in (QueryStrategy.EVOI, QueryStrategy.INFO_GAIN, QueryStrategy.RANDOM):
        raise ValueError(f"strategy: kind 'proxies' is chosen by 'evoi', 'info_gain' or 'random', got {strategy!r}")
    if chosen is QueryStrategy.EVOI and test is None:
        raise ValueError("strategy: 'evoi' needs the test map Rob will drive, and none was received")
    train = job.train_mdp
    samples = posterior.samples
    check_query_work(len(samples), train.height, train.width, train.horizon, train.num_features, num_options,
                     max_query_work)
    if test is not None:
        check_query_work(len(samples), test.height, test.width, test.horizon, test.num_features, num_options,
                         max_query_work)
    return ProxyQueryJob(train, job.proxy_mdp, job.proxy_weights, samples, beta, num_options, chosen, seed,
                         job.observation_model, test, query_reference(evidence))


def proxy_test_mdp(grid: "FeatureGridData", proxy: "ProxyReward | None") -> GridMDP:
    """The map Rob will drive for a proxies query's EVOI: the test map from the proxy's test start
    over its test horizon (``ValueError`` naming ``strategy`` without a proxy)."""
    if proxy is None:
        raise ValueError("strategy: 'evoi' needs /world/proxy's test start and horizon, and no proxy was received")
    return GridMDP(grid.features.astype(np.float64), (int(proxy.test_start_row), int(proxy.test_start_col)),
                   int(proxy.test_horizon))


def query_reference(evidence: "WorldEvidence") -> ReferenceJob | None:
    """The inputs of Rob's ``training_features`` baseline for a paths query: the evidence's proxy
    planned on its training map (the planner's default reference), counted in the posterior's
    features; ``None`` without evidence."""
    job = evidence.job
    if job is None:
        return None
    return ReferenceJob(job.proxy_mdp or job.train_mdp, job.proxy_weights, job.train_mdp.features)


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
        kind: what the designer chooses among (paths on the query map, or proxies whose
            ``options`` are their plans on the training map).
        option_proxies: ``(q, p)`` the offered proxy weights (kind "proxies"), else ``None``.
    """

    strategy: QueryStrategy
    options: tuple[Path, ...]
    feature_names: tuple[str, ...]
    option_features: np.ndarray
    information_gain: float
    kind: QueryKind = QueryKind.PATHS
    option_proxies: np.ndarray | None = None


@dataclass
class OpenQuery:
    """A proposed query of the current evidence and how the record shows it."""

    query_id: int
    query: core_queries.Query | core_proxy_queries.ProxyQuery
    feature_names: tuple[str, ...]
    record: ProposalRecord
    answered: bool = False


@dataclass
class WorldEvidence:
    """The current world's evidence (see the module doc). All methods are called on the node's
    executor thread, so no locking."""

    job: InferenceJob | None = None  # the job of the proxy observation; None = no evidence
    feature_names: tuple[str, ...] = ()
    proxy_feature_names: tuple[str, ...] = ()  # the proxy's p features (training or proxy map layers)
    train_geometry: tuple[float, tuple[float, float]] = (1.0, (0.0, 0.0))  # training map resolution, origin
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
              world_stamp: tuple[int, int], proxy_feature_names: tuple[str, ...] | None = None,
              train_geometry: tuple[float, tuple[float, float]] = (1.0, (0.0, 0.0))) -> None:
        """New evidence: the proxy of ``job`` (its posterior ``posterior``), no answers; the proxy's
        feature names (``None``: ``feature_names``) and the training map's resolution and origin
        (where a proxy query's plans are drawn)."""
        self._retire()
        self.job, self.posterior, self.feature_names, self.world_stamp = job, posterior, feature_names, world_stamp
        self.proxy_feature_names = feature_names if proxy_feature_names is None else tuple(proxy_feature_names)
        self.train_geometry = train_geometry

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

    def add_query(self, query: "core_queries.Query | core_proxy_queries.ProxyQuery", record: ProposalRecord) -> int:
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
