"""Sphinx configuration of the powerline_control documentation.

Build (warnings are errors, as in CI; the README's command):

    python -m sphinx -W --keep-going -b html docs docs/_build/html

It runs every example for the gallery's figures: 4 min 22 s on 2 shared cores (load average about
4); ``PLC_DOCS_EXECUTE=none`` runs none of them (34 s).

The Markdown pages are read by myst-parser; the API reference (``api/``) and the example gallery
(``gallery/``) are generated from the package and ``examples/`` by ``_ext/plc_pages.py``.
"""

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))
sys.path.insert(0, str(DOCS.parent))  # the checkout's package, even when not installed
os.environ.setdefault("MPLBACKEND", "Agg")

import powerline_control  # noqa: E402

project = "powerline_control"
author = "the powerline_control developers"
copyright = "2026, " + author  # noqa: A001 - Sphinx's name
release = powerline_control.__version__
version = ".".join(release.split(".")[:2])

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "plc_pages",
    "plc_layout",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_templates", "_ext", "gallery/_figures", "**/.ipynb_checkpoints"]

# Examples run during the build, so that each gallery page shows the figures its script draws
# (most of the build's 4 min 22 s on 2 shared cores). PLC_DOCS_EXECUTE=none (or all) overrides
# this.
plc_gallery_execute = "all"
templates_path = ["_templates"]

# Markdown: $...$ and $$...$$ math, ::: fences, anchors for "page.md#section" links, and
# {.class} after an image (the gallery index's thumbnails).
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist", "attrs_inline"]
myst_heading_anchors = 3
myst_dmath_double_inline = True

# API reference: one page per public name, rendered by numpydoc.
autosummary_generate = True
autosummary_imported_members = True
autodoc_typehints = "none"  # numpydoc's Parameters section says the types, in words
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

html_theme = "alabaster"
html_title = f"powerline_control {release}"
html_static_path = ["_static"]
html_css_files = ["plc.css"]  # the gallery thumbnails keep their size in the table
html_theme_options = {"description": "Vibration of overhead power lines, on python-control"}
