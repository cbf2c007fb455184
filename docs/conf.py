"""Sphinx configuration of ecam's documentation (pages in Markdown, read by MyST).

Build: ``python3 -m sphinx -W --keep-going -b html docs docs/_build/html`` (a warning fails the
build: a broken internal link, a missing page, a malformed docstring). No page fetches anything
from the network: external links are written, not checked.
"""

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent / "_ext"))

import ecam  # noqa: E402  (after the path: the checkout's ecam, not another install)

project = "ecam"
author = "the ecam authors"
copyright = "the ecam authors, MIT License"
version = release = ecam.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "ecam_docs",
]
source_suffix = {".md": "markdown"}
master_doc = root_doc = "index"
exclude_patterns = ["_build", "README.md"]
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence", "deflist"]
suppress_warnings = []

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
napoleon_numpy_docstring = True
napoleon_google_docstring = False
napoleon_use_rtype = False
napoleon_use_ivar = True  # Attributes as a field list: dataclass fields are documented once


_BARS = re.compile(r"(?<![|`\w])\|([^|`\n]{1,60})\|(?![|`\w])")


def _literal_bars(app, what, name, obj, options, lines):
    """Docstrings write |x| for a magnitude; reStructuredText reads it as a substitution."""
    for i, line in enumerate(lines):
        if not line.lstrip().startswith("| "):  # a line block
            lines[i] = _BARS.sub(r"``|\1|``", line)


def setup(app):
    app.connect("autodoc-process-docstring", _literal_bars)

html_theme = "alabaster"
html_title = f"ecam {release}"
html_static_path = []
html_theme_options = {
    "description": "Electronic cams for servo drives: certified cam tables, a C runtime, a CANopen rig",
    "fixed_sidebar": True,
    "page_width": "1180px",
    "sidebar_width": "240px",
}
html_sidebars = {"**": ["about.html", "navigation.html", "searchbox.html"]}
# Same sources, same pages: no build date in the footer.
html_last_updated_fmt = None
html_show_sourcelink = False
