"""The trajectory solver's deterministic work limit (``work_limit``, label expansions).

Properties: a plan finishes exactly when the work it needs is within the limit, and then it is
the unlimited plan; a stopped plan carries a legal path, its exact objective and a bound that
is at least the brute-force optimum; under a work limit alone the clock is never read, so the
outcome is a function of the inputs; the MILP (no deterministic running time) is never used.
"""

from __future__ import annotations

import types
from collections.abc import Callable

import numpy as np
import pytest
import scipy.optimize
from test_planning import brute_values, value_of

from ird_core import planning as P
from ird_core.mdp import GridMDP, validate_path
from ird_core.planning import trajectory_limits, trajectory_milp
from ird_core.planning import trajectory_solver as TS
from ird_core.worlds import lavaland

SHAPES = [(3, 3), (2, 4), (3, 4)]


def search_case(seed: int) -> tuple[GridMDP, np.ndarray]:
    """Small enough to enumerate (T = 6), big enough that the label search has work to do."""
    rng = np.random.default_rng(seed)
    height, width = SHAPES[seed % len(SHAPES)]
    features = rng.normal(size=(height, width, 3))
    weights = rng.normal(size=(6, 3))
    return GridMDP(features, (int(rng.integers(height)), int(rng.integers(width))), 6), weights


def work_needed(monkeypatch: pytest.MonkeyPatch, plan: Callable[[], P.Plan]) -> tuple[P.Plan, int]:
    """The plan with no work limit, and the label expansions it spent."""
    made: list[TS.Limits] = []

    class Recording(TS.Limits):
        def __init__(self, *args, **kwargs) -> None:  # type: ignore[no-untyped-def]
            super().__init__(*args, **kwargs)
            made.append(self)

    with monkeypatch.context() as patch:
        patch.setattr(TS, "Limits", Recording)
        result = plan()
    assert len(made) == 1
    return result, made[0].work


def outcome(call: Callable[[], P.Plan]) -> tuple:
    """Everything a caller sees: the plan, or the timeout's plan and reason."""
    try:
        return ("plan", call(), None)
    except P.PlanningTimeout as exc:
        return ("timeout", exc.plan, exc.reason)


def optimum(mdp: GridMDP, weights: np.ndarray) -> float:
    return float(brute_values(mdp, weights, "trajectory", np.zeros(len(weights)))[1].max())


@pytest.mark.parametrize("seed", range(12))
def test_a_plan_finishes_exactly_when_its_work_fits_the_limit(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    mdp, weights = search_case(seed)
    unlimited, needed = work_needed(monkeypatch, lambda: P.plan_path(mdp, weights, "trajectory"))
    assert needed > 1  # the label search ran (else the limit is never checked)
    assert close_to_optimum(unlimited.objective, optimum(mdp, weights))
    for limit in (needed, needed + 1, 10**12):  # enough work: exactly the unlimited plan
        assert P.plan_path(mdp, weights, "trajectory", work_limit=limit) == unlimited
    with pytest.raises(P.PlanningTimeout) as info:
        P.plan_path(mdp, weights, "trajectory", work_limit=needed - 1)
    assert info.value.reason == "work"
    assert str(info.value).startswith(f"work_limit: {needed - 1}: work limit reached after ")


def close_to_optimum(value: float, best: float) -> bool:
    return abs(value - best) <= 1e-9 * max(1.0, abs(best))


@pytest.mark.parametrize("seed", range(12))
def test_a_stopped_plan_is_legal_and_its_bound_holds_the_optimum(seed: int,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    mdp, weights = search_case(seed)
    _, needed = work_needed(monkeypatch, lambda: P.plan_path(mdp, weights, "trajectory"))
    best = optimum(mdp, weights)
    for limit in sorted({1, max(1, needed // 3), max(1, needed - 1)}):
        for solver in (None, "label-bb"):
            with pytest.raises(P.PlanningTimeout) as info:
                P.plan_path(mdp, weights, "trajectory", solver=solver, work_limit=limit)
            plan = info.value.plan
            validate_path(mdp, plan.cells)
            assert plan.cells[0] == mdp.start
            true_value = value_of(mdp, weights, "trajectory", np.zeros(len(weights)), plan.cells)
            assert close_to_optimum(plan.objective, true_value)
            assert true_value <= best + 1e-9 and true_value <= plan.bound
            assert plan.bound >= best - 1e-9 * max(1.0, abs(best))
            assert (info.value.reason, plan.solver) == ("work", "label-bb")


def jumping_clock(calls: list[float]) -> types.SimpleNamespace:
    """A ``time`` stand-in whose ``monotonic()`` jumps an hour at every call."""
    def monotonic() -> float:
        calls.append(3600.0 * (len(calls) + 1))
        return calls[-1]
    return types.SimpleNamespace(monotonic=monotonic)


def paper_scale_case() -> tuple[GridMDP, np.ndarray]:
    inst = lavaland.make_instance("latent_raw", 0, size=15, horizon=30, obs_dim=50)
    weights = np.random.default_rng(0).normal(size=(16, inst.test_features.shape[2]))
    return GridMDP(inst.test_features.astype(np.float64), inst.test_start, inst.test_horizon), weights


@pytest.mark.parametrize("case,limits", [
    ("search", (1, 50, 400, 10**9)),
    ("paper", (1, 5_000, 60_000)),
])
def test_under_a_work_limit_alone_the_clock_is_never_read(case: str, limits: tuple[int, ...],
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    cases = [search_case(seed) for seed in range(4)] if case == "search" else [paper_scale_case()]
    kinds = set()
    for mdp, weights in cases:
        for limit in limits:
            for baseline in ("none", "log_z"):
                def call() -> P.Plan:
                    return P.plan_path(mdp, weights, "trajectory", baseline, work_limit=limit)
                real = outcome(call)
                calls: list[float] = []
                with monkeypatch.context() as patch:
                    for module in (trajectory_limits, trajectory_milp):
                        patch.setattr(module, "time", jumping_clock(calls))
                    jumped = outcome(call)
                assert jumped == real
                assert calls == []
                kinds.add(real[0])
    assert kinds == ({"plan", "timeout"} if case == "search" else {"timeout"})


def test_the_clock_still_rules_when_a_time_limit_is_given(monkeypatch: pytest.MonkeyPatch) -> None:
    # The jumping clock passes any deadline at its next reading: the time limit, not the
    # (generous) work limit, stops the plan, and says so.
    mdp, weights = search_case(0)
    with monkeypatch.context() as patch:
        clock = jumping_clock([])
        for module in (trajectory_limits, trajectory_milp):
            patch.setattr(module, "time", clock)
        with pytest.raises(P.PlanningTimeout) as info:
            P.plan_path(mdp, weights, "trajectory", time_limit=60.0, work_limit=10**12)
    assert info.value.reason == "time"
    assert str(info.value).startswith("time_limit: 60.0 s passed")
    with pytest.raises(P.PlanningTimeout) as info:  # and the work limit when it comes first
        P.plan_path(mdp, weights, "trajectory", time_limit=3600.0, work_limit=1)
    assert info.value.reason == "work"


@pytest.mark.parametrize("seed", range(6))
def test_the_milp_is_never_run_under_a_work_limit(seed: int, monkeypatch: pytest.MonkeyPatch) -> None:
    # A tiny label memory budget makes the automatic choice fall back on the MILP; under a work
    # limit it must stop with the best path instead.
    mdp, weights = search_case(seed)
    ran: list[str] = []

    def refuse(*args, **kwargs):  # type: ignore[no-untyped-def]
        ran.append("milp")
        raise AssertionError("the MILP ran")

    monkeypatch.setattr(TS, "_LABEL_BUDGET", 10 * len(weights))
    monkeypatch.setattr(scipy.optimize, "milp", refuse)  # trajectory_milp imports it when it solves
    with pytest.raises(AssertionError):  # the patch does catch the fallback ...
        P.plan_path(mdp, weights, "trajectory")
    assert ran == ["milp"]
    monkeypatch.setattr(trajectory_milp, "_run_highs", refuse)
    with pytest.raises(P.PlanningTimeout) as info:  # ... which a work limit turns off
        P.plan_path(mdp, weights, "trajectory", work_limit=10**12)
    assert ran == ["milp"]
    assert info.value.reason == "work" and "memory budget" in str(info.value)
    plan = info.value.plan
    best = optimum(mdp, weights)
    assert plan.objective == P.path_objective(mdp, plan.cells, weights, "trajectory")
    assert plan.objective <= plan.bound and plan.bound >= best - 1e-9 * max(1.0, abs(best))


@pytest.mark.parametrize("bad", [0, -3, True, False, 1.5, 2.0, "10", np.float64(4.0)])
def test_bad_work_limits_are_refused_naming_work_limit(bad: object) -> None:
    mdp, weights = search_case(0)
    with pytest.raises(ValueError, match="^work_limit: expected an int >= 1"):
        P.check_plan_arguments("trajectory", "none", work_limit=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="^work_limit: expected an int >= 1"):
        P.plan_path(mdp, weights, "trajectory", work_limit=bad)  # type: ignore[arg-type]


def test_work_limit_is_refused_with_the_milp_solver() -> None:
    mdp, weights = search_case(0)
    with pytest.raises(ValueError, match="^work_limit: not supported by solver='milp-highs'"):
        P.check_plan_arguments("trajectory", "none", solver="milp-highs", work_limit=10)
    with pytest.raises(ValueError, match="^work_limit: not supported by solver='milp-highs'"):
        P.plan_path(mdp, weights, "trajectory", solver="milp-highs", work_limit=10)
    q = weights @ mdp.features.reshape(-1, 3).T
    with pytest.raises(ValueError, match="^work_limit:"):
        TS.plan_trajectory(mdp, q.reshape(6, *mdp.features.shape[:2]), solver="milp-highs", time_limit=None,
                           work_limit=10)


def test_numpy_integer_work_limits_are_accepted(monkeypatch: pytest.MonkeyPatch) -> None:
    mdp, weights = search_case(1)
    _, needed = work_needed(monkeypatch, lambda: P.plan_path(mdp, weights, "trajectory"))
    assert P.plan_path(mdp, weights, "trajectory", work_limit=np.int64(needed)) == \
        P.plan_path(mdp, weights, "trajectory", work_limit=needed)
