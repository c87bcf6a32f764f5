"""Sphinx configuration of the sb3-adc documentation (built with warnings as errors in CI)."""

import os
import sys

sys.path.insert(0, os.path.abspath(".."))

with open(os.path.join(os.path.dirname(__file__), "..", "sb3_adc", "version.txt")) as version_file:
    release = version_file.read().strip()

project = "sb3-adc"
author = "sb3-adc developers"
copyright = "2026, sb3-adc developers"
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
]

autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_default_options = {"members": True, "show-inheritance": True}
napoleon_google_docstring = False
napoleon_numpy_docstring = False
nitpicky = False

templates_path = ["_templates"]
exclude_patterns = ["_build"]
html_theme = "sphinx_rtd_theme"
html_static_path = ["_static"]
html_title = f"sb3-adc {release}"
