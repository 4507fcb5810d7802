# tiltpile: the two commands a user needs are `make figures` and `make test`.
# Everything is installed into .venv from environment.txt by `make setup` (a dependency of both).
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.tiltpile-installed
PRESET ?= default
DATA ?= data/$(PRESET)
NOTEBOOKS := $(wildcard notebooks/fig*.ipynb)
export NUMBA_CACHE_DIR ?= $(CURDIR)/.venv/numba-cache

.PHONY: setup test test-fast figures bench clean-data

setup: $(STAMP)

$(STAMP): environment.txt pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r environment.txt
	$(PY) -m pip install -q --no-deps -e .
	$(PY) -m ipykernel install --sys-prefix --name tiltpile --display-name "tiltpile" > /dev/null
	touch $@

test: setup
	$(PY) -m pytest -q

test-fast: setup
	$(PY) -m pytest -q -m "not slow"

# `make figures [PRESET=default|smoke|paper] [RUNS=M] [SCHEDULER=tcp://host:port] [WORKERS=W]`:
# the ensemble (finished runs are skipped, interrupted ones resume), its observables, every figure
# notebook through papermill (executed copies in notebooks/executed/PRESET/), then the reproduction
# report. The default preset writes figures/ and paper/REPRODUCTION.md (both committed); other
# presets write figures/PRESET/ and its own REPRODUCTION.md there.
RUNS_smoke := 4
RUNS_default := 6
RUNS_paper := 50
RUNS ?= $(RUNS_$(PRESET))
FIGURES ?= $(if $(filter default,$(PRESET)),figures,figures/$(PRESET))
REPORT ?= $(if $(filter default,$(PRESET)),paper/REPRODUCTION.md,$(FIGURES)/REPRODUCTION.md)
EXECUTED := notebooks/executed/$(PRESET)
ENSEMBLE_ARGS := $(if $(SCHEDULER),--scheduler $(SCHEDULER)) $(if $(WORKERS),--workers $(WORKERS))

figures: setup
	@test -n "$(RUNS)" || { echo "unknown PRESET=$(PRESET): give RUNS=M"; exit 2; }
	$(PY) -m tiltpile ensemble --preset $(PRESET) --runs $(RUNS) --out $(DATA) $(ENSEMBLE_ARGS)
	$(PY) -m tiltpile observables $(DATA)
	@mkdir -p $(EXECUTED) $(FIGURES)
	@for nb in $(NOTEBOOKS); do \
	  out=$(EXECUTED)/$$(basename $$nb); \
	  echo "papermill $$nb -> $$out"; \
	  $(PY) -m papermill --kernel tiltpile --cwd $(CURDIR) --no-progress-bar $$nb $$out \
	    -p data_dir $(DATA) -p preset $(PRESET) -p figures_dir $(FIGURES) \
	    || { echo "papermill failed: $$nb (output notebook: $$out)"; exit 1; }; \
	done
	$(PY) -m tiltpile report --figures $(FIGURES) --out $(REPORT)

# `make bench`: the speed x accuracy chart (tiltpile.perfchart; ~15 min on one core): tolerance x
# time-step sweep on the smoke pile, Pareto plot, scaling in N; CSV, PNG and summary.json in
# figures/performance/. The single-pile timing stays available: `tiltpile bench --n 1000 --steps 200`.
bench: setup
	$(PY) -m tiltpile bench --chart figures/performance

clean-data:
	rm -rf data/
