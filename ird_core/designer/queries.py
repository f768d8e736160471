"""Queries to the reward designer: information gain, query proposal, a simulated designer.

docs/spec.md section 7. The robot shows the designer ``q`` paths of the query MDP (by default the
test map it is about to drive) and asks which one they prefer; the answer enters the posterior as
an ``ird_core.posterior.evidence.ChoiceObservation`` with the Boltzmann likelihood
``P(k | w) = softmax_k(beta * F @ w)``, ``F`` the options' feature counts ``(q, d)``.

Information gain (``information_gain``): the mutual information in nats between the answer and
``w`` under the empirical posterior of ``K`` samples,
``H(mean_k p_k) - mean_k H(p_k)``, ``p_k = softmax(beta * F @ w_k)``, in log space and batched
over queries and samples. It lies in ``[0, log q]``; tiny negative rounding is clipped to 0.

Query proposal (``propose_query``):

- Candidates, rich (with Rob's ``PlanSettings``; ``ird_core.designer.candidates``): Rob's
  current plan, the plans at other risk levels and for clusters of samples, the samples' own
  optimal paths, detours and deviations of each, distinct by feature counts, bounded.
- Candidates, the samples' own (``info_gain`` and ``random`` without ``plan``): the literal
  (optimal) path of every posterior sample on the query MDP, from one hard-max dynamic program
  batched over the ``K`` samples (ties broken "stay" first, in ``ird_core.mdp.MOVES`` order, like
  ``mdp.optimal_path``). Paths with equal feature counts are one candidate: the answer likelihood
  sees only the feature counts, so such options cannot be told apart. Candidates are ordered by
  how many samples plan them (most first), ties by first occurrence.
- ``evoi``: the expected value of the answer for the plan Rob will drive, and ``max_regret``: the
  pair of sample optima with the largest mutual regret (``ird_core.designer.decision``); the best
  pair exactly, then greedily to ``q`` options.
- ``info_gain`` with 2 options: the exact best pair over all ``n (n - 1) / 2`` candidate pairs,
  evaluated in memory-bounded blocks from one ``(n, K)`` score matrix. With ``q > 2``: the best
  pair, then greedily the candidate that raises the set's information gain most, until ``q``.
  Greedy has no optimality guarantee (the exact search costs ``C(n, q)`` evaluations), and an
  added option can lower the information gain (a third option splits the answer's probability),
  so the greedy set contains the best pair but may be less informative than it.
- ``random``: ``q`` distinct candidates uniformly at random (seeded); the baseline.
- ``propose_oracle_query`` (experiments): the query whose simulated answer leads to the re-plan of
  highest expected TRUE return; the headroom of one question.
- Fewer than ``q`` distinct candidates: ``NotEnoughCandidates``, a ``ValueError`` naming
  ``num_options``. A caller that runs rounds (experiments) catches it and asks nothing.

Simulated designer (``simulated_answer``, ``SimulatedDesigner``): Boltzmann on the TRUE return of
each option with its own ``beta``, seeded. It takes the returns as an array, so this module knows
nothing of Lavaland (there ``ird_core.worlds.evaluation.true_return(labels, cells)`` gives them).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import logsumexp

from ird_core.checks import check_array, check_int, check_real
from ird_core.designer import decision
from ird_core.designer.candidates import MAX_CANDIDATES, PlanSettings, query_candidates
from ird_core.mdp import MOVES, GridMDP, successor_table
from ird_core.vocabulary import STRATEGIES, QueryStrategy, parse

__all__ = [
    "STRATEGIES",
    "Query",
    "NotEnoughCandidates",
    "information_gain",
    "literal_paths",
    "candidate_paths",
    "propose_query",
    "propose_oracle_query",
    "answer_probabilities",
    "simulated_answer",
    "SimulatedDesigner",
]

#: Float64 elements of the ``(T + 1, chunk, H, W)`` value table of one batched DP in
#: ``literal_paths`` (32 MB), which sets the number of samples per chunk.
_PATH_TABLE_ELEMENTS: int = 4_000_000
#: Pair searches with more pair-sample elements than this are screened in float32 first.
_SCREEN_ELEMENTS: int = 2_000_000


class NotEnoughCandidates(ValueError):
    """Fewer distinct candidate paths than the requested number of options."""


@dataclass(frozen=True, eq=False)
class Query:
    """A proposed query.

    Attributes:
        option_cells: ``q`` read-only ``(T + 1, 2)`` int64 arrays of ``(row, col)`` cells.
        option_features: ``(q, d)`` feature counts ``phi(xi)`` of the options in the query MDP.
        information_gain: nats, under the samples and the ``beta`` the query was proposed with.
        strategy: one of ``STRATEGIES`` (or ``oracle`` for :func:`propose_oracle_query`).
        num_candidates: distinct candidate paths the options were picked from.
        value: the criterion's score of the set: EVOI (return units), mutual regret, the
            oracle's expected true return; NaN for ``info_gain`` and ``random``.
    """

    option_cells: tuple[np.ndarray, ...]
    option_features: np.ndarray
    information_gain: float
    strategy: str
    num_candidates: int
    value: float = float("nan")

    @property
    def num_options(self) -> int:
        return len(self.option_cells)


# --------------------------------------------------------------------------------------------
# Information gain
# --------------------------------------------------------------------------------------------


def _information_gain_from_scores(scores: np.ndarray) -> np.ndarray:
    """Mutual information from answer scores ``beta * w_k . f_j``; ``(..., K, q) -> (...)``."""
    log_p = scores - logsumexp(scores, axis=-1, keepdims=True)
    p = np.exp(log_p)
    mean_entropy = -np.sum(p * log_p, axis=-1).mean(axis=-1)
    log_mean = logsumexp(log_p, axis=-2) - np.log(scores.shape[-2])
    entropy_of_mean = -np.sum(np.exp(log_mean) * log_mean, axis=-1)
    return np.maximum(entropy_of_mean - mean_entropy, 0.0)


def information_gain(option_features: np.ndarray, samples: np.ndarray, beta: float) -> "float | np.ndarray":
    """Mutual information (nats) between the designer's answer and ``w`` (module docstring).

    Args:
        option_features: ``(q, d)`` one query, or ``(n, q, d)`` a batch of queries; ``q >= 2``.
        samples: ``(K, d)`` posterior samples.
        beta: the assumed answer rationality, finite ``>= 0``.
    Returns:
        A float for one query, ``(n,)`` for a batch.
    """
    features = np.asarray(option_features, dtype=np.float64)
    single = features.ndim == 2
    features = check_array("option_features", features[None] if single else features, (None, None, None))
    if features.shape[1] < 2:
        raise ValueError(f"option_features: expected q >= 2 options, got shape {np.shape(option_features)}")
    w = check_array("samples", samples, (None, features.shape[2]))
    beta = check_real("beta", beta, positive=False)
    scores = beta * np.einsum("nqd,kd->nkq", features, w, optimize=True)
    gain = _information_gain_from_scores(scores)
    return float(gain[0]) if single else gain


# --------------------------------------------------------------------------------------------
# Candidates: the samples' literal plans
# --------------------------------------------------------------------------------------------


def literal_paths(mdp: GridMDP, samples: np.ndarray) -> np.ndarray:
    """The optimal path of every weight vector: ``mdp.optimal_path``'s DP batched over samples.

    Backward: hard-max values ``V[t] = r + max_succ V[t + 1]`` for all samples at once (the same
    arithmetic as ``mdp.hard_values``); forward: every sample follows the first maximising
    successor in ``MOVES`` order ("stay" first), as ``mdp.optimal_path`` does. Samples are
    processed in chunks that keep the ``(T + 1, chunk, H, W)`` value table within
    ``_PATH_TABLE_ELEMENTS``.

    Args:
        mdp: the query MDP ``(H, W, d)``.
        samples: ``(K, d)`` weights.
    Returns:
        ``(K, T + 1)`` int64 state indices ``row * W + col``, ``[:, 0]`` the start.
    """
    w = check_array("samples", samples, (None, mdp.num_features))
    table = successor_table(mdp.height, mdp.width)
    states = np.empty((len(w), mdp.horizon + 1), dtype=np.int64)
    states[:, 0] = mdp.start_state
    step = max(1, _PATH_TABLE_ELEMENTS // ((mdp.horizon + 1) * mdp.num_states))
    for lo in range(0, len(w), step):
        chunk = w[lo:lo + step]
        rewards = np.einsum("hwd,kd->khw", mdp.features, chunk, optimize=True)
        values = np.empty((mdp.horizon + 1,) + rewards.shape)
        values[-1] = rewards
        padded = np.full(rewards.shape[:1] + (mdp.height + 2, mdp.width + 2), -np.inf)
        for t in range(mdp.horizon - 1, -1, -1):
            padded[:, 1:-1, 1:-1] = values[t + 1]
            views = [padded[:, 1 + dr: mdp.height + 1 + dr, 1 + dc: mdp.width + 1 + dc] for dr, dc in MOVES]
            best = values[t]
            np.maximum(views[0], views[1], out=best)
            for view in views[2:]:
                np.maximum(best, view, out=best)
            best += rewards
        flat = values.reshape(mdp.horizon + 1, len(chunk), mdp.num_states)
        rows = np.arange(len(chunk))[:, None]
        current = states[lo:lo + len(chunk), 0]
        for t in range(1, mdp.horizon + 1):
            successors = table[current]  # (k, 5), -1 off the grid
            succ_values = np.where(successors >= 0, flat[t][rows, successors], -np.inf)
            current = successors[rows[:, 0], np.argmax(succ_values, axis=1)]
            states[lo:lo + len(chunk), t] = current
    return states


def candidate_paths(mdp: GridMDP, samples: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Distinct candidate paths of the samples' literal plans (module docstring).

    Returns:
        ``states`` ``(n, T + 1)`` state indices, ``features`` ``(n, d)`` feature counts, and
        ``counts`` ``(n,)`` how many samples plan each candidate (descending).
    """
    states = literal_paths(mdp, samples)
    flat = mdp.features.reshape(mdp.num_states, mdp.num_features)
    features = flat[states].sum(axis=1)
    _, first, counts = np.unique(features, axis=0, return_index=True, return_counts=True)
    order = np.lexsort((first, -counts))
    return states[first[order]], features[first[order]], counts[order]


# --------------------------------------------------------------------------------------------
# Proposal
# --------------------------------------------------------------------------------------------


def _pair_gains(a: np.ndarray) -> np.ndarray:
    """Information gain of two-option queries from answer logits ``a_k = s_ik - s_jk``.

    ``H_b(mean_k sigmoid(a_k)) - mean_k H_b(sigmoid(a_k))`` with the Bernoulli entropy at logit
    ``a`` written as ``log(1 + e^-|a|) + |a| sigmoid(-|a|)`` (one ``exp`` and one ``log`` per
    element, no overflow). ``(m, K) -> (m,)`` in the dtype of ``a``.
    """
    k = a.shape[1]
    magnitude = np.abs(a)
    small = np.exp(-magnitude)
    big = small + 1
    np.reciprocal(big, out=big)  # sigmoid(|a|)
    small *= big  # sigmoid(-|a|)
    entropy = magnitude * small
    entropy -= np.log(big)
    p = np.where(a >= 0, big, small).sum(axis=1) / k
    q = 1 - p
    with np.errstate(divide="ignore", invalid="ignore"):
        mean_entropy = -(np.where(p > 0, p * np.log(p), 0) + np.where(q > 0, q * np.log(q), 0))
    return np.maximum(mean_entropy - entropy.sum(axis=1) / k, 0)


def _all_pair_gains(scores: np.ndarray) -> np.ndarray:
    """``_pair_gains`` of every pair ``i < j`` in ``np.triu_indices`` order; one block per row."""
    n = len(scores)
    return np.concatenate([_pair_gains(scores[i + 1:] - scores[i]) for i in range(n - 1)])


def _best_pair(scores: np.ndarray) -> tuple[int, int, float]:
    """Exact best pair ``(i, j)`` by information gain from candidate scores ``(n, K)``.

    Large searches (more than ``_SCREEN_ELEMENTS`` pair-sample elements) screen every pair in
    float32 first (about half the cost) and re-evaluate in float64 every pair within
    ``1e-5 + 1e-6 max|s|`` nats of the screened best: the float32 rounding of a logit is about
    ``2e-7 max|s|`` and moves the gain of a competitive pair (answer probability not within
    ``e^-15`` of 0 or 1) by far less than that margin. When the screened best is below
    ``1e-3`` nats, every pair is evaluated in float64. Ties go to the first pair in
    ``np.triu_indices`` order, as in a full float64 scan.
    """
    n, k = scores.shape
    first, second = np.triu_indices(n, 1)
    if len(first) * k > _SCREEN_ELEMENTS:
        screened = _all_pair_gains(scores.astype(np.float32))
        top = float(screened.max())
        if top >= 1e-3:
            keep = np.flatnonzero(screened >= top - (1e-5 + 1e-6 * float(np.abs(scores).max())))
            gains = _pair_gains(scores[second[keep]] - scores[first[keep]])
            best = int(keep[int(np.argmax(gains))])
            return int(first[best]), int(second[best]), float(gains.max())
    gains = _all_pair_gains(scores)
    best = int(np.argmax(gains))
    return int(first[best]), int(second[best]), float(gains[best])


def _greedy_extend(scores: np.ndarray, chosen: list[int], num_options: int) -> list[int]:
    """Add, one at a time, the candidate that maximises the set's information gain."""
    chosen = list(chosen)
    while len(chosen) < num_options:
        rest = np.setdiff1d(np.arange(len(scores)), chosen)
        sets = np.concatenate([np.broadcast_to(scores[chosen].T, (len(rest),) + scores[chosen].T.shape),
                               scores[rest][:, :, None]], axis=2)  # (m, K, |chosen| + 1)
        chosen.append(int(rest[int(np.argmax(_information_gain_from_scores(sets)))]))
    return chosen


def _query(query_mdp: GridMDP, cells: np.ndarray, features: np.ndarray, chosen: list[int], scores: np.ndarray,
           strategy: str, value: float = float("nan")) -> Query:
    """The :class:`Query` of candidates ``chosen``; ``scores`` ``(n, K)`` are ``beta w_k . f_i``."""
    gain = float(_information_gain_from_scores(scores[chosen].T))
    paths = []
    for index in chosen:
        path = np.array(cells[index], dtype=np.int64)
        path.setflags(write=False)
        paths.append(path)
    option_features = features[chosen]
    option_features.setflags(write=False)
    return Query(tuple(paths), option_features, gain, strategy, len(features), value)


def _candidates(query_mdp: GridMDP, w: np.ndarray, strategy: str, plan: "PlanSettings | None", num_options: int,
                max_candidates: int, seed: int):
    """``(cells (n, T + 1, 2), features (n, d), sample_choice or None)``, at least ``num_options``."""
    if plan is None and strategy in (QueryStrategy.INFO_GAIN, QueryStrategy.RANDOM):
        states, features, _ = candidate_paths(query_mdp, w)
        cells, choice = np.stack(np.divmod(states, query_mdp.width), axis=2), None
    else:
        found = query_candidates(query_mdp, w, plan or PlanSettings(), max_candidates=max_candidates, seed=seed)
        cells, features, choice = found.cells, found.features, found.sample_choice
    if len(features) < num_options:
        raise NotEnoughCandidates(f"num_options: {num_options} options requested but the {len(w)} samples give "
                                  f"only {len(features)} distinct candidate path(s) on the query map")
    return cells, features, choice


def _check_query_arguments(query_mdp: object, samples: object, beta: object, num_options: object,
                           seed: object) -> tuple[np.ndarray, float, int, int]:
    if not isinstance(query_mdp, GridMDP):
        raise ValueError(f"query_mdp: expected a GridMDP, got {type(query_mdp).__name__}")
    return (check_array("samples", samples, (None, query_mdp.num_features)), check_real("beta", beta, positive=False),
            check_int("num_options", num_options, 2), check_int("seed", seed, 0))


def propose_query(query_mdp: GridMDP, samples: np.ndarray, beta: float, num_options: int = 2,
                  strategy: str = "info_gain", seed: int = 0, plan: "PlanSettings | None" = None, *,
                  max_candidates: int = MAX_CANDIDATES) -> Query:
    """Propose a ``num_options``-path query on ``query_mdp`` from posterior ``samples``.

    Candidates: with ``plan`` (Rob's plan settings), the rich candidates of
    :func:`ird_core.designer.candidates.query_candidates`; without it, ``info_gain`` and
    ``random`` use the samples' own optimal paths (module docstring) and ``evoi`` and
    ``max_regret`` the rich candidates with ``PlanSettings()`` (no baseline).

    Args:
        query_mdp: the MDP the options are paths of (default use: the test map), ``(H, W, d)``.
        samples: ``(K, d)`` posterior samples.
        beta: the answer rationality assumed by the criteria, finite ``>= 0``.
        num_options: ``q >= 2``.
        strategy: one of ``STRATEGIES``: ``evoi`` and ``max_regret``
            (:mod:`ird_core.designer.decision`), ``info_gain`` (module docstring), ``random``.
        seed: ``>= 0``, seeds ``random`` and the candidates' clustering.
        plan: Rob's plan settings on ``query_mdp`` (baseline), or ``None``.
        max_candidates: the rich candidates' bound.
    Returns:
        The ``Query``; its ``information_gain`` is the set's, for every strategy.
    Raises:
        NotEnoughCandidates: fewer than ``num_options`` distinct candidates (for ``max_regret``:
            candidates that are some sample's own optimum).
        ValueError: naming the field of any other bad argument.
    """
    w, beta, num_options, seed = _check_query_arguments(query_mdp, samples, beta, num_options, seed)
    parse(QueryStrategy, strategy, "strategy")
    cells, features, choice = _candidates(query_mdp, w, strategy, plan, num_options, max_candidates, seed)
    n = len(features)
    scores = beta * (features @ w.T)  # (n, K)
    value = float("nan")
    if strategy == QueryStrategy.RANDOM:
        chosen = [int(i) for i in np.random.default_rng(seed).choice(n, num_options, replace=False)]
    elif strategy == QueryStrategy.INFO_GAIN:
        i, j, _ = _best_pair(scores)
        chosen = _greedy_extend(scores, [i, j], num_options)
    elif strategy == QueryStrategy.EVOI:
        screen = decision.Screen(query_mdp, w, (plan or PlanSettings()).cell_rewards(query_mdp, w), cells[0])
        chosen, value = decision.best_query(lambda sets: decision.evoi_values(screen, features[sets], beta),
                                            n, num_options, decision.best_evoi_pair(screen, features, beta))
    else:
        regret = decision.mutual_regret(features, w, choice)
        owned = np.flatnonzero(np.isfinite(regret).any(axis=1))
        if len(owned) < num_options:
            raise NotEnoughCandidates(f"num_options: {num_options} options requested but the samples' own optimal "
                                      f"paths give only {len(owned)} distinct candidate(s)")
        sub = regret[np.ix_(owned, owned)]
        picked, value = decision.best_query(
            lambda sets: sub[sets[:, :, None], sets[:, None, :]].sum(axis=(1, 2)) / 2, len(owned), num_options)
        chosen = [int(owned[i]) for i in picked]
    return _query(query_mdp, cells, features, chosen, scores, strategy, value)


def propose_oracle_query(query_mdp: GridMDP, samples: np.ndarray, beta: float, true_cells: np.ndarray,
                         designer_beta: float, num_options: int = 2, plan: "PlanSettings | None" = None, *,
                         max_candidates: int = MAX_CANDIDATES, seed: int = 0) -> Query:
    """The query, among the rich candidates, whose answer by the simulated designer leads to the
    re-plan of highest expected TRUE return (:func:`ird_core.designer.decision.oracle_values`):
    the headroom of one question, for experiments (it needs the true reward).

    Args:
        true_cells: ``(H, W)`` the TRUE per-cell reward of ``query_mdp``.
        designer_beta: the simulated designer's rationality, finite ``>= 0``.
        Others as :func:`propose_query`.
    """
    w, beta, num_options, seed = _check_query_arguments(query_mdp, samples, beta, num_options, seed)
    truth = check_array("true_cells", true_cells, (query_mdp.height, query_mdp.width))
    designer_beta = check_real("designer_beta", designer_beta, positive=False, ranged=False)
    cells, features, _ = _candidates(query_mdp, w, "oracle", plan or PlanSettings(), num_options, max_candidates,
                                     seed)
    returns = truth[cells[:, :, 0], cells[:, :, 1]].sum(axis=1)  # (n,)
    screen = decision.Screen(query_mdp, w, (plan or PlanSettings()).cell_rewards(query_mdp, w), cells[0])
    chosen, value = decision.best_query(
        lambda sets: decision.oracle_values(screen, features[sets], returns[sets], beta, truth, designer_beta),
        len(features), num_options)
    return _query(query_mdp, cells, features, chosen, beta * (features @ w.T), "oracle", value)


# --------------------------------------------------------------------------------------------
# Simulated designer
# --------------------------------------------------------------------------------------------


def answer_probabilities(option_returns: np.ndarray, beta: float) -> np.ndarray:
    """Boltzmann answer probabilities ``softmax(beta * returns)``; ``(q,) -> (q,)``."""
    returns = check_array("option_returns", option_returns, (None,))
    beta = check_real("beta", beta, positive=False, ranged=False)  # softmax is stable at any beta
    scores = beta * returns
    return np.exp(scores - logsumexp(scores))


def simulated_answer(option_returns: np.ndarray, beta: float, rng: np.random.Generator) -> int:
    """A designer's answer: option ``k`` with probability ``softmax(beta * option_returns)_k``.

    Args:
        option_returns: ``(q,)`` TRUE returns of the options.
        beta: the designer's own rationality, finite ``>= 0``.
        rng: the random generator (seeded by the caller).
    Returns:
        The chosen index in ``[0, q)``.
    """
    p = answer_probabilities(option_returns, beta)
    return int(np.searchsorted(np.cumsum(p), rng.random() * p.sum(), side="right").clip(0, len(p) - 1))


class SimulatedDesigner:
    """A seeded simulated designer: ``answer(option_returns)`` as ``simulated_answer`` with a
    generator ``numpy.random.default_rng(seed)`` owned by the designer."""

    def __init__(self, beta: float, seed: int) -> None:
        self.beta = check_real("beta", beta, positive=False, ranged=False)
        self.rng = np.random.default_rng(check_int("seed", seed, 0))

    def answer(self, option_returns: np.ndarray) -> int:
        return simulated_answer(option_returns, self.beta, self.rng)
