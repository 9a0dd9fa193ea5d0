"""Sphinx configuration of papwc's documentation.

Build (from the checkout, with ``pip install -e ".[docs]"``)::

    python -m sphinx -W --keep-going -b html docs docs/_build/html

Pages are MyST Markdown. What is made at build time, never committed:

- ``docs/_generated/``: the scenario fields and the FMUs' variables from the model layer, and
  ``papwc reproduce``'s figures and tables (``_ext/papwc_docs.py``);
- ``docs/tutorials/``: the tutorials, the scripts of ``docs/examples/`` run by sphinx-gallery;
- ``docs/reference/generated/``: the API pages autosummary writes.
"""

from __future__ import annotations

import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

import papwc  # noqa: E402

project = "papwc"
author = "papwc maintainers"
copyright = "2026, papwc maintainers"  # noqa: A001
version = release = papwc.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "numpydoc",
    # before the gallery: its builder-inited runs papwc reproduce, which builds the plant FMU
    # (on a fresh venv zig compiles its C runtimes then, once), before the tutorials run
    "papwc_docs",
    "sphinx_gallery.gen_gallery",
    "sphinxarg.ext",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
templates_path = ["_templates"]
# _incoming/: pages other branches write for the lead to move into the site (not built).
exclude_patterns = ["_build", "_generated", "_incoming", "examples", "**/GALLERY_HEADER.rst",
                    "Thumbs.db", ".DS_Store"]

# --- MyST --------------------------------------------------------------------------------------
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3
suppress_warnings = ["myst.header"]  # the changelog's version headings start at level 2

# --- autodoc, autosummary, numpydoc ------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = False
autodoc_default_options = {"members": True, "show-inheritance": True}
autodoc_typehints = "none"  # the numpydoc sections give the types
autodoc_member_order = "bysource"
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# --- sphinx-gallery: every script of examples/ runs at every build ------------------------------
sphinx_gallery_conf = {
    "examples_dirs": ["examples"],
    "gallery_dirs": ["tutorials"],
    "filename_pattern": r"/tutorial_",
    "within_subsection_order": "FileNameSortKey",
    "abort_on_example_error": True,
    "download_all_examples": False,
    "remove_config_comments": True,
    "min_reported_time": 0,
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "reset_modules": ("matplotlib",),
    "show_memory": False,
    "plot_gallery": "True",
}
#: The longest a tutorial may take to run (s); papwc_docs fails the build beyond it.
tutorial_seconds_max = 30.0

# --- HTML ---------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"papwc {release}"
html_static_path = ["_static"]
html_css_files = ["papwc.css"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 6,
    "navbar_align": "left",
    "use_edit_page_button": False,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
# pages without sections of their own: no left sidebar
html_sidebars = {"changelog": [], "getting-started": [], "paper": []}
html_show_sourcelink = False
html_copy_source = False
