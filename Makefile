# Two entry points that set themselves up on a fresh machine with Python 3.11+:
#   make study   -> run the main study and write the HTML report
#   make test    -> run the test suite (installs Debian's chromium and chromium-driver for the browser test)
#   make bench   -> benchmarks (JSON), side by side with scikit-fem, scaling study
#   make docs    -> the documentation site (Sphinx) in reports/docs
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

CHROMIUM     := /usr/bin/chromium
CHROMEDRIVER := /usr/bin/chromedriver

.PHONY: setup browser test study seed bench docs clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "Python 3.11+ is required, found " + sys.version.split()[0]'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

# The browser test (tests/studies/report/test_browser.py) opens the reports in headless Chromium: Debian's packages,
# installed here when missing (as root, or through sudo), non-interactively (CI, no standard input).
browser:
	@if [ -x $(CHROMIUM) ] && [ -x $(CHROMEDRIVER) ]; then exit 0; fi; \
	if [ "$$(id -u)" = 0 ]; then sudo=""; \
	elif command -v sudo >/dev/null 2>&1; then sudo="sudo"; \
	else echo "make test: the browser test needs Debian's chromium and chromium-driver; install them as root: apt-get install chromium chromium-driver" >&2; exit 1; fi; \
	echo "installing Debian's chromium and chromium-driver (apt-get) for the browser test"; \
	$$sudo env DEBIAN_FRONTEND=noninteractive sh -c 'apt-get update -qq && apt-get install -y -qq chromium chromium-driver' </dev/null >/dev/null \
		|| { echo "make test: could not install chromium and chromium-driver with apt-get; install them as root: apt-get install chromium chromium-driver" >&2; exit 1; }; \
	[ -x $(CHROMIUM) ] && [ -x $(CHROMEDRIVER) ] \
		|| { echo "make test: apt-get ran but $(CHROMIUM) or $(CHROMEDRIVER) is still missing" >&2; exit 1; }

# The suite on TEST_WORKERS processes (pytest-xdist), a test file per process at a time so that
# a module's shared fixtures are computed once; BLAS and PARDISO on one thread each, so the
# processes do not oversubscribe the cores.
TEST_WORKERS ?= 2
test: browser $(STAMP)
	OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 \
		$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

study: $(STAMP)
	$(VENV)/bin/ibm-study run studies/specs/paper.toml --out reports/paper

seed: $(STAMP)
	$(VENV)/bin/ibm-study seed

# Benchmarks (pytest-benchmark, JSON in reports/benchmarks/) with the side-by-side
# scikit-fem ratios printed, then the scaling study (table + figure in reports/scaling/, 3D in
# reports/scaling-3d/: about 5 minutes more).
# BENCH_COMPARE_DOFS sets the size of the side-by-side run (default 500000).
bench: $(STAMP)
	mkdir -p reports/benchmarks
	$(PY) -m pytest benchmarks -q -s -p no:cacheprovider --benchmark-enable \
		--benchmark-json=reports/benchmarks/benchmarks.json --benchmark-columns=min,median,max,rounds
	$(PY) -m studies.run.scaling --out reports/scaling
	$(PY) -m studies.run.scaling --dim 3 --out reports/scaling-3d

# The documentation site: docs/*.md (MyST), the API reference (autodoc, numpydoc) and the gallery
# (sphinx-gallery runs examples/*.py), built by Sphinx; a warning (a broken link, a page left out of
# the table of contents, a docstring that does not parse) fails the build.
docs: $(STAMP)
	$(PY) -m sphinx -q -W --keep-going -b html docs reports/docs
	@echo "the site: reports/docs/index.html"

clean:
	rm -rf $(VENV) reports/*/ .pytest_cache docs/_build docs/gallery docs/sg_execution_times.rst
