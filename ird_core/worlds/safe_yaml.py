"""Reading a world file's bytes and YAML within limits, so a hostile file is refused, naming
the file and the key, instead of exhausting memory or the stack.

- :func:`read_capped`: a regular file only (a device such as ``/dev/zero``, a FIFO or a folder is
  refused before reading), at most ``limit`` bytes (one more is read to tell).
- :func:`read_yaml`: the document of a YAML file read so; a PNG or other non-UTF-8 file is refused
  as not a world file. Before any object is built, a walk over the parser's events refuses a
  document that, with every alias (``*name``) replaced by its anchor's node, has more than
  ``max_nodes`` nodes (a "billion laughs" file: a few lines whose aliases multiply at each level)
  or collections nested deeper than ``max_depth`` (PyYAML's composer recurses once per level);
  an alias inside its own anchor (a cycle), mapping keys that are not scalars and keys given
  twice (PyYAML would keep the last silently) are refused too. What remains is loaded by
  PyYAML's safe loader (no Python objects; an alias shares its anchor's object), so loading and
  any later walk over the data cost at most ``max_nodes`` steps.

Errors are ``ValueError`` ``"<file>: <key>: <problem>, got <value>"``; ``<key>`` is the path of
the offending node (``training_worlds[0].proxy``), ``(file)`` for the file itself, ``(top level)``
for a syntax error (its line and column in the problem, the line's text as the value).
"""

from __future__ import annotations

import os
import stat
from pathlib import Path
from typing import Any

import yaml

from ird_core.worlds.file_values import MAX_FILE_BYTES, MAX_YAML_DEPTH, MAX_YAML_NODES, FileErrors

__all__ = ["read_capped", "read_yaml"]

_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# libyaml's safe loader when PyYAML has it (parsing in C), else PyYAML's own: the same documents.
_LOADER: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def read_capped(ctx: FileErrors, path: Path, key: str, value: Any, limit: int, *, follow_symlinks: bool = True
                ) -> bytes:
    """The bytes of the regular file ``path`` (at most ``limit``); else ``ctx.fail(key, ..., value)``.

    Opened without blocking (a FIFO is refused, not waited on) and checked with ``fstat`` on the
    open descriptor, so what is read is what was checked. ``follow_symlinks=False`` refuses a
    symlink as the last component (``O_NOFOLLOW``).
    """
    flags = os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0)
    if not follow_symlinks:
        flags |= getattr(os, "O_NOFOLLOW", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        raise ctx.fail(key, f"cannot be opened ({exc.strerror or exc})", value) from None
    info = os.fstat(fd)
    if not stat.S_ISREG(info.st_mode) or info.st_size > limit:
        os.close(fd)
        if not stat.S_ISREG(info.st_mode):
            raise ctx.fail(key, "is not a regular file", value)
        raise ctx.fail(key, f"has {info.st_size} bytes, more than the limit {limit}", value)
    with os.fdopen(fd, "rb") as fh:
        try:
            data = fh.read(limit + 1)
        except OSError as exc:
            raise ctx.fail(key, f"cannot be read ({exc.strerror or exc})", value) from None
    if len(data) > limit:  # grew after fstat
        raise ctx.fail(key, f"has more than the limit of {limit} bytes", value)
    return data


class _Refused(Exception):
    """A node the loader refuses: the key path, the problem, the value shown."""

    def __init__(self, key: str, problem: str, value: Any) -> None:
        super().__init__(key, problem, value)
        self.key, self.problem, self.value = key, problem, value


class _Frame:
    """An open collection of the event walk: its key path and anchor, a sequence's next index, a
    mapping's keys so far and its pending key, and the expanded size and nesting depth of what it
    holds so far."""

    def __init__(self, path: str, mapping: bool, anchor: str | None) -> None:
        self.path, self.mapping, self.anchor = path, mapping, anchor
        self.index = 0
        self.keys: set[str] = set()
        self.key: str | None = None
        self.size = 0
        self.depth = 0


_KINDS = {yaml.SequenceStartEvent: "a sequence", yaml.MappingStartEvent: "a mapping", yaml.AliasEvent: "an alias"}


def _join(path: str, part: str) -> str:
    return path + part if part.startswith("[") or not path else f"{path}.{part}"


def _at(event: Any) -> str:
    return f" (line {event.start_mark.line + 1}, column {event.start_mark.column + 1})"


class _Walk:
    """The limits of :func:`_check_events` over one document's events.

    Sizes count nodes as if every alias were replaced by a copy of its anchor's node (what a
    program walking the loaded data visits); depths count nested collections likewise.
    """

    def __init__(self, max_depth: int, max_nodes: int) -> None:
        self.max_depth, self.max_nodes = max_depth, max_nodes
        self.stack: list[_Frame] = []
        self.anchors: dict[str, tuple[int, int]] = {}  # anchor -> (expanded size, nesting depth)
        self.total = 0

    def _path(self, event: Any) -> str | None:
        """The key path of the node ``event`` starts; None when it is a mapping key (checked here)."""
        frame = self.stack[-1] if self.stack else None
        if frame is None:
            return "(top level)"
        if not frame.mapping:
            frame.index += 1
            return _join(frame.path, f"[{frame.index - 1}]")
        if frame.key is None:
            where = frame.path or "(top level)"
            if not isinstance(event, yaml.ScalarEvent):
                raise _Refused(where, "mapping keys must be plain names" + _at(event), _KINDS.get(type(event), "?"))
            if event.value in frame.keys:
                raise _Refused(_join(frame.path, event.value), "is given twice" + _at(event), event.value)
            frame.keys.add(event.value)
            frame.key = event.value
            self._add(event, 1, 0)
            if event.anchor is not None:
                self.anchors[event.anchor] = (1, 0)
            return None
        path, frame.key = _join(frame.path, frame.key), None
        return path

    def _add(self, event: Any, size: int, depth: int, path: str = "") -> None:
        """Count a node of ``size`` nodes and ``depth`` nesting into the open collection."""
        self.total += size
        shown = f"*{event.anchor}" if isinstance(event, yaml.AliasEvent) else "a node"
        if self.total > self.max_nodes:
            raise _Refused(path or "(top level)", f"the document expands to more than {self.max_nodes} nodes "
                           "(YAML aliases repeat their anchor's node)" + _at(event), shown)
        if len(self.stack) + depth > self.max_depth:
            raise _Refused(path or "(top level)", f"nests collections deeper than {self.max_depth} levels" + _at(event),
                           shown)
        if self.stack:
            self.stack[-1].size += size
            self.stack[-1].depth = max(self.stack[-1].depth, depth)

    def event(self, event: Any) -> None:
        if isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
            frame = self.stack.pop()
            if frame.anchor is not None:
                self.anchors[frame.anchor] = (frame.size + 1, frame.depth + 1)
            if self.stack:
                self.stack[-1].size += frame.size + 1
                self.stack[-1].depth = max(self.stack[-1].depth, frame.depth + 1)
            return
        if not isinstance(event, yaml.NodeEvent):
            return  # stream and document events
        path = self._path(event)
        if path is None:
            return
        if isinstance(event, yaml.AliasEvent):
            if event.anchor not in self.anchors:
                inside = any(f.anchor == event.anchor for f in self.stack)
                raise _Refused(path, ("refers to a collection that contains it" if inside else "is an undefined alias")
                               + _at(event), f"*{event.anchor}")
            size, depth = self.anchors[event.anchor]
            self._add(event, size, depth, path)
        elif isinstance(event, yaml.ScalarEvent):
            self._add(event, 1, 0, path)
            if event.anchor is not None:
                self.anchors[event.anchor] = (1, 0)
        else:  # a collection starts: counted as one node now, its contents as they come
            self.total += 1
            if len(self.stack) >= self.max_depth:
                raise _Refused(path, f"nests collections deeper than {self.max_depth} levels" + _at(event),
                               _KINDS.get(type(event), "?"))
            self.stack.append(_Frame(path if path != "(top level)" else "", isinstance(event, yaml.MappingStartEvent),
                                     event.anchor))


def _check_events(text: str, max_depth: int, max_nodes: int) -> None:
    """Walk the YAML events (no nodes are built) and refuse, naming the key path: more than
    ``max_nodes`` nodes once aliases are expanded, collections nested deeper than ``max_depth``
    (aliases expanded), an alias inside its own anchor, mapping keys that are not scalars and keys
    given twice."""
    walk = _Walk(max_depth, max_nodes)
    for event in yaml.parse(text, Loader=_LOADER):
        walk.event(event)


def _syntax(exc: yaml.YAMLError, text: str) -> tuple[str, str]:
    """A PyYAML error as (``problem (line L, column C)``, the offending line), without PyYAML's
    "<unicode string>" name."""
    if isinstance(exc, yaml.MarkedYAMLError):
        mark = exc.problem_mark or exc.context_mark
        problem = str(exc.problem or exc.context)
        if mark is None:
            return problem, ""
        lines = text.splitlines()
        line = lines[mark.line] if mark.line < len(lines) else ""
        return f"{problem} (line {mark.line + 1}, column {mark.column + 1})", line
    if isinstance(exc, yaml.reader.ReaderError):
        line = text.count("\n", 0, exc.position) + 1
        return f"{exc.reason} (character #x{exc.character:04x}, line {line})", ""
    return str(exc), ""


def read_yaml(ctx: FileErrors, *, max_bytes: int = MAX_FILE_BYTES, max_depth: int = MAX_YAML_DEPTH,
              max_nodes: int = MAX_YAML_NODES) -> Any:
    """The YAML document of ``ctx.path`` (see the module docstring for what is refused)."""
    data = read_capped(ctx, ctx.path, "(file)", str(ctx.path), max_bytes)
    if data.startswith(_PNG_SIGNATURE):
        raise ctx.fail("(file)", "is a PNG image, not a world file (give the YAML file that names the images)",
                       data[:8])
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ctx.fail("(file)", f"is not UTF-8 text, so not a YAML world file (byte 0x{data[exc.start]:02x} at "
                       f"offset {exc.start})", data[max(0, exc.start - 8): exc.start + 8]) from None
    try:
        _check_events(text, max_depth, max_nodes)
        return yaml.load(text, Loader=_LOADER)  # aliases share their anchor's object: linear work
    except _Refused as refused:
        raise ctx.fail(refused.key, refused.problem, refused.value) from None
    except yaml.YAMLError as exc:
        problem, line = _syntax(exc, text)
        raise ctx.fail("(top level)", f"not valid YAML: {problem}", line) from None
    except (ValueError, TypeError, OverflowError) as exc:  # a scalar PyYAML cannot convert, e.g. an
        # integer of over 4300 digits (Python's int() limit)
        raise ctx.fail("(top level)", "a value cannot be converted", str(exc)) from None
