# report: error against run time of every stage and seed 000's Table 1 on the demo's inks
# (gonio report, docs/report.md). The demo writes the quick report (15–20 s measured); the full
# sweeps (about 76 s): `make report REPORT_FLAGS= -B`.
# Included by the top Makefile (GONIO, OUT, STAMP, INKS, RGBINK).

REPORT := $(OUT)/report
REPORT_FLAGS ?= --quick
REPORT_TARGETS := $(REPORT)/report.md
REPORT_INPUTS := $(foreach i,$(INKS),$(RGBINK)/$(i).measurement.json $(RGBINK)/$(i).material.json \
                                     $(RGBINK)/$(i).torrance-sparrow.material.json)

.PHONY: report
report: $(REPORT)/report.md

$(REPORT)/report.md: $(REPORT_INPUTS) | $(STAMP)
	$(GONIO) report $^ -o $(REPORT) $(REPORT_FLAGS)
