"""Decision-aware query criteria: what an answer is worth for the plan Rob will drive.

docs/spec.md section 7. All three criteria work on the posterior samples ``w_k`` (``K``, equal
weight) and a set of candidate paths (:mod:`ird_core.designer.candidates`), without new MCMC.

Expected value of the answer (``evoi``). For a query ``Q`` of options with feature counts
``f_a``, the robot's answer model gives ``p_k(a) = softmax_a(beta w_k . f_a)``, the predictive
probability ``P(a) = mean_k p_k(a)`` and the samples' weights after answer ``a``,
``omega^a_k = p_k(a) / sum_j p_j(a)``. ``xi_a`` is Rob's plan re-made with those weights: the
per-step weighted CVaR at ``alpha = 1/K`` of the baseline-shifted rewards (with uniform weights
exactly today's min; an answer that lowers a sample's weight below ``1/K`` lets the tail move on
to the next sample, which the weighted min would not). Then

    EVOI(Q) = sum_a P(a) sum_k omega^a_k w_k . (phi(xi_a) - phi(xi_0))
            = (1/K) sum_a sum_k p_k(a) w_k . (phi(xi_a) - phi(xi_0)),

the posterior-expected gain in return of the plan the answer leads to, ``xi_0`` the current plan
(the baselines cancel: both paths have ``T + 1`` cells). It is 0 when no answer moves the plan.

Maximum regret (``max_regret``, Wilde, Kulic and Smith 2020). Each candidate that is some
sample's own optimal path is owned by those samples; the mutual regret of candidates ``i, j`` is
``max_{k owns i} (R_k(xi_i) - R_k(xi_j)) + max_{l owns j} (R_l(xi_j) - R_l(xi_i))`` with
``R_k(xi) = w_k . phi(xi)``: the pair over which some plausible rewards disagree most.

The oracle query (``oracle_values``, experiments only) scores a query by the TRUE return of the
re-plan after each answer, weighted by the simulated designer's answer probabilities on the true
returns: an upper bound of what the screen can find with one question.

Queries of ``q > 2`` options: the best pair, then greedily the candidate that raises the score
most, as for information gain.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.special import log_softmax

from ird_core.mdp import GridMDP
from ird_core.mdp.optimal_paths import optimal_paths
from ird_core.planning.risk_measures import sort_columns, weighted_cvar_sorted

__all__ = ["Screen", "evoi_values", "evoi_bounds", "best_evoi_pair", "oracle_values", "mutual_regret", "best_query"]


class Screen:
    """Re-plans of Rob's per-step plan under re-weighted samples, for one query map.

    Args:
        mdp: the query MDP.
        samples: ``(K, d)``.
        cell_rewards: ``(K, H, W)`` the samples' baseline-shifted per-cell rewards.
        current: ``(T + 1, 2)`` Rob's current plan ``xi_0``.
    """

    def __init__(self, mdp: GridMDP, samples: np.ndarray, cell_rewards: np.ndarray, current: np.ndarray) -> None:
        self.mdp, self.samples = mdp, np.asarray(samples, dtype=np.float64)
        self.values = np.asarray(cell_rewards, dtype=np.float64).reshape(len(self.samples), -1)
        self.columns = sort_columns(self.values)  # once: every re-plan's CVaR reuses the order
        self.alpha = 1.0 / len(self.samples)
        self.current_features = mdp.features[current[:, 0], current[:, 1]].sum(axis=0)
        self.current_states = current[:, 0] * mdp.width + current[:, 1]  # (T + 1,) flat cells

    @classmethod
    def of_plan(cls, mdp: GridMDP, samples: np.ndarray, cell_rewards: np.ndarray) -> "Screen":
        """The screen of Rob's current per-step plan (the min of ``cell_rewards`` ``(K, H, W)``)."""
        current = optimal_paths(mdp, np.asarray(cell_rewards).min(axis=0)[None])[0]
        return cls(mdp, samples, cell_rewards, current)

    def replan(self, weights: np.ndarray, cell_values: "np.ndarray | None" = None) -> np.ndarray:
        """Feature counts ``(M, d)`` of the re-plans for sample weights ``(M, K)``; with
        ``cell_values`` ``(H, W)``, the re-plans' sums of those values ``(M,)`` instead."""
        shape = (self.mdp.height, self.mdp.width)
        table = self.mdp.features if cell_values is None else np.asarray(cell_values, dtype=np.float64)
        reward = weighted_cvar_sorted(self.columns, np.asarray(weights, dtype=np.float64), self.alpha)
        paths = optimal_paths(self.mdp, reward.reshape((-1,) + shape))
        return table[paths[:, :, 0], paths[:, :, 1]].sum(axis=1)


def _answer_logs(option_features: np.ndarray, samples: np.ndarray, beta: float) -> np.ndarray:
    """``log p_k(a)`` ``(n, K, q)`` for queries ``(n, q, d)``."""
    return log_softmax(beta * np.einsum("nqd,kd->nkq", option_features, samples, optimize=True), axis=2)


def _posterior_weights(log_p: np.ndarray) -> np.ndarray:
    """``omega^a`` ``(n, q, K)`` from ``log p_k(a)`` ``(n, K, q)``."""
    return np.exp(log_softmax(np.moveaxis(log_p, 1, 2), axis=2))


def evoi_values(screen: Screen, option_features: np.ndarray, beta: float) -> np.ndarray:
    """EVOI of each query (module docstring); ``(n, q, d) -> (n,)``."""
    n, q, _ = option_features.shape
    log_p = _answer_logs(option_features, screen.samples, beta)  # (n, K, q)
    replanned = screen.replan(_posterior_weights(log_p).reshape(n * q, -1)).reshape(n, q, -1)
    gain = np.einsum("nqd,kd->nqk", replanned - screen.current_features, screen.samples, optimize=True)
    return np.einsum("nkq,nqk->n", np.exp(log_p), gain, optimize=True) / len(screen.samples)


def evoi_bounds(screen: Screen, option_features: np.ndarray, beta: float) -> np.ndarray:
    """Upper bounds of :func:`evoi_values`, ``(n, q, d) -> (n,)``, from risk-neutral re-plans.

    After answer ``a`` no path beats, in posterior-mean return, the optimal path of the mean
    per-cell reward ``sum_k omega^a_k (w_k . F - b_k)`` (one DP, no sort), so
    ``EVOI <= sum_a P(a) (V*_a - V_a(xi_0))``.
    """
    n, q, _ = option_features.shape
    log_p = _answer_logs(option_features, screen.samples, beta)  # (n, K, q)
    weights = _posterior_weights(log_p).reshape(n * q, -1)
    mean = weights @ screen.values  # (n q, S)
    shape = (screen.mdp.height, screen.mdp.width)
    paths = optimal_paths(screen.mdp, mean.reshape((-1,) + shape))
    flat = paths[:, :, 0] * screen.mdp.width + paths[:, :, 1]
    best = np.take_along_axis(mean, flat, axis=1).sum(axis=1)
    current = mean[:, screen.current_states].sum(axis=1)
    return np.einsum("nq,nq->n", np.exp(log_p).mean(axis=1), (best - current).reshape(n, q))


def best_evoi_pair(screen: Screen, features: np.ndarray, beta: float, *, chunk: int = 64) -> tuple[list[int], float]:
    """The pair of candidates ``features`` ``(n, d)`` of largest EVOI, exactly as
    ``best_query(evoi_values ...)`` picks it (ties: the first pair in ``np.triu_indices`` order),
    by branch and bound: pairs in decreasing order of :func:`evoi_bounds`, ``chunk`` at a time,
    until no bound can reach the best value found."""
    first, second = np.triu_indices(len(features), 1)
    pairs = np.stack([first, second], axis=1)
    bounds = evoi_bounds(screen, features[pairs], beta)
    order = np.argsort(-bounds, kind="stable")
    values = np.full(len(pairs), -np.inf)
    best = -np.inf
    for lo in range(0, len(order), chunk):
        take = order[lo: lo + chunk]
        # Rounding margin: a bound within 1e-9 of the best may still tie it, so it is evaluated.
        take = take[bounds[take] >= best - 1e-9 * (1.0 + abs(best))]
        if not len(take):
            break
        values[take] = evoi_values(screen, features[pairs[take]], beta)
        best = max(best, float(values[take].max()))
    index = int(np.argmax(values))
    return [int(first[index]), int(second[index])], float(values[index])


def oracle_values(screen: Screen, option_features: np.ndarray, option_returns: np.ndarray, beta: float,
                  true_cells: np.ndarray, designer_beta: float) -> np.ndarray:
    """Expected TRUE return of the re-plan after the simulated designer's answer; ``(n,)``.

    Args:
        option_features: ``(n, q, d)``.
        option_returns: ``(n, q)`` the options' TRUE returns (the designer answers on them).
        beta: the robot's answer model (sets the re-weighting).
        true_cells: ``(H, W)`` the TRUE per-cell reward of the query map.
        designer_beta: the simulated designer's rationality on true returns.
    """
    n, q, _ = option_features.shape
    log_p = _answer_logs(option_features, screen.samples, beta)
    replanned = screen.replan(_posterior_weights(log_p).reshape(n * q, -1), true_cells).reshape(n, q)
    answers = np.exp(log_softmax(designer_beta * option_returns, axis=1))  # (n, q)
    return np.sum(answers * replanned, axis=1)


def mutual_regret(candidate_features: np.ndarray, samples: np.ndarray, sample_choice: np.ndarray) -> np.ndarray:
    """``(n, n)`` mutual regret of candidate pairs (module docstring); ``-inf`` where a candidate
    is nobody's own optimum.

    Args:
        candidate_features: ``(n, d)``.
        samples: ``(K, d)``.
        sample_choice: ``(K,)`` each sample's own optimal candidate (``-1``: none kept).
    """
    n = len(candidate_features)
    returns = samples @ candidate_features.T  # (K, n)
    owned = sample_choice >= 0
    regret = returns[owned, sample_choice[owned]][:, None] - returns[owned]  # (K', n)
    worst = np.full((n, n), -np.inf)
    np.maximum.at(worst, sample_choice[owned], regret)
    return worst + worst.T


def best_query(score: Callable[[np.ndarray], np.ndarray], num_candidates: int, num_options: int,
               pair: "tuple[list[int], float] | None" = None) -> tuple[list[int], float]:
    """The best pair of ``range(num_candidates)`` under ``score`` (index arrays ``(m, s)`` ->
    ``(m,)``), extended greedily to ``num_options``; ties go to the first in ``np.triu_indices``
    order. ``pair``: the best pair and its score, when already known (:func:`best_evoi_pair`).
    Returns the chosen indices and the set's score."""
    if pair is None:
        first, second = np.triu_indices(num_candidates, 1)
        values = score(np.stack([first, second], axis=1))
        best = int(np.argmax(values))
        pair = [int(first[best]), int(second[best])], float(values[best])
    chosen, value = pair
    while len(chosen) < num_options:
        rest = np.setdiff1d(np.arange(num_candidates), chosen)
        sets = np.concatenate([np.broadcast_to(chosen, (len(rest), len(chosen))), rest[:, None]], axis=1)
        values = score(sets)
        best = int(np.argmax(values))
        chosen, value = chosen + [int(rest[best])], float(values[best])
    return chosen, value
