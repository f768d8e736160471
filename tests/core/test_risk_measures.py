"""Risk measures over posterior samples and the plans that maximise them, against their
definitions and brute-force enumeration of every trajectory on tiny grids."""

from __future__ import annotations

import numpy as np
import pytest

from ird_core.mdp import GridMDP
from ird_core.mdp.enumeration import all_trajectories
from ird_core.planning import path_objective, plan_path
from ird_core.planning.novelty import novel_cells, novelty_avoiding_path
from ird_core.planning.risk_measures import check_risk, check_sample_weights, risk_statistic


def rockafellar_uryasev(values: np.ndarray, p: np.ndarray, alpha: float) -> float:
    """``max_z z - E[(z - R)^+] / alpha``; the maximum is attained at one of the values."""
    return max(z - float(np.sum(p * np.maximum(z - values, 0.0))) / alpha for z in values)


@pytest.mark.parametrize("seed", range(20))
def test_cvar_is_the_rockafellar_uryasev_optimum(seed: int) -> None:
    rng = np.random.default_rng(seed)
    k = int(rng.integers(1, 12))
    values = rng.integers(-3, 4, k).astype(float) if seed % 2 else rng.normal(size=k)  # ties when integer
    p = rng.random(k)
    p /= p.sum()
    for alpha in (0.05, 0.2, 0.5, 0.9, 1.0):
        got = risk_statistic(values[:, None], check_risk("cvar", alpha), check_sample_weights(p, k))[0]
        assert got == pytest.approx(rockafellar_uryasev(values, p, alpha), rel=1e-12, abs=1e-12)
        uniform = risk_statistic(values[:, None], check_risk("cvar", alpha))[0]
        assert uniform == pytest.approx(rockafellar_uryasev(values, np.full(k, 1 / k), alpha), rel=1e-12, abs=1e-12)


def test_cvar_ends_are_the_min_exactly_and_the_mean() -> None:
    rng = np.random.default_rng(0)
    values = rng.normal(size=(64, 5, 6))
    np.testing.assert_array_equal(risk_statistic(values, check_risk("cvar", 1 / 64)), values.min(axis=0))
    np.testing.assert_allclose(risk_statistic(values, check_risk("cvar", 1.0)), values.mean(axis=0), rtol=1e-12)


def test_cvar_is_monotone_in_alpha_and_mean_sd_in_lambda() -> None:
    values = np.random.default_rng(1).normal(size=(40, 50))
    cvars = [risk_statistic(values, check_risk("cvar", a)) for a in (0.05, 0.1, 0.3, 0.7, 1.0)]
    assert all(np.all(a <= b + 1e-12) for a, b in zip(cvars, cvars[1:]))
    sds = [risk_statistic(values, check_risk("mean_sd", lam)) for lam in (3.0, 1.0, 0.0)]
    assert all(np.all(a <= b) for a, b in zip(sds, sds[1:]))
    np.testing.assert_allclose(sds[1], values.mean(0) - values.std(0), rtol=1e-12)


def test_risk_measures_are_translation_equivariant() -> None:
    values = np.random.default_rng(2).normal(size=(30, 7))
    for risk in (check_risk("min"), check_risk("cvar", 0.3), check_risk("mean_sd", 1.5)):
        np.testing.assert_allclose(risk_statistic(values + 4.0, risk), risk_statistic(values, risk) + 4.0, rtol=1e-12)


def test_zero_probability_samples_never_set_the_min() -> None:
    values = np.array([[-100.0], [1.0], [2.0]])
    p = check_sample_weights([0.0, 0.5, 0.5], 3)
    assert risk_statistic(values, check_risk("min"), p)[0] == 1.0
    assert risk_statistic(values, check_risk("cvar", 0.5), p)[0] == 1.0


@pytest.mark.parametrize("measure, level, field", [
    ("cvar", 0.0, "risk_level"), ("cvar", 1.5, "risk_level"), ("cvar", None, "risk_level"),
    ("mean_sd", -1.0, "risk_level"), ("mean_sd", float("inf"), "risk_level"), ("min", 0.5, "risk_level"),
    ("worst", None, "risk")])
def test_bad_risk_arguments_are_refused_by_name(measure: str, level: object, field: str) -> None:
    with pytest.raises(ValueError, match=f"^{field}:"):
        check_risk(measure, level)


def test_bad_sample_weights_are_refused_by_name() -> None:
    for bad in ([0.5, 0.6], [1.0], [np.nan, 1.0], [-0.5, 1.5]):
        with pytest.raises(ValueError, match="^sample_weights:"):
            check_sample_weights(bad, 2)


def tiny(seed: int) -> tuple[GridMDP, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    h, w = (int(x) for x in rng.integers(1, 4, 2))
    d = 3
    mdp = GridMDP(rng.normal(size=(h, w, d)), (int(rng.integers(h)), int(rng.integers(w))), int(rng.integers(1, 5)))
    p = rng.random(6)
    return mdp, rng.normal(size=(6, d)), p / p.sum()


CASES = [("per_step", "cvar", 0.3), ("per_step", "cvar", 1.0), ("per_step", "mean_sd", 1.0),
         ("per_step", "mean_sd", 0.0), ("trajectory", "cvar", 0.3), ("trajectory", "cvar", 1.0),
         ("trajectory", "cvar", 1 / 6)]


@pytest.mark.parametrize("weighted", [False, True])
@pytest.mark.parametrize("mode, measure, level", CASES)
@pytest.mark.parametrize("seed", range(8))
def test_risk_averse_plans_are_brute_force_optima(seed: int, mode: str, measure: str, level: float,
                                                  weighted: bool) -> None:
    mdp, weights, p = tiny(seed)
    kw = dict(risk=measure, risk_level=level, sample_weights=p if weighted else None)
    plan = plan_path(mdp, weights, mode, "initial_state", **kw)
    best = max(path_objective(mdp, np.stack(np.divmod(t, mdp.width), axis=1), weights, mode, "initial_state", **kw)
               for t in all_trajectories(mdp))
    assert plan.objective == pytest.approx(best, rel=1e-7, abs=1e-7)
    assert plan.risk == check_risk(measure, level)


@pytest.mark.parametrize("seed", range(6))
def test_cvar_at_one_over_k_plans_like_the_min(seed: int) -> None:
    mdp, weights, _ = tiny(seed)
    for mode in ("per_step", "trajectory"):
        a = plan_path(mdp, weights, mode, "none")
        b = plan_path(mdp, weights, mode, "none", risk="cvar", risk_level=1 / len(weights))
        assert a.objective == pytest.approx(b.objective, rel=1e-9, abs=1e-9)


def test_mean_sd_per_trajectory_is_refused_naming_the_risk() -> None:
    mdp, weights, _ = tiny(0)
    with pytest.raises(ValueError, match="^risk: mean_sd is a per_step"):
        plan_path(mdp, weights, "trajectory", "none", risk="mean_sd", risk_level=1.0)


def test_a_test_map_equal_to_training_has_no_novel_cell_and_a_far_cell_is_novel() -> None:
    rng = np.random.default_rng(0)
    train = rng.normal(size=(6, 6, 5))
    assert not novel_cells(train, train).any()
    test = train.copy()
    test[2, 3] += 50.0
    novel = novel_cells([train], test)
    assert novel[2, 3] and novel.sum() == 1


def test_the_novelty_planner_keeps_off_novel_cells_it_can_avoid() -> None:
    features = np.zeros((1, 5, 2))
    features[0, :, 0] = [0, 0, 1, 2, 5]  # the proxy likes feature 0; the last cell has it most
    features[0, 4, 1] = 9.0  # ... and is unlike any training cell
    mdp = GridMDP(features, (0, 0), 6)
    novel = np.zeros((1, 5), dtype=bool)
    novel[0, 4] = True
    cells = novelty_avoiding_path(mdp, np.array([1.0, 0.0]), novel)
    assert (0, 4) not in cells and (0, 3) in cells
