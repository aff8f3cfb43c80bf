"""Sphinx configuration of the crowd_env documentation (furo theme, MyST Markdown pages, autodoc API).

Build: ``python -m sphinx -W -b html docs docs/_build/html`` (the test suite builds it with warnings as
errors: ``tests/docs/test_docs_build.py``).
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.abspath(".."))  # the package from the checkout, installed or not
sys.path.insert(0, os.path.abspath("_ext"))  # this site's own extension: generated_lists

project = "crowd_env"
author = "crowd_env developers"
copyright = "2026, crowd_env developers"
release = "0.1.0"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "generated_lists",  # the lists that follow the scenarios (docs/_ext/generated_lists.py)
]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 3
exclude_patterns = ["_build", "Thumbs.db", ".DS_Store", "validation/rimea/rimea_results.md",  # included by validation/rimea.md
                    "validation/reference_results/results.md"]  # included by validation/reference_results.md

autosummary_generate = True
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_mock_imports = ["ray", "pedpy", "jupedsim", "torch", "stable_baselines3", "supersuit"]
napoleon_google_docstring = False
napoleon_numpy_docstring = True
suppress_warnings = ["myst.header"]

html_theme = "furo"
html_title = "crowd_env"
html_static_path = ["_static"]
