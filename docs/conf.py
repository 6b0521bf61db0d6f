"""Sphinx configuration of the fluorogui documentation (``bash docs/build.sh`` builds it).

The site documents the checked-out tree: the repository root goes first on ``sys.path``,
whatever fluorogui the environment has installed. The command reference is generated from
the argparse parsers (sphinx-argparse), the API reference from numpydoc docstrings
(autodoc + numpydoc), and the validation page from ``docs/validation/results.json``, which
``docs/validation/regenerate.py`` writes with ``fluorogui validate`` (``_ext/validation_results``).
"""
from __future__ import annotations

import re
import sys
from datetime import date
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(DOCS / "_ext"))

_pyproject = (ROOT / "pyproject.toml").read_text(encoding="utf-8")
release = re.search(r'^version\s*=\s*"([^"]+)"', _pyproject, re.MULTILINE).group(1)
version = ".".join(release.split(".")[:2])

project = "fluorogui"
author = "The fluorogui developers"
_year = max(date.today().year, 2026)
copyright = f"2026{f'–{_year}' if _year > 2026 else ''}, {author}"

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.extlinks",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinxarg.ext",
    "myst_parser",
    "validation_results",
    "export_formats",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "README.md", "validation/*.json", "screenshots/*.py", "validation/*.py"]
templates_path = []
html_static_path = ["_static"]
html_css_files = ["fluorogui.css"]

# -- HTML ------------------------------------------------------------------------------------
html_theme = "furo"
html_title = f"fluorogui {release}"
html_logo = "../fluorogui/resources/icons/app.svg" if (ROOT / "fluorogui/resources/icons/app.svg").exists() else None
html_favicon = html_logo
html_theme_options = {"navigation_with_keys": True}
html_show_sourcelink = False
html_last_updated_fmt = None  # builds are reproducible: no build date on every page

extlinks = {"doi": ("https://doi.org/%s", "doi:%s")}

# -- autodoc and numpydoc --------------------------------------------------------------------
autodoc_default_options = {"member-order": "bysource"}
autodoc_typehints = "none"  # numpydoc's Parameters / Returns sections carry the types
autodoc_preserve_defaults = True
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# -- MyST (CHANGELOG.md, the one Markdown page) ------------------------------------------------
myst_heading_anchors = 2

# -- the build's own checks --------------------------------------------------------------------
nitpicky = False
suppress_warnings: list[str] = []
