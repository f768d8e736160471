"""Deterministic finite-horizon grid MDPs and exact maximum-entropy trajectory inference.

Conventions (IRD_SPEC.md section 1):

- A map is a feature array ``F`` of shape ``(H, W, d)``; cell ``(row, col)`` has state index
  ``s = row * W + col``; row 0 is the bottom row.
- The successors of a cell are the cell itself ("stay") and its in-grid 4-neighbours, each once.
  The relation is symmetric, so predecessors equal successors, which lets the forward and the
  backward passes share one operator.
- A trajectory ``xi = (s_0, ..., s_T)`` has ``T = horizon`` moves and ``T + 1`` states, start
  included; ``phi(xi) = sum_t F[s_t]`` and ``r(xi; w) = w . phi(xi)``.

Maximum-entropy agent (section 2): ``P(xi | w) ∝ exp(w . phi(xi))`` over all trajectories.
Every quantity is computed exactly by dynamic programming over the grid, vectorised over a
batch of ``K`` weight vectors and over cells, never a Python loop over cells or weights. Cost
``O(T * K * H * W * 5 + K * H * W * d)``. Two implementations:

- the fast path: scaled *linear-space* passes (``exp`` once per cell, then only adds and
  multiplies) on one flat array holding the whole batch, so a step is 5-7 numpy calls on
  contiguous memory (see "Fast path" below for why it is exact and when it is not used);
- the reference: *log-space* passes (log-sum-exp over shifted grid views), exact for any
  reward magnitudes; used for the batch elements the fast path flags (reward spreads of
  hundreds of nats) and by ``soft_values``.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from functools import cached_property

import numpy as np

__all__ = [
    "MOVES",
    "GridMDP",
    "cell_rewards",
    "soft_values",
    "log_partition",
    "expected_visitation",
    "feature_expectations",
    "hard_values",
    "optimal_path",
    "successor_table",
    "path_features",
    "path_return",
    "validate_path",
]

#: The actions as (d_row, d_col), in tie-breaking order: "stay" first, so an indifferent agent
#: stays put, then up (row + 1), down, right (col + 1), left.
MOVES: tuple[tuple[int, int], ...] = ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1))


@dataclass(frozen=True, eq=False)
class GridMDP:
    """A deterministic grid MDP with a finite horizon.

    Attributes:
        features: ``(H, W, d)`` float64 feature array, finite.
        start: ``(row, col)`` start cell, on the map.
        horizon: ``T >= 1`` moves; trajectories visit ``T + 1`` states.
    """

    features: np.ndarray
    start: tuple[int, int]
    horizon: int

    def __post_init__(self) -> None:
        features = np.asarray(self.features, dtype=np.float64)
        if features.ndim != 3:
            raise ValueError(f"features: expected shape (H, W, d), got {features.shape}")
        if min(features.shape) < 1:
            raise ValueError(f"features: every dimension must be >= 1, got {features.shape}")
        if not np.all(np.isfinite(features)):
            raise ValueError("features: contains NaN or infinite values")
        try:
            row, col = (int(v) for v in self.start)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"start: expected (row, col), got {self.start!r}") from exc
        height, width = features.shape[:2]
        if not (0 <= row < height and 0 <= col < width):
            raise ValueError(f"start: ({row}, {col}) is off the {height}x{width} map")
        if isinstance(self.horizon, bool) or int(self.horizon) != self.horizon or self.horizon < 1:
            raise ValueError(f"horizon: expected an integer >= 1, got {self.horizon!r}")
        features.setflags(write=False)
        object.__setattr__(self, "features", features)
        object.__setattr__(self, "start", (row, col))
        object.__setattr__(self, "horizon", int(self.horizon))

    @property
    def height(self) -> int:
        return int(self.features.shape[0])

    @property
    def width(self) -> int:
        return int(self.features.shape[1])

    @property
    def num_features(self) -> int:
        return int(self.features.shape[2])

    @property
    def num_states(self) -> int:
        return self.height * self.width

    @property
    def start_state(self) -> int:
        return self.start[0] * self.width + self.start[1]

    def with_features(self, features: np.ndarray) -> "GridMDP":
        """The same grid, start and horizon with another ``(H, W, d')`` feature array."""
        return GridMDP(features, self.start, self.horizon)


def _as_weights(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """Validate a ``(K, d)`` batch of weight vectors (a single ``(d,)`` vector is rejected)."""
    w = np.asarray(weights, dtype=np.float64)
    if w.ndim != 2 or w.shape[1] != mdp.num_features:
        raise ValueError(f"weights: expected shape (K, {mdp.num_features}), got {w.shape}")
    if not np.all(np.isfinite(w)):
        raise ValueError("weights: contains NaN or infinite values")
    return w


def cell_rewards(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """Per-cell rewards ``w_k . F[row, col]``.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(K, H, W)``.
    """
    w = _as_weights(mdp, weights)
    # A plain gemm: einsum's path search cost 0.16 ms a call, 7% of an MCMC step at 15x15.
    flat = mdp.features.reshape(-1, mdp.num_features)
    return (w @ flat.T).reshape(len(w), mdp.height, mdp.width)


def _shifted(values: np.ndarray, fill: float) -> list[np.ndarray]:
    """The five successor views of ``values`` ``(..., H, W)``, off-grid entries set to ``fill``.

    Entry ``m`` at ``[..., r, c]`` holds ``values[..., r + dr, c + dc]`` for ``MOVES[m]``.
    """
    # np.full + one assignment: ~4x cheaper than np.pad on the small grids of the hot loops.
    padded = np.full(values.shape[:-2] + (values.shape[-2] + 2, values.shape[-1] + 2), fill)
    padded[..., 1:-1, 1:-1] = values
    views = []
    for d_row, d_col in MOVES:
        views.append(padded[..., 1 + d_row : padded.shape[-2] - 1 + d_row,
                            1 + d_col : padded.shape[-1] - 1 + d_col])
    return views


#: A neighbour sum below this (relative to the batch's largest value) may have lost terms to
#: underflow; such cells are recomputed with the per-cell maximum.
_UNDERFLOW_GUARD = 1e-250


def _neighbour_logsumexp(values: np.ndarray) -> np.ndarray:
    """``log sum_{s' in succ(s)} exp(values[s'])`` for every cell; ``(..., H, W)`` -> same.

    Fast path: one ``exp`` per cell, scaled by the largest value of each grid in the batch,
    then shifted sums. Where a sum is so small that a term may have underflowed, those cells
    are recomputed exactly with their own neighbourhood maximum, so the result is exact for
    any magnitudes and for ``-inf`` entries (unreachable cells).
    """
    peak = np.max(values, axis=(-2, -1), keepdims=True)
    peak = np.where(np.isfinite(peak), peak, 0.0)
    total = sum(_shifted(np.exp(values - peak), 0.0))
    with np.errstate(divide="ignore"):
        result = peak + np.log(total)
    suspect = total < _UNDERFLOW_GUARD
    if suspect.any():
        views = _shifted(values, -np.inf)
        local_peak = np.maximum.reduce(views)
        suspect &= np.isfinite(local_peak)  # an all -inf neighbourhood is exactly -inf
        if suspect.any():
            finite_peak = np.where(np.isfinite(local_peak), local_peak, 0.0)
            exact_total = sum(np.exp(view - finite_peak) for view in views)
            with np.errstate(divide="ignore"):
                exact = finite_peak + np.log(exact_total)
            result = np.where(suspect, exact, result)
    return result


def _soft_values_from_rewards(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """Log-space backward induction on per-cell rewards ``(K, H, W)``; ``-> (T + 1, K, H, W)``."""
    values = np.empty((mdp.horizon + 1,) + rewards.shape)
    values[-1] = rewards
    for t in range(mdp.horizon - 1, -1, -1):
        values[t] = rewards + _neighbour_logsumexp(values[t + 1])
    return values


def soft_values(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """Soft (log-sum-exp) values of the time-indexed grid, by backward induction.

    ``V[T] = r`` and ``V[t](s) = r(s) + log sum_{s' in succ(s)} exp(V[t+1](s'))``, so
    ``V[t](s)`` is the log of the summed exponentiated return of all trajectory suffixes that
    occupy ``s`` at time ``t``.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(T + 1, K, H, W)``.
    """
    return _soft_values_from_rewards(mdp, cell_rewards(mdp, weights))


def _log_visitation_exact(mdp: GridMDP, rewards: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Log occupancy ``log P(s_t = s)`` summed over time, and ``log Z``, in log space throughout.

    Uses forward messages ``alpha[t](s)`` (log summed exponentiated return of prefixes ending in
    ``s`` at ``t``) and backward soft values: ``P(s_t = s) = exp(alpha[t] + V[t] - r - log Z)``.
    Exact for any reward magnitudes; the fallback of the linear-space passes below.

    Args:
        rewards: ``(K, H, W)``.
    Returns:
        ``(K, H, W)`` log expected visit counts, and ``(K,)`` log Z.
    """
    values = _soft_values_from_rewards(mdp, rewards)
    row, col = mdp.start
    log_z = values[0][:, row, col].copy()
    alpha = np.full_like(rewards, -np.inf)
    alpha[:, row, col] = rewards[:, row, col]
    offset = (log_z[:, None, None] + rewards)  # subtracted from alpha + V at every step
    log_visits = alpha + values[0] - offset
    for t in range(1, mdp.horizon + 1):
        alpha = rewards + _neighbour_logsumexp(alpha)
        log_visits = np.logaddexp(log_visits, alpha + values[t] - offset)
    return log_visits, log_z


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
# recomputed with the exact log-space passes above unless ``delta`` is below
# ``_RELATIVE_TOLERANCE`` times ``Z``'s scaled value and, summed over the forward pass, times
# the probability-weighted inverse neighbour sums ``sum_t sum_s d_t(s) / u_t(s)`` that the
# policy divides by. Ordinary rewards never get there; reward spreads of hundreds of nats do.

#: Relative error allowed from subnormal underflow before an element is recomputed exactly.
_RELATIVE_TOLERANCE = 1e-13
#: Backward steps between rescalings; ``5^{256} < 1e180`` so values cannot overflow in between.
_RESCALE_EVERY = 256


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

    def positions(self, row: int, col: int) -> np.ndarray:
        """Flat indices ``(K,)`` of cell ``(row, col)`` in every grid."""
        return (np.arange(self.num) * (self.height + 1) + row + 1) * self.stride + col


def _neighbour_sum(layout: _FlatGrids, src: np.ndarray, dst: np.ndarray) -> None:
    """``dst = sum_{s' in succ(s)} src[s']`` on the computed range (separators: garbage)."""
    here, left, right, up, down = layout.windows
    out = dst[here]
    np.add(src[here], src[left], out=out)
    out += src[right]
    out += src[up]
    out += src[down]


@dataclass(frozen=True, eq=False)
class _LinearBackward:
    """The fast backward pass of a chunk of the batch.

    Attributes:
        layout: the flat layout of the chunk's ``K`` grids.
        exp_rewards: ``(size,)`` ``E = exp(r - max r)`` per grid, 0 on the separators.
        sums: ``(T + 1, size)`` neighbour sums ``u[t] = S v[t + 1]`` (``u[T] = 1``), so that
            ``v[t] = E * u[t] / rescale[t]``; or ``None`` when not kept.
        values: ``(T + 1, size)`` the scaled values ``v[t]`` themselves, or ``None`` when the
            sums are not kept.
        rescale: backward step ``t`` -> ``(K,)`` factor ``v[t]`` was divided by.
        log_z: ``(K,)``.
        suspect: ``(K,)`` True where ``log Z`` may be off by more than ``_RELATIVE_TOLERANCE``.
    """

    layout: _FlatGrids
    exp_rewards: np.ndarray
    sums: "np.ndarray | None"
    values: "np.ndarray | None"
    rescale: dict[int, np.ndarray]
    log_z: np.ndarray
    suspect: np.ndarray


_SCRATCH = threading.local()


def _scratch(role: str, rows: int, size: int) -> np.ndarray:
    """A ``(rows, size)`` float64 work array of this thread, reused from call to call.

    Contents are left over from the previous call: callers write every entry they read. Fresh
    multi-megabyte arrays are page-faulted in on every call, which cost the passes up to 4x.
    """
    cache = _SCRATCH.__dict__.setdefault("arrays", {})
    key = (role, rows, size)
    out = cache.get(key)
    if out is None:
        if len(cache) >= 16:  # many batch shapes in one thread: keep memory bounded
            cache.clear()
        out = cache[key] = np.empty((rows, size))
    return out


def _linear_backward(mdp: GridMDP, rewards: np.ndarray, keep_sums: bool = True) -> _LinearBackward:
    """Scaled linear-space soft values of ``rewards`` ``(K, H, W)`` (finite)."""
    k = rewards.shape[0]
    layout = _FlatGrids(k, mdp.height, mdp.width)
    peak = rewards.max(axis=(1, 2))
    exp_rewards = layout.pad(np.exp(rewards - peak[:, None, None]))
    horizon = mdp.horizon
    rows = horizon + 1 if keep_sums else 2  # without the kept sums, two alternating value rows
    sums = _scratch("sums", horizon + 1 if keep_sums else 1, layout.size)
    # u = 1 where no neighbour sum is written (u[T], the first and last separator rows).
    sums[-1] = 1.0
    sums[:, : layout.stride] = 1.0
    sums[:, layout.size - layout.stride :] = 1.0
    # Every v[t] is kept for the forward pass (one product per step there instead of two).
    values = _scratch("values", rows, layout.size)
    values[horizon % rows] = exp_rewards
    log_scale = np.zeros(k)
    rescale: dict[int, np.ndarray] = {}
    for t in range(horizon - 1, -1, -1):
        u = sums[t] if keep_sums else sums[0]
        later, v = values[(t + 1) % rows], values[t % rows]
        _neighbour_sum(layout, later, u)
        np.multiply(exp_rewards, u, out=v)
        if (horizon - t) % _RESCALE_EVERY == 0:
            grids = layout.blocks(v)
            scale = grids.max(axis=1)
            scale = np.where(scale > 0.0, scale, 1.0)
            grids /= scale[:, None]
            log_scale += np.log(scale)
            rescale[t] = scale
    with np.errstate(divide="ignore"):
        log_start = np.log(v[layout.positions(*mdp.start)])
    suspect = ~(log_start - _log_underflow_error(horizon) >= -np.log(_RELATIVE_TOLERANCE))
    return _LinearBackward(layout, exp_rewards, sums if keep_sums else None, values if keep_sums else None,
                           rescale, log_start + log_scale + (horizon + 1) * peak, suspect)


def _linear_visitation(mdp: GridMDP, back: _LinearBackward) -> tuple[np.ndarray, np.ndarray]:
    """Expected visits ``(K, H, W)`` from forward probabilities under the soft-optimal policy
    ``pi(s' | s) = v[t + 1](s') / u[t](s)``, and a ``(K,)`` flag, True where they may be off by
    more than ``_RELATIVE_TOLERANCE``."""
    layout, u, v = back.layout, back.sums, back.values
    d = np.zeros(layout.size)
    d[layout.positions(*mdp.start)] = 1.0
    visits = d.copy()
    ratio = np.empty(layout.size)
    ratio_sum = np.zeros(layout.size)
    spread = np.zeros(layout.size)
    for t in range(mdp.horizon):
        np.divide(d, u[t], out=ratio)
        ratio_sum += ratio
        _neighbour_sum(layout, ratio, spread)
        np.multiply(spread, v[t + 1], out=d)  # v[t + 1] = E u[t + 1] / rescale[t + 1]
        visits += d
    with np.errstate(divide="ignore"):
        log_ratio = np.log(layout.blocks(ratio_sum).sum(axis=1))
    suspect = ~(log_ratio + _log_underflow_error(mdp.horizon) <= np.log(_RELATIVE_TOLERANCE))
    # A NaN from a flagged element can leak into its neighbours in the layout: flag those too.
    suspect |= ~np.isfinite(layout.blocks(visits).sum(axis=1))
    return layout.interior(visits), suspect


#: Working set of one fast-path chunk (the kept neighbour sums and values, two
#: ``(T + 1) (H + 1) (W + 1)`` float64 arrays per weight). Larger batches are split evenly:
#: measured on 15x15, T = 30 (2-core EPYC), 55 us per weight at K = 64 in one chunk.
_CHUNK_BYTES = 8_000_000


def _chunks(mdp: GridMDP, num: int) -> list[slice]:
    """Even slices of a batch of ``num`` weights, each within ``_CHUNK_BYTES``."""
    per_weight = 2 * 8 * (mdp.horizon + 1) * (mdp.height + 1) * (mdp.width + 1)
    count = -(-num * per_weight // _CHUNK_BYTES)
    if count <= 1:
        return [slice(0, num)] if num else []
    bounds = np.linspace(0, num, max(1, count) + 1).round().astype(int)
    return [slice(int(lo), int(hi)) for lo, hi in zip(bounds[:-1], bounds[1:]) if hi > lo]


def _visitation_and_log_partition(mdp: GridMDP, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Expected visits ``(K, H, W)`` and ``log Z`` ``(K,)``: linear-space passes on cache-sized
    chunks, with the exact log-space passes for the elements the fast path flags."""
    rewards = cell_rewards(mdp, weights)
    visits = np.empty(rewards.shape)
    log_z = np.empty(len(rewards))
    for part in _chunks(mdp, len(rewards)):
        back = _linear_backward(mdp, rewards[part])
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            visits[part], unsure = _linear_visitation(mdp, back)
        log_z[part] = back.log_z
        redo = np.flatnonzero(back.suspect | unsure | ~np.isfinite(back.log_z)) + part.start
        if len(redo):
            log_visits, log_z[redo] = _log_visitation_exact(mdp, rewards[redo])
            visits[redo] = np.exp(log_visits)
    return visits, log_z


def log_partition(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """``log Z(w) = log sum_xi exp(w . phi(xi))`` over all trajectories from the start.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(K,)``.
    """
    rewards = cell_rewards(mdp, weights)
    log_z = np.empty(len(rewards))
    redo = np.zeros(len(rewards), dtype=bool)
    for part in _chunks(mdp, len(rewards)):
        back = _linear_backward(mdp, rewards[part], keep_sums=False)
        log_z[part], redo[part] = back.log_z, back.suspect | ~np.isfinite(back.log_z)
    if redo.any():
        row, col = mdp.start
        log_z[redo] = _soft_values_from_rewards(mdp, rewards[redo])[0][:, row, col]
    return log_z


def expected_visitation(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """Expected number of visits to each cell over ``t = 0..T`` under ``P(xi | w)``.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(K, H, W)``; each slice sums to ``T + 1``.
    """
    return _visitation_and_log_partition(mdp, weights)[0]


def feature_expectations(mdp: GridMDP, weights: np.ndarray) -> np.ndarray:
    """``E[phi(xi) | w]``, the gradient of ``log Z`` with respect to ``w``.

    Args:
        weights: ``(K, d)``.
    Returns:
        ``(K, d)``.
    """
    return log_partition_and_feature_expectations(mdp, weights)[1]


def log_partition_and_feature_expectations(
    mdp: GridMDP, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """``log Z`` ``(K,)`` and ``E[phi]`` ``(K, d)`` from one pair of passes (for gradients)."""
    visits, log_z = _visitation_and_log_partition(mdp, weights)
    flat = mdp.features.reshape(mdp.num_states, mdp.num_features)
    return log_z, visits.reshape(len(visits), mdp.num_states) @ flat


__all__.append("log_partition_and_feature_expectations")


def _check_cell_rewards(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    r = np.asarray(rewards, dtype=np.float64)
    if r.shape != (mdp.height, mdp.width):
        raise ValueError(f"cell_rewards: expected shape ({mdp.height}, {mdp.width}), got {r.shape}")
    if np.any(np.isnan(r)) or np.any(r == np.inf):
        raise ValueError("cell_rewards: contains NaN or +inf")
    return r


def hard_values(mdp: GridMDP, rewards: np.ndarray) -> np.ndarray:
    """Optimal (hard max) values for a per-cell reward: ``V[t] = r + max_succ V[t+1]``.

    Args:
        rewards: ``(H, W)`` per-cell reward (``-inf`` marks a forbidden cell).
    Returns:
        ``(T + 1, H, W)``; ``V[0][start]`` is the best total reward of ``T + 1`` states.
    """
    r = _check_cell_rewards(mdp, rewards)
    values = np.empty((mdp.horizon + 1,) + r.shape)
    values[-1] = r
    for t in range(mdp.horizon - 1, -1, -1):
        values[t] = r + np.maximum.reduce(_shifted(values[t + 1], -np.inf))
    return values


def optimal_path(mdp: GridMDP, rewards: np.ndarray) -> tuple[list[tuple[int, int]], float]:
    """A path maximising ``sum_t rewards[s_t]`` and its value.

    Ties are broken in ``MOVES`` order (stay first), so the result is deterministic.

    Args:
        rewards: ``(H, W)`` per-cell reward.
    Returns:
        ``T + 1`` cells ``(row, col)`` starting at the start, and the optimal value.
    """
    values = hard_values(mdp, rewards)
    row, col = mdp.start
    cells = [(row, col)]
    for t in range(1, mdp.horizon + 1):
        best_move, best_value = None, -np.inf
        for d_row, d_col in MOVES:
            r2, c2 = row + d_row, col + d_col
            if 0 <= r2 < mdp.height and 0 <= c2 < mdp.width and values[t][r2, c2] > best_value:
                best_move, best_value = (r2, c2), values[t][r2, c2]
        if best_move is None:  # every successor forbidden: stay (value is -inf anyway)
            best_move = (row, col)
        row, col = best_move
        cells.append((row, col))
    return cells, float(values[0][mdp.start])


def successor_table(height: int, width: int) -> np.ndarray:
    """Successor state indices of every cell, ``-1`` where a move leaves the grid.

    Returns:
        ``(H * W, 5)`` int64, columns in ``MOVES`` order (column 0 is the cell itself).
    """
    rows, cols = np.divmod(np.arange(height * width), width)
    table = np.full((height * width, len(MOVES)), -1, dtype=np.int64)
    for m, (d_row, d_col) in enumerate(MOVES):
        r2, c2 = rows + d_row, cols + d_col
        inside = (r2 >= 0) & (r2 < height) & (c2 >= 0) & (c2 < width)
        table[inside, m] = r2[inside] * width + c2[inside]
    return table


def validate_path(mdp: GridMDP, cells: "list[tuple[int, int]] | np.ndarray") -> np.ndarray:
    """Check that ``cells`` is a legal trajectory of ``mdp``; return it as ``(T + 1, 2)`` ints."""
    path = np.asarray(cells, dtype=np.int64)
    if path.shape != (mdp.horizon + 1, 2):
        raise ValueError(f"cells: expected {mdp.horizon + 1} (row, col) pairs, got shape {path.shape}")
    if tuple(path[0]) != mdp.start:
        raise ValueError(f"cells: path starts at {tuple(path[0])}, not at the start {mdp.start}")
    inside = (path[:, 0] >= 0) & (path[:, 0] < mdp.height) & (path[:, 1] >= 0) & (path[:, 1] < mdp.width)
    if not inside.all():
        raise ValueError(f"cells: step {int(np.argmin(inside))} is off the map")
    steps = np.abs(np.diff(path, axis=0)).sum(axis=1)
    if np.any(steps > 1):
        raise ValueError(f"cells: move {int(np.argmax(steps > 1))} is not a stay or a 4-neighbour step")
    return path


def path_features(mdp: GridMDP, cells: "list[tuple[int, int]] | np.ndarray") -> np.ndarray:
    """``phi(xi) = sum_t F[s_t]`` for a legal path; ``(d,)``."""
    path = validate_path(mdp, cells)
    return mdp.features[path[:, 0], path[:, 1]].sum(axis=0)


def path_return(mdp: GridMDP, cells: "list[tuple[int, int]] | np.ndarray", weights: np.ndarray) -> np.ndarray:
    """``w_k . phi(xi)`` for a batch ``(K, d)`` of weights; ``(K,)``."""
    return _as_weights(mdp, weights) @ path_features(mdp, cells)
