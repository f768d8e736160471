"""Sphinx extension of the IRD docs: the ``ird-api`` directive and its coverage check.

``ird-api`` documents one package: its docstring, then every module directly in it, each with
``automodule`` (``:members:``, ``:ignore-module-all:``: the functions and classes the module itself
defines, so a name a package re-exports is described once, where it is written). Modules are
found on disk at build time, so a new module appears in the reference without editing a page::

    ```{ird-api} ird_core.mdp
    ```

At the end of the read phase (``ird_api_coverage``, on by default), every package of ``ird_core`` and ``ird_ros`` must have been given
to some ``ird-api`` directive: a new sub-package without an API page is a build warning (an
error under ``-W``).
"""

from __future__ import annotations

import importlib
import pkgutil
from typing import Any

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.application import Sphinx
from sphinx.util import logging
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

LOGGER = logging.getLogger(__name__)
ROOT_PACKAGES = ("ird_core", "ird_ros")


def modules_of(package: str) -> tuple[list[str], list[str]]:
    """The modules and the sub-packages directly in ``package`` (sorted names); ImportError if
    the package does not import."""
    path = importlib.import_module(package).__path__
    found = sorted(pkgutil.iter_modules(path), key=lambda m: m.name)
    modules = [f"{package}.{m.name}" for m in found if not m.ispkg]
    packages = [f"{package}.{m.name}" for m in found if m.ispkg]
    return modules, packages


def all_packages(root: str) -> list[str]:
    """``root`` and every package below it."""
    out = [root]
    for sub in modules_of(root)[1]:
        out.extend(all_packages(sub))
    return out


class IrdApi(SphinxDirective):
    """``ird-api PACKAGE``: the package's docstring, then one section per module directly in it."""

    required_arguments = 1
    has_content = False

    def run(self) -> list[nodes.Node]:
        package = self.arguments[0]
        try:
            modules, _ = modules_of(package)
        except Exception as exc:  # noqa: BLE001 - reported as a build warning (an error under -W)
            LOGGER.warning("ird-api %s: the package does not import: %r", package, exc,
                           location=self.get_location(), type="ird", subtype="api")
            return []
        lines = [f".. automodule:: {package}", "   :no-members:", ""]
        for module in modules:
            lines += [f"``{module}``", "-" * (len(module) + 4), "",
                      f".. automodule:: {module}", "   :members:", "   :undoc-members:", "   :ignore-module-all:", ""]
        self.env.note_dependency(importlib.import_module(package).__file__)
        self.env.ird_api_packages = getattr(self.env, "ird_api_packages", {})
        self.env.ird_api_packages[package] = self.env.docname
        container = nodes.container()
        nested_parse_with_titles(self.state, StringList(lines, source=f"ird-api {package}"), container)
        return container.children


def _merge(app: Sphinx, env: Any, docnames: set[str], other: Any) -> None:
    env.ird_api_packages = {**getattr(env, "ird_api_packages", {}), **getattr(other, "ird_api_packages", {})}


def _purge(app: Sphinx, env: Any, docname: str) -> None:
    packages = getattr(env, "ird_api_packages", {})
    for package in [p for p, doc in packages.items() if doc == docname]:
        del packages[package]


def _check_coverage(app: Sphinx, env: Any) -> None:
    if not app.config.ird_api_coverage:
        return
    documented = set(getattr(env, "ird_api_packages", {}))
    for root in ROOT_PACKAGES:
        try:
            packages = all_packages(root)
        except Exception as exc:  # noqa: BLE001 - reported by the ird-api directive as well
            LOGGER.warning("%s does not import: %r", root, exc, type="ird", subtype="api")
            continue
        for package in packages:
            if package not in documented:
                LOGGER.warning("package %s has no API page: add docs/api/%s.md with an ird-api directive",
                               package, package, type="ird", subtype="api")


def setup(app: Sphinx) -> dict[str, Any]:
    # False for a doc set that is not the project's site (the tests' small doc sets)
    app.add_config_value("ird_api_coverage", True, "env", bool)
    app.add_directive("ird-api", IrdApi)
    app.connect("env-merge-info", _merge)
    app.connect("env-purge-doc", _purge)
    app.connect("env-check-consistency", _check_coverage)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}
