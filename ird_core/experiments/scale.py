"""Where IRD goes wrong on robot-sized maps: the posterior's value of lava, where the plan
steps on it, and why it misses the target (docs/experiments.md, "Robot-sized maps"). Pure
numpy/scipy, no ROS.

One diagnosis (:func:`diagnose`) is one Lavaland trial's posterior and main IRD plan (the
experiments' own :func:`ird_core.experiments.trials.trial_posterior` and per-step planner, so a
diagnosis describes exactly the plans the experiments score), read three ways:

- **the posterior's value of lava**, per sample ``k``: ``v_k = w_k . (m_lava - m_dirt)``, where
  ``m_t`` is the mean test feature vector of the cells of terrain ``t`` (the class mean in the
  latent conditions, the indicator in the others). Its spread says how uncertain IRD still is
  about lava after the training evidence; ``share_below`` is the share of samples that value
  lava below dirt (the samples that make the per-step min avoid it). The true reward values
  lava 10.1 below dirt;
- **where the plan touches lava**: the lava steps and the distinct lava cells of the executed
  path, and whether the plan *parks* there (its last step is on lava: the per-step objective
  stays on the cell whose min over the samples is highest);
- **the lava cells' standing**: the best per-step min reward over lava cells against the best
  over safe cells (``lava_margin = best lava - best safe``; positive means some lava cell is the
  map's best parking spot for the risk-averse reward);
- **the target's standing** (:func:`target_signal`): how far the test target stands above the
  dirt cells in the posterior-mean reward, in units of the dirt cells' spread
  (``(mean over target cells - median over dirt cells) / sd over dirt cells`` of the per-cell
  mean reward over the samples the planner uses), beside the same number for the proxy on its
  own features. In the latent conditions the dirt cells' spread is observation noise, and the
  best of the about 150 dirt cells of a 15x15 map stands about 2.6 spreads above their median
  (the expected maximum of 150 normal draws): a target below that competes with the best noisy
  dirt cell even for a risk-neutral planner. ``target_margin`` is the best per-step min reward over
  target cells minus the best over the other safe cells (positive: the risk-averse reward's
  best parking spot is the target).

A diagnosis is a pure function of its spec (seeded like the trials), so a table of them
reproduces bit for bit.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ird_core import planning, posterior
from ird_core.experiments.trials import MAIN_BASELINE, MAIN_GRANULARITY, TrialSpec, trial_instance, trial_posterior
from ird_core.worlds import lavaland
from ird_core.worlds.terrain import SAFE_TERRAINS, Terrain

__all__ = ["ScaleDiagnosis", "terrain_mean_features", "lava_values", "target_signal", "diagnose", "DIAGNOSIS_COLUMNS"]


@dataclass(frozen=True)
class ScaleDiagnosis:
    """One trial's posterior value of lava and its main IRD plan's contact with lava."""

    condition: str
    seed: int
    size: int
    horizon: int
    beta: float
    method: str
    novelty_feature: bool  # the hypothesis features include "novel" (ird_core.hypothesis.novelty)
    lava_value_mean: float  # mean over samples of w . (m_lava - m_dirt)
    lava_value_sd: float  # its standard deviation over samples
    lava_value_min: float  # its minimum over samples
    share_below: float  # share of samples with w . (m_lava - m_dirt) < 0
    proxy_lava_value: float  # the proxy's own w~ . (m_lava - m_dirt), on the proxy's features
    lava_steps: int  # steps of the main IRD path on lava
    lava_cells: int  # distinct lava cells on it
    parked: bool  # its last step is on lava
    lava_margin: float  # best per-step min over lava cells minus best over safe cells
    target_signal: float  # posterior-mean target minus median dirt, in dirt sds (target_signal())
    proxy_target_signal: float  # the same for the proxy on its own features
    target_margin: float  # best per-step min over target cells minus best over the other safe cells
    reached_target: bool  # the main IRD path visits a target cell
    r_hat_max: float
    infer_seconds: float


#: The columns of a diagnosis table (:class:`ScaleDiagnosis`'s fields).
DIAGNOSIS_COLUMNS: tuple[str, ...] = tuple(ScaleDiagnosis.__dataclass_fields__)


def _cells_of(labels: np.ndarray, terrain: int) -> np.ndarray:
    """The ``(H, W)`` mask of the cells labelled ``terrain``; ``ValueError`` naming the terrain
    when the map has none."""
    mask = np.asarray(labels) == int(terrain)
    if not mask.any():
        raise ValueError(f"terrain: no cell of terrain {int(terrain)} on the map")
    return mask


def terrain_mean_features(features: np.ndarray, labels: np.ndarray, terrain: int) -> np.ndarray:
    """Mean feature vector of the cells labelled ``terrain``: ``(H, W, d), (H, W) -> (d,)``.

    Raises ``ValueError`` naming the terrain when the map has no such cell.
    """
    return np.asarray(features, dtype=np.float64)[_cells_of(labels, terrain)].mean(axis=0)


def lava_values(features: np.ndarray, labels: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Each weight's value of lava relative to dirt on this map, ``w . (m_lava - m_dirt)``.

    Args:
        features: ``(H, W, d)`` test features.
        labels: ``(H, W)`` terrain labels.
        weights: ``(K, d)``.
    Returns:
        ``(K,)``.
    """
    gap = terrain_mean_features(features, labels, Terrain.LAVA) - terrain_mean_features(features, labels, Terrain.DIRT)
    return np.atleast_2d(np.asarray(weights, dtype=np.float64)) @ gap


#: Relative difference below which rewards count as the same in :func:`target_signal`.
_SAME_REWARD: float = 1e-12


def target_signal(features: np.ndarray, labels: np.ndarray, weights: np.ndarray) -> float:
    """How far the target stands above dirt in the mean reward of ``weights``, in dirt spreads.

    ``r(s) = mean_k w_k . F[s]``; returns ``(mean of r over target cells - median over dirt
    cells) / sd over dirt cells``; ``+-inf`` (or NaN when equal) when every dirt cell has the same
    reward, as on indicator features (the same up to a relative ``_SAME_REWARD``: a matrix product
    may round identical rows differently).

    Args:
        features: ``(H, W, d)``; labels: ``(H, W)``; weights: ``(K, d)`` or ``(d,)``.
    Raises:
        ValueError naming the terrain when the map has no target or no dirt cell.
    """
    mean_weight = np.atleast_2d(np.asarray(weights, dtype=np.float64)).mean(axis=0)
    rewards = np.asarray(features, dtype=np.float64) @ mean_weight
    target, dirt = rewards[_cells_of(labels, Terrain.TARGET)], rewards[_cells_of(labels, Terrain.DIRT)]
    gap = float(target.mean() - np.median(dirt))
    spread = float(dirt.std())
    rounding = _SAME_REWARD * max(float(np.abs(dirt).max()), abs(gap))  # identical cells differ by rounding
    if spread > rounding:
        return gap / spread
    return math.copysign(math.inf, gap) if abs(gap) > rounding else math.nan


def diagnose(spec: TrialSpec, method: str) -> ScaleDiagnosis:
    """The diagnosis of ``spec``'s trial for one Z-approximation (``method``)."""
    inst = trial_instance(spec)
    test = lavaland.test_mdp(inst)
    start = time.perf_counter()
    post = trial_posterior(spec, inst, method)
    seconds = time.perf_counter() - start
    reference = posterior.proxy_feature_expectations(inst, spec.observation_model()) / (inst.train_horizon + 1)
    samples = spec.planning_samples(inst, post.samples)  # as the trial's IRD planner scales them
    plan = planning.plan_path(test, samples, MAIN_GRANULARITY, MAIN_BASELINE, reference, **spec.main_risk())
    labels = inst.test_labels
    values = lava_values(inst.test_features, labels, post.samples)
    proxy_value = float(lava_values(inst.proxy_test_features, labels, inst.proxy_weights)[0])
    on_lava = [labels[r, c] == Terrain.LAVA for r, c in plan.cells]
    step_reward = planning.per_step_reward(test, samples, MAIN_BASELINE, reference)
    lava = labels == Terrain.LAVA
    target = labels == Terrain.TARGET
    other_safe = np.isin(labels, [t for t in SAFE_TERRAINS if t != Terrain.TARGET])
    return ScaleDiagnosis(
        condition=spec.condition, seed=spec.seed, size=spec.size, horizon=spec.horizon, beta=spec.beta,
        method=method, novelty_feature=spec.novelty_feature, lava_value_mean=float(values.mean()),
        lava_value_sd=float(values.std()),
        lava_value_min=float(values.min()), share_below=float(np.mean(values < 0.0)),
        proxy_lava_value=proxy_value, lava_steps=int(sum(on_lava)),
        lava_cells=len({cell for cell, hit in zip(plan.cells, on_lava) if hit}), parked=bool(on_lava[-1]),
        lava_margin=float(step_reward[lava].max() - step_reward[~lava].max()),
        target_signal=target_signal(inst.test_features, labels, samples),
        proxy_target_signal=target_signal(inst.proxy_test_features, labels, inst.proxy_weights),
        target_margin=float(step_reward[target].max() - step_reward[other_safe].max()),
        reached_target=any(labels[r, c] == Terrain.TARGET for r, c in plan.cells),
        r_hat_max=float(post.r_hat_max), infer_seconds=seconds)
