"""Parameter tables: each node module's ``PARAMETERS`` is the one home of its parameters' defaults.

A node declares exactly the parameters of its table (:func:`declare_all`), so the table is what
``ros2 param describe`` shows and what ``msgs_config/params/graph.yaml`` may set; the yaml
repeats the defaults only as documentation for whoever edits it, and
``tests/test_graph_params.py`` checks that it names declared parameters, with their types and
(apart from deliberate overrides listed there) their defaults. No ROS import at module level,
so the tables can be read without rclpy.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Mapping, Union

from ird_ros.runtime.node_main import StartupError, declare

__all__ = ["Param", "ParamValue", "declare_all", "check_choices", "read_all", "runtime_except"]

#: A parameter's type: bool, int, float, str or a string array (a tuple; ``()`` = empty).
ParamValue = Union[bool, int, float, str, tuple[str, ...]]


@dataclass(frozen=True)
class Param:
    """One declared parameter.

    Attributes:
        default: the value when neither the params file nor ``-p`` sets it; its Python type is
            the parameter's ROS type (a tuple is a string array).
        description: shown by ``ros2 param describe``.
        min_value, max_value: the range rclpy enforces (numbers only).
        choices: allowed string values (checked at configure and when set; rclpy has no enum
            constraint).
        runtime: may be set while the node runs, and is honoured then (the node's
            ``apply_parameters``, ``ird_ros.runtime.lifecycle``); every other parameter is declared
            read-only and rclpy refuses to change it.
    """

    default: ParamValue
    description: str
    min_value: float | None = None
    max_value: float | None = None
    choices: tuple[str, ...] | None = None
    runtime: bool = False


def declare_all(node: Any, table: Mapping[str, Param], check: bool = True) -> dict[str, Any]:
    """Declare every parameter of ``table`` on ``node``; return ``{name: value}``.

    String arrays come back as lists. An empty default array is declared by type only
    (rclpy cannot infer the type of ``[]``). ``check``: refuse a value outside ``choices``
    (``StartupError``); a managed node checks them at configure instead (:func:`read_all`).
    """
    from rclpy.parameter import Parameter

    values: dict[str, Any] = {}
    for name, p in table.items():
        default: Any = p.default
        if isinstance(default, tuple):
            default = list(default) if default else Parameter.Type.STRING_ARRAY
        values[name] = declare(node, name, default, p.description, min_value=p.min_value, max_value=p.max_value,
                               choices=p.choices, read_only=not p.runtime, check_choices=check)
    return values


def runtime_except(table: Mapping[str, Param], fixed: tuple[str, ...]) -> dict[str, Param]:
    """``table`` with every parameter but those named in ``fixed`` marked ``runtime``."""
    unknown = set(fixed) - set(table)
    if unknown:
        raise KeyError(f"not in the table: {sorted(unknown)}")
    return {name: replace(p, runtime=name not in fixed) for name, p in table.items()}


def check_choices(name: str, p: Param, value: Any) -> None:
    """Raise ``StartupError`` naming the parameter when ``value`` is not one of ``p.choices``."""
    if p.choices is not None and value not in p.choices:
        raise StartupError(f"parameter {name}: must be one of {list(p.choices)}, got {value!r}")


def read_all(node: Any, table: Mapping[str, Param]) -> dict[str, Any]:
    """The current values of ``table``'s parameters on ``node``, their choices checked."""
    from rclpy.exceptions import ParameterUninitializedException

    values: dict[str, Any] = {}
    for name in table:
        try:
            values[name] = node.get_parameter(name).value
        except ParameterUninitializedException:  # an empty array declared by type: never set
            values[name] = None
    for name, p in table.items():
        check_choices(name, p, values[name])
    return values
