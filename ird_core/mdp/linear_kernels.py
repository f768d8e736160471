"""The time loops of ``ird_core.mdp.linear_passes``, compiled with numba when it is installed.

A pass at the experiments' sizes (15x15, T = 30, 4-16 weights) is about 400 numpy calls on
arrays of a few thousand floats, so it costs mostly numpy's fixed per-call price. These kernels
run the same loops in three compiled calls per pass (set-up, backward, forward), with the same
arithmetic in the same order: every entry is the same sequence of IEEE additions,
multiplications and divisions as in the numpy loops (no ``fastmath``, so no reassociation and
no fused multiply-adds; numpy's error model, so a division by zero gives inf or NaN as in
numpy). Results are therefore bit for bit the same with and without numba
(``tests/core/test_linear_kernels.py``), and numba stays an optional accelerator: without it, or
with ``IRD_ENGINE=numpy``, the numpy loops run. The functions below are numba source: they are
only ever run compiled (:func:`compiled`), never as Python loops.

Layout and meaning of the arrays: ``ird_core.mdp.linear_passes`` (``_FlatGrids``). What is not a
loop over cells (the exponentials, rescaling every ``_RESCALE_EVERY`` steps, logs, the underflow
flags) stays in numpy there: numpy's ``exp`` and ``log`` need not round like the C library's.

Speed-ups are measured by ``scripts/bench_mdp.py`` (docs/benchmarks.md).
"""

from __future__ import annotations

import importlib.util
import os
from functools import lru_cache
from typing import Callable, NamedTuple

import numpy as np

__all__ = ["ENGINES", "available", "engine", "Kernels", "compiled"]

#: ``IRD_ENGINE`` values: ``auto`` (numba if installed), ``numpy``, ``numba`` (an error without it).
ENGINES: tuple[str, ...] = ("auto", "numpy", "numba")


@lru_cache(maxsize=1)
def available() -> bool:
    """Whether numba is installed (without importing it: that is slow, paid on first use)."""
    return importlib.util.find_spec("numba") is not None


def engine() -> str:
    """The engine the passes use: ``"numba"`` or ``"numpy"``, from ``IRD_ENGINE`` (read on every
    call, so a test or a benchmark can switch it; the answer is cached per value).

    Raises:
        ValueError: naming ``IRD_ENGINE`` when it is not one of :data:`ENGINES`, or is ``numba``
            and numba is not installed.
    """
    raw = os.environ.get("IRD_ENGINE", "")
    cached = _ENGINE_BY_VALUE.get(raw)
    if cached is not None:
        return cached
    wanted = raw.strip().lower() or "auto"
    if wanted not in ENGINES:
        raise ValueError(f"IRD_ENGINE: expected one of {ENGINES}, got {raw!r}")
    if wanted == "numba" and not available():
        raise ValueError("IRD_ENGINE: 'numba' was asked for but numba is not installed (pip install numba)")
    answer = "numpy" if wanted == "numpy" or not available() else "numba"
    _ENGINE_BY_VALUE[raw] = answer
    return answer


_ENGINE_BY_VALUE: "dict[str, str]" = {}


def _backward_start(exp_grids: np.ndarray, exp_rewards: np.ndarray, u_all: np.ndarray, v_all: np.ndarray,
                    horizon: int, stride: int) -> None:
    """The backward pass's set-up: ``exp_rewards`` = ``exp_grids`` ``(K, H, W)`` padded to the
    flat layout (0 on the separators), ``u = 1`` where no neighbour sum is written (the last row
    of ``u_all``, the first and last ``stride`` entries of every row), ``v[T % rows] = E``."""
    num, height, width = exp_grids.shape
    size = exp_rewards.shape[0]
    exp_rewards[:] = 0.0
    for k in range(num):
        for r in range(height):
            base = (k * (height + 1) + r + 1) * stride
            for c in range(width):
                exp_rewards[base + c] = exp_grids[k, r, c]
    u_all[u_all.shape[0] - 1, :] = 1.0
    for row in range(u_all.shape[0]):
        u_all[row, :stride] = 1.0
        u_all[row, size - stride:] = 1.0
    v_all[horizon % v_all.shape[0], :] = exp_rewards


def _backward_steps(exp_rewards: np.ndarray, u_all: np.ndarray, v_all: np.ndarray, t_first: int, t_last: int,
                    keep_sums: bool, stride: int) -> None:
    """Backward steps ``t = t_first, t_first - 1, ..., t_last``: ``u[row] = S v[(t + 1) % rows]``
    on the computed range, then ``v[t % rows] = E * u[row]`` everywhere (``row = t`` when the sums
    are kept, else 0). Arrays: ``exp_rewards`` ``(size,)``, ``u_all`` ``(T + 1 or 1, size)``,
    ``v_all`` ``(T + 1 or 2, size)``, written in place.

    Loops run from 0 over slices: with ``src[i - 1]`` indexing numba cannot rule out a negative
    index and the loop does not vectorise (6x slower)."""
    rows = v_all.shape[0]
    size = exp_rewards.shape[0]
    lo, hi = stride, size - stride
    for t in range(t_first, t_last - 1, -1):
        src = v_all[(t + 1) % rows]
        u = u_all[t if keep_sums else 0]
        v = v_all[t % rows]
        here, left, right = src[lo:hi], src[lo - 1:hi - 1], src[lo + 1:hi + 1]
        up, down = src[lo - stride:hi - stride], src[lo + stride:hi + stride]
        u_mid, v_mid, e_mid = u[lo:hi], v[lo:hi], exp_rewards[lo:hi]
        for j in range(hi - lo):  # here, left, right, up, down: linear_passes._neighbour_sum's order
            total = here[j] + left[j] + right[j] + up[j] + down[j]
            u_mid[j] = total
            v_mid[j] = e_mid[j] * total
        for i in range(lo):
            v[i] = exp_rewards[i] * u[i]
        for i in range(hi, size):
            v[i] = exp_rewards[i] * u[i]


def _forward_steps(u_all: np.ndarray, v_all: np.ndarray, starts: np.ndarray, ratio: np.ndarray, ratio_next: np.ndarray,
                   ratio_sum: np.ndarray, visits: np.ndarray, horizon: int, stride: int) -> None:
    """The forward pass from ``d = 1`` at the flat ``starts``: for ``t = 0..T-1``,
    ``ratio = d / u[t]``, ``ratio_sum += ratio``, ``d = (S ratio) * v[t + 1]`` (``S ratio`` is 0
    outside the computed range), ``visits += d``; ``visits`` starts as ``d``. Arrays ``(size,)``
    but ``u_all``, ``v_all`` ``(T + 1, size)``; ``ratio``, ``ratio_next`` are scratch.

    One loop per step: ``d`` at a cell is needed only for that cell's next ratio, so it is not
    stored; the next step's ratios go to the other scratch array while this step's are read."""
    size = visits.shape[0]
    lo, hi = stride, size - stride
    visits[:] = 0.0
    ratio_sum[:] = 0.0
    for i in range(starts.shape[0]):
        visits[starts[i]] = 1.0
    u = u_all[0]
    for i in range(size):  # the ratios of d_0 = visits
        r = visits[i] / u[i]
        ratio[i] = r
        ratio_sum[i] = ratio_sum[i] + r
    for t in range(horizon):
        last = t == horizon - 1
        v, u_next = v_all[t + 1], u_all[t + 1]
        for i in range(lo):
            step = 0.0 * v[i]
            visits[i] = visits[i] + step
            ratio_next[i] = step / u_next[i]
        here, left, right = ratio[lo:hi], ratio[lo - 1:hi - 1], ratio[lo + 1:hi + 1]
        up, down = ratio[lo - stride:hi - stride], ratio[lo + stride:hi + stride]
        v_mid, u_mid, vis_mid, next_mid = v[lo:hi], u_next[lo:hi], visits[lo:hi], ratio_next[lo:hi]
        for j in range(hi - lo):
            step = (here[j] + left[j] + right[j] + up[j] + down[j]) * v_mid[j]
            vis_mid[j] = vis_mid[j] + step
            next_mid[j] = step / u_mid[j]
        for i in range(hi, size):
            step = 0.0 * v[i]
            visits[i] = visits[i] + step
            ratio_next[i] = step / u_next[i]
        if not last:
            for i in range(size):
                ratio_sum[i] = ratio_sum[i] + ratio_next[i]
        ratio, ratio_next = ratio_next, ratio


class Kernels(NamedTuple):
    """The compiled kernels (:func:`compiled`)."""

    backward_start: Callable[..., None]
    backward_steps: Callable[..., None]
    forward_steps: Callable[..., None]


@lru_cache(maxsize=1)
def compiled() -> Kernels:
    """The kernels compiled with numba, made on first use: importing numba takes a noticeable
    fraction of a second, which processes that never run a pass (most ROS nodes) should not pay.
    ``cache=True``: compiled once per machine into ``__pycache__``, then loaded from there."""
    import numba  # noqa: PLC0415 - deliberately lazy, see above

    jit = numba.njit(cache=True, nogil=True, error_model="numpy")
    return Kernels(jit(_backward_start), jit(_backward_steps), jit(_forward_steps))
