"""Messages for people: a ROS message as YAML (``ros2 topic echo``'s layout), ``--field`` paths,
and message classes from type names.

Long arrays are cut to ``truncate`` values followed by ``'...'`` (``ros2``'s ``--truncate-length``;
0 = whole); ``no_arr`` replaces every array by ``<sequence of N values>``. rclpy only imports a type
when asked (:func:`message_class`); the rest works on any object with ``get_fields_and_field_types``.
"""

from __future__ import annotations

import array
import importlib
import math
from typing import Any

import numpy as np
import yaml

__all__ = ["message_class", "is_message", "to_plain", "to_yaml", "check_field", "get_field"]

ELLIPSIS = "..."


def message_class(type_name: str) -> Any:
    """The class of ``package/msg/Name`` (or ``srv``, ``action``); ``ValueError`` naming the type when
    it is malformed or not installed here."""
    parts = type_name.split("/")
    if len(parts) != 3 or not all(parts):
        raise ValueError(f"type {type_name!r}: expected package/msg/Name")
    package, kind, name = parts
    try:
        cls = getattr(importlib.import_module(f"{package}.{kind}"), name)
    except (ImportError, AttributeError):
        raise ValueError(f"type {type_name}: not installed in this Python environment") from None
    if not is_message(cls):
        raise ValueError(f"type {type_name}: not a message type")
    return cls


def is_message(value: Any) -> bool:
    """Whether ``value`` is a ROS message (class or instance)."""
    return callable(getattr(value, "get_fields_and_field_types", None))


def _is_sequence(value: Any) -> bool:
    return isinstance(value, (list, tuple, array.array, np.ndarray, bytes, bytearray))


def _scalar(value: Any) -> Any:
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return value  # YAML writes .nan / .inf
    return value


def to_plain(value: Any, *, truncate: int = 128, no_arr: bool = False) -> Any:
    """``value`` (a message, a sequence or a scalar) as dicts, lists and scalars for YAML."""
    if is_message(value):
        return {name: to_plain(getattr(value, name), truncate=truncate, no_arr=no_arr)
                for name in value.get_fields_and_field_types()}
    if _is_sequence(value):
        items = list(value)
        if no_arr:
            return f"<sequence of {len(items)} values>"
        cut = truncate > 0 and len(items) > truncate
        plain = [to_plain(v, truncate=truncate, no_arr=no_arr) for v in (items[:truncate] if cut else items)]
        return plain + [ELLIPSIS] if cut else plain
    return _scalar(value)


class _Dumper(yaml.SafeDumper):
    """Block style for messages, flow style for lists of scalars (as ``ros2 topic echo``)."""


def _represent_list(dumper: yaml.SafeDumper, data: list[Any]) -> Any:
    flow = all(not isinstance(v, (dict, list)) for v in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_Dumper.add_representer(list, _represent_list)


def to_yaml(value: Any, *, truncate: int = 128, no_arr: bool = False) -> str:
    """``value`` as YAML text (no trailing newline); a scalar as its plain text."""
    plain = to_plain(value, truncate=truncate, no_arr=no_arr)
    if not isinstance(plain, (dict, list)):
        return str(plain)
    return yaml.dump(plain, Dumper=_Dumper, sort_keys=False, width=100, allow_unicode=True).rstrip("\n")


def check_field(msg_class: Any, path: str, type_name: str) -> None:
    """``ValueError`` naming the first part of the dotted ``path`` that ``msg_class`` has no field
    for (every part but the last must be a message)."""
    value = msg_class()
    for depth, part in enumerate(path.split(".")):
        so_far = ".".join(path.split(".")[:depth])
        if not is_message(value):
            raise ValueError(f"field {path!r}: {so_far} is not a message, it has no field {part!r}")
        fields = value.get_fields_and_field_types()
        if part not in fields:
            owner = f"{type_name}.{so_far}" if so_far else type_name
            raise ValueError(f"field {path!r}: {owner} has no field {part!r} (its fields: {', '.join(fields)})")
        value = getattr(value, part)


def get_field(msg: Any, path: str) -> Any:
    """The value at the dotted ``path`` of ``msg`` (checked with :func:`check_field` first)."""
    for part in path.split("."):
        msg = getattr(msg, part)
    return msg

