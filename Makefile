# tiltpile: `make figures` and `make test`. Every target and variable: docs/cli.md, "Make targets".
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.tiltpile-installed
export NUMBA_CACHE_DIR ?= $(CURDIR)/.venv/numba-cache
.PHONY: setup test test-fast figures reports docs bench clean-data FORCE build-lock check-nb records ensemble preparation \
        preparation-runs preparation-paper zcount definitions definition-records engines solver-study stiffness-study study
comma := ,

setup: $(STAMP)
# the kernel logs errors only, less papermill's shutdown interrupt (docs/cli.md, "What make does around the commands")
$(STAMP): environment.txt pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r environment.txt
	$(PY) -m pip install -q --no-deps -e .
	$(PY) -m ipykernel install --sys-prefix --name tiltpile --display-name "tiltpile" > /dev/null
	$(PY) -c "import json, pathlib; p = pathlib.Path('$(VENV)/share/jupyter/kernels/tiltpile/kernel.json'); \
	  k = json.loads(p.read_text()); k['argv'] += ['--IPKernelApp.log_level=ERROR', '--IPKernelApp.extra_extensions=tiltpile.figures.kernel']; \
	  p.write_text(json.dumps(k, indent=1))"
	touch $@

test: setup
	$(PY) -m pytest -q
test-fast: setup
	$(PY) -m pytest -q -m "not slow"

# PRESET (or SCALE HISTORY ENGINE) and PRESET_ROWS, every preset's name:runs:report, read from the package once, when a
# goal needs them (docs/cli.md, "Make targets" and "Presets")
PRESETS_CMD = PYTHONPATH=$(CURDIR)/src $(if $(wildcard $(PY)),$(PY),$(PYTHON)) -m tiltpile.cli.presets
AXES_GIVEN := $(strip $(if $(SCALE),--scale '$(SCALE)') $(if $(filter-out preset repose+%,$(HISTORY)),--history '$(HISTORY)') $(if $(ENGINE),--engine '$(ENGINE)'))
AXES_SAID = $(strip $(foreach v,SCALE HISTORY ENGINE,$(if $($(v)),$(v)=$($(v)))))
ifneq ($(AXES_GIVEN),)
AXES_PRESET := $(shell $(PRESETS_CMD) --name $(AXES_GIVEN) 2>&1)
$(if $(filter 1,$(words $(AXES_PRESET))),,$(error $(AXES_SAID): $(subst tiltpile presets: error: ,,$(AXES_PRESET))))
$(and $(filter command line,$(origin PRESET)),$(filter-out x$(AXES_PRESET)x,x$(PRESET)x),$(error PRESET=$(PRESET) is not $(AXES_PRESET), the preset of $(AXES_SAID): give one or the other))
PRESET := $(AXES_PRESET)
endif
PRESET ?= default
PRESET_ROWS = $(eval PRESET_ROWS := $(shell $(PRESETS_CMD) --make))$(PRESET_ROWS)
preset_names = $(foreach r,$(1),$(firstword $(subst :, ,$(r))))
RUNS ?= $(word 2,$(subst :, ,$(filter $(PRESET):%,$(PRESET_ROWS))))
# the analysis at numpy's and OpenBLAS's AVX2 kernels on x86-64 (docs/cli.md, "Bit for bit on another machine")
ANALYSIS_ENV := $(if $(filter x86_64,$(shell uname -m)),NPY_DISABLE_CPU_FEATURES="X86_V4 AVX512_ICL AVX512_SPR" \
                $(if $(shell grep -qw avx2 /proc/cpuinfo 2>/dev/null && echo y),OPENBLAS_CORETYPE=Haswell))

# where the runs, figures and report go (docs/cli.md, the table), and what the figures read (FROM, RUNS)
$(if $(strip $(VARIANT)),,$(if $(strip $(SET)$(NB)),$(error SET and NB change the results: give VARIANT=name, so that the default figures stay untouched)))
BASE_DATA := data/$(PRESET)
BASE_FIGURES := $(if $(filter default,$(PRESET)),figures,figures/$(PRESET))
DATA ?= $(if $(strip $(VARIANT)),data/$(PRESET)-$(VARIANT),$(BASE_DATA))
FIGURES ?= $(if $(filter default,$(PRESET)),figures,figures/$(PRESET))$(if $(strip $(VARIANT)),/$(VARIANT))
REPORT ?= $(FIGURES)/REPRODUCTION.md
MAIN_REPORT := $(if $(strip $(VARIANT)),,$(if $(filter default paper,$(PRESET)),$(if $(filter figures figures/paper,$(FIGURES)),paper/REPRODUCTION.md)))
EXECUTED := notebooks/executed/$(PRESET)$(if $(strip $(VARIANT)),-$(VARIANT))
RECORDS ?= $(if $(strip $(SET)),$(FIGURES),$(BASE_FIGURES))/records
FROM ?= auto
$(if $(filter x$(FROM)x,xautox xrunsx xrecordsx),,$(error FROM=$(FROM): give FROM=auto, FROM=runs or FROM=records))
FROM_RECORDS := $(if $(filter records,$(FROM)),yes,$(if $(filter auto,$(FROM)),$(if $(wildcard $(DATA)/run_*.h5),,$(if $(wildcard $(RECORDS)/run_*.npz),yes))))
ALL_RECORDS := $(if $(FROM_RECORDS),$(sort $(wildcard $(RECORDS)/run_*.npz)))
$(if $(FROM_RECORDS),$(if $(strip $(RUNS)),$(if $(shell test "$(RUNS)" -ge 1 2> /dev/null && echo y),,$(error RUNS=$(RUNS): give the number of runs, a whole number >= 1))))
USED_RECORDS := $(if $(FROM_RECORDS),$(if $(strip $(RUNS)),$(wordlist 1,$(RUNS),$(ALL_RECORDS)),$(ALL_RECORDS)))
FIG_DATA := $(if $(FROM_RECORDS),$(if $(filter $(words $(ALL_RECORDS)),$(words $(USED_RECORDS))),$(RECORDS),$(EXECUTED)/records-$(RUNS)),$(DATA))
FIG_INPUT := $(if $(FROM_RECORDS),$(EXECUTED)/.records,$(DATA)/.runs)
NOTEBOOKS := $(wildcard notebooks/fig*.ipynb)
FIG_JSON := $(patsubst notebooks/%.ipynb,$(FIGURES)/%.json,$(NOTEBOOKS))
# what every figure, study and report is computed with: any edit under src/ rebuilds them
PACKAGE := $(shell find src/tiltpile -name '*.py' -not -path '*/__pycache__/*')
ENSEMBLE_ARGS := $(if $(SCHEDULER),--scheduler $(SCHEDULER)) $(if $(WORKERS),--workers $(WORKERS)) $(foreach kv,$(SET),--set '$(kv)')
DIAGNOSTICS := $(if $(FROM_RECORDS),,$(if $(wildcard notebooks/run_diagnostics.ipynb),$(EXECUTED)/diagnostics/.executed))
# a file rewritten only when its content changes, so that its dependents rebuild only then; notebook $(1) into $(2) with $(3)
update_if_changed = if cmp -s $(1).tmp $(1); then rm -f $(1).tmp; else mv -f $(1).tmp $(1); fi
papermill = $(ANALYSIS_ENV) $(PY) -m papermill --kernel tiltpile --cwd $(CURDIR) --no-progress-bar $(1) $(2) $(3) \
            || { echo "papermill failed: $(1) (output notebook: $(2))"; exit 1; }

figures: $(FIG_JSON) $(REPORT) $(MAIN_REPORT) $(DIAGNOSTICS)
# an unknown PRESET stops make before anything is installed, written or locked
UNKNOWN_PRESET = unknown PRESET=$(PRESET): the presets are $(sort $(call preset_names,$(PRESET_ROWS))) (`tiltpile presets`: their scale, history and engine)
$(if $(filter ensemble study,$(MAKECMDGOALS))$(if $(ALL_RECORDS),,$(filter figures $(FIG_JSON) $(REPORT),$(MAKECMDGOALS))),$(if $(strip $(RUNS)),,$(error $(UNKNOWN_PRESET))))
# one build at a time per FIGURES: every target that writes waits for the lock (docs/cli.md)
build-lock: | $(STAMP) check-nb
	@$(PY) -m tiltpile.outputs hold $(FIGURES) .build.lock --what "make figures" --pid $$PPID
# the runs and their observables, always checked; the stamp changes only when a run file does
$(DATA)/.runs: FORCE | $(STAMP) check-nb build-lock
	@test -n "$(RUNS)" || { echo "$(UNKNOWN_PRESET)"; exit 2; }
	$(PY) -m tiltpile ensemble --preset $(PRESET) --runs $(RUNS) --out $(if $(strip $(SET)),$(DATA),$(BASE_DATA)) $(ENSEMBLE_ARGS)
	$(if $(strip $(SET)),,$(if $(filter-out $(BASE_DATA),$(DATA)),@mkdir -p $(DATA) && for f in $(BASE_DATA)/run_*.h5; do ln -sfn ../$(PRESET)/$$(basename $$f) $(DATA)/; done))
	$(if $(strip $(NB)),,$(ANALYSIS_ENV) $(PY) -m tiltpile observables $(DATA) --quiet > /dev/null)
	@if [ -d $(RECORDS) ]; then set -o pipefail; $(ANALYSIS_ENV) $(PY) -m tiltpile record $(DATA) --out $(RECORDS) \
	  --quiet $(if $(WORKERS),--workers $(WORKERS)) | tail -1; fi
	@stat -L -c '%n %s %Y' $(DATA)/run_*.h5 > $@.tmp; $(call update_if_changed,$@)
# the records instead of the runs: the stamp holds the SHA-256 of those used (RUNS=M: links to the first M)
$(EXECUTED)/.records: FORCE | check-nb build-lock
	@mkdir -p $(@D)
	@ls $(RECORDS)/run_*.npz > /dev/null 2>&1 || { echo "no records run_*.npz in $(RECORDS): write them with \
	  'make records PRESET=$(PRESET) DATA=/path/to/runs'"; exit 2; }
	@echo "figures from $(if $(filter $(RECORDS),$(FIG_DATA)),the records,the first $(RUNS) of the $(words $(ALL_RECORDS)) records) in $(RECORDS) ($(if $(filter $(RECORDS),$(FIG_DATA)),$(words $(ALL_RECORDS)) runs,RUNS=$(RUNS)); no ensemble is run)"
	$(if $(filter $(RECORDS),$(FIG_DATA)),,@rm -rf $(FIG_DATA) && mkdir -p $(FIG_DATA) && ln -s $(abspath $(USED_RECORDS)) $(FIG_DATA)/)
	@(cd $(RECORDS) && sha256sum $(notdir $(USED_RECORDS))) > $@.tmp; $(call update_if_changed,$@)
records: | $(STAMP)
	$(if $(strip $(PARAMS)),$(if $(filter file,$(origin RECORDS)),$(error make records PARAMS=...: give RECORDS=dir, a directory of its own for the records at those parameters (not $(RECORDS)))))
	$(ANALYSIS_ENV) $(PY) -m tiltpile record $(DATA) --out $(RECORDS) $(if $(WORKERS),--workers $(WORKERS)) \
	  $(if $(strip $(PARAMS)),--params '$(PARAMS)')
# the ensemble alone, from a copy of the committed code (docs/cli.md, "An ensemble over many sessions")
ENSEMBLE_COMMIT = $(shell git rev-parse --short=12 HEAD 2>/dev/null)
ENSEMBLE_CODE = $(DATA)-code/$(ENSEMBLE_COMMIT)
ensemble: | $(STAMP)
	@test -n "$(RUNS)" || { echo "$(UNKNOWN_PRESET)"; exit 2; }
	@test -n "$(ENSEMBLE_COMMIT)" || { echo "make ensemble runs a copy of the committed code: run it in a git checkout"; exit 2; }
	@test -d $(ENSEMBLE_CODE)/src || { rm -rf $(ENSEMBLE_CODE).tmp && mkdir -p $(ENSEMBLE_CODE).tmp && \
	  git archive $(ENSEMBLE_COMMIT) src | tar -x -C $(ENSEMBLE_CODE).tmp && mv $(ENSEMBLE_CODE).tmp $(ENSEMBLE_CODE); }
	NUMBA_CACHE_DIR=$(ENSEMBLE_CODE)/numba-cache PYTHONPATH=$(ENSEMBLE_CODE)/src \
	  $(PY) -m tiltpile ensemble --preset $(PRESET) --runs $(RUNS) --out $(DATA) $(if $(FIRST),--first-seed $(FIRST)) $(ENSEMBLE_ARGS) \
	  $(if $(RERUN),,$(if $(wildcard $(RECORDS)/run_*.npz),--skip-recorded $(RECORDS))) --quiet

# NB, checked before anything runs against the notebooks this make executes; each then gets its share (docs/cli.md)
NB_NOTEBOOKS := $(sort $(patsubst $(FIGURES)/%.json,notebooks/%.ipynb,$(filter $(FIG_JSON),$(MAKECMDGOALS))) \
                       $(if $(filter preparation,$(MAKECMDGOALS)),notebooks/preparation.ipynb) $(if $(filter figures $(REPORT),$(MAKECMDGOALS)),$(NOTEBOOKS)))
$(if $(strip $(NB)),$(if $(strip $(NB_NOTEBOOKS)),,$(error NB: none of the goals ($(or $(MAKECMDGOALS),the default)) executes a notebook; NB applies to figures$(comma) a figure's JSON and preparation)))
check-nb: | $(STAMP)
	$(if $(strip $(NB)),@$(PY) -m tiltpile.figures.parameters check $(NB_NOTEBOOKS) -- $(NB))
$(EXECUTED)/%.parameters.yaml: FORCE | $(STAMP) check-nb build-lock
	@mkdir -p $(@D)
	@$(PY) -m tiltpile.figures.parameters select notebooks/$*.ipynb \
	  --note 'data_dir=$(FIG_DATA) preset=$(PRESET)' -- $(NB) > $@.tmp && $(call update_if_changed,$@)
# one target per figure: notebooks/figN_<name>.ipynb (tiltpile.figures.build)
$(FIG_JSON): $(FIGURES)/%.json: notebooks/%.ipynb $(PACKAGE) $(FIG_INPUT) $(EXECUTED)/%.parameters.yaml | $(STAMP)
	@mkdir -p $(EXECUTED) $(FIGURES)
	@echo "papermill $< -> $(EXECUTED)/$*.ipynb"
	@$(call papermill,$<,$(EXECUTED)/$*.ipynb,-f $(EXECUTED)/$*.parameters.yaml -p data_dir $(FIG_DATA) -p preset $(PRESET) -p figures_dir $(FIGURES))
	@test -f $@ || { echo "$< did not write $@"; exit 1; }
	@touch $@

# the reports and what they read (tiltpile.report.inputs); REPORT_SCALES: the scales with figures of their own
REPORT_SCALES = $(filter-out default,$(call preset_names,$(filter %:claims %:fig2,$(PRESET_ROWS))))
REPORT_READS := $(FIG_JSON) $(wildcard $(FIGURES)/fig*.json)
$(REPORT): $(REPORT_READS) $(PACKAGE) $(wildcard src/tiltpile/report/templates/*.j2) | $(STAMP)
	$(PY) -m tiltpile report --figures $(FIGURES) --out $@
ALL_REPORT_READS := $(wildcard figures/fig*.json figures/*.json figures/*/fig*.json figures/*/*.json figures/*/same-piles/*.json \
                      figures/*/same-piles/*/fig*.json figures/records/run_*.npz figures/*/records/run_*.npz)
paper/REPRODUCTION.md: $(ALL_REPORT_READS) $(PACKAGE) $(wildcard src/tiltpile/report/templates/*.j2) | $(STAMP)
	$(PY) -m tiltpile report --root figures --out $@
	$(PY) -m tiltpile report --root figures --studies --out paper/STUDIES.md
reports: | $(STAMP)
	$(PY) -m tiltpile report --root figures --out paper/REPRODUCTION.md
	$(PY) -m tiltpile report --root figures --studies --out paper/STUDIES.md
	$(PY) -m tiltpile docs
	$(PY) -m tiltpile report --figures figures --out figures/REPRODUCTION.md
	@set -e; for s in $(REPORT_SCALES); do \
	  $(PY) -m tiltpile report --figures figures/$$s --out figures/$$s/REPRODUCTION.md; done
docs: | $(STAMP)
	$(PY) -m tiltpile docs
$(EXECUTED)/diagnostics/.executed: notebooks/run_diagnostics.ipynb $(DATA)/.runs | $(STAMP)
	@mkdir -p $(EXECUTED) $(@D)
	$(call papermill,$<,$(EXECUTED)/run_diagnostics.ipynb,-p run_file $$(ls $(DATA)/run_*.h5 | head -1) -p data_dir $(DATA) -p preset $(PRESET) -p figures_dir $(@D))
	@touch $@
bench: setup
	$(PY) -m benchmarks.chart figures/performance
clean-data:
	rm -rf data/

# the preparation study and <z> by counting rule (docs/cli.md, "The preparation study, end to end")
PREP_ROOT ?= data/preparation
PREP_RUNS ?= 6
PREP_HISTORIES ?= fresh cyc10 cyc16 cyc18 cyc16r10
# PREP_SET_<history>: fresh piles; cycD, Deboeuf et al.'s two full cycles +-D deg at the ramp's rate; cyc16r10 at 10x it
PREP_SET_fresh := protocol.cycles=0 protocol.theta_rev_deg=0.0 protocol.pretilt_per_step_deg=0.0
$(foreach d,10 16 18,$(eval PREP_SET_cyc$(d) := protocol.cycles=2 protocol.theta_rev_deg=$(d).0 protocol.pretilt_per_step_deg=0.0))
PREP_SET_cyc16r10 := $(PREP_SET_cyc16) protocol.pretilt_per_step_deg=0.02
PREP_GIVEN := $(PREP_DIRS)
PREP_DIRS ?= $(foreach h,$(PREP_HISTORIES),$(PREP_ROOT)/$(h))
PREP_FIGURES ?= figures$(if $(strip $(VARIANT)),/$(VARIANT))
PREP_EXECUTED := notebooks/executed/preparation$(subst /,-,$(patsubst figures%,%,$(PREP_FIGURES)))
$(if $(strip $(SET)),$(if $(filter preparation preparation-runs zcount,$(MAKECMDGOALS)),$(error SET does not apply to the preparation study: its ensembles are set by PREP_SET_<history>)))
PREP_PARAMS = {"data_dirs": [$(subst " ","$(comma)",$(foreach d,$(PREP_DIRS),"$(d)"))], \
               "labels": [$(if $(strip $(PREP_LABELS)),"$(subst |,"$(comma)",$(PREP_LABELS))")], "figures_dir": "$(PREP_FIGURES)"}
preparation-runs: | $(STAMP) check-nb
	$(if $(strip $(PREP_GIVEN)),,@$(foreach h,$(PREP_HISTORIES),\
	  $(PY) -m tiltpile ensemble --preset default --runs $(PREP_RUNS) --out $(PREP_ROOT)/$(h) \
	    $(if $(PREP_WORKERS),--workers $(PREP_WORKERS)) $(foreach kv,$(PREP_SET_$(h)),--set '$(kv)') \
	  && { test -f $(PREP_ROOT)/$(h)/repose.json \
	       && test -z "$$(find $(PREP_ROOT)/$(h) -maxdepth 1 -name 'run_*.h5' -newer $(PREP_ROOT)/$(h)/repose.json)" \
	       || $(PY) -m tiltpile repose $(PREP_ROOT)/$(h) --json $(PREP_ROOT)/$(h)/repose.json \
	            $(if $(PREP_WORKERS),--workers $(PREP_WORKERS)); } || exit 1;))
# the study's inputs (each run file and repose.json of PREP_DIRS) and parameters; .executed and .zcount stand for its JSON
$(PREP_EXECUTED)/.inputs: FORCE | preparation-runs
	@mkdir -p $(@D)
	@for d in $(PREP_DIRS); do stat -L -c '%n %s %Y' $$d/run_*.h5 $$d/run_*.npz \
	  $$(ls $$d/repose.json 2> /dev/null) 2> /dev/null; done > $@.tmp; $(call update_if_changed,$@)
$(PREP_EXECUTED)/preparation.parameters.yaml: FORCE | $(STAMP) check-nb
	@mkdir -p $(@D)
	@$(PY) -m tiltpile.figures.parameters select notebooks/preparation.ipynb \
	  --note '$(PREP_PARAMS)' -- $(NB) > $@.tmp && $(call update_if_changed,$@)
preparation: $(PREP_EXECUTED)/.executed
$(PREP_EXECUTED)/.executed: notebooks/preparation.ipynb $(PACKAGE) $(PREP_EXECUTED)/.inputs $(PREP_EXECUTED)/preparation.parameters.yaml \
                            $(if $(wildcard $(PREP_FIGURES)/preparation.json),,FORCE) | $(STAMP)
	@mkdir -p $(PREP_FIGURES)
	@echo "papermill notebooks/preparation.ipynb -> $(PREP_EXECUTED)/preparation.ipynb"
	@$(call papermill,notebooks/preparation.ipynb,$(PREP_EXECUTED)/preparation.ipynb,-f $(PREP_EXECUTED)/preparation.parameters.yaml -y '$(PREP_PARAMS)')
	@test -f $(PREP_FIGURES)/preparation.json || { echo "notebooks/preparation.ipynb did not write $(PREP_FIGURES)/preparation.json"; exit 1; }
	@touch $@
preparation-paper:
	@$(MAKE) --no-print-directory preparation PREP_DIRS="figures/paper-fresh/records figures/paper/records" \
	  PREP_FIGURES=figures/paper VARIANT=paper-prep NB="-p slide_ke 0.001"
zcount: $(PREP_EXECUTED)/.zcount
$(PREP_EXECUTED)/.zcount: $(PACKAGE) $(PREP_EXECUTED)/.inputs $(if $(wildcard $(PREP_FIGURES)/zcount.json),,FORCE) | $(STAMP)
	@mkdir -p $(PREP_FIGURES)
	$(ANALYSIS_ENV) $(PY) -m tiltpile zcount $(PREP_DIRS) --out $(PREP_FIGURES)/zcount $(if $(PREP_WORKERS),--workers $(PREP_WORKERS))
	@touch $@

# every figure number under each definition the paper leaves open, and their records (docs/cli.md; tiltpile definitions)
definitions: | $(STAMP)
	@test -n "$(wildcard $(DATA)/run_*.h5)" || { echo "make definitions: no run files in DATA=$(DATA) (the definitions need them, not records)"; exit 2; }
	$(ANALYSIS_ENV) $(PY) -m tiltpile definitions $(DATA) --out $(FIGURES)/definitions.json $(if $(G),--g $(G))
DEF_G ?= 0.00216
DEF_KEYS ?= list,mixed,stride-2
definition-records: | $(STAMP)
	@test -n "$(wildcard $(DATA)/run_*.h5)" || { echo "make definition-records: no run files in DATA=$(DATA)"; exit 2; }
	$(ANALYSIS_ENV) $(PY) -m tiltpile definitions $(DATA) --write-records $(BASE_FIGURES)/definitions \
	  --g $(DEF_G) $(if $(filter all,$(DEF_KEYS)),,--only $(DEF_KEYS)) $(if $(WORKERS),--workers $(WORKERS)) --quiet
	$(if $(wildcard $(BASE_FIGURES)/records/run_*.npz),$(PY) -m tiltpile definitions $(BASE_FIGURES)/records \
	  --compact $(BASE_FIGURES)/definitions --quiet)

# the piles of preset ENGINES in both engines, pile against pile (docs/cli.md; tiltpile same-piles)
ENGINES ?= default
ENGINES_REF ?= $(if $(filter default,$(ENGINES)),data/default,figures/$(ENGINES)/records)
ENGINES_DEM ?= $(if $(filter default,$(ENGINES)),data/default-dem,figures/$(ENGINES)-dem/records)
engines: | $(STAMP)
	@case "$(ENGINES)" in default|paper-fast|paper-5x|paper) ;; *) echo "make engines: ENGINES=$(ENGINES): give default, paper-fast, paper-5x or paper"; exit 2;; esac
	$(ANALYSIS_ENV) $(PY) -m tiltpile same-piles $(ENGINES_REF) $(ENGINES_DEM) --ref-label $(ENGINES) \
	  --label $(ENGINES)-dem --out figures/$(ENGINES)-dem/same-piles --quiet

# the studies (docs/cli.md): the runs, then the analysis under ANALYSIS_ENV; RECORDS_ONLY=1: the records of what is done
define stages
$(if $(RECORDS_ONLY),,$(PY) -m tiltpile $(1) $(2) --runs-only)
$(ANALYSIS_ENV) $(PY) -m tiltpile $(1) $(2)$(if $(RECORDS_ONLY), --records-only)
endef
# --option VALUE, quoted with qopt, for each option whose variable is given; the command's default otherwise
opt = $(if $($(1)),--$(2) $($(1)))
qopt = $(if $($(1)),--$(2) '$($(1))')
SETTINGS_OPTS = $(call opt,WORKERS,workers) $(call qopt,ONLY,only) $(call opt,NULL,null)
SOLVER_ARGS = $(call qopt,SOLVER_DATA,data) $(call qopt,SOLVER_FIGURES,figures) $(call opt,SOLVER_RUNS,runs) $(SETTINGS_OPTS)
solver-study: | $(STAMP)
	$(call stages,solver-study,$(SOLVER_ARGS))
STIFFNESS_CD ?= figures/solver-study/records/reference
STIFFNESS_ARGS = $(call qopt,STIFFNESS_DATA,data) $(call qopt,STIFFNESS_FIGURES,figures) $(call opt,STIFFNESS_RUNS,runs) \
                 --reference-records figures/default-dem/records --cd '$(STIFFNESS_CD)' --paper-records figures/paper-5x-dem/records $(SETTINGS_OPTS)
stiffness-study: | $(STAMP)
	$(call stages,stiffness-study,$(STIFFNESS_ARGS))
NAME ?= $(lastword $(subst ., ,$(KEY)))
STUDY_ARGS = --key '$(KEY)' --values $(foreach v,$(VALUES),'$(v)') --preset $(PRESET) --runs $(RUNS) --name '$(NAME)' \
             $(if $(filter command line,$(origin DATA)),--data '$(DATA)') $(call qopt,STUDY_FIGURES,figures) \
             --history '$(or $(filter preset repose+%,$(HISTORY)),preset)' $(call opt,WORKERS,workers)
study: | $(STAMP)
	@test -n "$(strip $(KEY))" -a -n "$(strip $(VALUES))" || { echo "make study: give KEY=section.key and VALUES=\"v1 v2 ...\""; exit 2; }
	@test -n "$(RUNS)" || { echo "$(UNKNOWN_PRESET)"; exit 2; }
	$(call stages,study,$(STUDY_ARGS))
