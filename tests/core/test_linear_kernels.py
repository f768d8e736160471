"""The compiled engine of the linear-space passes (``ird_core.mdp.linear_kernels``) against the numpy
loops it replaces: bit for bit, on every output the passes have (log Z, visits, the underflow
flags), on batches that take the rescaling and the exact fallback paths, and end to end on a
seeded posterior. Also ``likelihoods.logsumexp_rows`` against scipy and the work-array cache.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections import OrderedDict

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.special import logsumexp

from ird_core import mdp, posterior
from ird_core.mdp import linear_kernels, linear_passes
from ird_core.posterior.likelihoods import logsumexp_rows
from ird_core.worlds import lavaland

pytestmark = pytest.mark.skipif(not linear_kernels.available(), reason="numba is pinned in requirements.txt")


def _outputs(engine: str, monkeypatch: pytest.MonkeyPatch, grid: mdp.GridMDP, weights: np.ndarray
             ) -> list[np.ndarray]:
    """Every output of both passes and of the public functions, under one engine."""
    monkeypatch.setenv("IRD_ENGINE", engine)
    rewards = mdp.cell_rewards(grid, weights)
    back = linear_passes.linear_backward(grid, rewards)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        visits, unsure = linear_passes.linear_visitation(grid, back)
    short = linear_passes.linear_backward(grid, rewards, keep_sums=False)
    out = [back.exp_rewards.copy(), back.log_z, back.suspect, visits.copy(), unsure, short.log_z, short.suspect]
    out += [mdp.log_partition(grid, weights), *mdp.log_partition_and_feature_expectations(grid, weights)]
    return out


def _assert_same(first: list[np.ndarray], second: list[np.ndarray]) -> None:
    for i, (a, b) in enumerate(zip(first, second)):
        assert a.shape == b.shape and np.array_equal(a, b, equal_nan=True), f"output {i} differs"


@st.composite
def _batches(draw: st.DrawFn) -> tuple[mdp.GridMDP, np.ndarray]:
    height, width = draw(st.integers(1, 7)), draw(st.integers(1, 7))
    horizon = draw(st.one_of(st.integers(1, 40), st.sampled_from([255, 256, 257, 520])))
    dim, num = draw(st.integers(1, 4)), draw(st.integers(1, 9))
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    # Up to hundreds of nats per cell: the fast path flags those and mdp recomputes them exactly.
    scale = draw(st.sampled_from([0.01, 1.0, 10.0, 300.0]))
    start = (draw(st.integers(0, height - 1)), draw(st.integers(0, width - 1)))
    grid = mdp.GridMDP(rng.standard_normal((height, width, dim)), start, horizon)
    return grid, scale * rng.standard_normal((num, dim))


@settings(max_examples=60, deadline=None)
@given(batch=_batches())
def test_compiled_passes_are_bit_for_bit_the_numpy_loops(batch: tuple[mdp.GridMDP, np.ndarray]) -> None:
    grid, weights = batch
    with pytest.MonkeyPatch.context() as monkeypatch:
        _assert_same(_outputs("numpy", monkeypatch, grid, weights), _outputs("numba", monkeypatch, grid, weights))


def test_the_equality_covers_rescaling_and_flagged_elements(monkeypatch: pytest.MonkeyPatch) -> None:
    """The property above is not vacuous: some batches rescale (T > 256) and some are flagged."""
    rng = np.random.default_rng(3)
    grid = mdp.GridMDP(rng.standard_normal((4, 5, 2)), (1, 2), 300)
    weights = np.array([[0.3, -0.2], [400.0, -300.0]])
    numpy_out = _outputs("numpy", monkeypatch, grid, weights)
    assert numpy_out[2].tolist() == [False, True]  # the second element underflows: flagged
    _assert_same(numpy_out, _outputs("numba", monkeypatch, grid, weights))


def test_the_experiments_sizes_agree_bit_for_bit(monkeypatch: pytest.MonkeyPatch) -> None:
    inst = lavaland.make_instance("latent_raw", 0, size=15, horizon=30, obs_dim=50)
    grid = posterior.proxy_observations(inst, None, 0, 1.0)[0].train_mdp
    weights = np.random.default_rng(0).standard_normal((8, grid.num_features)) * 0.3
    _assert_same(_outputs("numpy", monkeypatch, grid, weights), _outputs("numba", monkeypatch, grid, weights))


@pytest.mark.filterwarnings("ignore:sample_joint_posterior")  # a short run: only equality matters
def test_a_seeded_posterior_draws_the_same_samples_with_either_engine(monkeypatch: pytest.MonkeyPatch) -> None:
    inst = lavaland.make_instance("latent_raw", 2, size=8, horizon=12, obs_dim=10)
    observations = posterior.proxy_observations(inst, 100, 7, 1.0)
    draws = {}
    for engine in ("numpy", "numba"):
        monkeypatch.setenv("IRD_ENGINE", engine)
        post = posterior.sample_joint_posterior(observations, 50.0, "sample_z", 16, 11, num_chains=2, warmup=20,
                                                thin=1, max_leapfrog=8)
        draws[engine] = post.samples
    assert np.array_equal(draws["numpy"], draws["numba"])


def test_engine_reads_ird_engine(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("IRD_ENGINE", "numpy")
    assert linear_kernels.engine() == "numpy"
    monkeypatch.setenv("IRD_ENGINE", " NUMBA ")
    assert linear_kernels.engine() == "numba"
    monkeypatch.delenv("IRD_ENGINE")
    assert linear_kernels.engine() == "numba"  # auto: numba when installed
    monkeypatch.setenv("IRD_ENGINE", "fortran")
    with pytest.raises(ValueError, match="IRD_ENGINE"):
        linear_kernels.engine()


def test_engine_numba_without_numba_is_an_error(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(linear_kernels, "available", lambda: False)
    monkeypatch.setattr(linear_kernels, "_ENGINE_BY_VALUE", {})
    monkeypatch.setenv("IRD_ENGINE", "numba")
    with pytest.raises(ValueError, match="IRD_ENGINE.*not installed"):
        linear_kernels.engine()
    monkeypatch.setenv("IRD_ENGINE", "auto")
    assert linear_kernels.engine() == "numpy"


@settings(max_examples=200, deadline=None)
@given(rows=st.integers(1, 5), cols=st.integers(1, 1200), seed=st.integers(0, 2**32 - 1),
       log_scale=st.floats(-3, 4), ties=st.integers(0, 3), rounded=st.booleans())
def test_logsumexp_rows_is_scipys_bit_for_bit(rows: int, cols: int, seed: int, log_scale: float, ties: int,
                                              rounded: bool) -> None:
    rng = np.random.default_rng(seed)
    scores = rng.standard_normal((rows, cols)) * 10.0**log_scale
    for _ in range(ties):  # several maxima: scipy divides the rest by their count
        scores[:, rng.integers(cols)] = scores.max(axis=1)
    if rounded:
        scores = np.round(scores)
    assert np.array_equal(logsumexp_rows(scores), logsumexp(scores, axis=1))


def test_work_arrays_are_dropped_least_recently_used_first(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(linear_passes, "_WORK_BYTES", 3 * 8 * 10 * linear_passes._layout(4, 3, 3).size)
    monkeypatch.setattr(linear_passes._SCRATCH, "arrays", OrderedDict(), raising=False)
    first = linear_passes._work("a", 10, linear_passes._layout(4, 3, 3))
    second = linear_passes._work("b", 10, linear_passes._layout(4, 3, 3))
    assert linear_passes._work("a", 10, linear_passes._layout(4, 3, 3)) is first  # reused, now most recent
    linear_passes._work("c", 10, linear_passes._layout(4, 3, 3))
    linear_passes._work("d", 10, linear_passes._layout(4, 3, 3))  # over the budget: drops "b" only
    assert linear_passes._work("a", 10, linear_passes._layout(4, 3, 3)) is first
    assert linear_passes._work("b", 10, linear_passes._layout(4, 3, 3)) is not second


def test_warm_up_loads_every_kernel_signature_a_real_pass_uses() -> None:
    """After ``mdp.warm_up()`` a sampler-sized pass compiles nothing new: the worker pools call it
    at start-up so that a node's first request does not pay for numba. In a fresh process, since
    this one has compiled the kernels already."""
    script = (
        "import numpy as np\n"
        "from ird_core import mdp\n"
        "from ird_core.mdp import linear_kernels\n"
        "mdp.warm_up()\n"
        "counts = lambda: [len(k.signatures) for k in linear_kernels.compiled()]\n"
        "before = counts()\n"
        "grid = mdp.GridMDP(np.random.default_rng(0).standard_normal((15, 15, 50)), (3, 4), 30)\n"
        "w = np.random.default_rng(1).standard_normal((8, 50)) * 0.3\n"
        "mdp.log_partition_and_feature_expectations(grid, w)\n"
        "mdp.log_partition(grid, w)\n"
        "print(before, counts())\n")
    env = {**os.environ, "IRD_ENGINE": "numba"}
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    before, after = out.stdout.strip().split("] [")
    assert "0" not in before.strip("[").split(", "), out.stdout
    assert before.strip("[") == after.strip("]"), out.stdout
