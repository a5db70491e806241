# carpaint: a metallic paint from a multi-angle spectrophotometer (seed 004) → the
# per-wavelength Cook–Torrance material (seed 004 eqs. 9–14) and its plot.
# Included by the top Makefile, which defines GONIO, OUT and STAMP.

CARPAINT := $(OUT)/carpaint

CARPAINT_TARGETS := $(CARPAINT)/paint.measurement.json $(CARPAINT)/paint.material.json \
                    $(CARPAINT)/paint.fit.png

.PHONY: carpaint
carpaint: $(CARPAINT_TARGETS)

# ASTM E2194 aspecular geometries, reflectance factor at 5 nm (resampled to 10 nm).
$(CARPAINT)/paint.measurement.json: sample_data/carpaint_multiangle.csv | $(STAMP)
	$(GONIO) ingest $^ -o $@ --quantity reflectance-factor

# One run writes the material and its plot: a pattern rule with two targets (make's
# grouped targets, `&:`, need make 4.3 and hide their dependents from `make -n`).
$(CARPAINT)/%.material.json $(CARPAINT)/%.fit.png: $(CARPAINT)/%.measurement.json
	$(GONIO) fit $< -o $(CARPAINT)/$*.material.json --model cook-torrance \
	  --plot $(CARPAINT)/$*.fit.png
