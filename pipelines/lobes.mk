# lobes: cosine-lobe basis over the demo's materials and lobe weights per material
# (seed 001 §3–4). Included by the top Makefile (GONIO, OUT, STAMP, RGBINK, CARPAINT).

LOBES := $(OUT)/lobes
LOBE_MATERIALS := $(foreach i,$(INKS),$(RGBINK)/$(i).material.json) $(CARPAINT)/paint.material.json
LOBE_COUNT := 8

LOBES_TARGETS := $(LOBES)/basis.json $(LOBES)/basis.png \
  $(foreach i,$(INKS),$(LOBES)/$(i).lobes.json) $(LOBES)/paint.lobes.json

.PHONY: lobes
lobes: $(LOBES_TARGETS)

# Exponents for 1…11 lobes chosen over all four materials (seed 001 eq. 4). One run
# writes both files: a two-target pattern rule (the stem is the dot), which make -n and
# every GNU make version handle; the file the lobe fits read comes first.
$(LOBES)/basis%json $(LOBES)/basis%png: $(LOBE_MATERIALS)
	$(GONIO) lobes basis $^ --max-lobes 11 -o $(LOBES)/basis.json --plot $(LOBES)/basis.png

# Weights per view angle with LOBE_COUNT lobes of that basis (seed 001 eqs. 5–6, §5.2).
$(LOBES)/%.lobes.json: $(RGBINK)/%.material.json $(LOBES)/basis.json
	$(GONIO) lobes fit $< --basis $(LOBES)/basis.json --lobes $(LOBE_COUNT) -o $@

# The paint is rendered under the sky: lobes fitted over the whole hemisphere (in-plane
# samples give lobes too wide across the plane for environment light, docs/lobes.md).
$(LOBES)/paint.lobes.json: $(CARPAINT)/paint.material.json $(LOBES)/basis.json
	$(GONIO) lobes fit $< --basis $(LOBES)/basis.json --lobes $(LOBE_COUNT) -o $@ \
	  --samples hemisphere --solver nnls
