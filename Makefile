# gonio — two commands do all the set-up on a fresh machine with Python 3.11:
#   make demo   create .venv, install gonio, run the demo pipeline on sample_data/
#   make test   create .venv, install gonio, run the whole test suite
# Others: make bench (error against run time), make clean.

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.gonio-installed
OUT    ?= out
GONIO  := $(BIN)/gonio

export PATH := $(abspath $(BIN)):$(PATH)

.PHONY: demo test bench clean setup
.DEFAULT_GOAL := demo

setup: $(STAMP)

# Reinstall when the dependency list changes; the package itself is editable.
$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e .
	@touch $@

include pipelines/rgbink.mk
include pipelines/carpaint.mk
include pipelines/lobes.mk
include pipelines/sky.mk
include pipelines/render.mk

demo: $(STAMP) rgbink carpaint lobes sky render
	@echo
	@echo "Demo outputs (measurements, materials and their plots, the print, lobes, the prefiltered sky):"
	@for d in rgbink carpaint lobes sky render; do echo "  $(OUT)/$$d/"; ls -1 $(OUT)/$$d | sed 's/^/    /'; done

test: $(STAMP)
	$(BIN)/python -m pytest -q

bench: $(STAMP)
	@for b in benchmarks/bench_*.py; do echo; echo "### $$b"; $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(OUT)
