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
# Seed 000 leaves out the unreliable 70° row.
RGBINK_FIT := --exclude-theta-i-deg 70

RGBINK_TARGETS := \
  $(foreach i,$(INKS),$(RGBINK)/$(i).measurement.json $(RGBINK)/$(i).material.json \
                      $(RGBINK)/$(i).fit.png $(RGBINK)/$(i).torrance-sparrow.material.json) \
  $(RGBINK)/print.png $(RGBINK)/print.json

.PHONY: rgbink
rgbink: $(RGBINK_TARGETS)

# The three inks come in the three layouts ingest reads (see docs/ingest.md).
$(RGBINK)/red.measurement.json: sample_data/ink_red.csv | $(STAMP)
	$(GONIO) ingest $^ -o $@ --summary

$(RGBINK)/green.measurement.json: sample_data/ink_green.csv | $(STAMP)
	$(GONIO) ingest $^ -o $@ --quantity ratio-to-white --white-reflectance 0.99 --summary

$(RGBINK)/blue.measurement.json: sample_data/ink_blue_a.csv sample_data/ink_blue_b.csv | $(STAMP)
	$(GONIO) ingest $^ -o $@ --summary

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
