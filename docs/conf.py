"""Sphinx configuration of the IRD documentation site (build: bash scripts/build_docs.sh).

Sources: the Markdown pages in this folder (myst-parser) and the API reference generated from the
docstrings (autodoc + napoleon, through the ``ird-api`` directive of ``_ext/ird_api.py``).
Strict: ``scripts/build_docs.sh`` builds with ``-W --keep-going`` (every warning fails the build),
``nitpicky`` cross references, and myst reports a relative link to a page or heading that does
not exist. Nothing is loaded from the network when building or viewing the site: the theme
(furo) bundles its assets, no math renderer is used, and ``tests/test_docs_site.py`` checks the
built pages reference no ``http(s)://`` script, style sheet or font.
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(DOCS / "_ext"))

project = "IRD: Inverse Reward Design as a ROS 2 navigation stack"
html_title = "IRD"
author = "the IRD maintainers"
copyright = "the IRD maintainers, Apache-2.0"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "ird_api",
    "ird_xref",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_ext"]

# --- Markdown ---------------------------------------------------------------------------------
# Headings get anchors up to level 3, so [text](page.md#a-heading) is checked like a page link.
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence"]  # no dollarmath: no math renderer, no MathJax download
# A relative link to a file that is not a page (a script, a CSV) is a link to that file in the
# repository; a link to a page or a heading that does not exist is a warning (myst.xref_missing).
myst_url_schemes = ["http", "https", "mailto"]

# --- API reference --------------------------------------------------------------------------------
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
autodoc_default_options = {"show-inheritance": False}
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # "Attributes:" as fields: a NamedTuple field is described once

# Cross references: nitpicky, and every ``py:`` reference must name something that imports
# (_ext/ird_xref.py links project objects, shows other libraries' objects as text). Left out:
# targets that are not dotted names (the free text napoleon reads as a type, "name (a tuple of
# ints): ..."), and type variables (single capital letters).
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(?![A-Za-z_][\w.]*$).+"),
    (r"py:.*", r"(.*\.)?[A-Z]"),
]
# "more than one target" for a short name in a type hint (``Plan``: ird_core's and the client's):
# Sphinx links the first; the ambiguity is not an error.
suppress_warnings = ["ref.python"]

# --- HTML -------------------------------------------------------------------------------------------
html_theme = "furo"
html_static_path: list[str] = []
html_show_sourcelink = False
html_copy_source = False
