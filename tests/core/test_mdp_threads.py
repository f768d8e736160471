"""IRD_THREADS: the passes' chunks on threads give the same numbers bit for bit as on one thread."""

from __future__ import annotations

import multiprocessing
import os

import numpy as np
import pytest

from ird_core import mdp as M
from ird_core.mdp import passes, threads


def chunked_problem() -> tuple[M.GridMDP, np.ndarray]:
    rng = np.random.default_rng(5)
    mdp = M.GridMDP(rng.normal(size=(9, 8, 4)), (4, 3), 25)
    # Ordinary weights and a few huge ones (flagged: recomputed by the exact passes).
    scales = np.array([1.0, 0.5, 2.0, 1.0, 600.0, 900.0, 1.0, 0.1, 3.0, 1.5, 1200.0, 800.0])
    return mdp, rng.normal(size=(len(scales), 4)) * scales[:, None]


@pytest.mark.parametrize("engine", ["numpy", "numba"])
def test_threads_give_the_single_thread_numbers_bit_for_bit(monkeypatch, engine: str) -> None:
    if engine == "numba":
        pytest.importorskip("numba")
    monkeypatch.setenv("IRD_ENGINE", engine)
    mdp, weights = chunked_problem()
    per_weight = 2 * 8 * (mdp.horizon + 1) * (mdp.height + 1) * (mdp.width + 1)
    monkeypatch.setattr(passes, "_CHUNK_BYTES", 2 * per_weight)  # six fast-path chunks
    monkeypatch.setattr(passes, "_EXACT_CHUNK_BYTES", 8 * (mdp.horizon + 1) * mdp.height * mdp.width)
    results = {}
    for count in ("1", "2", "3"):
        monkeypatch.setenv("IRD_THREADS", count)
        results[count] = (*M.log_partition_and_feature_expectations(mdp, weights), M.log_partition(mdp, weights))
    for count in ("2", "3"):
        for ours, single in zip(results[count], results["1"]):
            assert np.array_equal(ours, single)
    assert np.all(np.isfinite(results["1"][0])) and np.all(np.isfinite(results["1"][1]))


@pytest.mark.parametrize("raw, expected", [("", 1), ("1", 1), ("2", 2), (" 4 ", 4), ("AUTO", os.cpu_count() or 1)])
def test_thread_count_from_the_environment(monkeypatch, raw: str, expected: int) -> None:
    monkeypatch.setenv("IRD_THREADS", raw)
    assert threads.threads() == expected


@pytest.mark.parametrize("raw", ["0", "-2", "two", "1.5", "257"])
def test_bad_thread_counts_name_the_variable(monkeypatch, raw: str) -> None:
    monkeypatch.setenv("IRD_THREADS", raw)
    with pytest.raises(ValueError, match="IRD_THREADS"):
        threads.threads()
    mdp, weights = chunked_problem()
    with pytest.raises(ValueError, match="IRD_THREADS"):
        M.log_partition(mdp, weights)


def test_map_chunks_keeps_order_and_raises_the_first_error(monkeypatch) -> None:
    monkeypatch.setenv("IRD_THREADS", "2")
    assert threads.map_chunks(lambda x: x * x, list(range(20))) == [x * x for x in range(20)]

    def boom(x: int) -> int:
        if x == 3:
            raise RuntimeError("chunk 3")
        return x

    with pytest.raises(RuntimeError, match="chunk 3"):
        threads.map_chunks(boom, list(range(6)))


def _child_uses_the_pool() -> None:
    assert not threads._POOLS
    assert threads.map_chunks(lambda x: x + 1, [1, 2, 3]) == [2, 3, 4]


def test_a_forked_child_makes_its_own_pool(monkeypatch) -> None:
    # The parent's pool threads do not exist in a forked child (the experiments' workers are
    # forked): the child still runs chunks on threads, in pools of its own.
    monkeypatch.setenv("IRD_THREADS", "2")
    threads.map_chunks(lambda x: x, [1, 2])  # the parent now holds a pool
    child = multiprocessing.get_context("fork").Process(target=_child_uses_the_pool)
    child.start()
    child.join(60)
    if child.exitcode is None:
        child.kill()
    assert child.exitcode == 0
