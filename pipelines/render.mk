# render: the soft proofs (seed 000 Figures 5 and 7) and the car paint under the sky
# (seed 001), with glints. Scenes are templates in sample_data/scenes/; ${out} points them at OUT.
# Included by the top Makefile after the other pipelines (GONIO, OUT, STAMP, INKS,
# RGBINK, CARPAINT, LOBES, SKY).

RENDER := $(OUT)/render
SCENES := sample_data/scenes
RENDER_VARS := --var out=$(abspath $(OUT))
RENDER_TARGETS := $(RENDER)/figure5.png $(RENDER)/print-D65.png $(RENDER)/print-A.png \
                  $(RENDER)/print-A-unadapted.png $(RENDER)/paint_env.png \
                  $(RENDER)/sparkle.png $(RENDER)/paint_sparkle.png $(RENDER)/paint_sky.png

.PHONY: render
render: $(RENDER_TARGETS)

# Figure 5: each ink as measured (reference), fitted by eq. 5 and by the standard model.
$(RENDER)/figure5.png: $(SCENES)/figure5.toml \
  $(foreach i,$(INKS),$(RGBINK)/$(i).measurement.json $(RGBINK)/$(i).material.json \
                      $(RGBINK)/$(i).torrance-sparrow.material.json)
	$(GONIO) render $< -o $@ --exr $(RENDER)/figure5.exr --report $(RENDER)/figure5.json \
	  $(RENDER_VARS)

PRINT_INPUTS := $(SCENES)/print.toml $(SCENES)/sheet.obj $(RGBINK)/print.png \
  $(foreach i,$(INKS),$(RGBINK)/$(i).material.json)

# Figure 7: the halftoned print on a curved sheet under D65 and under A, as a viewer
# adapted to the light sees it (the default chromatic adaptation, Bradford: the light's
# white shown as the display's white) ...
$(RENDER)/print-%.png: $(PRINT_INPUTS)
	$(GONIO) render $< -o $@ --exr $(RENDER)/print-$*.exr --report $(RENDER)/print-$*.json \
	  $(RENDER_VARS) --var illuminant=$*

# ... and under A unadapted (--adapt none): the light's own colour, as a camera set to
# daylight would record it; shown beside the adapted print-A.png.
$(RENDER)/print-A-unadapted.png: $(PRINT_INPUTS)
	$(GONIO) render $< -o $@ --exr $(RENDER)/print-A-unadapted.exr \
	  --report $(RENDER)/print-A-unadapted.json $(RENDER_VARS) --var illuminant=A --adapt none

# The car paint under the prefiltered sky with its lobe weights (seed 001 eqs. 7–9).
$(RENDER)/paint_env.png: $(SCENES)/paint_env.toml $(CARPAINT)/paint.material.json \
  $(LOBES)/paint.lobes.json $(SKY)/index.json
	$(GONIO) render $< -o $@ --exr $(RENDER)/paint_env.exr --report $(RENDER)/paint_env.json \
	  $(RENDER_VARS)

SPARKLE_PHOTOS := $(sort $(wildcard sample_data/sparkle/photo_ti*.png))

# Sparkles (seed 004 §6): the texture from the sample flake photos (eqs. 15–16).
$(RENDER)/sparkle.png: $(SPARKLE_PHOTOS) | $(STAMP)
	$(GONIO) sparkle $^ -o $@ --theta-i-deg 10,20,30,40,50,60,70

# Glints: the car paint under the sample sky and its sun alone, half its flake lobe drawn
# as flakes (docs/render.md, "Glints").
$(RENDER)/paint_sparkle.png: $(SCENES)/paint_sparkle.toml $(CARPAINT)/paint.material.json \
  $(SKY)/sun/index.json
	$(GONIO) render $< -o $@ --exr $(RENDER)/paint_sparkle.exr \
	  --report $(RENDER)/paint_sparkle.json $(RENDER_VARS)

# The clear-coated paint on Spot (sample_data/meshes/) on a floor under the real sky,
# every lobe of the paint reading the prefiltered chain at its own sharpness.
$(RENDER)/paint_sky.png: $(SCENES)/paint_sky.toml $(CARPAINT)/coat.material.json \
  $(SCENES)/floor.material.json sample_data/meshes/spot.obj $(SKY)/quarry/index.json
	$(GONIO) render $< -o $@ --exr $(RENDER)/paint_sky.exr --report $(RENDER)/paint_sky.json \
	  $(RENDER_VARS)
