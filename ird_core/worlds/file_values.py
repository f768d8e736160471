"""The world file's value readers and limits (docs/spec.md section 5).

Every error is a ``ValueError`` ``"<file>: <key>: <problem>, got <value>"`` naming the offending
key and value (long values shortened).

The limits bound what loading a world file may cost (memory, time) and keep every world that
loads within what the graph's services accept with their default parameters, so a world is
refused while loading, before any node starts, rather than published and then refused by every
service. Each limit that mirrors a node's parameter is at most that parameter's default
(tests/test_world_file_cli.py compares them).
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any, Iterable

import numpy as np

__all__ = ["FileErrors", "read_int", "read_vector", "read_colour", "read_name", "check_keys", "shown",
           "MAX_FILE_BYTES", "MAX_YAML_DEPTH", "MAX_YAML_NODES", "MAX_IMAGE_BYTES", "MAX_MAP_SIDE", "MAX_MAP_VALUES",
           "MAX_HORIZON", "MAX_PLAN_WORK", "MAX_TERRAINS", "MAX_FEATURES", "MAX_TRAINING_WORLDS", "MAX_NAME_LENGTH",
           "MAX_SEED", "RESOLUTION_RANGE"]

#: Bytes of the YAML file (a hand-written world is a few kB).
MAX_FILE_BYTES = 1 << 20
#: Nesting of YAML collections (the format needs 4: ``terrains[i].covariance`` rows).
MAX_YAML_DEPTH = 16
#: Nodes of the YAML document with every alias expanded (a 1 MiB file without aliases has fewer).
MAX_YAML_NODES = 1_000_000
#: Bytes of one image file (a 1000 x 1000 16-bit RGBA PNG, stored uncompressed, is 8 MB).
MAX_IMAGE_BYTES = 32 << 20
#: Cells per map side: the world node's ``height`` and ``width`` range.
MAX_MAP_SIDE = 1000
#: ``H*W*d`` of every map's features and ``H*W*p`` of its proxy features: ``max_map_values`` of the
#: inference and planner nodes.
MAX_MAP_VALUES = 5_000_000
#: Every horizon: ``max_horizon`` of the inference and planner nodes.
MAX_HORIZON = 1000
#: ``(T + 1) * H * W`` of every world, the work of a one-sample plan: the planner's ``max_plan_work``
#: (plans of K samples cost K times more; a request's K is checked by the planner).
MAX_PLAN_WORK = 50_000_000
#: Terrains in the legend (labels are int8: the Lavaland terrains plus these).
MAX_TERRAINS = 64
#: Features ``d`` (indicator, vectors or Gaussian dimension); a Gaussian terrain holds a d x d matrix.
MAX_FEATURES = 256
#: Training worlds (each is one MDP of the posterior's likelihood).
MAX_TRAINING_WORLDS = 16
#: Characters of ``name``, terrain names and feature names.
MAX_NAME_LENGTH = 64
#: Seeds: the world node's ``seed`` range (a uint32).
MAX_SEED = 2**32 - 1
#: Metres per cell: the world node's ``resolution`` range.
RESOLUTION_RANGE = (1e-6, 1e6)

_MAX_SHOWN = 120  # characters of a value an error message shows


def shown(value: Any) -> str:
    """``repr(value)``, shortened to ``_MAX_SHOWN`` characters (an integer too long to print in
    decimal is described by its size)."""
    try:
        text = repr(value)
    except ValueError:  # int -> str refuses more than sys.get_int_max_str_digits() digits
        text = f"<an integer of {value.bit_length()} bits>"
    return text if len(text) <= _MAX_SHOWN else f"{text[:_MAX_SHOWN]}... ({len(text)} characters)"


class FileErrors:
    """Error messages that name the file."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, key: str, problem: str, value: Any) -> ValueError:
        return ValueError(f"{self.path}: {key}: {problem}, got {shown(value)}")

    def get(self, mapping: dict, key: str, where: str) -> Any:
        if not isinstance(mapping, dict) or key not in mapping:
            raise ValueError(f"{self.path}: {where}{key}: missing required key")
        return mapping[key]


def check_keys(ctx: FileErrors, mapping: Any, allowed: Iterable[str], where: str) -> dict:
    """``mapping`` if it is a mapping whose keys are all in ``allowed``; else a ``ValueError``
    naming ``where`` (the mapping's key with a trailing ``.``, "" for the top level) or the unknown
    key, with the closest allowed key as a hint."""
    allowed = tuple(allowed)
    if not isinstance(mapping, dict):
        raise ctx.fail(where.rstrip(".") or "(top level)", f"must be a mapping of {', '.join(allowed)}", mapping)
    for key, value in mapping.items():
        if key not in allowed:
            close = difflib.get_close_matches(str(key), allowed, n=1)
            hint = f"did you mean {close[0]!r}?" if close else f"allowed: {', '.join(allowed)}"
            raise ctx.fail(f"{where}{key}", f"unknown key ({hint})", value)
    return mapping


def read_int(ctx: FileErrors, value: Any, key: str, minimum: int | None = None, maximum: int | None = None) -> int:
    """An integer (bools refused), in ``[minimum, maximum]`` (each bound if given)."""
    if (isinstance(value, bool) or not isinstance(value, int) or (minimum is not None and value < minimum)
            or (maximum is not None and value > maximum)):
        bound = ("" if minimum is None and maximum is None else f" >= {minimum}" if maximum is None
                 else f" <= {maximum}" if minimum is None else f" in [{minimum}, {maximum}]")
        raise ctx.fail(key, "must be an integer" + bound, value)
    return value


def read_vector(ctx: FileErrors, value: Any, key: str, length: int | None = None, limit: float | None = None
                ) -> np.ndarray:
    """A 1-d float64 array of finite numbers, of ``length`` and magnitudes at most ``limit`` if given."""
    try:
        out = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError, OverflowError):
        raise ctx.fail(key, "must be a list of numbers", value) from None
    if out.ndim != 1 or not np.all(np.isfinite(out)) or (length is not None and out.size != length):
        count = f"{length} " if length is not None else ""
        raise ctx.fail(key, f"must be a list of {count}finite numbers", value)
    if limit is not None and out.size and float(np.max(np.abs(out))) > limit:
        raise ctx.fail(key, f"has a value of magnitude above the limit {limit:g}", value)
    return out


def read_colour(ctx: FileErrors, value: Any, key: str) -> tuple[int, int, int]:
    """An ``[r, g, b]`` colour, or a grey value, integers in 0..255."""
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value <= 255:
        return (value, value, value)
    if (isinstance(value, list) and len(value) == 3
            and all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255 for v in value)):
        return (value[0], value[1], value[2])
    raise ctx.fail(key, "must be [r, g, b] or a grey value, integers in 0..255", value)


def read_name(ctx: FileErrors, value: Any, key: str) -> str:
    """A non-empty printable string of at most :data:`MAX_NAME_LENGTH` characters."""
    if not isinstance(value, str) or not value or len(value) > MAX_NAME_LENGTH or not value.isprintable():
        raise ctx.fail(key, f"must be a printable string of 1 to {MAX_NAME_LENGTH} characters", value)
    return value
