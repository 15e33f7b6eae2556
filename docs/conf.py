"""Sphinx configuration of the ibm-mpm documentation (`make docs` builds reports/docs).

Pages are MyST Markdown (docs/*.md); the API reference is autodoc with numpydoc; the gallery is
sphinx-gallery running examples/*.py (their output and figures; examples/plugin is a package, not
an example). `-D sphinx_gallery_conf.plot_gallery=0` builds the gallery without running it.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "docs")]           # the packages, and the gallery's hooks

project = "ibm-mpm"
author = "the ibm-mpm authors"
extensions = ["myst_parser", "sphinx.ext.autodoc", "numpydoc", "sphinx_gallery.gen_gallery"]
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 4              # [text](page.md#a-heading) links, as on GitHub
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build"]
html_theme = "furo"
html_title = "ibm-mpm"

autodoc_member_order = "bysource"
autodoc_typehints = "none"            # the signatures show them; docstrings say the shapes
numpydoc_show_class_members = False
numpydoc_validation_checks = set()

sphinx_gallery_conf = {
    "examples_dirs": str(ROOT / "examples"),
    "gallery_dirs": "gallery",
    "filename_pattern": r".*\.py$",           # run every example, not only plot_*.py
    "ignore_pattern": r"plugin",
    "reset_argv": "gallery_hooks.example_arguments",
    "image_scrapers": ("matplotlib", "gallery_hooks.written_figures"),
    "download_all_examples": False,
    "remove_config_comments": True,
}
