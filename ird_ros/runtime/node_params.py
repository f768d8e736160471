"""Parameter tables: each node module's ``PARAMETERS`` is the one home of its parameters' defaults.

A node declares exactly the parameters of its table (:func:`declare_all`), so the table is what
``ros2 param describe`` shows and what ``msgs_config/params/graph.yaml`` may set; the yaml
repeats the defaults only as documentation for whoever edits it, and
``tests/test_graph_params.py`` checks that it names declared parameters, with their types and
(apart from deliberate overrides listed there) their defaults. No ROS import at module level,
so the tables can be read without rclpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping, Union

from ird_ros.runtime.node_main import declare

__all__ = ["Param", "ParamValue", "declare_all"]

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
        choices: allowed string values (checked at start-up; rclpy has no enum constraint).
        read_only: cannot be changed after start-up.
    """

    default: ParamValue
    description: str
    min_value: float | None = None
    max_value: float | None = None
    choices: tuple[str, ...] | None = None
    read_only: bool = False


def declare_all(node: Any, table: Mapping[str, Param]) -> dict[str, Any]:
    """Declare every parameter of ``table`` on ``node``; return ``{name: value}``.

    String arrays come back as lists. An empty default array is declared by type only
    (rclpy cannot infer the type of ``[]``).
    """
    from rclpy.parameter import Parameter

    values: dict[str, Any] = {}
    for name, p in table.items():
        default: Any = p.default
        if isinstance(default, tuple):
            default = list(default) if default else Parameter.Type.STRING_ARRAY
        values[name] = declare(node, name, default, p.description, min_value=p.min_value, max_value=p.max_value,
                               choices=p.choices, read_only=p.read_only)
    return values
