"""Sphinx configuration: Markdown pages (MyST), the CLI reference from the parser, the API by autodoc.

Built by ``.ci/run`` with warnings as errors:
``sphinx-build -W -q -b html docs docs/_build``.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import phid_ros  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reference_pages import write_pages  # noqa: E402

# the reference of parameters, effects, control models and node parameters, from their declarations
write_pages(Path(__file__).resolve().parent / "reference")

project = "phid_ros"
author = "phid_ros maintainers"
copyright = "2026, phid_ros maintainers (Apache-2.0)"
release = version = phid_ros.__version__

extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "sphinxarg.ext"]
source_suffix = {".md": "markdown"}
myst_enable_extensions = ["colon_fence", "deflist"]
myst_heading_anchors = 3
exclude_patterns = ["_build", "make_screenshots.py", "reference_pages.py"]
autodoc_typehints = "description"
autodoc_member_order = "bysource"
# furo: the content column takes the window (alabaster's fixed 660-pixel column cut every code
# block: a channel map, a usage line), a code block scrolls rather than being cut, and the
# navigation folds away on a narrow screen
html_theme = "furo"
html_title = f"phid_ros {release}"
html_static_path = ["_static"]
html_css_files = ["wide.css"]
# no typographic quotes or dashes: "--fix" copied from the command reference must stay two hyphens
smartquotes = False
# The guides link to files of the repository (a test, a module, a config file) by path in
# backquotes; they are not documents of this site, and nothing here should pretend they are.
