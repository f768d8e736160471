"""The fast path of ``ird_core.mdp``: scaled linear-space passes on a flat zero-padded layout.

Internal to the ``ird_core.mdp`` package (:mod:`ird_core.mdp.passes` calls its entry points
:func:`linear_backward` and :func:`linear_visitation`): it takes an MDP's per-cell rewards and returns
log Z, expected visits and flags for the batch elements that must be recomputed with
``mdp``'s exact log-space passes. The passes' time loops run as numpy calls or, when numba is
installed, as the compiled kernels of ``ird_core.mdp.linear_kernels`` (``IRD_ENGINE``), which give
the same results bit for bit.
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from ird_core.mdp import linear_kernels
from ird_core.mdp.grid import GridMDP

# --------------------------------------------------------------------------------------------
# Fast path: scaled linear-space passes on a flat zero-padded layout
# --------------------------------------------------------------------------------------------
#
# The K grids of a batch are stored row-major in one 1-D array of rows of width ``W + 1``: each
# row holds a grid row and one zero "separator" entry, and a zero separator row precedes each
# grid and ends the array. The 5-point neighbour sum of every cell of every grid is then 4 adds
# of shifted *contiguous* slices (offsets +-1 and +-(W + 1)): a step off a grid lands on a
# separator, which holds zero in the values and zero "exp-reward" (so garbage computed there
# is wiped at the next multiply). Every separator inside the computed range has a cell among
# its neighbours, so the neighbour sums there are positive and safe to divide by.
#
# With ``E = exp(r - max r)`` (so ``E <= 1``), the backward values ``v_t = E * (S v_{t+1})`` lie
# in ``[exp(-(T + 1) range), 5^T]``: no rescaling is needed below ``_RESCALE_EVERY`` steps. The
# forward pass propagates probabilities through the soft-optimal policy
# ``pi(s' | s) = v_{t+1}(s') / (S v_{t+1})(s)``, which stay in ``[0, 1]``.
#
# Exactness: the passes are linear maps with coefficients in [0, 1], so the only errors beyond
# ordinary rounding are absolute ones from results that fall into the subnormal range (at most
# ``smallest_subnormal`` per operation), magnified at most 5x per step: every value carries an
# absolute error below ``delta = 2 * smallest_subnormal * 5^(T + 1)``. A batch element is
# recomputed with the exact log-space passes of ``ird_core.mdp`` unless ``delta`` is below
# ``_RELATIVE_TOLERANCE`` times ``Z``'s scaled value and, summed over the forward pass, times
# the probability-weighted inverse neighbour sums ``sum_t sum_s d_t(s) / u_t(s)`` that the
# policy divides by. Ordinary rewards never get there; reward spreads of hundreds of nats do.

#: Relative error allowed from subnormal underflow before an element is recomputed exactly.
_RELATIVE_TOLERANCE = 1e-13
#: Its log, computed once: the flags compare against it twice per pass.
_LOG_RELATIVE_TOLERANCE = float(np.log(_RELATIVE_TOLERANCE))
#: Backward steps between rescalings; ``5^{256} < 1e180`` so values cannot overflow in between.
_RESCALE_EVERY = 256


@lru_cache(maxsize=64)
def _log_underflow_error(horizon: int) -> float:
    """``log delta``: a bound on the absolute error of any scaled linear-space value."""
    periods = 1 + horizon // _RESCALE_EVERY
    steps = min(horizon, _RESCALE_EVERY) + 1
    return float(np.log(2.0 * periods * np.finfo(np.float64).smallest_subnormal) + steps * np.log(5.0))


@dataclass(frozen=True, eq=False)
class _FlatGrids:
    """The flat layout of ``K`` copies of an ``H x W`` grid (``size = (K (H + 1) + 1) (W + 1)``).

    Cell ``(r, c)`` of grid ``k`` is at ``(k (H + 1) + r + 1) (W + 1) + c``; neighbour sums are
    computed on ``[W + 1, size - W - 1)``, everything but the first and last separator rows.
    """

    num: int
    height: int
    width: int

    # Cached: the passes read these a few million times per posterior.
    @cached_property
    def stride(self) -> int:
        return self.width + 1

    @cached_property
    def size(self) -> int:
        return (self.num * (self.height + 1) + 1) * self.stride

    @cached_property
    def windows(self) -> tuple[slice, slice, slice, slice, slice]:
        """The computed range and its left, right, up and down neighbours, as slices."""
        w = self.stride
        lo, hi = w, self.size - w
        return (slice(lo, hi), slice(lo - 1, hi - 1), slice(lo + 1, hi + 1), slice(lo - w, hi - w),
                slice(lo + w, hi + w))

    def pad(self, values: np.ndarray, fill: float = 0.0) -> np.ndarray:
        """``(K, H, W)`` -> flat ``(size,)`` with ``fill`` on the separators."""
        out = np.full(self.size, fill)
        self.interior(out)[...] = values
        return out

    def interior(self, flat: np.ndarray) -> np.ndarray:
        """``(..., size)`` -> ``(..., K, H, W)`` view of the grid cells."""
        rows = flat.reshape(flat.shape[:-1] + (-1, self.stride))[..., 1:, :]
        grids = rows.reshape(flat.shape[:-1] + (self.num, self.height + 1, self.stride))
        return grids[..., : self.height, : self.width]

    def blocks(self, flat: np.ndarray) -> np.ndarray:
        """``(size,)`` -> ``(K, (H + 1) (W + 1))`` view: each grid with the separators after it."""
        return flat[self.stride :].reshape(self.num, -1)

    @lru_cache(maxsize=16)  # the passes ask twice per call for the start cell
    def positions(self, row: int, col: int) -> np.ndarray:
        """Flat indices ``(K,)`` of cell ``(row, col)`` in every grid (read-only)."""
        out = (np.arange(self.num) * (self.height + 1) + row + 1) * self.stride + col
        out.flags.writeable = False
        return out


@lru_cache(maxsize=256)
def _layout(num: int, height: int, width: int) -> _FlatGrids:
    """The shared ``_FlatGrids`` of a batch shape, so that its cached sizes, windows and start
    positions are computed once per shape, not once per pass."""
    return _FlatGrids(num, height, width)


def _neighbour_sum(src: "tuple[np.ndarray, ...]", dst: np.ndarray) -> None:
    """``dst = sum_{s' in succ(s)} src[s']`` on the computed range (separators: garbage).

    ``src``: a row's five windows (``_FlatGrids.windows`` applied: here, left, right, up, down);
    ``dst``: another row's ``here`` window. The views are made once per work array (``_work``)
    instead of five slicings per step (bit for bit the same).
    """
    here, left, right, up, down = src
    np.add(here, left, out=dst)
    np.add(dst, right, out=dst)
    np.add(dst, up, out=dst)
    np.add(dst, down, out=dst)


@dataclass(frozen=True, eq=False)
class LinearBackward:
    """The fast backward pass of a chunk of the batch.

    Attributes:
        layout: the flat layout of the chunk's ``K`` grids.
        exp_rewards: ``(size,)`` ``E = exp(r - max r)`` per grid, 0 on the separators.
        sums: work array ``(T + 1, size)`` of neighbour sums ``u[t] = S v[t + 1]`` (``u[T] = 1``),
            so that ``v[t] = E * u[t]``, divided by the step's rescaling if it had one; or
            ``None`` when not kept.
        values: work array ``(T + 1, size)`` of the scaled values ``v[t]`` themselves, or
            ``None`` when the sums are not kept.
        log_z: ``(K,)``.
        suspect: ``(K,)`` True where ``log Z`` may be off by more than ``_RELATIVE_TOLERANCE``.

    ``sums`` and ``values`` are this thread's work arrays (``_work``): valid until its next pass.
    """

    layout: _FlatGrids
    exp_rewards: np.ndarray
    sums: "_Work | None"
    values: "_Work | None"
    log_z: np.ndarray
    suspect: np.ndarray


_SCRATCH = threading.local()


class _Work:
    """A ``(rows, size)`` work array and, per row, its five windows (``_FlatGrids.windows``),
    made on first use: only the numpy loops read them, and each is made once per work array."""

    __slots__ = ("array", "_slices", "_windows")

    def __init__(self, array: np.ndarray, slices: "tuple[slice, ...]") -> None:
        self.array = array
        self._slices = slices
        self._windows: "dict[int, tuple[np.ndarray, ...]]" = {}

    def windows(self, row: int) -> "tuple[np.ndarray, ...]":
        out = self._windows.get(row)
        if out is None:
            out = self._windows[row] = tuple(self.array[row][s] for s in self._slices)
        return out


#: Bytes of work arrays one thread keeps between calls (least recently used dropped first).
_WORK_BYTES = 64_000_000


def _work(role: str, rows: int, layout: _FlatGrids) -> _Work:
    """A ``(rows, layout.size)`` float64 work array of this thread, reused from call to call.

    Contents are left over from the previous call: callers write every entry they read. Fresh
    multi-megabyte arrays are page-faulted in on every call, which cost the passes 2x at 64 weights.
    Samplers whose batch size varies from call to call (the slice moves) cycle through a few
    dozen shapes, so the cache drops the least recently used arrays, not all of them.
    """
    cache: "OrderedDict[tuple, _Work]" = _SCRATCH.__dict__.setdefault("arrays", OrderedDict())
    key = (role, rows, layout.size, layout.stride)
    out = cache.get(key)
    if out is not None:
        cache.move_to_end(key)
        return out
    out = cache[key] = _Work(np.empty((rows, layout.size)), layout.windows)
    total = sum(w.array.nbytes for w in cache.values())
    while total > _WORK_BYTES and len(cache) > 1:
        total -= cache.popitem(last=False)[1].array.nbytes
    return out


def linear_backward(mdp: GridMDP, rewards: np.ndarray, keep_sums: bool = True) -> LinearBackward:
    """Scaled linear-space soft values of ``rewards`` ``(K, H, W)`` (finite)."""
    k = rewards.shape[0]
    layout = _layout(k, mdp.height, mdp.width)
    peak = rewards.max(axis=(1, 2))
    exp_grids = np.exp(rewards - peak[:, None, None])
    horizon = mdp.horizon
    rows = horizon + 1 if keep_sums else 2  # without the kept sums, two alternating value rows
    sums = _work("sums", horizon + 1 if keep_sums else 1, layout)
    u_all = sums.array
    # Every v[t] is kept for the forward pass (one product per step there instead of two).
    values = _work("values", rows, layout)
    v_all = values.array
    kernels = linear_kernels.compiled() if linear_kernels.engine() == "numba" else None
    if kernels is not None:
        exp_rewards = np.empty(layout.size)
        kernels.backward_start(exp_grids, exp_rewards, u_all, v_all, horizon, layout.stride)
    else:
        exp_rewards = layout.pad(exp_grids)
        # u = 1 where no neighbour sum is written (u[T], the first and last separator rows).
        u_all[-1] = 1.0
        u_all[:, : layout.stride] = 1.0
        u_all[:, layout.size - layout.stride :] = 1.0
        v_all[horizon % rows] = exp_rewards
    log_scale = np.zeros(k)
    for t_first in range(horizon - 1, -1, -_RESCALE_EVERY):  # segments between rescalings
        t_last = max(t_first - _RESCALE_EVERY + 1, 0)
        if kernels is not None:
            kernels.backward_steps(exp_rewards, u_all, v_all, t_first, t_last, keep_sums, layout.stride)
        else:
            for t in range(t_first, t_last - 1, -1):
                row = t if keep_sums else 0
                _neighbour_sum(values.windows((t + 1) % rows), sums.windows(row)[0])
                np.multiply(exp_rewards, u_all[row], out=v_all[t % rows])
        if (horizon - t_last) % _RESCALE_EVERY == 0:
            grids = layout.blocks(v_all[t_last % rows])
            scale = grids.max(axis=1)
            scale = np.where(scale > 0.0, scale, 1.0)
            grids /= scale[:, None]
            log_scale += np.log(scale)
    v = v_all[0]
    with np.errstate(divide="ignore"):
        log_start = np.log(v[layout.positions(*mdp.start)])
    suspect = ~(log_start - _log_underflow_error(horizon) >= -_LOG_RELATIVE_TOLERANCE)
    return LinearBackward(layout, exp_rewards, sums if keep_sums else None, values if keep_sums else None,
                           log_start + log_scale + (horizon + 1) * peak, suspect)


def linear_visitation(mdp: GridMDP, back: LinearBackward) -> tuple[np.ndarray, np.ndarray]:
    """Expected visits ``(K, H, W)`` from forward probabilities under the soft-optimal policy
    ``pi(s' | s) = v[t + 1](s') / u[t](s)``, and a ``(K,)`` flag, True where they may be off by
    more than ``_RELATIVE_TOLERANCE``."""
    layout, horizon = back.layout, mdp.horizon
    u, v = back.sums.array, back.values.array
    work = _work("forward", 4, layout)
    d, ratio, spread, ratio_sum = work.array
    starts = layout.positions(*mdp.start)
    visits = np.empty(layout.size)
    if linear_kernels.engine() == "numba":
        linear_kernels.compiled().forward_steps(u, v, starts, ratio, spread, ratio_sum, visits, horizon, layout.stride)
    else:
        d[:] = 0.0
        d[starts] = 1.0
        visits[:] = d
        ratio_sum[:] = 0.0
        spread[: layout.stride] = 0.0  # never written below: zero so that 0 * garbage cannot be NaN
        spread[layout.size - layout.stride :] = 0.0
        for t in range(horizon):
            np.divide(d, u[t], out=ratio)
            np.add(ratio_sum, ratio, out=ratio_sum)
            _neighbour_sum(work.windows(1), work.windows(2)[0])
            np.multiply(spread, v[t + 1], out=d)  # v[t + 1] = E u[t + 1], after its rescaling if any
            np.add(visits, d, out=visits)
    with np.errstate(divide="ignore"):
        log_ratio = np.log(layout.blocks(ratio_sum).sum(axis=1))
    suspect = ~(log_ratio + _log_underflow_error(mdp.horizon) <= _LOG_RELATIVE_TOLERANCE)
    # A NaN from a flagged element can leak into its neighbours in the layout: flag those too.
    suspect |= ~np.isfinite(layout.blocks(visits).sum(axis=1))
    return layout.interior(visits), suspect
