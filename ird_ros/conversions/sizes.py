"""Size checks of request fields from their declared lengths, before anything is decoded.

A service reads ``len(msg.data)``, ``info.height x info.width x len(layers)`` and ``len(array)``
(O(1) on the deserialised message) and refuses an oversize field at once, naming it and the
limit, so a huge request never costs the node a numpy copy, a finiteness scan or a worker job.

Part of :mod:`ird_ros.conversions`; no numpy, no ROS import (the messages are duck-typed).
"""

from __future__ import annotations

from typing import Any

from ird_core.checks import MAX_TEXT_LENGTH

__all__ = ["MAX_TEXT", "grid_is_empty", "declared_grid_values", "check_grid_size", "check_length", "check_text"]

#: Longest free-text field of a request (labels, who answered), in characters: they are echoed
#: in answers and published records (``ird_core.checks.MAX_TEXT_LENGTH``).
MAX_TEXT = MAX_TEXT_LENGTH


def grid_is_empty(msg: Any) -> bool:
    """A FeatureGrid field left empty (no layers, no data): "none" / "the default" by convention."""
    return not (len(msg.layers) or len(msg.data))


def declared_grid_values(msg: Any) -> int:
    """The larger of a FeatureGrid's ``len(data)`` and ``height x width x len(layers)``."""
    return max(len(msg.data), int(msg.info.height) * int(msg.info.width) * len(msg.layers))


def check_grid_size(msg: Any, field: str, limit: int, limit_name: str = "max_map_values") -> int:
    """Refuse a FeatureGrid holding or declaring more than ``limit`` values; returns
    :func:`declared_grid_values`.

    Raises:
        ValueError: ``<field>.data: N values exceed <limit_name>=L`` (``len(data)`` or the
            declared ``H x W x d``).
    """
    n = len(msg.data)
    if n > limit:
        raise ValueError(f"{field}.data: {n} values exceed {limit_name}={limit}")
    h, w, d = int(msg.info.height), int(msg.info.width), len(msg.layers)
    if h * w * d > limit:
        raise ValueError(f"{field}.data: the declared {h}x{w} map of {d} layers ({h * w * d} values) exceeds "
                         f"{limit_name}={limit}")
    return max(n, h * w * d)


def check_length(values: Any, field: str, limit: int, what: str = "values") -> int:
    """Refuse a sequence field longer than ``limit``; returns its length.

    Raises:
        ValueError: ``<field>: N <what> exceed L``.
    """
    n = len(values)
    if n > limit:
        raise ValueError(f"{field}: {n} {what} exceed {limit}")
    return n


def check_text(value: str, field: str, limit: int = MAX_TEXT) -> str:
    """A free-text field of at most ``limit`` characters (``ValueError`` naming ``field``)."""
    if len(value) > limit:
        raise ValueError(f"{field}: {len(value)} characters exceed {limit}")
    return value
