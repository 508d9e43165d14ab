# Two commands: `make twin` runs the twin on its built-in defaults, `make test` runs the tests.
# Both create .venv on first use (Python 3.11 and PyPI only) and reuse it afterwards.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
PIP := $(BIN)/python -m pip --disable-pip-version-check -q

.PHONY: setup twin test bench clean

setup: $(STAMP)

$(STAMP): setup.py setup.cfg package.xml scripts/link_ament_files.py
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else \
	  "drill_twin needs Python 3.11 (the ROS 2 Jazzy wheels on PyPI are built for it); set PYTHON=")'
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(PIP) install --upgrade pip
	$(PIP) install -e '.[ros,test]'
	$(BIN)/python scripts/link_ament_files.py $(VENV) --activate
	$(BIN)/python -m drill_twin.cli.warm_up
	@touch $(STAMP)

twin: $(STAMP)
	$(BIN)/drill-twin twin

# Two workers (pytest-xdist), a test file to each in turn: the files' module fixtures run once.
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) build *.egg-info

# The figures and tables of docs/results, each with a MANIFEST.json (docs/results/README.md).
# `make results`: Table 1, the mean model and the map (a few minutes); the studies apart.
.PHONY: results results-montecarlo results-lateral results-drives results-all
results: $(STAMP)
	$(BIN)/python scripts/make_results.py results

results-montecarlo: $(STAMP)
	$(BIN)/python scripts/make_results.py montecarlo

results-lateral: $(STAMP)
	$(BIN)/python scripts/make_results.py lateral

results-drives: $(STAMP)
	$(BIN)/python scripts/make_results.py drives

results-all: $(STAMP)
	$(BIN)/python scripts/make_results.py all
