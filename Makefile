# tiltpile: the two commands a user needs are `make figures` and `make test`.
# Everything is installed into .venv from environment.txt by `make setup` (a dependency of both).
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.tiltpile-installed
export NUMBA_CACHE_DIR ?= $(CURDIR)/.venv/numba-cache

.PHONY: setup test test-fast figures reports docs bench clean-data FORCE
.SECONDEXPANSION:

setup: $(STAMP)

$(STAMP): environment.txt pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r environment.txt
	$(PY) -m pip install -q --no-deps -e .
	$(PY) -m ipykernel install --sys-prefix --name tiltpile --display-name "tiltpile" > /dev/null
	@# The kernel logs errors only: ipykernel >= 7.3 warns at every start that its loopback TCP
	@# sockets are unencrypted, a line per notebook that papermill's CLI cannot turn off. And not
	@# the interrupt of papermill's shutdown, an ERROR line after a notebook that ran without fault
	@# (the extension tiltpile.figures.kernel drops that line alone: its docstring says why).
	$(PY) -c "import json, pathlib; p = pathlib.Path('$(VENV)/share/jupyter/kernels/tiltpile/kernel.json'); \
	  k = json.loads(p.read_text()); k['argv'] += ['--IPKernelApp.log_level=ERROR', '--IPKernelApp.extra_extensions=tiltpile.figures.kernel']; \
	  p.write_text(json.dumps(k, indent=1))"
	touch $@

test: setup
	$(PY) -m pytest -q

test-fast: setup
	$(PY) -m pytest -q -m "not slow"

# ---------------------------------------------------------------------------------------------
# `make figures [PRESET=default|smoke|paper|... | SCALE=s HISTORY=h ENGINE=e] [RUNS=M] [SCHEDULER=tcp://host:port]
#               [WORKERS=W] [SET="section.key=value ..."] [NB="-p name value ..."] [VARIANT=name]`
#
# A build graph: the ensemble (finished runs are skipped, interrupted ones resume) and its
# observables, then one target per figure, $(FIGURES)/figN_<name>.json (with its PNG and PDF),
# rebuilt only when its notebook, the package (any file under src/), the runs or the notebook
# parameters changed; then the reproduction report from the JSON.
# The default preset writes figures/ and paper/REPRODUCTION.md (both committed); another preset
# writes figures/PRESET/. SET (configuration keys, a new ensemble) and NB (papermill parameters,
# e.g. NB="-p lost_gap 0.0001") need VARIANT=name: the variant's runs go to data/PRESET-VARIANT/
# (with NB alone, links to the preset's runs) and its figures to figures/VARIANT/
# (figures/PRESET/VARIANT/ for another preset), leaving the default figures untouched. A name in
# NB that none of the notebooks to run declares stops make before anything runs, naming it
# (tiltpile.figures.parameters); each notebook gets the parameters it declares.
#
# Records (`tiltpile record`, docs/cli.md): one small file per finished run, RECORDS/run_SSSS.npz
# (RECORDS default: FIGURES/records/; a variant with NB alone reads its preset's), holding what the
# figures read from the run, so that a preset's records can be committed in place of its run files
# (figures/paper/records/). FROM=auto (default): when DATA holds no run files and RECORDS holds
# records, the figures are built from the records and no ensemble is run; otherwise the ensemble
# is run as above and, if the directory RECORDS exists, its records are brought up to date with
# the run files (new or changed runs) before the figures are built from the run files.
# FROM=records always builds from RECORDS, FROM=runs always from the ensemble.
# From the records, RUNS=M takes the first M of them by seed (all of them when there are no more):
# `make figures PRESET=paper RUNS=16` rebuilds figures of the first 16 runs while later runs'
# records are committed beside them. The notebooks then read EXECUTED/records-M/, links to those.
# `make records [PRESET=P] [DATA=/path/to/runs] [WORKERS=W]` writes RECORDS from the finished run
# files of DATA (records up to date are skipped), running nothing else. PARAMS='{"name": value,
# ...}' (a JSON object of analysis parameters, `tiltpile record --params`) writes them with the
# tables at those parameters, into RECORDS=dir, which must then be given: one parameter set per
# directory, e.g. `make records PRESET=paper DATA=/work/runs/paper
# PARAMS='{"contact_rule": "gap:0.00218"}' RECORDS=figures/paper/records-gap`.
#
# The presets (docs/presets.md) are a scale, a history and an engine each, declared once in the
# package (tiltpile.config; `tiltpile presets` prints them): `make figures SCALE=paper HISTORY=5x
# ENGINE=dem` is PRESET=paper-5x-dem, an axis left out taking its default (scale default, the
# scale's own history, engine cd). HISTORY=preset|repose+D is make study's own, not an axis.
# make reads the presets (their names, and the runs of each one's `make figures`) from
# `python -m tiltpile.cli.presets`, which needs the standard library alone (the venv's python, or
# $(PYTHON) before `make setup`), and only when a goal needs them.
PRESETS_CMD = PYTHONPATH=$(CURDIR)/src $(if $(wildcard $(PY)),$(PY),$(PYTHON)) -m tiltpile.cli.presets
AXES_GIVEN := $(strip $(if $(SCALE),--scale '$(SCALE)') $(if $(filter-out preset repose+%,$(HISTORY)),--history '$(HISTORY)') \
                      $(if $(ENGINE),--engine '$(ENGINE)'))
AXES_SAID = $(strip $(foreach v,SCALE HISTORY ENGINE,$(if $($(v)),$(v)=$($(v)))))
ifneq ($(AXES_GIVEN),)
AXES_PRESET := $(shell $(PRESETS_CMD) --name $(AXES_GIVEN) 2>&1)
ifneq ($(words $(AXES_PRESET)),1)
$(error $(AXES_SAID): $(subst tiltpile presets: error: ,,$(AXES_PRESET)))
endif
ifeq ($(origin PRESET),command line)
ifneq ($(PRESET),$(AXES_PRESET))
$(error PRESET=$(PRESET) is not $(AXES_PRESET), the preset of $(AXES_SAID): give one or the other)
endif
endif
PRESET := $(AXES_PRESET)
endif
PRESET ?= default
VARIANT ?=
SET ?=
NB ?=
# every preset's name:runs:report (config.ALL_PRESETS), read once when first needed; the runs of
# PRESET's `make figures` from it
PRESET_ROWS = $(eval PRESET_ROWS := $(shell $(PRESETS_CMD) --make))$(PRESET_ROWS)
preset_names = $(foreach r,$(1),$(firstword $(subst :, ,$(r))))
RUNS ?= $(word 2,$(subst :, ,$(filter $(PRESET):%,$(PRESET_ROWS))))

# The analysis's numbers bit for bit from one x86-64 machine to another. numpy's AVX-512 kernels
# (its vectorized exp, log, power among them) and OpenBLAS's per-CPU kernels (SkylakeX against
# Haswell) round the last bits differently from the AVX2 ones, which moved Fig. 2's mixture fit
# and Fig. 5's fits by 1e-16 to 1e-12 relative between two machines of this workplace. Every
# analysis command below (observables, records, notebooks, zcount) runs with both held to the
# AVX2 level; the simulation does not need it (tests/sim/test_paper_pin.py).
ifeq ($(shell uname -m),x86_64)
ANALYSIS_ENV := NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" \
                $(if $(shell grep -qw avx2 /proc/cpuinfo 2>/dev/null && echo y),OPENBLAS_CORETYPE=Haswell)
endif

BASE_DATA := data/$(PRESET)
ifeq ($(strip $(VARIANT)),)
ifneq ($(strip $(SET)$(NB)),)
$(error SET and NB change the results: give VARIANT=name, so that the default figures stay untouched)
endif
DATA ?= $(BASE_DATA)
FIGURES ?= $(if $(filter default,$(PRESET)),figures,figures/$(PRESET))
REPORT ?= $(FIGURES)/REPRODUCTION.md
# the main report (tiltpile.report.main), rewritten by the presets it reads first
MAIN_REPORT := $(if $(filter default paper,$(PRESET)),$(if $(filter figures figures/paper,$(FIGURES)),paper/REPRODUCTION.md))
EXECUTED := notebooks/executed/$(PRESET)
else
DATA ?= data/$(PRESET)-$(VARIANT)
FIGURES ?= figures/$(if $(filter default,$(PRESET)),,$(PRESET)/)$(VARIANT)
REPORT ?= $(FIGURES)/REPRODUCTION.md
EXECUTED := notebooks/executed/$(PRESET)-$(VARIANT)
endif

BASE_FIGURES := $(if $(filter default,$(PRESET)),figures,figures/$(PRESET))
RECORDS ?= $(if $(strip $(SET)),$(FIGURES),$(BASE_FIGURES))/records
FROM ?= auto
ifeq ($(FROM),auto)
FROM_RECORDS := $(if $(wildcard $(DATA)/run_*.h5),,$(if $(wildcard $(RECORDS)/run_*.npz),yes))
else ifeq ($(FROM),records)
FROM_RECORDS := yes
else ifeq ($(FROM),runs)
FROM_RECORDS :=
else
$(error FROM=$(FROM): give FROM=auto, FROM=runs or FROM=records)
endif
# what the notebooks read (data_dir) and the target that stands for it
ifeq ($(FROM_RECORDS),yes)
ALL_RECORDS := $(sort $(wildcard $(RECORDS)/run_*.npz))
ifneq ($(strip $(RUNS)),)
ifneq ($(shell test "$(RUNS)" -ge 1 2> /dev/null && echo y),y)
$(error RUNS=$(RUNS): give the number of runs, a whole number >= 1)
endif
endif
USED_RECORDS := $(if $(strip $(RUNS)),$(wordlist 1,$(RUNS),$(ALL_RECORDS)),$(ALL_RECORDS))
ifeq ($(words $(USED_RECORDS)),$(words $(ALL_RECORDS)))
FIG_DATA := $(RECORDS)
else
FIG_DATA := $(EXECUTED)/records-$(RUNS)
endif
FIG_INPUT := $(EXECUTED)/.records
else
FIG_DATA := $(DATA)
FIG_INPUT := $(DATA)/.runs
endif

NOTEBOOKS := $(wildcard notebooks/fig*.ipynb)
FIG_JSON := $(patsubst notebooks/%.ipynb,$(FIGURES)/%.json,$(NOTEBOOKS))
# What a figure, a study or a report is computed with: the package. Any edit under src/ rebuilds
# them (minutes from records); their notebooks and data are their other inputs. No list to keep.
PACKAGE := $(shell find src/tiltpile -name '*.py' -not -path '*/__pycache__/*')
ENSEMBLE_ARGS := $(if $(SCHEDULER),--scheduler $(SCHEDULER)) $(if $(WORKERS),--workers $(WORKERS)) \
                 $(foreach kv,$(SET),--set '$(kv)')
# notebooks/run_diagnostics.ipynb, if present: executed on the first run of the ensemble
# (parameters run_file, data_dir, preset, figures_dir); its pictures are not figures of the paper
# nor a regression baseline, so they go beside the executed notebooks (not from records: no run file)
DIAGNOSTICS := $(if $(FROM_RECORDS),,$(if $(wildcard notebooks/run_diagnostics.ipynb),$(EXECUTED)/diagnostics/.executed))
# a file is rewritten only when its new content differs, so that its dependents rebuild only then
define update_if_changed
if cmp -s $(1).tmp $(1); then rm -f $(1).tmp; else mv -f $(1).tmp $(1); fi
endef

figures: $(FIG_JSON) $(REPORT) $(MAIN_REPORT) $(DIAGNOSTICS)

# An unknown PRESET (none of the package's presets, no RUNS=M, no records to build from) is
# answered with the list of the presets when make reads this file, before anything is installed,
# written or locked (tests/workflow/test_presets.py): for the ensemble, a study, or figures made
# from runs.
PRESET_NAMES = $(sort $(call preset_names,$(PRESET_ROWS)))
UNKNOWN_PRESET = unknown PRESET=$(PRESET): the presets are $(PRESET_NAMES) (`tiltpile presets`: their scale, history and engine)
ifneq ($(filter ensemble study,$(MAKECMDGOALS))$(if $(ALL_RECORDS),,$(filter figures $(FIG_JSON) $(REPORT),$(MAKECMDGOALS))),)
ifeq ($(strip $(RUNS)),)
$(error $(UNKNOWN_PRESET))
endif
endif

# One build at a time per figures directory: before anything is written (but after the NB check,
# which writes nothing), FIGURES/.build.lock is taken for this make process and held until it
# exits, by a background process that watches it (`python -m tiltpile.outputs hold`; a flock the
# kernel releases even when make is killed). A second `make figures` on the same FIGURES, or
# any of its figure targets, is refused in one line naming the directory and the make that holds
# it. Every target that writes (the runs' stamp, the records' stamp, the notebook parameters and
# through them each figure, the report) waits for it. The commands run inside take their own
# locks: `tiltpile ensemble` refuses a second one on its DIR, `observables` and `record` wait
# for the one writing their cache or RECORDS (docs/faults.md, "two builds at once").
.PHONY: build-lock
build-lock: | $(STAMP) check-nb
	@$(PY) -m tiltpile.outputs hold $(FIGURES) .build.lock --what "make figures" --pid $$PPID

# The runs and their observables. Always checked (the ensemble skips finished runs); the stamp
# lists every run file's name, size and time and changes only when a run does.
$(DATA)/.runs: FORCE | $(STAMP) check-nb build-lock
	@test -n "$(RUNS)" || { echo "$(UNKNOWN_PRESET)"; exit 2; }
ifeq ($(strip $(SET)),)
	$(PY) -m tiltpile ensemble --preset $(PRESET) --runs $(RUNS) --out $(BASE_DATA) $(ENSEMBLE_ARGS)
ifneq ($(DATA),$(BASE_DATA))
	@mkdir -p $(DATA) && for f in $(BASE_DATA)/run_*.h5; do ln -sfn ../$(PRESET)/$$(basename $$f) $(DATA)/; done
endif
else
	$(PY) -m tiltpile ensemble --preset $(PRESET) --runs $(RUNS) --out $(DATA) $(ENSEMBLE_ARGS)
endif
ifeq ($(strip $(NB)),)
	$(ANALYSIS_ENV) $(PY) -m tiltpile observables $(DATA) --quiet > /dev/null
endif
	@if [ -d $(RECORDS) ]; then set -o pipefail; $(ANALYSIS_ENV) $(PY) -m tiltpile record $(DATA) --out $(RECORDS) \
	  --quiet $(if $(WORKERS),--workers $(WORKERS)) | tail -1; fi
	@stat -L -c '%n %s %Y' $(DATA)/run_*.h5 > $@.tmp; $(call update_if_changed,$@)

# The records instead of the runs (FROM_RECORDS): always checked; the stamp lists the SHA-256 of
# every record used and changes only when one of them does. With fewer records used than there
# are (RUNS), FIG_DATA is made anew: links to the records used.
$(EXECUTED)/.records: FORCE | check-nb build-lock
	@mkdir -p $(@D)
	@ls $(RECORDS)/run_*.npz > /dev/null 2>&1 || { echo "no records run_*.npz in $(RECORDS): write them with \
	  'make records PRESET=$(PRESET) DATA=/path/to/runs'"; exit 2; }
ifeq ($(FIG_DATA),$(RECORDS))
	@echo "figures from the records in $(RECORDS) ($(words $(ALL_RECORDS)) runs; no ensemble is run)"
else
	@echo "figures from the first $(RUNS) of the $(words $(ALL_RECORDS)) records in $(RECORDS) (RUNS=$(RUNS); no ensemble is run)"
	@rm -rf $(FIG_DATA) && mkdir -p $(FIG_DATA) && ln -s $(abspath $(USED_RECORDS)) $(FIG_DATA)/
endif
	@(cd $(RECORDS) && sha256sum $(notdir $(USED_RECORDS))) > $@.tmp; $(call update_if_changed,$@)

.PHONY: records
records: | $(STAMP)
	$(if $(strip $(PARAMS)),$(if $(filter file,$(origin RECORDS)),$(error make records PARAMS=...: give RECORDS=dir, a directory of its own for the records at those parameters (not $(RECORDS)))))
	$(ANALYSIS_ENV) $(PY) -m tiltpile record $(DATA) --out $(RECORDS) $(if $(WORKERS),--workers $(WORKERS)) \
	  $(if $(strip $(PARAMS)),--params '$(PARAMS)')

# `make ensemble [PRESET=paper] [DATA=/path/outside/the/checkout] [WORKERS=W]`: only the ensemble,
# for a computation spread over many sessions (README, "The paper's scale, over many sessions").
# It runs from a copy of the committed code, DATA-code/COMMIT/src (`git archive`), so that editing
# the checkout never reaches its workers, and skips the seeds whose record is in RECORDS
# (--skip-recorded; none there: nothing skipped). Finished runs are skipped and interrupted ones
# resume from their checkpoints, so the same command starts it anew in every session, e.g.
# `nohup make ensemble PRESET=paper DATA=/work/runs/paper WORKERS=2 > /work/runs/paper.log 2>&1 &`.
# RERUN=1 computes the recorded seeds too (their run files again, for an analysis the records
# cannot do; FIRST=S starts at seed S): `tiltpile verify DATA --against RECORDS` then checks that
# each reproduces the frames its record was made from.
ENSEMBLE_COMMIT = $(shell git rev-parse --short=12 HEAD 2>/dev/null)
ENSEMBLE_CODE = $(DATA)-code/$(ENSEMBLE_COMMIT)
.PHONY: ensemble
ensemble: | $(STAMP)
	@test -n "$(RUNS)" || { echo "$(UNKNOWN_PRESET)"; exit 2; }
	@test -n "$(ENSEMBLE_COMMIT)" || { echo "make ensemble runs a copy of the committed code: run it in a git checkout"; exit 2; }
	@test -d $(ENSEMBLE_CODE)/src || { rm -rf $(ENSEMBLE_CODE).tmp && mkdir -p $(ENSEMBLE_CODE).tmp && \
	  git archive $(ENSEMBLE_COMMIT) src | tar -x -C $(ENSEMBLE_CODE).tmp && mv $(ENSEMBLE_CODE).tmp $(ENSEMBLE_CODE); }
	NUMBA_CACHE_DIR=$(ENSEMBLE_CODE)/numba-cache PYTHONPATH=$(ENSEMBLE_CODE)/src \
	  $(PY) -m tiltpile ensemble --preset $(PRESET) --runs $(RUNS) --out $(DATA) $(if $(FIRST),--first-seed $(FIRST)) $(ENSEMBLE_ARGS) \
	  $(if $(RERUN),,$(if $(wildcard $(RECORDS)/run_*.npz),--skip-recorded $(RECORDS))) --quiet

# NB, checked before anything runs: every name must be a parameter of a notebook this invocation
# executes (those of the figure targets named, the preparation study's, or every figure's). Then
# per notebook, the parameters of NB it declares, as the YAML file papermill reads (-f), beside the
# executed notebooks (git ignores them); its first line names the data and preset, so that the
# file, and the figure after it, changes only when what the notebook is given does.
NB_NOTEBOOKS := $(sort $(patsubst $(FIGURES)/%.json,notebooks/%.ipynb,$(filter $(FIG_JSON),$(MAKECMDGOALS))) \
                       $(if $(filter preparation,$(MAKECMDGOALS)),notebooks/preparation.ipynb) \
                       $(if $(filter figures $(REPORT),$(MAKECMDGOALS)),$(NOTEBOOKS)))
ifneq ($(strip $(NB)),)
ifeq ($(strip $(NB_NOTEBOOKS)),)
$(error NB: none of the goals ($(or $(MAKECMDGOALS),the default)) executes a notebook; NB applies to figures, a figure's JSON and preparation)
endif
endif
.PHONY: check-nb
check-nb: | $(STAMP)
ifneq ($(strip $(NB)),)
	@$(PY) -m tiltpile.figures.parameters check $(NB_NOTEBOOKS) -- $(NB)
endif
$(EXECUTED)/%.parameters.yaml: FORCE | $(STAMP) check-nb build-lock
	@mkdir -p $(@D)
	@$(PY) -m tiltpile.figures.parameters select notebooks/$*.ipynb \
	  --note 'data_dir=$(FIG_DATA) preset=$(PRESET)' -- $(NB) > $@.tmp && $(call update_if_changed,$@)

# one target per figure: notebooks/figN_<name>.ipynb (tiltpile.figures.build)
$(FIG_JSON): $(FIGURES)/%.json: notebooks/%.ipynb $(PACKAGE) $(FIG_INPUT) \
                   $(EXECUTED)/%.parameters.yaml | $(STAMP)
	@mkdir -p $(EXECUTED) $(FIGURES)
	@echo "papermill $< -> $(EXECUTED)/$*.ipynb"
	@$(ANALYSIS_ENV) $(PY) -m papermill --kernel tiltpile --cwd $(CURDIR) --no-progress-bar $< $(EXECUTED)/$*.ipynb \
	  -f $(EXECUTED)/$*.parameters.yaml -p data_dir $(FIG_DATA) -p preset $(PRESET) -p figures_dir $(FIGURES) \
	  || { echo "papermill failed: $< (output notebook: $(EXECUTED)/$*.ipynb)"; exit 1; }
	@test -f $@ || { echo "$< did not write $@"; exit 1; }
	@touch $@

# A scale's report reads its own figures' JSON (tiltpile.report.inputs); the main report and
# paper/STUDIES.md read every scale's (below). REPORT_SCALES: the scales with figures of their
# own below figures/ (config.PRESET_TABLE's report "claims" or "fig2"); REPORT_COMPARED: those
# whose every claim's verdict the report sets beside the default's ("claims").
REPORT_SCALES = $(filter-out default,$(call preset_names,$(filter %:claims %:fig2,$(PRESET_ROWS))))
REPORT_COMPARED = $(filter-out default,$(call preset_names,$(filter %:claims,$(PRESET_ROWS))))
REPORT_READS := $(FIG_JSON) $(wildcard $(FIGURES)/fig*.json)
$(REPORT): $(REPORT_READS) $(PACKAGE) $(wildcard src/tiltpile/report/templates/*.j2) | $(STAMP)
	$(PY) -m tiltpile report --figures $(FIGURES) --out $@

# The main report, paper/REPRODUCTION.md: the paper's scale first, every axis beside it; it reads
# the figures' JSON of every scale and study under figures/ (tiltpile.report.main), and the wall
# times of their runs from the committed records (tiltpile.report.wall: the figures' JSON hold none).
# `make docs`: the README's and the docs' generated blocks from the committed figures' JSON
# (tiltpile.report.blocks); `make reports` runs it too.
docs: | $(STAMP)
	$(PY) -m tiltpile docs

ALL_REPORT_READS := $(wildcard figures/fig*.json figures/*.json figures/*/fig*.json figures/*/*.json \
                      figures/*/same-piles/*.json figures/*/same-piles/*/fig*.json \
                      figures/records/run_*.npz figures/*/records/run_*.npz)
paper/REPRODUCTION.md: $(ALL_REPORT_READS) $(PACKAGE) \
                       $(wildcard src/tiltpile/report/templates/*.j2) | $(STAMP)
	$(PY) -m tiltpile report --root figures --out $@
	$(PY) -m tiltpile report --root figures --studies --out paper/STUDIES.md

# `make reports`: every committed report rewritten from the committed figures' JSON, nothing run
# or executed (a few seconds): the main report, then each scale's own. Each scale's report reads
# every scale's JSON, so after the figures of one scale change, all of them change
# (tests/figures/test_report.py checks they agree).
reports: | $(STAMP)
	$(PY) -m tiltpile report --root figures --out paper/REPRODUCTION.md
	$(PY) -m tiltpile report --root figures --studies --out paper/STUDIES.md
	$(PY) -m tiltpile docs
	$(PY) -m tiltpile report --figures figures --out figures/REPRODUCTION.md
	@set -e; for s in $(REPORT_SCALES); do \
	  $(PY) -m tiltpile report --figures figures/$$s --out figures/$$s/REPRODUCTION.md; done

$(EXECUTED)/diagnostics/.executed: notebooks/run_diagnostics.ipynb $(DATA)/.runs | $(STAMP)
	@mkdir -p $(EXECUTED) $(@D)
	$(ANALYSIS_ENV) $(PY) -m papermill --kernel tiltpile --cwd $(CURDIR) --no-progress-bar $< $(EXECUTED)/run_diagnostics.ipynb \
	  -p run_file $$(ls $(DATA)/run_*.h5 | head -1) -p data_dir $(DATA) -p preset $(PRESET) -p figures_dir $(@D) \
	  || { echo "papermill failed: $< (output notebook: $(EXECUTED)/run_diagnostics.ipynb)"; exit 1; }
	@touch $@

# `make bench`: the speed x accuracy chart (benchmarks/chart; ~15 min on one core): tolerance x
# time-step sweep on the smoke pile, Pareto plot, scaling in N; CSV, PNG and summary.json in
# figures/performance/. The single-pile timing: `python -m benchmarks.timing --n 1000 --steps 200`.
bench: setup
	$(PY) -m benchmarks.chart figures/performance

clean-data:
	rm -rf data/

# `make preparation [PREP_HISTORIES="fresh cyc10 cyc16 cyc18"] [PREP_ROOT=data/preparation]
#                   [PREP_RUNS=6] [PREP_WORKERS=W] [PREP_LABELS="fresh|..."] [PREP_FIGURES=figures]`:
# the preparation study (docs/figures.md). For each history H of PREP_HISTORIES, the ensemble
# PREP_ROOT/H of the default preset with the settings PREP_SET_H (PREP_RUNS seeds from 0;
# finished runs are skipped, interrupted ones resume) and its repose angles, PREP_ROOT/H/repose.json
# (`tiltpile repose`, redone when a run file is newer); then notebooks/preparation.ipynb on them
# (the first history is the reference, normally fresh piles) into
# PREP_FIGURES/preparation.{png,pdf,json}. PREP_DIRS="dir ..." instead names existing ensembles
# (run files, or their records alone: no frame-0 structure then) and runs nothing. NB="-p name value ..." with VARIANT=V passes analysis parameters to the
# notebook, writing figures/V/ (PREP_FIGURES) instead. `make zcount` charts <z> by counting rule
# on the same ensembles (`tiltpile zcount`, PREP_FIGURES/zcount.{png,json}). About 3.5 hours on two cores for the five
# histories (a cycled run costs 2.6-6 times the sweeps of a fresh one).
PREP_ROOT ?= data/preparation
PREP_RUNS ?= 6
PREP_WORKERS ?=
PREP_HISTORIES ?= fresh cyc10 cyc16 cyc18 cyc16r10
# Deboeuf et al.'s history: 0 -> theta_rev, two full cycles +-theta_rev, back to 0, at the ramp's
# rate (the default preset's own history is cyc16r10; fresh is the preset default-fresh)
PREP_SET_fresh := protocol.cycles=0 protocol.theta_rev_deg=0.0 protocol.pretilt_per_step_deg=0.0
PREP_SET_cyc10 := protocol.cycles=2 protocol.theta_rev_deg=10.0 protocol.pretilt_per_step_deg=0.0
PREP_SET_cyc16 := protocol.cycles=2 protocol.theta_rev_deg=16.0 protocol.pretilt_per_step_deg=0.0
PREP_SET_cyc18 := protocol.cycles=2 protocol.theta_rev_deg=18.0 protocol.pretilt_per_step_deg=0.0
# the same history at 10x the ramp's rate (0.02 deg per step in its legs): the rate check
PREP_SET_cyc16r10 := $(PREP_SET_cyc16) protocol.pretilt_per_step_deg=0.02
PREP_GIVEN := $(PREP_DIRS)
PREP_DIRS ?= $(foreach h,$(PREP_HISTORIES),$(PREP_ROOT)/$(h))
PREP_LABELS ?=
PREP_FIGURES ?= figures$(if $(strip $(VARIANT)),/$(VARIANT))
# one executed directory per output directory: a study into figures/paper does not retire the
# default one's stamps
PREP_EXECUTED := notebooks/executed/preparation$(subst /,-,$(patsubst figures%,%,$(PREP_FIGURES)))
ifneq ($(strip $(SET)),)
ifneq ($(filter preparation preparation-runs zcount,$(MAKECMDGOALS)),)
$(error SET does not apply to the preparation study: its ensembles are set by PREP_SET_<history>)
endif
endif
prep_comma := ,
prep_empty :=
prep_space := $(prep_empty) $(prep_empty)
PREP_PARAMS = {"data_dirs": [$(subst $(prep_space),$(prep_comma),$(foreach d,$(PREP_DIRS),"$(d)"))], \
               "labels": [$(if $(strip $(PREP_LABELS)),"$(subst |,"$(prep_comma)",$(PREP_LABELS))")], \
               "figures_dir": "$(PREP_FIGURES)"}
.PHONY: preparation preparation-runs zcount
preparation-runs: | $(STAMP) check-nb
ifeq ($(strip $(PREP_GIVEN)),)
	@$(foreach h,$(PREP_HISTORIES),\
	  $(PY) -m tiltpile ensemble --preset default --runs $(PREP_RUNS) --out $(PREP_ROOT)/$(h) \
	    $(if $(PREP_WORKERS),--workers $(PREP_WORKERS)) $(foreach kv,$(PREP_SET_$(h)),--set '$(kv)') \
	  && { test -f $(PREP_ROOT)/$(h)/repose.json \
	       && test -z "$$(find $(PREP_ROOT)/$(h) -maxdepth 1 -name 'run_*.h5' -newer $(PREP_ROOT)/$(h)/repose.json)" \
	       || $(PY) -m tiltpile repose $(PREP_ROOT)/$(h) --json $(PREP_ROOT)/$(h)/repose.json \
	            $(if $(PREP_WORKERS),--workers $(PREP_WORKERS)); } || exit 1;)
endif

# The study's inputs, as a file its targets depend on: every run file and repose.json of
# PREP_DIRS (name, size, time), rewritten only when one changes; and its notebook parameters.
$(PREP_EXECUTED)/.inputs: FORCE | preparation-runs
	@mkdir -p $(@D)
	@for d in $(PREP_DIRS); do stat -L -c '%n %s %Y' $$d/run_*.h5 $$d/run_*.npz \
	  $$(ls $$d/repose.json 2> /dev/null) 2> /dev/null; done > $@.tmp; $(call update_if_changed,$@)
$(PREP_EXECUTED)/preparation.parameters.yaml: FORCE | $(STAMP) check-nb
	@mkdir -p $(@D)
	@$(PY) -m tiltpile.figures.parameters select notebooks/preparation.ipynb \
	  --note '$(PREP_PARAMS)' -- $(NB) > $@.tmp && $(call update_if_changed,$@)

# The study and the <z> chart are rebuilt when their code, notebook, parameters or inputs change
# (or their output is missing); .executed and .zcount stand for PREP_FIGURES/preparation.json and
# zcount.json, which the report reads without building them.
preparation: $(PREP_EXECUTED)/.executed
$(PREP_EXECUTED)/.executed: notebooks/preparation.ipynb $(PACKAGE) $(PREP_EXECUTED)/.inputs \
                            $(PREP_EXECUTED)/preparation.parameters.yaml \
                            $(if $(wildcard $(PREP_FIGURES)/preparation.json),,FORCE) | $(STAMP)
	@mkdir -p $(PREP_FIGURES)
	@echo "papermill notebooks/preparation.ipynb -> $(PREP_EXECUTED)/preparation.ipynb"
	@$(ANALYSIS_ENV) $(PY) -m papermill --kernel tiltpile --cwd $(CURDIR) --no-progress-bar notebooks/preparation.ipynb \
	  $(PREP_EXECUTED)/preparation.ipynb -f $(PREP_EXECUTED)/preparation.parameters.yaml -y '$(PREP_PARAMS)' \
	  || { echo "papermill failed: notebooks/preparation.ipynb (output notebook: $(PREP_EXECUTED)/preparation.ipynb)"; exit 1; }
	@test -f $(PREP_FIGURES)/preparation.json || { echo "notebooks/preparation.ipynb did not write $(PREP_FIGURES)/preparation.json"; exit 1; }
	@touch $@

# `make preparation-paper`: the same study at the paper's scale from the committed records,
# cycled (figures/paper/records) against fresh (figures/paper-fresh/records), slides at the
# avalanche angle's 1e-3 m g d per grain, into figures/paper/preparation.{png,json} (seconds)
.PHONY: preparation-paper
preparation-paper:
	@$(MAKE) --no-print-directory preparation PREP_DIRS="figures/paper-fresh/records figures/paper/records" \
	  PREP_FIGURES=figures/paper VARIANT=paper-prep NB="-p slide_ke 0.001"

zcount: $(PREP_EXECUTED)/.zcount
$(PREP_EXECUTED)/.zcount: $(PACKAGE) $(PREP_EXECUTED)/.inputs \
                          $(if $(wildcard $(PREP_FIGURES)/zcount.json),,FORCE) | $(STAMP)
	@mkdir -p $(PREP_FIGURES)
	$(ANALYSIS_ENV) $(PY) -m tiltpile zcount $(PREP_DIRS) --out $(PREP_FIGURES)/zcount $(if $(PREP_WORKERS),--workers $(PREP_WORKERS))
	@touch $@

# `make definitions [PRESET=default] [DATA=dir] [G=g]`: every figure number of the ensemble's run
# files under each definition the paper leaves open (contact rule, lost rule, frame stride, Fig. 3's
# peaks; `tiltpile definitions`, docs/cli.md), into FIGURES/definitions.json, which the report
# reads ("What the disagreements depend on"). G: the contact list's gap (default: fitted by
# <z> = 3.5). Needs the run files; about 10 times `make figures`' analysis.
.PHONY: definitions
definitions: | $(STAMP)
	@test -n "$(wildcard $(DATA)/run_*.h5)" || { echo "make definitions: no run files in DATA=$(DATA) (the definitions need them, not records)"; exit 2; }
	$(ANALYSIS_ENV) $(PY) -m tiltpile definitions $(DATA) --out $(FIGURES)/definitions.json $(if $(G),--g $(G))

# `make engines [ENGINES=default|paper-fast|paper-5x|paper] [ENGINES_REF=dir] [ENGINES_DEM=dir]`: the piles of
# preset ENGINES in both engines (preset ENGINES-dem: the soft-sphere DEM), pile against pile and
# every figure number ensemble against ensemble (`tiltpile same-piles`), into
# figures/ENGINES-dem/same-piles/ (same_piles.json and both sides' figure documents), which
# the report's section "Same piles, another model" reads (then `make reports`); its subsection
# "At 4000 grains" is ENGINES=paper-fast, "..., with paper-5x's history" ENGINES=paper-5x and
# "..., with paper's history" ENGINES=paper. Either side may be run files or records: by default
# data/default and data/default-dem, for the 4000-grain presets the committed records of both.
ENGINES ?= default
ENGINES_REF ?= $(if $(filter default,$(ENGINES)),data/default,figures/$(ENGINES)/records)
ENGINES_DEM ?= $(if $(filter default,$(ENGINES)),data/default-dem,figures/$(ENGINES)-dem/records)
.PHONY: engines
engines: | $(STAMP)
	@case "$(ENGINES)" in default|paper-fast|paper-5x|paper) ;; *) echo "make engines: ENGINES=$(ENGINES): give default, paper-fast, paper-5x or paper"; exit 2;; esac
	$(ANALYSIS_ENV) $(PY) -m tiltpile same-piles $(ENGINES_REF) $(ENGINES_DEM) --ref-label $(ENGINES) \
	  --label $(ENGINES)-dem --out figures/$(ENGINES)-dem/same-piles --quiet

# `make definition-records [PRESET=paper-fast] [DATA=dir] [DEF_G=0.00216] [DEF_KEYS=keys] [WORKERS=W]`:
# the records of every finished run of DATA at the parameters of the definitions DEF_KEYS
# (comma-separated; default the three the 4000-grain study keeps for every run: the list at
# DEF_G, the g fitted at 1000 grains; the mixed rule; stride 2; `all` for every definition with
# analysis parameters), into BASE_FIGURES/definitions/<key>/ (up-to-date ones skipped;
# `tiltpile definitions --write-records`): run it with `make records` as runs finish, so that
# `tiltpile definitions BASE_FIGURES/records --records BASE_FIGURES/definitions --g DEF_G`
# needs no run files. Then each definition's records are rewritten holding only what the records
# at the default parameters (BASE_FIGURES/records) or an earlier definition's do not hold bit for
# bit (`tiltpile definitions --compact`; docs/run-file.md).
DEF_G ?= 0.00216
DEF_KEYS ?= list,mixed,stride-2
.PHONY: definition-records
definition-records: | $(STAMP)
	@test -n "$(wildcard $(DATA)/run_*.h5)" || { echo "make definition-records: no run files in DATA=$(DATA)"; exit 2; }
	$(ANALYSIS_ENV) $(PY) -m tiltpile definitions $(DATA) --write-records $(BASE_FIGURES)/definitions \
	  --g $(DEF_G) $(if $(filter all,$(DEF_KEYS)),,--only $(DEF_KEYS)) $(if $(WORKERS),--workers $(WORKERS)) --quiet
	$(if $(wildcard $(BASE_FIGURES)/records/run_*.npz),$(PY) -m tiltpile definitions $(BASE_FIGURES)/records \
	  --compact $(BASE_FIGURES)/definitions --quiet)

# `make solver-study [SOLVER_DATA=/path] [SOLVER_FIGURES=figures/solver-study] [SOLVER_RUNS=6] [WORKERS=W]
# [ONLY=S1,S2] [NULL=K] [RECORDS_ONLY=1]`: the solver's choice (`tiltpile solver-study`, docs/cli.md):
# one ensemble of the default preset per NLGS setting in SOLVER_DATA/<setting>/, each compared with
# the committed setting (SOLVER_DATA/reference/) pile against pile and claim by claim; the chart,
# JSON and report section in SOLVER_FIGURES. Resumable across sessions; RECORDS_ONLY=1 runs nothing
# and writes the records of what is finished, so that they can be committed.
SOLVER_DATA ?= data/solver-study
SOLVER_FIGURES ?= figures/solver-study
SOLVER_RUNS ?= 6
SOLVER_ARGS = --data '$(SOLVER_DATA)' --figures '$(SOLVER_FIGURES)' --runs $(SOLVER_RUNS) \
              $(if $(WORKERS),--workers $(WORKERS)) $(if $(ONLY),--only '$(ONLY)') $(if $(NULL),--null $(NULL))
.PHONY: solver-study
solver-study: | $(STAMP)
ifeq ($(RECORDS_ONLY),)
	$(PY) -m tiltpile solver-study $(SOLVER_ARGS) --runs-only
	$(ANALYSIS_ENV) $(PY) -m tiltpile solver-study $(SOLVER_ARGS)
else
	$(ANALYSIS_ENV) $(PY) -m tiltpile solver-study $(SOLVER_ARGS) --records-only
endif

# `make stiffness-study [STIFFNESS_DATA=/path] [STIFFNESS_FIGURES=figures/stiffness-study]
# [STIFFNESS_RUNS=6] [STIFFNESS_CD=dir] [WORKERS=W] [ONLY=S1,S2] [NULL=K] [RECORDS_ONLY=1]`: the DEM in
# its rigid limit (`tiltpile stiffness-study`, docs/dem.md "The stiffness series"): default-dem's
# piles at 4 k_n (dt / 2, STIFFNESS_RUNS piles) and 16 k_n (dt / 4, half of them) in
# STIFFNESS_DATA/<setting>/, k_n from default-dem's committed records; each against k_n and against
# Contact Dynamics' records of the same piles (STIFFNESS_CD: the solver study's committed setting,
# the default preset), every number against 1/k_n and extrapolated where the trend allows it; the
# figure, JSON and report section in STIFFNESS_FIGURES. Resumable across sessions; RECORDS_ONLY=1
# runs nothing and writes the records of what is finished, so that they can be committed.
STIFFNESS_DATA ?= data/stiffness-study
STIFFNESS_FIGURES ?= figures/stiffness-study
STIFFNESS_RUNS ?= 6
STIFFNESS_CD ?= figures/solver-study/records/reference
STIFFNESS_ARGS = --data '$(STIFFNESS_DATA)' --figures '$(STIFFNESS_FIGURES)' --runs $(STIFFNESS_RUNS) \
                 --reference-records figures/default-dem/records --cd '$(STIFFNESS_CD)' \
                 --paper-records figures/paper-5x-dem/records \
                 $(if $(WORKERS),--workers $(WORKERS)) $(if $(ONLY),--only '$(ONLY)') $(if $(NULL),--null $(NULL))
.PHONY: stiffness-study
stiffness-study: | $(STAMP)
ifeq ($(RECORDS_ONLY),)
	$(PY) -m tiltpile stiffness-study $(STIFFNESS_ARGS) --runs-only
	$(ANALYSIS_ENV) $(PY) -m tiltpile stiffness-study $(STIFFNESS_ARGS)
else
	$(ANALYSIS_ENV) $(PY) -m tiltpile stiffness-study $(STIFFNESS_ARGS) --records-only
endif

# `make study KEY=section.key VALUES="v1 v2 ..." [PRESET=default] [RUNS=M] [WORKERS=W] [NAME=name]
#             [HISTORY=preset|repose+D] [DATA=/path/outside/the/checkout] [STUDY_FIGURES=dir]`:
# a parameter study (`tiltpile study`, docs/cli.md "How to study another parameter"). For each
# value V of KEY (TOML syntax, as SET), the ensemble of PRESET with KEY=V, RUNS seeds from 0, in
# DATA/V (DATA default data/study-NAME; NAME default the key's last part), finished runs skipped
# and interrupted ones resumed; its repose angles DATA/V/repose.json (`tiltpile repose`, redone
# when a run file is newer), observables and records STUDY_FIGURES/records/V/; then the figure,
# JSON and report section STUDY_FIGURES/study.{png,pdf,json,md} (default figures/study-NAME):
# every figure's number per run and per value with bootstrap intervals over runs, and for
# KEY=scene.mu the Mohr-Coulomb test of the clusters' orientation. HISTORY=repose+D: per value
# first the fresh piles DATA/V-fresh and their repose angle r (surface), then the study's piles
# cycled twice to r + D deg rounded to the whole degree (the amplitudes in the JSON). A bad key
# or value stops it before anything runs, naming it. The friction study (about 5.5 core-hours):
# `make study KEY=scene.mu VALUES="0.2 0.4 0.5 0.8 1.0" NAME=friction HISTORY=repose+1 WORKERS=2`.
# The runs and repose angles run first, the analysis after them with ANALYSIS_ENV. RECORDS_ONLY=1
# runs nothing: the records of the values whose runs are done, to commit them while the rest runs.
KEY ?=
VALUES ?=
HISTORY ?= preset
NAME ?= $(lastword $(subst ., ,$(KEY)))
STUDY_DATA := $(if $(filter command line,$(origin DATA)),$(DATA),data/study-$(NAME))
STUDY_FIGURES ?= figures/study-$(NAME)
STUDY_ARGS = --key '$(KEY)' --values $(foreach v,$(VALUES),'$(v)') --preset $(PRESET) --runs $(RUNS) \
             --name '$(NAME)' --data '$(STUDY_DATA)' --figures '$(STUDY_FIGURES)' \
             --history '$(or $(filter preset repose+%,$(HISTORY)),preset)' \
             $(if $(WORKERS),--workers $(WORKERS))
.PHONY: study
study: | $(STAMP)
	@test -n "$(strip $(KEY))" -a -n "$(strip $(VALUES))" || { echo "make study: give KEY=section.key and VALUES=\"v1 v2 ...\""; exit 2; }
	@test -n "$(RUNS)" || { echo "$(UNKNOWN_PRESET)"; exit 2; }
ifeq ($(RECORDS_ONLY),)
	$(PY) -m tiltpile study $(STUDY_ARGS) --runs-only
	$(ANALYSIS_ENV) $(PY) -m tiltpile study $(STUDY_ARGS)
else
	$(ANALYSIS_ENV) $(PY) -m tiltpile study $(STUDY_ARGS) --records-only
endif
