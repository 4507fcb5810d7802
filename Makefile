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

figures: setup
	@if [ -z "$(NOTEBOOKS)" ]; then echo "no figure notebooks yet (see issue 5)"; fi
	@mkdir -p notebooks/executed figures
	@for nb in $(NOTEBOOKS); do \
	  out=notebooks/executed/$$(basename $$nb); \
	  $(PY) -m papermill --kernel tiltpile $$nb $$out -p data_dir $(DATA) -p preset $(PRESET) \
	    || { echo "papermill failed: $$nb (output notebook: $$out)"; exit 1; }; \
	done

bench: setup
	$(PY) -m tiltpile bench

clean-data:
	rm -rf data/
