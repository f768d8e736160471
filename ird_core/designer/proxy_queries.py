"""Active IRD's query type: the designer picks which of a few proxy rewards they would have written.

docs/spec.md section 7 ("The proxy-choice query"); Mindermann, Shah, Gleave and Hadfield-Menell
2018, "Active Inverse Reward Design" (discrete queries). The robot offers ``q`` proxy rewards
``w~_1 .. w~_q`` for the training world and the designer picks the one they would have written.
IRD's observation model (docs/spec.md section 3) with its normaliser over the offered set only
gives the evidence term

``P(i | w) = exp(beta w . phi~(w~_i)) / sum_j exp(beta w . phi~(w~_j))``,

``phi~(w~)`` the proxy's behaviour in the training world counted in the hypothesis space
(:func:`ird_core.posterior.behaviour_counts` under the posterior's
:class:`~ird_core.posterior.ObservationModel`: optimal-path or MaxEnt counts). That is a
Boltzmann choice over the options' behaviour counts, so the answer enters the posterior as an
:class:`ird_core.posterior.ChoiceObservation` (:func:`proxy_choice_observation`) and every
criterion of :mod:`ird_core.designer.queries` (information gain, the exact best pair, greedy
extension, random) applies unchanged to the candidates' counts.

Candidates (:func:`candidate_proxies`): the written proxy first, then

- where the proxy acts on the hypothesis features (``proxy_mdp`` ``None``: the indicator
  conditions), the posterior samples themselves: each is a reward the designer might have
  written;
- where it acts on other features (latent_classifier: ``proxy_mdp`` holds the classifier
  outputs), the samples do not live in the proxy's space, and the candidates are seeded
  perturbations ``w~ + perturbation_sigma * N(0, I)`` of the written proxy.

Candidates with equal behaviour counts (rounded to 1e-9) are one candidate (the answer likelihood
sees only the counts); the first occurrence is kept, so the written proxy is candidate 0. At most
``max_candidates`` proxies are planned (a ``ValueError`` naming ``samples`` or
``num_perturbations`` beyond it).

Each option's plan on the training map (``ProxyQuery.option_cells``, what the designer is shown)
is the proxy's optimal path on its planning MDP (``ird_core.mdp.optimal_paths``, the same cells as
``ird_core.mdp.optimal_path``). Under the "optimal" observation model its counts are the option's
``option_features``; under "maxent" the counts are the expectations of the MaxEnt designer and the
plan is their most likely single path.

The simulated designer (:func:`simulated_proxy_answer`) picks by the TRUE return of each option's
plan on the training map (``ird_core.worlds.evaluation.true_return``), Boltzmann with its own beta.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ird_core.checks import check_array, check_int, check_real
from ird_core.designer.candidates import PlanSettings
from ird_core.designer.decision import Screen, best_evoi_pair, best_query, evoi_values
from ird_core.designer.queries import (NotEnoughCandidates, _best_pair, _greedy_extend,
                                       _information_gain_from_scores, simulated_answer)
from ird_core.mdp import GridMDP, cell_rewards, optimal_paths
from ird_core.posterior.evidence import ChoiceObservation
from ird_core.posterior.observation_model import DEFAULT_OBSERVATION_MODEL, ObservationModel, behaviour_counts
from ird_core.vocabulary import QueryKind, QueryStrategy, parse
from ird_core.worlds.evaluation import true_return
from ird_core.worlds.lavaland import TRUE_TERRAIN_REWARD

__all__ = [
    "DEFAULT_MAX_CANDIDATES",
    "ProxyQuery",
    "proxy_choice_observation",
    "proxy_behaviour",
    "proxy_plans",
    "candidate_proxies",
    "propose_proxy_query",
    "proxy_option_returns",
    "simulated_proxy_answer",
]

#: Largest number of proxies :func:`candidate_proxies` plans (one batched MDP pass each).
DEFAULT_MAX_CANDIDATES: int = 4096
#: The strategies of a proxy query (``ird_core.designer.queries``' criteria on behaviour counts).
_STRATEGIES: tuple[str, ...] = (QueryStrategy.EVOI.value, QueryStrategy.INFO_GAIN.value, QueryStrategy.RANDOM.value)
#: Decimals the behaviour counts are rounded to when candidates are de-duplicated.
_DEDUP_DECIMALS: int = 9


@dataclass(frozen=True, eq=False)
class ProxyQuery:
    """A proposed proxy-choice query (module docstring).

    Attributes:
        proxies: ``(q, p)`` the offered proxy weights, in the proxy's own feature space.
        option_features: ``(q, d)`` their behaviour counts ``phi~(w~_i)`` in the training world,
            in the hypothesis space (what the answer's likelihood sees).
        option_cells: ``q`` read-only ``(T + 1, 2)`` int64 arrays: each proxy's optimal plan on
            the training map (its planning MDP), ``(row, col)`` cells from the start.
        information_gain: nats, under the samples and ``beta`` the query was proposed with.
        strategy: ``"info_gain"`` or ``"random"``.
        num_candidates: distinct candidate proxies the options were picked from.
        kind: ``"proxies"`` (``ird_core.vocabulary.QueryKind.PROXIES``).
    """

    proxies: np.ndarray
    option_features: np.ndarray
    option_cells: tuple[np.ndarray, ...]
    information_gain: float
    strategy: str
    num_candidates: int
    kind: str = QueryKind.PROXIES.value

    @property
    def num_options(self) -> int:
        return len(self.option_cells)


def proxy_choice_observation(query: ProxyQuery, chosen: int, beta: float) -> ChoiceObservation:
    """The evidence of the designer's pick: ``ChoiceObservation(query.option_features, chosen, beta)``.

    ``log P(chosen | w) = beta w . phi~_chosen - logsumexp_j(beta w . phi~_j)`` over the ``q``
    offered proxies (IRD's observation model normalised over the offered set).

    Raises:
        ValueError: naming ``query``, ``chosen`` or ``beta``.
    """
    if not isinstance(query, ProxyQuery):
        raise ValueError(f"query: expected a ProxyQuery, got {type(query).__name__}")
    return ChoiceObservation(query.option_features, chosen, beta)


def _planning(train_mdp: GridMDP, proxy_mdp: GridMDP | None) -> GridMDP:
    """The MDP the proxies are planned on, checked against the training MDP."""
    if not isinstance(train_mdp, GridMDP):
        raise ValueError(f"train_mdp: expected a GridMDP, got {type(train_mdp).__name__}")
    if proxy_mdp is None:
        return train_mdp
    if not isinstance(proxy_mdp, GridMDP):
        raise ValueError(f"proxy_mdp: expected a GridMDP or None, got {type(proxy_mdp).__name__}")
    if (proxy_mdp.height, proxy_mdp.width, proxy_mdp.start, proxy_mdp.horizon) != \
            (train_mdp.height, train_mdp.width, train_mdp.start, train_mdp.horizon):
        raise ValueError("proxy_mdp: must have the training MDP's grid, start and horizon")
    return proxy_mdp


def _model(observation_model: ObservationModel) -> ObservationModel:
    if not isinstance(observation_model, ObservationModel):
        raise ValueError(f"observation_model: expected an ObservationModel, got {type(observation_model).__name__}")
    return observation_model


def proxy_behaviour(train_mdp: GridMDP, proxy_mdp: GridMDP | None, proxies: np.ndarray,
                    observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL) -> np.ndarray:
    """``phi~(w~)`` of each proxy in the training world, counted in the hypothesis space.

    Args:
        train_mdp: the training MDP on the hypothesis features ``(H, W, d)``.
        proxy_mdp: the same grid on the proxy's features ``(H, W, p)``, or ``None`` (``p = d``).
        proxies: ``(n, p)`` proxy weights.
        observation_model: how behaviour is counted (the posterior's model).
    Returns:
        ``(n, d)``, as ``ird_core.posterior.proxy_observation`` computes a proxy's ``phi~``.
    """
    planning = _planning(train_mdp, proxy_mdp)
    w = check_array("proxies", proxies, (None, planning.num_features))
    hypothesis = None if proxy_mdp is None else train_mdp.features
    return behaviour_counts(planning, w, _model(observation_model), hypothesis)


def proxy_plans(train_mdp: GridMDP, proxy_mdp: GridMDP | None, proxies: np.ndarray) -> tuple[np.ndarray, ...]:
    """Each proxy's optimal plan on its planning MDP: ``n`` read-only ``(T + 1, 2)`` int64 cell arrays."""
    planning = _planning(train_mdp, proxy_mdp)
    w = check_array("proxies", proxies, (None, planning.num_features))
    paths = optimal_paths(planning, cell_rewards(planning, w))  # (n, T + 1, 2)
    out = []
    for path in paths:
        path = np.array(path, dtype=np.int64)
        path.setflags(write=False)
        out.append(path)
    return tuple(out)


def candidate_proxies(
    proxy_weights: np.ndarray,
    samples: np.ndarray,
    train_mdp: GridMDP,
    proxy_mdp: GridMDP | None = None,
    *,
    observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL,
    num_perturbations: int | None = None,
    perturbation_sigma: float = 1.0,
    seed: int = 0,
    max_candidates: int = DEFAULT_MAX_CANDIDATES,
) -> tuple[np.ndarray, np.ndarray]:
    """The distinct proxies the designer might have written (module docstring).

    Args:
        proxy_weights: ``(p,)`` the written proxy.
        samples: ``(K, d)`` posterior samples (candidates themselves when ``proxy_mdp`` is None).
        train_mdp: the training MDP ``(H, W, d)``.
        proxy_mdp: the proxy's feature view ``(H, W, p)`` of the same grid, or ``None``.
        observation_model: how behaviour is counted.
        num_perturbations: seeded perturbations of the written proxy added as candidates;
            ``None`` = none when the proxy shares the hypothesis space, ``K`` otherwise.
        perturbation_sigma: ``> 0``, their standard deviation per weight.
        seed: ``>= 0``, seeds the perturbations.
        max_candidates: ``>= 2``, the most proxies planned.
    Returns:
        ``proxies`` ``(n, p)`` and their ``counts`` ``(n, d)``, distinct counts, the written
        proxy first, then first-occurrence order.
    Raises:
        ValueError: naming the field (``samples`` or ``num_perturbations`` past ``max_candidates``).
    """
    planning = _planning(train_mdp, proxy_mdp)
    written = check_array("proxy_weights", proxy_weights, (planning.num_features,))
    w = check_array("samples", samples, (None, train_mdp.num_features))
    seed = check_int("seed", seed, 0)
    max_candidates = check_int("max_candidates", max_candidates, 2)
    sigma = check_real("perturbation_sigma", perturbation_sigma, positive=True, ranged=False)
    same_space = proxy_mdp is None
    if num_perturbations is None:
        num_perturbations = 0 if same_space else len(w)
    num_perturbations = check_int("num_perturbations", num_perturbations, 0)
    parts = [written[None]]
    if same_space:
        if 1 + len(w) > max_candidates:
            raise ValueError(f"samples: {len(w)} samples give {1 + len(w)} candidate proxies, more than "
                             f"max_candidates={max_candidates}")
        parts.append(w)
    total = sum(len(part) for part in parts) + num_perturbations
    if total > max_candidates:
        raise ValueError(f"num_perturbations: {num_perturbations} perturbations give {total} candidate proxies, "
                         f"more than max_candidates={max_candidates}")
    if num_perturbations:
        noise = np.random.default_rng([seed, 1]).standard_normal((num_perturbations, len(written)))
        parts.append(written[None] + sigma * noise)
    proxies = np.concatenate(parts)
    counts = proxy_behaviour(train_mdp, proxy_mdp, proxies, observation_model)
    _, first = np.unique(np.round(counts, _DEDUP_DECIMALS), axis=0, return_index=True)
    keep = np.sort(first)
    return proxies[keep], counts[keep]


def propose_proxy_query(
    train_mdp: GridMDP,
    proxy_mdp: GridMDP | None,
    proxy_weights: np.ndarray,
    samples: np.ndarray,
    beta: float,
    num_options: int = 2,
    strategy: str = "info_gain",
    seed: int = 0,
    observation_model: ObservationModel = DEFAULT_OBSERVATION_MODEL,
    *,
    num_perturbations: int | None = None,
    perturbation_sigma: float = 1.0,
    max_candidates: int = DEFAULT_MAX_CANDIDATES,
    test_mdp: GridMDP | None = None,
    plan: PlanSettings | None = None,
) -> ProxyQuery:
    """Propose a ``num_options``-proxy query for the training world from posterior ``samples``.

    ``evoi``: the expected value of the answer for Rob's plan on ``test_mdp``
    (:func:`ird_core.designer.decision.evoi_values` with the proxies' behaviour counts as the
    options' features: the answer model is the same Boltzmann choice), exact best pair, then
    greedily; it needs ``test_mdp`` (and Rob's ``plan`` settings, default no baseline).

    ``info_gain``: the exact best pair of candidates by information gain, then greedily the
    candidate that raises the set's gain most (``ird_core.designer.queries``' machinery on the
    candidates' behaviour counts). ``random``: ``q`` distinct candidates drawn with ``seed``.

    Args:
        train_mdp: the training MDP on the hypothesis features ``(H, W, d)``.
        proxy_mdp: the proxy's feature view ``(H, W, p)``, or ``None`` (the proxy acts on
            ``train_mdp``'s features).
        proxy_weights: ``(p,)`` the written proxy.
        samples: ``(K, d)`` posterior samples.
        beta: the answer rationality assumed by the information gain, finite ``>= 0``.
        num_options: ``q >= 2``.
        strategy: ``"info_gain"`` or ``"random"``.
        seed: ``>= 0``; seeds ``random`` and the perturbations.
        observation_model: how behaviour is counted (the posterior's model).
        num_perturbations, perturbation_sigma, max_candidates: as :func:`candidate_proxies`.
        test_mdp: the map Rob will drive, ``(H', W', d)``, for ``evoi``.
        plan: Rob's plan settings on ``test_mdp``, for ``evoi``.
    Returns:
        The :class:`ProxyQuery`; its ``information_gain`` is the set's, for either strategy.
    Raises:
        NotEnoughCandidates: fewer than ``num_options`` distinct candidates (names ``num_options``).
        ValueError: naming the field of any other bad argument.
    """
    beta = check_real("beta", beta, positive=False)
    num_options = check_int("num_options", num_options, 2)
    if parse(QueryStrategy, strategy, "strategy") not in _STRATEGIES:
        raise ValueError(f"strategy: a proxy query is chosen by one of {_STRATEGIES}, got {strategy!r}")
    seed = check_int("seed", seed, 0)
    if strategy == QueryStrategy.EVOI and not isinstance(test_mdp, GridMDP):
        raise ValueError("test_mdp: 'evoi' needs the map Rob will drive (a GridMDP)")
    proxies, counts = candidate_proxies(proxy_weights, samples, train_mdp, proxy_mdp,
                                        observation_model=observation_model, num_perturbations=num_perturbations,
                                        perturbation_sigma=perturbation_sigma, seed=seed,
                                        max_candidates=max_candidates)
    w = np.asarray(samples, dtype=np.float64)
    n = len(proxies)
    if n < num_options:
        raise NotEnoughCandidates(f"num_options: {num_options} options requested but only {n} distinct candidate "
                                  "proxy behaviour(s) exist in the training world")
    scores = beta * (counts @ w.T)  # (n, K)
    if strategy == QueryStrategy.RANDOM:
        chosen = [int(i) for i in np.random.default_rng(seed).choice(n, num_options, replace=False)]
    elif strategy == QueryStrategy.EVOI:
        assert test_mdp is not None
        screen = Screen.of_plan(test_mdp, w, (plan or PlanSettings()).cell_rewards(test_mdp, w))
        chosen, _ = best_query(lambda sets: evoi_values(screen, counts[sets], beta), n, num_options,
                               best_evoi_pair(screen, counts, beta))
    else:
        i, j, _ = _best_pair(scores)
        chosen = _greedy_extend(scores, [i, j], num_options)
    gain = float(_information_gain_from_scores(scores[chosen].T))
    offered, features = proxies[chosen], counts[chosen]
    offered.setflags(write=False)
    features.setflags(write=False)
    cells = proxy_plans(train_mdp, proxy_mdp, offered)
    return ProxyQuery(offered, features, cells, gain, QueryStrategy(strategy).value, n)


def proxy_option_returns(query: ProxyQuery, train_labels: np.ndarray,
                         terrain_reward: np.ndarray = TRUE_TERRAIN_REWARD) -> np.ndarray:
    """``(q,)`` TRUE returns of the options' plans on the training map's ``(H, W)`` labels
    (``ird_core.worlds.evaluation.true_return``; a file world passes its ``true_terrain_reward``)."""
    if not isinstance(query, ProxyQuery):
        raise ValueError(f"query: expected a ProxyQuery, got {type(query).__name__}")
    return np.array([true_return(train_labels, cells, terrain_reward) for cells in query.option_cells])


def simulated_proxy_answer(query: ProxyQuery, train_labels: np.ndarray, beta: float, rng: np.random.Generator,
                           terrain_reward: np.ndarray = TRUE_TERRAIN_REWARD) -> int:
    """A simulated designer's pick: option ``i`` with probability ``softmax(beta * returns)_i``,
    ``returns`` = :func:`proxy_option_returns` (the true return of each proxy's training-map plan).

    Args:
        query: the proposed query.
        train_labels: ``(H, W)`` terrain labels of the training map.
        beta: the designer's own rationality, finite ``>= 0``.
        rng: the random generator (seeded by the caller).
        terrain_reward: the true reward per label.
    Returns:
        The chosen index in ``[0, q)``.
    """
    return simulated_answer(proxy_option_returns(query, train_labels, terrain_reward), beta, rng)
