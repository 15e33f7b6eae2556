"""Sphinx configuration of the ibm-mpm documentation (`make docs` builds docs/_build/html)."""
project = "ibm-mpm"
author = "the ibm-mpm authors"
extensions = ["myst_parser"]
myst_enable_extensions = ["dollarmath"]
myst_heading_anchors = 4              # [text](page.md#a-heading) links, as on GitHub
source_suffix = {".md": "markdown"}
exclude_patterns = ["_build"]
html_theme = "furo"
html_title = "ibm-mpm"
