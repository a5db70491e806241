# carpaint: a metallic paint from a multi-angle spectrophotometer (seed 004) → the
# per-wavelength Cook–Torrance material (seed 004 eqs. 9–14) and its plot.
# Included by the top Makefile, which defines GONIO, OUT and STAMP.

CARPAINT := $(OUT)/carpaint

CARPAINT_TARGETS := $(CARPAINT)/paint.measurement.json $(CARPAINT)/paint.material.json \
                    $(CARPAINT)/paint.fit.png $(CARPAINT)/coat.measurement.json \
                    $(CARPAINT)/coat.material.json $(CARPAINT)/coat.fit.png

.PHONY: carpaint
carpaint: $(CARPAINT_TARGETS)

# ASTM E2194 aspecular geometries, reflectance factor at 5 nm (resampled to 10 nm).
$(CARPAINT)/paint.measurement.json: sample_data/carpaint_multiangle.csv | $(STAMP)
	$(GONIO) ingest $^ -o $@ --quantity reflectance-factor

# One run writes the material and its plot: a pattern rule with two targets (make's
# grouped targets, `&:`, need make 4.3 and hide their dependents from `make -n`). The
# model per material: CARPAINT_MODEL_<stem>, else Cook–Torrance (seed 004).
CARPAINT_MODEL_coat := goniochromatic-coat
$(CARPAINT)/%.material.json $(CARPAINT)/%.fit.png: $(CARPAINT)/%.measurement.json
	$(GONIO) fit $< -o $(CARPAINT)/$*.material.json --model $(or $(CARPAINT_MODEL_$*),cook-torrance) \
	  --plot $(CARPAINT)/$*.fit.png

# A clear-coated blue paint measured in plane with samples close to the mirror
# (sample_data/make_coat_paint.py), fitted by the pattern rule above with a clear coat
# over eq. 5 and a body (goniochromatic-coat; the truth's coat α 0.02 comes back within
# 0.1 %).
$(CARPAINT)/coat.measurement.json: sample_data/coat_paint.csv | $(STAMP)
	$(GONIO) ingest $^ -o $@
