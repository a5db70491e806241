# gonio — two commands do all the set-up on a fresh machine with Python 3.11:
#   make demo   create .venv, install gonio with the pinned dependencies, run the demo pipeline
#   make test   create .venv, install gonio with the pinned dependencies, run the test suite
# Others: make bench (error against run time), make clean, make schemas (docs/schemas/ from
# gonio_cli/schemas/), make lock (refresh the pins in
# requirements.lock after changing dependencies in pyproject.toml). One stage: make rgbink,
# make carpaint, make lobes, make sky, make render, or one file (make out/render/figure5.png).
# make report: error against run time of every stage and seed 000's Table 1 (quick in the
# demo; the full sweeps: make report REPORT_FLAGS= -B).
# The file graph and how to write a batch Makefile of your own: docs/pipelines.md.
#
# Variables, set on the command line (make demo OUT=/tmp/run):
#   OUT    where the pipelines write (default out)
#   VENV   the virtual environment gonio runs from (default .venv, created on first use)
#   STAMP  the file marking VENV as installed (reinstalled when pyproject.toml or
#          requirements.lock is newer); STAMP= (empty) uses VENV as it is: no venv
#          creation, no install step
#   make demo VENV=/opt/gonio-env STAMP= OUT=/tmp/run   runs an installed gonio elsewhere

PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.gonio-installed
OUT    ?= out
GONIO  := $(BIN)/gonio
# The tested dependency set: every package pinned, pip and the build backend included.
LOCK   := requirements.lock
# The tool that writes LOCK (make lock), pinned like everything else.
UV_VERSION := 0.13.9

export PATH := $(abspath $(BIN)):$(PATH)

.PHONY: demo test bench clean setup lock refresh-references schemas readme-images readme-check js-tools
.DEFAULT_GOAL := demo

setup: $(STAMP)

# Install exactly the pinned set (LOCK) so a fresh machine runs what the tests were run
# with; PIP_CONSTRAINT also pins pip's isolated build of gonio (setuptools). Reinstall when
# the dependency list or the pins change; the package itself is editable. Pipeline stages
# take the stamp as an order-only prerequisite: a reinstall reruns nothing.
ifneq ($(STAMP),)
$(STAMP): pyproject.toml setup.py gonio_cli/halftone/_diffuse.c gonio_cli/render/_envlookup.c gonio_cli/render/_rasterscan.c $(LOCK)
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	PIP_CONSTRAINT=$(abspath $(LOCK)) $(BIN)/python -m pip install --quiet --quiet pip
	PIP_CONSTRAINT=$(abspath $(LOCK)) $(BIN)/python -m pip install --quiet --quiet -e '.[test,batch,cluster,mitsuba,exchange]'
	@touch $@
endif

# Refresh the pins: after changing dependencies in pyproject.toml (or to move to newer
# releases), run `make lock`, then `make test`, and commit both files. The lock is
# universal (any OS) for Python 3.11+, one version per package where one fits all.
lock:
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet uv==$(UV_VERSION)
	printf 'pip\nsetuptools\n' | $(BIN)/uv pip compile pyproject.toml - --all-extras \
	  --universal --fork-strategy fewest --python-version 3.11 --quiet -o $(LOCK)

include pipelines/rgbink.mk
include pipelines/carpaint.mk
include pipelines/lobes.mk
include pipelines/sky.mk
include pipelines/render.mk
include pipelines/report.mk

DEMO_TARGETS := $(RGBINK_TARGETS) $(CARPAINT_TARGETS) $(LOBES_TARGETS) $(SKY_TARGETS) \
                $(RENDER_TARGETS) $(REPORT_TARGETS)

# demo has no recipe of its own, so `make -q demo` exits 0 once everything is built. The
# list of outputs is a file, rewritten and printed whenever an output was remade.
demo: $(STAMP) $(OUT)/demo.txt

$(OUT)/demo.txt: $(DEMO_TARGETS)
	@{ echo "Demo outputs (measurements, materials and their plots, the print, lobes," \
	    "the prefiltered sky, renders, the report):"; \
	  for d in rgbink carpaint lobes sky render report; do echo "  $(OUT)/$$d/"; \
	    ls -1 $(OUT)/$$d | sed 's/^/    /'; done; } > $@
	@echo; cat $@; echo "(this list: $@)"

test: $(STAMP) js-tools
	$(BIN)/python -m pytest -q

# JavaScript tools the tests use, pinned in tests/js/package-lock.json: the Khronos glTF
# validator (tests/test_export_gltf.py checks every exported .glb with it) and three.js
# (tests/test_export_gltf_browser.py opens one in headless Chromium). Installed with npm
# where npm is found; without it (or offline) those tests skip and say why.
JS_DIR   := tests/js
JS_STAMP := $(JS_DIR)/node_modules/.gonio-installed

js-tools: $(JS_STAMP)

$(JS_STAMP): $(JS_DIR)/package.json $(JS_DIR)/package-lock.json
	@if command -v npm >/dev/null 2>&1; then \
	  npm ci --prefix $(JS_DIR) --no-audit --no-fund --silent && touch $@ || \
	    echo "make: npm ci in $(JS_DIR) failed: the glTF validator and viewer tests skip"; \
	else echo "make: npm not found: the glTF validator and viewer tests skip (install nodejs and npm)"; fi

# The README's images are demo outputs (tests/readme_images.py lists which): copy them
# into docs/images, or check they are what the demo makes (CI runs the check after demo).
readme-images: demo
	$(BIN)/python tests/readme_images.py --write --out $(OUT)

readme-check: demo
	$(BIN)/python tests/readme_images.py --check --out $(OUT)

bench: $(STAMP)
	@for b in benchmarks/bench_*.py; do echo; echo "### $$b"; $(BIN)/python $$b || exit 1; done

# Rewrite tests/regression/references on purpose (tests/regression/README.md);
# one or more: make refresh-references NAMES="fit-red-goniochromatic render-print-small"
refresh-references: $(STAMP)
	$(BIN)/python tests/regression/refresh.py $(NAMES)

# Regenerate the published JSON Schemas (docs/schemas/) from gonio_cli/schemas/ after
# changing an artifact's fields; tests/test_schemas.py fails while they differ.
schemas: $(STAMP)
	$(BIN)/python -m gonio_cli.schemas docs/schemas

clean:
	rm -rf $(OUT)
