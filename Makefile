# Two entry points that set themselves up on a fresh machine with Python 3.11+:
#   make study   -> run the main study and write the HTML report
#   make test    -> run the test suite
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

clean:
	rm -rf $(VENV) reports/*/ .pytest_cache
