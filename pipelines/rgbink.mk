# rgbink: structural-colour reflective inks (seed 000), sample measurements → materials.
#
#   ingest each ink's CSVs → fit the goniochromatic model (seed 000 eq. 5) and the
#   standard Torrance–Sparrow model → Figure-4 plots.
#
# Each artifact is a file with its inputs as prerequisites, so make rebuilds only what
# changed (try `make -n demo` after touching one CSV). Included by the top Makefile,
# which defines GONIO, OUT and STAMP.

RGBINK     := $(OUT)/rgbink
INKS       := red green blue
# How the demo ingests and fits each ink is said once, in sample_data/inks.toml (read by
# gonio report and the tests too): its options as flags, read when a recipe runs (the
# fit's once per make run).
RGBINK_INKS_TOML := sample_data/inks.toml
rgbink_ingest_args = $(shell GONIO_SAMPLE_DATA=$(dir $(RGBINK_INKS_TOML)) $(BIN)/python -m gonio_cli.samples ingest-args $(1))
RGBINK_FIT = $(eval RGBINK_FIT := $(shell GONIO_SAMPLE_DATA=$(dir $(RGBINK_INKS_TOML)) $(BIN)/python -m gonio_cli.samples fit-args))$(RGBINK_FIT)

RGBINK_TARGETS := \
  $(foreach i,$(INKS),$(RGBINK)/$(i).measurement.json $(RGBINK)/$(i).material.json \
                      $(RGBINK)/$(i).fit.png $(RGBINK)/$(i).torrance-sparrow.material.json) \
  $(RGBINK)/print.png $(RGBINK)/print.json

.PHONY: rgbink
rgbink: $(RGBINK_TARGETS)

# The three inks come in the three layouts ingest reads (see docs/ingest.md).
$(RGBINK)/red.measurement.json: sample_data/ink_red.csv $(RGBINK_INKS_TOML) | $(STAMP)
	$(GONIO) ingest $(filter %.csv,$^) -o $@ $(call rgbink_ingest_args,red) --summary

$(RGBINK)/green.measurement.json: sample_data/ink_green.csv $(RGBINK_INKS_TOML) | $(STAMP)
	$(GONIO) ingest $(filter %.csv,$^) -o $@ $(call rgbink_ingest_args,green) --summary

$(RGBINK)/blue.measurement.json: sample_data/ink_blue_a.csv sample_data/ink_blue_b.csv \
                                 $(RGBINK_INKS_TOML) | $(STAMP)
	$(GONIO) ingest $(filter %.csv,$^) -o $@ $(call rgbink_ingest_args,blue) --summary

# A pattern rule with two targets: one run writes the material and its plot.
$(RGBINK)/%.material.json $(RGBINK)/%.fit.png: $(RGBINK)/%.measurement.json
	$(GONIO) fit $< -o $(RGBINK)/$*.material.json --plot $(RGBINK)/$*.fit.png $(RGBINK_FIT)

$(RGBINK)/%.torrance-sparrow.material.json: $(RGBINK)/%.measurement.json
	$(GONIO) fit $< -o $@ --model torrance-sparrow $(RGBINK_FIT)

# The print: dot-off-dot R/G/B ink masks of the sample image (seed 000 Figure 6), with
# the three screens a screen printer burns and the coverage/tone report. One run writes
# both: a two-target pattern rule (the stem is the dot; why not `&:`: carpaint.mk).
$(RGBINK)/print%png $(RGBINK)/print%json: sample_data/print_image.png | $(STAMP)
	$(GONIO) halftone $< -o $(RGBINK)/print.png --method floyd-steinberg --split \
	  --report $(RGBINK)/print.json
