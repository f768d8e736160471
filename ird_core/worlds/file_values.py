"""The world file's value readers (docs/spec.md section 5): every error is a ``ValueError``
``"<file>: <key>: <problem>, got <value>"`` naming the offending key and value."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["FileErrors", "read_int", "read_vector", "read_colour"]


class FileErrors:
    """Error messages that name the file."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, key: str, problem: str, value: Any) -> ValueError:
        return ValueError(f"{self.path}: {key}: {problem}, got {value!r}")

    def get(self, mapping: dict, key: str, where: str) -> Any:
        if not isinstance(mapping, dict) or key not in mapping:
            raise ValueError(f"{self.path}: {where}{key}: missing required key")
        return mapping[key]


def read_int(ctx: FileErrors, value: Any, key: str, minimum: int | None = None) -> int:
    """An integer (bools refused), at least ``minimum`` if given."""
    if isinstance(value, bool) or not isinstance(value, int) or (minimum is not None and value < minimum):
        raise ctx.fail(key, "must be an integer" + ("" if minimum is None else f" >= {minimum}"), value)
    return value


def read_vector(ctx: FileErrors, value: Any, key: str, length: int | None = None) -> np.ndarray:
    """A 1-d float64 array of finite numbers, of ``length`` if given."""
    try:
        out = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ctx.fail(key, "must be a list of numbers", value) from None
    if out.ndim != 1 or not np.all(np.isfinite(out)) or (length is not None and out.size != length):
        raise ctx.fail(key, "must be a list of " + (f"{length} " if length is not None else "") + "finite numbers", value)
    return out


def read_colour(ctx: FileErrors, value: Any, key: str) -> tuple[int, int, int]:
    """An ``[r, g, b]`` colour, or a grey value, integers in 0..255."""
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 255:
        return (value, value, value)
    if (isinstance(value, list) and len(value) == 3
            and all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255 for v in value)):
        return (value[0], value[1], value[2])
    raise ctx.fail(key, "must be [r, g, b] or a grey value, integers in 0..255", value)
