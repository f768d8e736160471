"""What a call to the graph returns: a status, the decoded payload, and the raw answer.

Every IRD service answers ``success`` and a ``message`` (docs/spec.md section 6). The client maps
that pair onto :class:`CallStatus` here, and only here:

- ``DONE``: ``success: true``; the payload is decoded (numpy arrays via ``ird_ros.conversions``).
- ``BUSY``: the message starts with ``ird_ros.runtime.offload.BUSY_PREFIX``: the node is at its
  ``max_pending`` limit or re-sampling; the same request may succeed later (docs/spec.md section 8).
- ``REFUSED``: the message names the bad field (``field: ...``, e.g. ``weights: ...``,
  ``map.data: ...``, ``training_worlds[0].horizon: ...``); :attr:`CallResult.field` holds it.
- ``FAILED``: any other failure (``internal error: ...``, ``planning failed: ...``, an answer
  that was not taken because the evidence changed meanwhile).

The payload types (:class:`Plan`, :class:`Query`, :class:`RobDrive`, :class:`WorldMessages`) hold
numpy arrays and plain values, plus the message they came from where a caller needs it.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass
from dataclasses import field as dataclass_field
from enum import StrEnum
from typing import Any, Callable, Generic, TypeVar

import numpy as np

from ird_ros.runtime.offload import BUSY_PREFIX
from ird_ros.stamps import stamp_key

__all__ = [
    "CallStatus",
    "CallResult",
    "CallFailed",
    "classify_answer",
    "decode_answer",
    "Plan",
    "Query",
    "with_query_kind",
    "RobDrive",
    "WorldMessages",
]

T = TypeVar("T")

# A field name at the start of a message: "weights", "map.data", "/world/proxy.condition",
# "training_worlds[0].horizon" (the nodes' ValueError messages begin with the field they refuse).
_FIELD = re.compile(r"(/?[A-Za-z_][\w./\[\]]*): ")


class CallStatus(StrEnum):
    """How a service answered (see the module docstring)."""

    DONE = "done"
    BUSY = "busy"
    REFUSED = "refused"
    FAILED = "failed"


def classify_answer(success: bool, message: str) -> tuple[CallStatus, str | None]:
    """The status of an answer ``(success, message)`` and the field its message names (or None)."""
    if success:
        return CallStatus.DONE, None
    if message.startswith(BUSY_PREFIX):
        return CallStatus.BUSY, None
    named = _FIELD.match(message)
    if named is not None:
        return CallStatus.REFUSED, named.group(1)
    return CallStatus.FAILED, None


class CallFailed(RuntimeError):
    """Raised by :meth:`CallResult.unwrap` for an answer that is not ``DONE``."""

    def __init__(self, service: str, status: CallStatus, message: str) -> None:
        super().__init__(f"{service} {status}: {message}")
        self.service, self.status, self.message = service, status, message


@dataclass(frozen=True)
class CallResult(Generic[T]):
    """One answer of a service: ``value`` is the decoded payload (None unless ``status`` is DONE);
    ``field`` the field a refusal names; ``response`` the raw ``<Srv>.Response``."""

    service: str
    status: CallStatus
    message: str
    value: T | None = None
    field: str | None = None
    response: Any = dataclass_field(default=None, repr=False, compare=False)

    @property
    def ok(self) -> bool:
        """Whether the call succeeded (``status is DONE``)."""
        return self.status is CallStatus.DONE

    def unwrap(self) -> T:
        """The payload; raises :class:`CallFailed` (service, status and message) unless DONE."""
        if self.status is not CallStatus.DONE:
            raise CallFailed(self.service, self.status, self.message)
        assert self.value is not None
        return self.value


@dataclass(frozen=True)
class Plan:
    """An ``/ird/plan`` answer: the T+1 (row, col) cells (row 0 at the bottom), the objective
    under the request's mode and baseline (docs/spec.md section 4), and the stamp of the published
    ``/plan`` that Rob's status refers to (``RobStatus.plan_stamp``)."""

    cells: tuple[tuple[int, int], ...]
    objective: float
    stamp: Any

    @property
    def rows(self) -> tuple[int, ...]:
        return tuple(r for r, _ in self.cells)

    @property
    def cols(self) -> tuple[int, ...]:
        return tuple(c for _, c in self.cells)


@dataclass(frozen=True)
class Query:
    """An ``/ird/query`` answer (docs/spec.md section 7): ``options`` are q (T+1, 2) int64 cell
    arrays, on the query map for ``kind`` "paths", each offered proxy's plan on the TRAINING map
    for "proxies"; ``option_features`` (q, d) their feature counts (a proxy's behaviour counts),
    ``information_gain`` the mutual information (nats) between the designer's answer and the true
    reward; ``option_proxies`` (q, p) the offered proxy weights ((q, 0) for "paths") and
    ``proxy_feature_names`` their p names (empty for "paths").

    :func:`decode_answer` fills ``kind``, ``option_proxies`` and ``proxy_feature_names`` from the
    response (:func:`with_query_kind`; a response without them, an older server's, is "paths")."""

    query_id: int
    options: tuple[np.ndarray, ...]
    feature_names: tuple[str, ...]
    option_features: np.ndarray
    information_gain: float
    kind: str = "paths"
    option_proxies: np.ndarray = dataclass_field(default_factory=lambda: np.zeros((0, 0)))
    proxy_feature_names: tuple[str, ...] = ()


def with_query_kind(query: Query, response: Any) -> Query:
    """``query`` with the ``/ird/query`` response's ``kind`` ("" or missing = "paths"),
    ``option_proxies`` reshaped to (q, p) and ``proxy_feature_names``.

    Raises:
        ValueError: naming ``option_proxies`` when its length is not q times the names' count.
    """
    kind = str(getattr(response, "kind", "")) or "paths"
    names = tuple(str(n) for n in getattr(response, "proxy_feature_names", ()))
    flat = np.asarray(getattr(response, "option_proxies", ()), dtype=np.float64).reshape(-1)
    q = len(query.options)
    p = len(names) if names else (flat.size // q if q and flat.size % q == 0 else -1)
    if p < 0 or flat.size != q * p:
        raise ValueError(f"option_proxies: expected q*p = {q}*{len(names)} values, got {flat.size}")
    return dataclasses.replace(query, kind=kind, option_proxies=flat.reshape(q, p), proxy_feature_names=names)


@dataclass(frozen=True)
class RobDrive:
    """Rob's reports on one plan (``/rob/status`` with that plan's stamp): every status in
    order, ``final`` the one with ``done`` set (its lava, target and true return judge the plan)."""

    statuses: tuple[Any, ...]
    final: Any

    @property
    def touched_lava(self) -> bool:
        return bool(self.final.touched_lava)

    @property
    def reached_target(self) -> bool:
        return bool(self.final.reached_target)

    @property
    def true_return(self) -> float:
        return float(self.final.true_return)


@dataclass(frozen=True)
class WorldMessages:
    """One generation of the world node (every message carries the same header stamp): the
    training and test feature maps, the proxy's training map (latent_classifier: the classified
    map) and the proxy (``ird_msgs`` messages as received)."""

    train: Any
    test: Any
    proxy_train: Any
    proxy: Any

    @property
    def stamp(self) -> tuple[int, int]:
        """The generation's stamp as (sec, nanosec)."""
        return stamp_key(self.proxy.header.stamp)


def decode_answer(service: str, response: Any, decode: Callable[[Any], T] | None) -> CallResult[T]:
    """The answer as a CallResult; without ``decode`` the payload of a DONE answer is the response.
    A decoded :class:`Query` gets the response's kind and proxies (:func:`with_query_kind`)."""
    status, named = classify_answer(bool(response.success), str(response.message))
    value = None
    if status is CallStatus.DONE:
        value = decode(response) if decode is not None else response
        if isinstance(value, Query):
            value = with_query_kind(value, response)  # type: ignore[assignment]
    return CallResult(service, status, str(response.message), value, named, response)
