"""Argument validation: bad input is a ``ValueError`` naming its field; the ranges of every number.

The ranges (docs/spec.md section 8, Limits) are written here once. They keep every quantity the
library computes finite with room to spare (``beta * |w| * |F| * (T + 1)`` stays below 1e14 for
horizons up to 1e4, far from float64 overflow), so a number out of range is refused up front
by name rather than surfacing later as an overflow, a NaN or a solver failure:

- :data:`MAX_ABS_WEIGHT`: every weight (proxy weights, posterior samples a plan uses,
  reference features).
- :data:`MAX_ABS_FEATURE`: every map value (features, observations, class probabilities).
- :data:`BETA_RANGE`, :data:`PRIOR_SIGMA_RANGE`: the designer's rationality and the prior's
  standard deviation.

``check_real`` and ``check_array`` apply the range registered for the field's name in
:data:`RANGES` (by magnitude for arrays), so every module that checks ``beta``,
``prior_sigma`` or ``proxy_weights`` applies the same range.
"""

from __future__ import annotations

import numpy as np

from ird_core.vocabulary import ZMethod, parse

__all__ = ["MAX_ABS_WEIGHT", "MAX_ABS_FEATURE", "BETA_RANGE", "PRIOR_SIGMA_RANGE", "MAX_TEXT_LENGTH", "RANGES",
           "check_int", "check_real", "check_array", "check_magnitude", "check_posterior_arguments"]

# Checked: sample_posterior (both methods) and plan_path (every mode, log_z) at the corners of
# these ranges give finite results (tests/core/test_ranges.py); at 1e6 the samplers did not.
MAX_ABS_WEIGHT = 1e4  # > the prior's largest sigma by far: posterior samples stay plannable
MAX_ABS_FEATURE = 1e3
BETA_RANGE = (0.0, 1e3)
PRIOR_SIGMA_RANGE = (1e-3, 1e3)
#: Longest free-text field of a request (a plan's label, who answered a query), in characters:
#: such text is echoed in answers and published records.
MAX_TEXT_LENGTH = 256
#: Closed ranges of scalars (``(low, high)``) and magnitude limits of arrays (``high`` only, as
#: ``(None, high)``), by field name.
RANGES: dict[str, tuple[float | None, float]] = {
    "beta": BETA_RANGE,
    "prior_sigma": PRIOR_SIGMA_RANGE,
    "proxy_weights": (None, MAX_ABS_WEIGHT),
    "reference_features": (None, MAX_ABS_WEIGHT),
}


def check_int(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{name}: expected an integer >= {minimum}, got {value!r}")
    return int(value)


def check_real(name: str, value: object, *, positive: bool, ranged: bool = True) -> float:
    """A finite float ``> 0`` (``positive``) or ``>= 0``, within ``RANGES[name]`` if registered
    and ``ranged`` (the ranges keep the samplers finite; a quantity that never reaches a sampler,
    such as the simulated designer's own rationality, passes ``ranged=False``)."""
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a real number, got {value!r}") from exc
    if isinstance(value, bool) or not np.isfinite(x) or (x <= 0 if positive else x < 0):
        bound = "> 0" if positive else ">= 0"
        raise ValueError(f"{name}: expected a finite number {bound}, got {value!r}")
    low, high = RANGES.get(name, (None, np.inf)) if ranged else (None, np.inf)
    if (low is not None and x < low) or x > high:
        raise ValueError(f"{name}: {x:g} is outside the allowed range [{low if low is not None else 0:g}, "
                         f"{high:g}]")
    return x


def check_magnitude(name: str, values: np.ndarray, limit: float) -> np.ndarray:
    """``values`` unchanged if every ``|value| <= limit``; else a ``ValueError`` naming ``name``."""
    if values.size:
        largest = float(np.max(np.abs(values)))
        if largest > limit:
            raise ValueError(f"{name}: a value of magnitude {largest:g} exceeds the limit {limit:g}")
    return values


def check_array(name: str, value: object, shape: tuple[int | None, ...]) -> np.ndarray:
    """A finite float64 array whose shape matches ``shape`` (``None`` = any size >= 1)."""
    try:
        x = np.array(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a numeric array, got {type(value).__name__}") from exc
    ok = x.ndim == len(shape) and all((s is None and n >= 1) or n == s for n, s in zip(x.shape, shape))
    if not ok:
        want = "(" + ", ".join("N" if s is None else str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        raise ValueError(f"{name}: expected shape {want}, got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name}: contains NaN or infinite values")
    if name in RANGES:
        check_magnitude(name, x, RANGES[name][1])
    return x


def check_posterior_arguments(proxy_weights: object, num_proxy_features: int, beta: object, method: object,
                              num_samples: object, prior_sigma: object) -> np.ndarray:
    """The checks of :func:`sample_posterior`'s arguments that need no MDP pass.

    For callers that must refuse a bad request before queueing it (the inference node).
    ``num_proxy_features`` is ``p``, the length the proxy weights must have (``d`` unless the
    proxy lives on its own features).

    Returns:
        The proxy weights as a finite ``(p,)`` float64 array.
    Raises:
        ValueError: naming ``method``, ``beta``, ``num_samples``, ``prior_sigma`` or ``proxy_weights``.
    """
    parse(ZMethod, method, "method")
    check_real("beta", beta, positive=False)
    check_int("num_samples", num_samples, 1)
    check_real("prior_sigma", prior_sigma, positive=True)
    return check_array("proxy_weights", proxy_weights, (num_proxy_features,))
