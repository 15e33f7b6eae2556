# Two entry points that set themselves up on a fresh machine with Python 3.11+:
#   make study   -> run the main study and write the HTML report
#   make test    -> run the test suite
#   make bench   -> benchmarks (JSON), side by side with scikit-fem, scaling study
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup test study seed bench clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "Python 3.11+ is required, found " + sys.version.split()[0]'
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q

study: $(STAMP)
	$(VENV)/bin/ibm-study run studies/specs/paper.toml --out reports/paper

seed: $(STAMP)
	$(VENV)/bin/ibm-study seed

# Benchmarks (pytest-benchmark, JSON in reports/benchmarks/) with the side-by-side
# scikit-fem ratios printed, then the scaling study (table + figure in reports/scaling/).
# BENCH_COMPARE_DOFS sets the size of the side-by-side run (default 500000).
bench: $(STAMP)
	mkdir -p reports/benchmarks
	$(PY) -m pytest benchmarks -q -s -p no:cacheprovider --benchmark-enable \
		--benchmark-json=reports/benchmarks/benchmarks.json --benchmark-columns=min,median,max,rounds
	$(PY) -m studies.scaling --out reports/scaling

clean:
	rm -rf $(VENV) reports/*/ .pytest_cache
