"""Candidate options of a path query: the plans Rob might drive, not only the samples' own.

docs/spec.md section 7. A question can only change the plan if its options include the paths
the plan would move between, so the candidates are, in this order of priority:

1. ``plan``: Rob's current risk-averse plan (per step, the min over the samples, minus the
   baseline of :class:`PlanSettings`; ``ird_core.planning.plan_path``'s ``per_step`` plan).
2. ``risk``: the per-step plans at the other CVaR levels of :data:`RISK_LEVELS` (1 is the
   posterior mean: risk-neutral).
3. ``cluster``: the per-step min over each cluster of samples (k-means on the unit-normalised
   samples, seeded): the plan Rob would drive if an answer left only that cluster.
4. ``sample``: each sample's own optimal path (the literal plan of ``w_k``).
5. ``alternative``: for each distinct path of kinds 1-4, the best path under the reward that
   planned it that avoids every cell of that path except the start, then avoids those and the
   first alternative's cells, up to ``alternatives`` detours: routes on the other side of an
   obstacle, which no sample's optimum need contain; then, best first, every path that is
   optimal when one cell of such a path is avoided (the deviations of Yen's k-shortest-paths
   algorithm): small variations of each plan; and the plans of Rob's reward tilted towards or
   away from each feature, which move one feature count at a time.

Candidates are distinct by feature counts (the answer model sees only those) and keep the first
path of each in the order above; at most ``max_candidates`` are kept. Every plan is one exact DP
(``ird_core.mdp.optimal_paths``, ties broken as ``optimal_path``), batched over plans.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from scipy.cluster.vq import kmeans2

from ird_core.checks import check_array, check_int
from ird_core.mdp import GridMDP
from ird_core.mdp.optimal_paths import optimal_paths
from ird_core.planning import sample_cell_rewards
from ird_core.planning.risk_measures import weighted_cvar_batch
from ird_core.planning.sample_scale import normalise_samples
from ird_core.vocabulary import Baseline, parse

__all__ = ["RISK_LEVELS", "MAX_CANDIDATES", "PlanSettings", "Candidates", "query_candidates"]

#: CVaR levels of the ``risk`` candidates (the min is the ``plan`` candidate).
RISK_LEVELS: tuple[float, ...] = (0.05, 0.1, 0.25, 0.5, 1.0)
#: Default bound on the number of candidates (pair searches grow with its square).
MAX_CANDIDATES: int = 32
#: Largest number of candidates a caller may ask for.
CANDIDATE_LIMIT: int = 256


@dataclass(frozen=True, eq=False)
class PlanSettings:
    """How Rob plans on the query map: per step, the min over the samples of ``w_k . F - b_k``.

    Attributes:
        baseline: one of ``ird_core.vocabulary.BASELINES``.
        reference_features: ``(d,)`` for the ``training_features`` baseline, else ``None``.
        scale_features: the training map(s) (``(H, W, d)`` each) over which every sample is
            rescaled to span one unit before the min (``planning.sample_scale.normalise_samples``,
            as the experiments' and the planner node's IRD plans do), or ``None``: the samples as
            they are. A positive factor per sample: each sample's own ranking of paths is kept.
    """

    baseline: str = Baseline.NONE.value
    reference_features: "np.ndarray | None" = None
    scale_features: "np.ndarray | tuple[np.ndarray, ...] | None" = None

    def __post_init__(self) -> None:
        parse(Baseline, self.baseline, "baseline")

    def scaled(self, samples: np.ndarray) -> np.ndarray:
        """``(K, d)`` the samples Rob plans on: rescaled over ``scale_features``, or as they are."""
        return samples if self.scale_features is None else normalise_samples(samples, self.scale_features)

    def cell_rewards(self, mdp: GridMDP, samples: np.ndarray) -> np.ndarray:
        """``(K, H, W)`` baseline-shifted per-cell rewards of the (rescaled) samples."""
        return sample_cell_rewards(mdp, self.scaled(samples), self.baseline, self.reference_features)


class Candidates(NamedTuple):
    """Distinct candidate paths.

    Attributes:
        cells: ``(n, T + 1, 2)`` int64 ``(row, col)`` cells.
        features: ``(n, d)`` feature counts.
        sources: ``n`` kinds (``plan``, ``risk``, ``cluster``, ``sample``, ``alternative``).
        sample_choice: ``(K,)`` index of each sample's own optimal path among the candidates
            (-1 when it was cut by ``max_candidates``).
    """

    cells: np.ndarray
    features: np.ndarray
    sources: tuple[str, ...]
    sample_choice: np.ndarray


def _min_rewards(values: np.ndarray, groups: list[np.ndarray]) -> np.ndarray:
    """``(len(groups), S)``: the per-cell min over each group of sample rows of ``values (K, S)``."""
    return np.stack([values[g].min(axis=0) for g in groups]) if groups else np.empty((0, values.shape[1]))


def _clusters(samples: np.ndarray, count: int, seed: int) -> list[np.ndarray]:
    """Sample indices of each non-empty k-means cluster of the unit-normalised samples."""
    norms = np.linalg.norm(samples, axis=1, keepdims=True)
    unit = samples / np.where(norms > 0, norms, 1.0)
    if count < 2 or len(np.unique(unit, axis=0)) < 2 * count:
        return []  # too few distinct samples to split
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an empty cluster is dropped below
        _, labels = kmeans2(unit, count, minit="++", seed=np.random.default_rng(seed))
    return [np.flatnonzero(labels == c) for c in range(count) if np.any(labels == c)]


def _detours(mdp: GridMDP, rewards: np.ndarray, bases: np.ndarray, rounds: int) -> np.ndarray:
    """Best paths avoiding the cells of ``bases`` (and of earlier detours), ``rounds`` times.

    ``rewards`` ``(m, H, W)``, ``bases`` ``(m, T + 1, 2)``; returns ``(m * rounds, T + 1, 2)``.
    A forbidden cell costs more than any path's reward range, so a path avoiding them all wins
    whenever one exists (staying at the start always does).
    """
    out = []
    banned = np.zeros(rewards.shape, dtype=bool)
    rows = np.arange(len(bases))[:, None]
    current = bases
    penalty = (mdp.horizon + 2) * (float(np.ptp(rewards)) + 1.0)
    for _ in range(rounds):
        banned[rows, current[:, :, 0], current[:, :, 1]] = True
        banned[:, mdp.start[0], mdp.start[1]] = False
        current = optimal_paths(mdp, np.where(banned, rewards - penalty, rewards))
        out.append(current)
    return np.concatenate(out) if out else np.empty((0, mdp.horizon + 1, 2), dtype=np.int64)


def _tilts(mdp: GridMDP, reward: np.ndarray) -> np.ndarray:
    """Plans of ``reward`` ``(H, W)`` tilted towards and away from each feature: ``reward +/- s
    F[..., j]`` at two scales ``s`` (a quarter and twice the reward's spread per cell); each
    moves the path's count of feature ``j`` (``(4 d, T + 1, 2)``)."""
    spread = float(np.std(reward)) or 1.0
    features = np.moveaxis(mdp.features, 2, 0)  # (d, H, W)
    scale = np.array([0.25, -0.25, 2.0, -2.0])[:, None, None, None] * spread
    return optimal_paths(mdp, (reward + scale * features).reshape((-1,) + reward.shape))


def _deviations(mdp: GridMDP, rewards: np.ndarray, bases: np.ndarray) -> np.ndarray:
    """Yen-style deviations: for each base path and each of its cells but the start, the best
    path avoiding that one cell; ordered by reward (best first) across all bases.

    ``rewards`` ``(m, H, W)``, ``bases`` ``(m, T + 1, 2)``; returns ``(m * T, T + 1, 2)``.
    """
    m, horizon = len(bases), mdp.horizon
    penalty = (horizon + 2) * (float(np.ptp(rewards)) + 1.0)
    which = np.repeat(np.arange(m), horizon)
    cells = bases[:, 1:].reshape(-1, 2)
    banned = rewards[which].copy()
    banned[np.arange(len(which)), cells[:, 0], cells[:, 1]] -= penalty
    banned[:, mdp.start[0], mdp.start[1]] = rewards[which, mdp.start[0], mdp.start[1]]
    paths = optimal_paths(mdp, banned)
    value = banned[np.arange(len(which))[:, None], paths[:, :, 0], paths[:, :, 1]].sum(axis=1)
    return paths[np.argsort(-value, kind="stable")]


def query_candidates(mdp: GridMDP, samples: np.ndarray, plan: PlanSettings = PlanSettings(), *,
                     max_candidates: int = MAX_CANDIDATES, clusters: int = 6, alternatives: int = 2,
                     seed: int = 0) -> Candidates:
    """The distinct candidate paths of the module docstring, in its order of priority.

    Args:
        mdp: the query MDP ``(H, W, d)``.
        samples: ``(K, d)`` posterior samples.
        plan: Rob's plan settings (baseline).
        max_candidates: keep at most this many, in ``[2, CANDIDATE_LIMIT]``.
        clusters: k-means clusters of samples (``< 2``: none).
        alternatives: detours per distinct base path (``0``: none).
        seed: seeds the clustering.
    Raises:
        ValueError: naming the field of a bad argument.
    """
    w = check_array("samples", samples, (None, mdp.num_features))
    max_candidates = check_int("max_candidates", max_candidates, 2)
    if max_candidates > CANDIDATE_LIMIT:
        raise ValueError(f"max_candidates: at most {CANDIDATE_LIMIT}, got {max_candidates}")
    clusters = check_int("clusters", clusters, 0)
    alternatives = check_int("alternatives", alternatives, 0)
    if alternatives > 8:
        raise ValueError(f"alternatives: at most 8, got {alternatives}")
    seed = check_int("seed", seed, 0)
    k, shape = len(w), (mdp.height, mdp.width)
    values = plan.cell_rewards(mdp, w).reshape(k, -1)  # (K, S)
    averse = np.concatenate([
        values.min(axis=0)[None],
        np.concatenate([weighted_cvar_batch(values, np.full((1, k), 1.0 / k), a) for a in RISK_LEVELS]),
        _min_rewards(values, _clusters(w, clusters, seed)),
    ]).reshape((-1,) + shape)
    kinds = ["plan"] + ["risk"] * len(RISK_LEVELS)
    kinds += ["cluster"] * (len(averse) - len(kinds))
    averse_paths = optimal_paths(mdp, averse)
    own_paths = optimal_paths(mdp, values.reshape((k,) + shape))
    base = np.concatenate([averse_paths, own_paths])
    kinds += ["sample"] * k
    # Detours of every distinct base path, each under the reward that planned it.
    _, distinct = np.unique(mdp.features[base[:, :, 0], base[:, :, 1]].sum(axis=1), axis=0, return_index=True)
    distinct = np.sort(distinct)
    base_rewards = np.concatenate([averse, values.reshape((k,) + shape)])[distinct]
    detours = np.concatenate([_detours(mdp, base_rewards, base[distinct], alternatives),
                              _tilts(mdp, averse[0]) if alternatives else base[:0],
                              _deviations(mdp, base_rewards, base[distinct]) if alternatives else base[:0]])
    cells = np.concatenate([base, detours])
    kinds += ["alternative"] * len(detours)
    features = mdp.features[cells[:, :, 0], cells[:, :, 1]].sum(axis=1)
    _, first, inverse = np.unique(features, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")[:max_candidates]
    rank = np.full(len(first), -1)
    rank[order] = np.arange(len(order))
    keep = first[order]
    choice = rank[inverse.reshape(-1)[len(averse): len(averse) + k]]
    return Candidates(cells[keep], features[keep], tuple(kinds[i] for i in keep), choice)
