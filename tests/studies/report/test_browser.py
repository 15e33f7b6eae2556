"""The study report in a real browser: headless Chromium (Debian's chromium and chromium-driver),
driven from Python by Selenium's client, opens the smoke study's report, a small large-deformation
study's report and (when `make study` has written it) reports/paper/index.html, and checks what a
reader would meet: every image decoded, every internal link and contents entry landing on an
element, every table with rows, a quiet console, and a screenshot of the top of the page.

`make test` installs the browser when it is missing; without it these tests fail, they do not skip.
Selenium never downloads anything here: the driver's path is given (no selenium-manager) and
SE_OFFLINE is set.
"""
from __future__ import annotations

import os
import re
import struct
import time
from pathlib import Path

import pytest

from studies.report import canvas, collapse_figures, large_deformation, maps, panels, plots, sweep_lines
from studies.run.runner import run_study
from studies.run.spec import load
from tests.test_docs import build_site

try:
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service
    from selenium.webdriver.support.ui import WebDriverWait
except ImportError:          # reported as the failure below, not at collection
    webdriver = None

ROOT = Path(__file__).resolve().parents[3]
SMOKE = ROOT / "studies" / "specs" / "smoke.toml"
PAPER = ROOT / "reports" / "paper" / "index.html"
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
MISSING = ("the browser test needs {what}; run `make test`, which installs Debian's chromium and "
           "chromium-driver (apt-get) and selenium (pip, the dev extras)")

# The AMPLE-m column, coarse: two grid levels, nodal against Nitsche, every large-deformation figure.
LARGE = """
title = "Large-deformation column (browser check)"
description = "Self-weight column, ten load steps, two grid levels."

[[sweep]]
name = "column"
summary = "The self-weight column at two grid levels, nodal against Nitsche."
problems = ["column"]
methods = ["nodal", "nitsche"]
kinematics = "large"
steps = 10
E = 1e4
nu = 0.0
load = 40000
width = 3.125
height = 50
cell = [6.25, 3.125]
basis = ["gimp"]
ppc = 2
angle = 90
offset = [0, 0]
fields = true
tables = ["convergence"]
figures = ["error-vs-h-peer", "error-vs-step", "newton-iterations", "stress-profile", "snapshots"]
"""


def _missing() -> str:
    absent = [str(p) for p in (CHROMIUM, CHROMEDRIVER) if not p.exists()]
    if webdriver is None:
        absent.append("the selenium package")
    return MISSING.format(what=" and ".join(absent)) if absent else ""


# --- the reports (built once per module) and the axis labels of every figure drawn on the way ---

UNLABELLED: list[str] = []
# The modules that call canvas.finish_figure, and plots, which gathers the figures: patched there too, the report
# draws in this process, where the patch is seen.
WRITERS = (panels, sweep_lines, maps, large_deformation, collapse_figures, plots)


def _labelled_finish(finish):
    """canvas.finish_figure that first records every visible axis without a label (colour bars: their long axis)."""
    def wrapped(fig, path):
        for index, ax in enumerate(fig.axes):
            if not ax.get_visible():
                continue
            colorbar = getattr(ax, "_colorbar", None)
            if colorbar is not None:
                labels = {"colour bar": ax.get_ylabel() if colorbar.orientation == "vertical" else ax.get_xlabel()}
            else:
                labels = {"x": ax.get_xlabel(), "y": ax.get_ylabel()}
            UNLABELLED.extend(f"{Path(path).name}: axes {index} has no {name} label"
                              for name, text in labels.items() if not text.strip())
        return finish(fig, path)
    return wrapped


def _build(spec: Path, out: Path) -> Path:
    with pytest.MonkeyPatch.context() as patch:
        for module in WRITERS:
            patch.setattr(module, "finish_figure", _labelled_finish(canvas.finish_figure))
        summary = run_study(spec, out, progress=False)
    assert not summary.interrupted and summary.run == summary.total
    return out / "index.html"


@pytest.fixture(scope="module")
def reports(tmp_path_factory) -> dict[str, tuple[Path, Path]]:
    """name -> (index.html, spec) for the smoke study and the large-deformation column."""
    large = tmp_path_factory.mktemp("large-spec") / "column.toml"
    large.write_text(LARGE)
    return {"smoke": (_build(SMOKE, tmp_path_factory.mktemp("smoke")), SMOKE),
            "large": (_build(large, tmp_path_factory.mktemp("large")), large)}


@pytest.fixture(scope="module")
def browser():
    """A headless Chromium through /usr/bin/chromedriver, or None when either is missing."""
    if _missing():
        yield None
        return
    saved = os.environ.get("SE_OFFLINE")
    os.environ["SE_OFFLINE"] = "true"          # selenium-manager must never fetch a browser or a driver
    options = Options()
    options.binary_location = str(CHROMIUM)
    for argument in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                     "--window-size=1280,1000", "--hide-scrollbars", "--no-first-run"):
        options.add_argument(argument)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
    try:
        yield driver
    finally:
        driver.quit()
        if saved is None:
            os.environ.pop("SE_OFFLINE", None)
        else:
            os.environ["SE_OFFLINE"] = saved


# --- what the page looks like to a reader ------------------------------------------------------

FACTS = """
const ids = Array.from(document.querySelectorAll('[id]')).map(e => e.id);
const resolves = h => h.length > 1 && document.getElementById(decodeURIComponent(h.slice(1))) !== null;
const heading = t => {   // the nearest heading above an element, to name it in a failure
  for (let e = t; e; e = e.previousElementSibling || e.parentElement) {
    if (/^H[1-3]$/.test(e.tagName)) return e.firstChild ? e.firstChild.textContent : '';
  }
  return '';
};
return {
  ids: ids,
  images: Array.from(document.images).map(i => ({alt: i.alt, complete: i.complete, width: i.naturalWidth,
                                                 height: i.naturalHeight})),
  links: Array.from(document.querySelectorAll('a[href^="#"]')).map(a => ({href: a.getAttribute('href'),
                                                                          ok: resolves(a.getAttribute('href'))})),
  contents: Array.from(document.querySelectorAll('nav.toc a')).map(a => a.getAttribute('href')),
  tables: Array.from(document.querySelectorAll('table')).map((t, i) => ({
      index: i, heading: heading(t),
      rows: Array.from(t.tBodies).reduce((n, b) => n + Array.from(b.rows).filter(r => r.querySelector('td')).length, 0)})),
  figures: Array.from(document.querySelectorAll('figure')).map(f => ({
      image: f.querySelector('img, div.interactive') !== null,
      how: (f.querySelector('figcaption .how') || {}).textContent || ''})),
  footer: (document.getElementById('page-size') || {}).textContent || '',
  scorecard: Array.from(document.querySelectorAll('#scorecard td')).map(td => td.className),
  interactive: Array.from(document.querySelectorAll('div.interactive')).map(d => d.childElementCount),
  plotted: (window.Bokeh ? Bokeh.documents : []).map(doc => Array.from(doc.all_models)
      .filter(m => m instanceof Bokeh.ColumnDataSource).reduce((n, m) => n + (m.data.x ? m.data.x.length : 0), 0)),
};
"""


def _open(driver, page: Path) -> dict:
    driver.get_log("browser")                              # drop what an earlier page logged
    driver.get(page.as_uri())
    WebDriverWait(driver, 30).until(lambda d: d.execute_script(
        "return document.readyState === 'complete' && Array.from(document.images).every(i => i.complete)"
        " && Array.from(document.querySelectorAll('div.interactive')).every(d => d.childElementCount > 0)"))
    return driver.execute_script(FACTS)


def _check_page(driver, page: Path, sweeps: list[str], shots: Path, spec: Path | None = None) -> None:
    facts = _open(driver, page)

    # every interactive figure drawn by BokehJS (offline: the script is in the page), each with points
    assert len(facts["plotted"]) == len(facts["interactive"]), facts
    assert all(count > 0 for count in facts["interactive"]) and all(n > 0 for n in facts["plotted"]), facts

    # every image decoded (a broken data URI loads as complete with naturalWidth 0)
    assert facts["images"], "the report shows no figure"
    broken = [i["alt"] for i in facts["images"] if not (i["complete"] and i["width"] > 0 and i["height"] > 0)]
    assert not broken, f"images that did not decode: {broken}"

    # every internal link and every contents entry lands on an element, and ids are unique
    duplicates = sorted({i for i in facts["ids"] if facts["ids"].count(i) > 1})
    assert not duplicates, f"ids used twice: {duplicates}"
    dangling = [link["href"] for link in facts["links"] if not link["ok"]]
    assert not dangling, f"internal links to no element: {dangling}"
    contents = facts["contents"]
    assert contents and all(h.startswith("#") and h[1:] in facts["ids"] for h in contents), contents
    missing = [name for name in sweeps if f"#{name}" not in contents]
    assert not missing, f"sweep sections not in the table of contents: {missing}"

    # following a contents entry brings its section into view (the browser really navigates)
    height = driver.execute_script("return window.innerHeight")
    for href in contents:
        driver.execute_script("window.scrollTo(0, 0)")
        driver.find_element("css selector", f'nav.toc a[href="{href}"]').click()
        top = driver.execute_script(f"return document.getElementById({href[1:]!r}).getBoundingClientRect().top")
        assert driver.execute_script("return location.hash") == href
        assert -2 <= top < height, f"{href}: the section is {top:.0f} px from the top of a {height} px window"

    # every table has body rows (with data cells), every figure a how-to-read line
    empty = [t["heading"].strip()[:60] or f"table {t['index']}" for t in facts["tables"] if t["rows"] < 1]
    assert facts["tables"] and not empty, f"tables without a body row: {empty}"
    unread = [f for f in facts["figures"] if not (f["image"] and len(f["how"].strip()) > len("How to read: ") + 20)]
    assert not unread, f"figures without a how-to-read caption: {unread}"

    # the verdict's scorecard, where the spec has one: every cell banded or empty, some of each band shown
    if spec is not None and spec.exists() and load(spec).verdict:
        bands = facts["scorecard"]
        assert bands and set(bands) <= {"good", "fair", "poor", ""}, bands
        assert "good" in bands and "poor" in bands, bands

    # the footer states the page's own size, to the byte
    stated = re.search(r"This page: ([\d,]+) bytes", facts["footer"])
    assert stated and int(stated.group(1).replace(",", "")) == page.stat().st_size, facts["footer"]

    # a quiet console: nothing the browser itself reports as SEVERE
    severe = [entry for entry in driver.get_log("browser") if entry.get("level") == "SEVERE"]
    assert not severe, f"console errors: {severe}"

    # a screenshot of the top of the report
    driver.execute_script("window.scrollTo(0, 0)")
    shot = shots / f"{page.parent.name}-top.png"
    assert driver.save_screenshot(str(shot))
    data = shot.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000, (shot, len(data))
    width, tall = struct.unpack(">II", data[16:24])
    assert width >= 800 and tall >= 600, (width, tall)
    print(f"\n{page}: {page.stat().st_size:,} bytes, {len(facts['images'])} figures, "
          f"{len(facts['tables'])} tables; screenshot {shot}")


@pytest.mark.parametrize("name", ["smoke", "large"])
def test_report_in_a_real_browser(name, browser, request, tmp_path_factory):
    if browser is None:
        pytest.fail(_missing(), pytrace=False)
    page, spec = request.getfixturevalue("reports")[name]     # built only once the browser is known to be there
    started = time.perf_counter()
    _check_page(browser, page, _section_ids(spec), tmp_path_factory.mktemp("screenshots"), spec)
    print(f"browser checks of the {name} report: {time.perf_counter() - started:.1f} s")


def test_make_study_report_in_a_real_browser(browser, tmp_path_factory):
    """reports/paper/index.html as `make study` left it; the full study is never run here."""
    if not PAPER.exists():
        pytest.skip(f"{PAPER.relative_to(ROOT)} does not exist (`make study` writes it)")
    if 'id="page-size"' not in PAPER.read_text(errors="replace"):
        pytest.skip(f"{PAPER.relative_to(ROOT)} was written before the report had its contents and captions; "
                    "rebuild it from the stored results with `ibm-study report reports/paper`")
    if browser is None:
        pytest.fail(_missing(), pytrace=False)
    spec = PAPER.parent / "spec.toml"
    sections = _section_ids(spec) if spec.exists() else []
    _check_page(browser, PAPER, sections, tmp_path_factory.mktemp("screenshots"), spec)


def _section_ids(spec: Path) -> list[str]:
    """The contents entry each sweep of `spec` must have: its own, or "three-dimensions" for the 3D
    sweeps, which share that section (studies.report.page: tests/studies/report/test_report_3d.py asserts they have no
    id of their own)."""
    from studies.report.page import section_name
    return list(dict.fromkeys(section_name(s) for s in load(spec).sweeps))


def test_every_axis_of_every_figure_is_labelled(reports):
    assert not UNLABELLED, "\n".join(UNLABELLED)


# --- the documentation site ---------------------------------------------------------------------

SITE_FACTS = """
return {title: document.title, h1: (document.querySelector('h1') || {}).textContent || '',
        ids: Array.from(document.querySelectorAll('[id]')).map(e => e.id),
        code: document.querySelectorAll('div.highlight pre').length,
        broken: Array.from(document.images).filter(i => !(i.complete && i.naturalWidth > 0)).map(i => i.src)};
"""


@pytest.mark.slow
def test_the_documentation_site_in_a_real_browser(browser, tmp_path_factory):
    """The site's index, a gallery page and the API reference open with a quiet console: the index
    links the guides, the gallery page shows its code, the API page has an entry per documented object."""
    if browser is None:
        pytest.fail(_missing(), pytrace=False)
    site = tmp_path_factory.mktemp("site")
    built = build_site(site)
    assert built.returncode == 0, built.stderr[-3000:]
    expected = {"index.html": "ibm-mpm", "gallery/seed_reproduction.html": "validation, reproduced",
                "api.html": "API reference"}
    for page, heading in expected.items():
        browser.get_log("browser")
        browser.get((site / page).as_uri())
        WebDriverWait(browser, 30).until(lambda d: d.execute_script("return document.readyState === 'complete'"))
        facts = browser.execute_script(SITE_FACTS)
        assert heading in facts["h1"], (page, facts["h1"])
        assert not facts["broken"], (page, facts["broken"])
        severe = [entry for entry in browser.get_log("browser") if entry.get("level") == "SEVERE"]
        assert not severe, (page, severe)
        if page.startswith("gallery/"):
            assert facts["code"] >= 1, page
        if page == "api.html":
            assert {"ibm.implicit_boundary.solve_ibm", "studies.run.case.CaseSpec"} <= set(facts["ids"])
