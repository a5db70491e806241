# sky: the sample HDR sky (sun ~1e5× the sky) prefiltered once per lobe exponent of the
# car paint's lobe weights, plus the diffuse map (seed 001 §5.1, eqs. 7–9). Included by
# the top Makefile after lobes.mk (GONIO, OUT, STAMP, LOBES).

SKY := $(OUT)/sky
SKY_TARGETS := $(SKY)/index.json $(SKY)/sun/index.json $(SKY)/quarry/index.json

.PHONY: sky
sky: $(SKY_TARGETS)

$(SKY)/index.json: sample_data/sky.exr $(LOBES)/paint.lobes.json | $(STAMP)
	$(GONIO) prefilter $< --lobes $(LOBES)/paint.lobes.json -o $(SKY)

# The same sky prefiltered as a chain with its sun split off as a light (82 % of its
# light): what lights the paint's glints (render/paint_sparkle.png, docs/render.md).
$(SKY)/sun/index.json: sample_data/sky.exr | $(STAMP)
	$(GONIO) prefilter $< --chain --sun -o $(SKY)/sun

# A real sky (Poly Haven "Quarry 01", CC0: sample_data/envmaps/README.md) prefiltered as a
# chain, E = 1 … 32768: every lobe of a material reads it at its own sharpness
# ([environment] method = "model", docs/render.md); its sun split off first as a light.
$(SKY)/quarry/index.json: sample_data/envmaps/quarry_01_1k.hdr | $(STAMP)
	$(GONIO) prefilter $< --chain --sun -o $(SKY)/quarry
