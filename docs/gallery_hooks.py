"""The gallery's hooks (sphinx-gallery names them by their dotted names in docs/conf.py).

What the examples write (a figure, a study) goes to a scratch folder, not into the sources; the
PNGs an example saves there (not its study's report) become its figures on the page.
"""
import shutil
import tempfile
from pathlib import Path

from sphinx_gallery.scrapers import figure_rst

OUTPUT = Path(tempfile.mkdtemp(prefix="ibm-mpm-gallery-"))
ARGUMENTS = {"inclined_column.py": [str(OUTPUT / "inclined_column.png")],
             "small_study.py": [str(OUTPUT / "small-study")]}
_SHOWN: set[Path] = set()


def example_arguments(gallery_conf, script_vars) -> list[str]:
    """The command-line arguments an example runs with in the gallery."""
    return ARGUMENTS.get(Path(script_vars["src_file"]).name, [])


def written_figures(block, block_vars, gallery_conf) -> str:
    """Image scraper: the PNGs saved in OUTPUT since the last call, copied to the gallery's images."""
    new = sorted(set(OUTPUT.glob("*.png")) - _SHOWN)
    _SHOWN.update(new)
    paths = []
    for png, target in zip(new, block_vars["image_path_iterator"]):
        shutil.copyfile(png, target)
        paths.append(target)
    return figure_rst(paths, gallery_conf["src_dir"])
