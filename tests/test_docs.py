"""The README is the front door and the guides live in docs/: its links resolve, it stays short,
every page of docs/ is in the site's table of contents, the site builds without a warning (its
guides, the API reference and the gallery of examples), and every object of the API reference has a
docstring of its own."""
from __future__ import annotations

import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text()


def test_the_readme_is_a_front_door():
    assert len(README.splitlines()) <= 200
    assert README.index("make study") < README.index("## What it is") and "make test" in README


def test_every_link_of_the_readme_resolves():
    links = re.findall(r"\]\(([^)#]+)(?:#[^)]*)?\)", README)
    assert links and all((ROOT / link).exists() for link in links if "://" not in link), links


def test_every_page_is_in_the_table_of_contents():
    index = (ROOT / "docs" / "index.md").read_text()
    listed = set(re.findall(r"^([a-z-]+)$", index, flags=re.MULTILINE))
    pages = {p.stem for p in (ROOT / "docs").glob("*.md")} - {"index"}
    assert pages == listed


def build_site(out: Path) -> subprocess.CompletedProcess:
    """`make docs`'s Sphinx build into `out` from scratch, warnings as errors, the gallery not run
    (tests/test_examples.py runs the examples and checks their numbers)."""
    return subprocess.run([sys.executable, "-m", "sphinx", "-q", "-E", "-W", "--keep-going", "-b", "html",
                           "-D", "sphinx_gallery_conf.plot_gallery=0", str(ROOT / "docs"), str(out)],
                          capture_output=True, text=True, timeout=900)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    built = build_site(out)
    assert built.returncode == 0, f"the site does not build without warnings:\n{built.stderr[-3000:]}"
    return out


@pytest.mark.slow
def test_the_site_has_its_guides_api_and_gallery(site):
    pages = {p.relative_to(site).as_posix() for p in site.rglob("*.html")}
    guides = {f"{p.stem}.html" for p in (ROOT / "docs").glob("*.md")}
    examples = {f"gallery/{p.stem}.html" for p in (ROOT / "examples").glob("*.py")}
    assert guides | examples | {"gallery/index.html"} <= pages, sorted(guides | examples - pages)
    api = (site / "api.html").read_text()
    for name in API_OBJECTS:
        assert f'id="{name}"' in api, name


API_OBJECTS = re.findall(r"^\.\. auto(?:class|function):: ([\w.]+)$", (ROOT / "docs" / "api.md").read_text(),
                         flags=re.MULTILINE)


@pytest.mark.parametrize("name", API_OBJECTS)
def test_every_object_of_the_api_reference_has_its_own_docstring(name):
    module, attribute = name.rsplit(".", 1)
    target = getattr(importlib.import_module(module), attribute)
    own = target.__dict__.get("__doc__") if isinstance(target, type) else target.__doc__
    assert own and not own.startswith(f"{attribute}("), f"{name} has no docstring of its own"
