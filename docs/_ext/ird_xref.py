"""Sphinx extension of the IRD docs: the API reference's references, checked the way Python sees them.

The docstrings name objects as the code imports them: ``ird_core.posterior.sample_posterior``
(a package re-exporting ``ird_core.posterior.sampler.sample_posterior``), ``plan_path`` inside a
module that imported it, ``Terrain`` or ``FeatureGrid`` in a type hint. autodoc describes each
object once, where it is defined. On ``missing-reference`` this extension imports the name in
the context the reference was written in (as written, in the current class, in the current
module) and then:

- a project object (``ird_core``, ``ird_ros``) links to its description, found from its own
  ``__module__`` and ``__qualname__``; a project constant without a description of its own links
  to the module that defines it;
- an object of another library (numpy, the ROS messages, the standard library) is shown as
  text: it exists, and its documentation is not part of this site (no inventory is downloaded);
- a name that does not import stays a warning (an error under ``-W``): a reference to something
  that does not exist.

Two more rules keep the docstrings' plain style from reading as markup:

- napoleon reads the first line of a constant's docstring, up to a colon, as its type
  ("Degrees of freedom: ..." would become the type "Degrees of freedom"); here a constant's
  docstring gets no inferred type (its type hint, if any, is still shown);
- a docutils formatting message inside a docstring (a plain-text list without a blank line,
  say) is printed as a note at the end of the build, not as a warning: the docstrings are
  written for ``help()`` first. Formatting messages in the pages themselves stay warnings.
"""

from __future__ import annotations

import ast
import functools
import importlib
import inspect
import logging as std_logging
import sys
import types
from typing import Any

from docutils import nodes
from sphinx.addnodes import pending_xref
from sphinx.application import Sphinx
from sphinx.environment import BuildEnvironment
from sphinx.util import logging

LOGGER = logging.getLogger(__name__)
PROJECT = ("ird_core", "ird_ros")


@functools.cache
def lookup(path: str) -> tuple[bool, Any]:
    """``(found, object)`` for a dotted path: the longest importable module prefix, then attributes.
    Cached: one build imports each module once, and a failed import searches the file system."""
    parts = path.split(".")
    for split in range(len(parts), 0, -1):
        try:
            obj: Any = importlib.import_module(".".join(parts[:split]))
        except Exception:  # noqa: BLE001 - not a module (or not importable): try a shorter prefix
            continue
        try:
            for attr in parts[split:]:
                obj = getattr(obj, attr)
        except AttributeError:
            return False, None
        return True, obj
    return False, None


def _in_project(name: str) -> bool:
    return name.split(".")[0] in PROJECT


def _home(candidate: str, obj: Any) -> str:
    """The module an object belongs to: its own ``__module__``, else the module it was found in."""
    if isinstance(obj, types.ModuleType):
        return obj.__name__
    module = getattr(obj, "__module__", None)
    if isinstance(module, str) and not isinstance(obj, (int, float, str, tuple, list, dict, frozenset, set)):
        return module
    return candidate.rpartition(".")[0]


def _targets(candidate: str, obj: Any) -> list[str]:
    """Where the object ``candidate`` names may be described, best first."""
    if isinstance(obj, types.ModuleType):
        return [obj.__name__]
    out = []
    module, qualname = getattr(obj, "__module__", None), getattr(obj, "__qualname__", None)
    if isinstance(module, str) and isinstance(qualname, str) and "<" not in qualname:
        out.append(f"{module}.{qualname}")
    out.append(candidate)
    # a constant re-exported by a package: described (or at least present) in a defining module
    parent, _, attr = candidate.rpartition(".")
    found, owner = lookup(parent) if parent else (False, None)
    if found and isinstance(owner, types.ModuleType):
        prefix = owner.__name__ + "."
        for name, sub in sorted(sys.modules.items()):
            if (name == owner.__name__ or name.startswith(prefix)) and isinstance(sub, types.ModuleType) \
                    and getattr(sub, attr, object()) is obj:
                out += [f"{name}.{attr}", name]
    return out


def _scopes(target: str, node: pending_xref) -> list[str]:
    """``target`` as written, in the current class, in the current module and its parent packages."""
    out = [target]
    module, klass = node.get("py:module"), node.get("py:class")
    if module and klass:
        out.append(f"{module}.{klass}.{target}")
    parts = module.split(".") if module else []
    for i in range(len(parts), 0, -1):
        out.append(".".join(parts[:i] + [target]))
    return out


@functools.lru_cache(maxsize=None)
def _imported_names(module: str) -> dict[str, str]:
    """Every ``import``/``from ... import`` of a module's source, wherever it is (``TYPE_CHECKING``
    blocks, functions): the local name -> the dotted path it stands for."""
    found, mod = lookup(module)
    try:
        tree = ast.parse(inspect.getsource(mod)) if found else None
    except (OSError, TypeError, SyntaxError):
        tree = None
    out: dict[str, str] = {}
    for stmt in ast.walk(tree) if tree else ():
        if isinstance(stmt, ast.Import):
            for alias in stmt.names:
                out[alias.asname or alias.name.split(".")[0]] = alias.name if alias.asname else alias.name.split(".")[0]
        elif isinstance(stmt, ast.ImportFrom) and stmt.module and not stmt.level:
            for alias in stmt.names:
                out[alias.asname or alias.name] = f"{stmt.module}.{alias.name}"
    return out


def _as_imported(target: str, node: pending_xref) -> list[str]:
    """``target`` with its first name replaced by what the current module imported under it."""
    module = node.get("py:module")
    head, _, rest = target.partition(".")
    path = _imported_names(module).get(head) if module else None
    return [f"{path}.{rest}" if rest else path] if path else []


@functools.lru_cache(maxsize=4)
def _by_last_names(described: tuple[str, ...]) -> dict[str, list[str]]:
    """Every dotted tail of each described project object's name (``sample_posterior``,
    ``posterior.sample_posterior``, ...) -> the names that end with it."""
    out: dict[str, list[str]] = {}
    for name in described:
        if _in_project(name):
            parts = name.split(".")
            for i in range(1, len(parts)):
                out.setdefault(".".join(parts[i:]), []).append(name)
    return out


@functools.cache
def _class_source(klass: type) -> str | None:
    """The source of a class (None if it has none); parsed once per class and build."""
    try:
        return inspect.getsource(klass)
    except (OSError, TypeError):
        return None


def _instance_attribute(target: str, node: pending_xref, domain: Any) -> str | None:
    """The described project class whose methods assign ``self.<attr>`` (an instance attribute)."""
    for candidate in _scopes(target, node):
        parent, _, attr = candidate.rpartition(".")
        found, klass = lookup(parent) if parent else (False, None)
        if found and inspect.isclass(klass) and parent in domain.objects:
            source = _class_source(klass)
            if source is None:
                continue
            if f"self.{attr} =" in source or f"self.{attr}:" in source:
                return parent
    return None


def _link(app: Sphinx, env: BuildEnvironment, node: pending_xref, contnode: nodes.Element, name: str) -> Any:
    domain = env.get_domain("py")
    new = node.deepcopy()
    new["reftarget"] = name
    new["refspecific"] = False  # ``name`` is the full name: no search through every object's name
    kind = "mod" if domain.objects[name].objtype == "module" else "obj"
    return domain.resolve_xref(env, node["refdoc"], app.builder, kind, name, new, contnode)


def _resolve(app: Sphinx, env: BuildEnvironment, node: pending_xref, contnode: nodes.Element) -> Any:
    if node.get("refdomain") != "py":
        return None
    domain = env.get_domain("py")
    target = node["reftarget"].lstrip("~.")
    for candidate in _scopes(target, node) + _as_imported(target, node):
        found, obj = lookup(candidate)
        if not found:
            continue
        if not _in_project(_home(candidate, obj)):
            return contnode  # another library's object: it exists, shown as text
        for name in _targets(candidate, obj):
            if name in domain.objects:
                return _link(app, env, node, contnode, name)
    # a project name written without its module (``sample_posterior`` in ird_core.checks): the one
    # described object of that name, if there is exactly one
    matches = _by_last_names(tuple(domain.objects)).get(target, [])
    if len(matches) == 1:
        return _link(app, env, node, contnode, matches[0])
    owner = _instance_attribute(target, node, domain)
    return _link(app, env, node, contnode, owner) if owner else None


def _no_inferred_type(app: Sphinx, what: str, name: str, obj: Any, options: Any, lines: list[str]) -> None:
    if what in ("data", "attribute") and lines and ":" in lines[0]:
        # napoleon takes the first non-empty line's "text:" as a type: give it an empty comment
        lines[0:0] = ["..", ""]


class _DocstringMarkupNotes(std_logging.Filter):
    """Keeps docutils formatting messages located in docstrings out of the warnings."""

    def __init__(self) -> None:
        super().__init__()
        self.notes: list[str] = []

    def filter(self, record: std_logging.LogRecord) -> bool:
        location = str(getattr(record, "location", "") or "")
        if getattr(record, "type", None) == "docutils" and "docstring of" in location:
            self.notes.append(f"{location}: {record.getMessage()}")
            return False
        return True


NOTES = _DocstringMarkupNotes()


def _install_filter(app: Sphinx) -> None:
    for handler in std_logging.getLogger(logging.NAMESPACE).handlers:
        if isinstance(handler, logging.WarningStreamHandler) and NOTES not in handler.filters:
            handler.filters.insert(0, NOTES)


def _report_notes(app: Sphinx, exc: Exception | None) -> None:
    if NOTES.notes:
        LOGGER.info("docstring formatting notes (not warnings: the docstrings are plain text first):")
        for note in sorted(set(NOTES.notes)):
            LOGGER.info("  %s", note)


def setup(app: Sphinx) -> dict[str, Any]:
    app.connect("missing-reference", _resolve)
    app.connect("autodoc-process-docstring", _no_inferred_type, priority=400)  # before napoleon (500)
    app.connect("builder-inited", _install_filter)
    app.connect("build-finished", _report_notes)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
