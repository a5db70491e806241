"""Writing a rendered frame out: the images (EXR, PNG, gamut warning, spectral EXR) with
their metadata, and the run report (``gonio render --report``).

:func:`write_outputs` writes a :class:`~gonio_cli.render.frame.Frame` atomically
(:mod:`gonio_cli.imageio`, :mod:`gonio_cli.artifact`); :func:`exr_pixels` gives the colour
EXR in its space; :func:`write_report` the ``gonio.render-report``. Kept apart from the
core of :mod:`gonio_cli.render.pipeline` (scene → frame); both stand on :mod:`.frame`.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..artifact import image_metadata, make_document, write_json
from ..imageio import write_exr, write_png, write_spectral_exr
# the run report's schema and version (its fields: schemas.render_report_spec)
from ..schemas import RENDER_REPORT_SCHEMA as REPORT_SCHEMA
from ..schemas import RENDER_REPORT_VERSION as REPORT_VERSION
from ..spectra import grid_spec
from . import Stats
from .frame import FRAME_STAGES, Frame, Stage, frame_time
from .scene_types import Scene
from .tonemap import (DEFAULT_EXR_ADAPTATION, get_adaptation, get_exr_space, scene_white,
                      xyz_to_exr_matrix, xyz_to_linear)

#: Schema of the rendered images' metadata (``gonio:schema`` of the PNG and the EXR).
IMAGE_SCHEMA = "gonio.render"
IMAGE_SCHEMA_VERSION = 1
#: Schema of a turntable's animated PNG (``gonio render --turntable``, ``gonio batch``).
TURNTABLE_SCHEMA = "gonio.turntable"
TURNTABLE_SCHEMA_VERSION = 1


def turntable_metadata(frames, **fields) -> dict:
    """The metadata of a turntable's animated PNG: its frames (hashed) and ``fields``."""
    return image_metadata(TURNTABLE_SCHEMA, TURNTABLE_SCHEMA_VERSION, inputs=frames,
                          turntable_frames=len(frames), **fields)


# ----------------------------------------------------------------------------- output --

def settings(scene: Scene) -> dict[str, Any]:
    """The render settings, as written into the EXR metadata and the run report."""
    cam = scene.camera
    out = scene.output
    white = scene_white(scene)
    white = [round(float(v), 6) for v in white] if white is not None else None
    return {"scene": str(scene.path), "vars": scene.variables,
            "camera": {"eye": cam.eye.tolist(), "target": cam.target.tolist(),
                       "up": cam.up.tolist(), "fov_deg": cam.fov_deg,
                       "width": cam.width, "height": cam.height},
            "ssaa": out.ssaa, "spectral": out.spectral, "exposure": out.exposure,
            "tonemap": out.tonemap, "adapt": out.adapt, "scene_white_xyz": white,
            "display_white": "D65 (sRGB)", "grid_nm": out.grid_nm,
            "objects": [{"name": o.name, "kind": o.kind, "mesh": o.mesh} for o in scene.objects],
            "lights": [_light_settings(l) for l in scene.lights],
            "environment": (str(scene.environment.prefiltered) if scene.environment else None)}


def _light_settings(light) -> dict[str, Any]:
    """A light as the settings name it: name, kind, whether it casts shadows, and then
    its size (angular diameter or radius)."""
    out: dict[str, Any] = {"name": light.name, "kind": light.kind, "shadow": light.shadow}
    if light.shadow:
        out.update({"angular_diameter_deg": light.angular_diameter_deg}
                   if light.kind == "directional" else {"radius": light.radius})
    return out


#: The colour that marks out-of-gamut pixels in the gamut-warning image: the mid grey
#: (sRGB 128) that image editors use for their gamut warning, unlike any ink's colour.
GAMUT_WARNING_RGB = (128, 128, 128)


def gamut_warning_image(frame: Frame) -> np.ndarray:
    """The PNG image with every out-of-gamut pixel painted :data:`GAMUT_WARNING_RGB`."""
    out = frame.display.copy()
    if frame.out_of_gamut is not None:
        out[frame.out_of_gamut] = GAMUT_WARNING_RGB
    return out


#: What the values of the spectral EXR are (its ``gonio:radiance_units`` attribute).
SPECTRAL_UNITS = ("spectral radiance L(λ) in the scene's irradiance units (the lights' E, "
                  "I / d²) per steradian, per wavelength sample of the grid: each light's "
                  "spectrum is scaled so that Σλ S ȳ / Σλ ȳ = 1, so Y = Σλ L ȳ / Σλ ȳ and "
                  "XYZ = Σλ L cmf / Σλ ȳ (CIE 1931 2°) is the colour EXR's XYZ before "
                  "adaptation; a white Lambertian surface lit at normal incidence by E = π "
                  "has L(λ) = S(λ) (docs/conventions.md)")


def exr_pixels(frame: Frame, scene: Scene, space: str = "srgb",
               adapt: str | None = None) -> np.ndarray:
    """The colour EXR's (H, W, 3) float32 in ``space`` (:data:`.tonemap.EXR_SPACES`)
    after the chromatic adaptation ``adapt`` (:data:`.tonemap.ADAPTATIONS`; default
    :data:`.tonemap.DEFAULT_EXR_ADAPTATION`, none: scene-referred) of the scene white to
    D65: the frame's XYZ through :func:`.tonemap.xyz_to_exr_matrix`, plus the background.
    Linear sRGB with the display's own adaptation is the frame's ``linear`` itself."""
    adapt = DEFAULT_EXR_ADAPTATION if adapt is None else adapt
    get_exr_space(space)
    get_adaptation(adapt)
    if space == "srgb" and adapt == scene.output.adapt:
        return frame.linear
    m = xyz_to_exr_matrix(space, adapt, scene_white(scene))
    out = xyz_to_linear(frame.xyz, m)
    if frame.background is not None:         # given in linear sRGB, the display's space
        background = frame.background
        if space != "srgb":
            to_space = get_exr_space(space).matrix() @ np.linalg.inv(
                get_exr_space("srgb").matrix())
            background = background @ to_space.T
        out += ((1.0 - frame.coverage)[..., None] * background).astype(np.float32)
    return out


def exr_colour(space_help: str, adapt: str) -> str:
    """What the colour EXR's values are (its ``gonio:colour``): scene-referred, adapted or
    not (``adapt``, also in ``gonio:exr_adapt``), before exposure and tone mapping."""
    how = ("without chromatic adaptation: the lights' colour is kept (settings."
           "scene_white_xyz), as the PNG's settings.adapt does not" if adapt == "none" else
           f"after chromatic adaptation ({adapt}: settings.scene_white_xyz → D65)")
    return f"scene-referred {space_help}, {how}, before exposure and tone mapping"


def write_outputs(frame: Frame, scene: Scene, stats: Stats, *, png, exr=None,
                  start: float | None = None, gamut_warning=None, exr_space: str = "srgb",
                  spectral_exr=None, exr_adapt: str | None = None) -> None:
    """Write the EXR (scene-linear float32 in ``exr_space``, default linear sRGB; the
    space in its ``chromaticities`` and ``gonio:exr_space``; its adaptation ``exr_adapt``,
    default none, in ``gonio:exr_adapt`` and ``gonio:colour``; settings and time in its
    metadata), the PNG (8-bit sRGB, adapted by the scene's ``adapt``), if asked the
    gamut-warning PNG and the spectral EXR (:func:`gonio_cli.imageio.write_spectral_exr`,
    the frame's ``spectra``; its R, G, B preview is the colour EXR's linear sRGB),
    atomically."""
    exr_adapt = DEFAULT_EXR_ADAPTATION if exr_adapt is None else exr_adapt
    elapsed = time.perf_counter() - start if start is not None else None
    space = get_exr_space(exr_space)
    # the envelope of the EXRs (inputs hashed once); the PNG's leaves the inputs out: a
    # re-fitted material of the same parameters (new file, new hash) must give the same
    # PNG bytes, so gonio batch can skip what depends on the frame (docs/batch.md)
    base = image_metadata(IMAGE_SCHEMA, IMAGE_SCHEMA_VERSION, inputs=scene.inputs)
    png_base = {k: v for k, v in base.items() if k != "inputs"}
    meta = {**base, "settings": settings(scene),
            "render_time_s": elapsed if elapsed is not None else
            sum(v for k, v in stats.time_s.items() if "." not in k),
            "frame_time_s": frame_time(stats), "exr_space": exr_space,
            "exr_adapt": exr_adapt, "colour": exr_colour(space.help, exr_adapt)}
    if exr is not None:
        with Stage(stats, "write_exr"):
            write_exr(exr, exr_pixels(frame, scene, exr_space, exr_adapt), meta,
                      chromaticities=space.chromaticities(), channel_names=space.channels)
    if spectral_exr is not None:
        if frame.spectra is None:
            raise ValueError("the frame has no spectra: render_scene(..., spectra=True)")
        with Stage(stats, "write_spectral_exr"):
            write_spectral_exr(
                spectral_exr, frame.spectra, scene.grid_nm,
                exr_pixels(frame, scene, "srgb", exr_adapt),
                {**base, "schema": "gonio.render-spectra", "settings": settings(scene),
                 "grid_nm": grid_spec(scene.grid_nm) or [float(v) for v in scene.grid_nm],
                 "radiance_units": SPECTRAL_UNITS,
                 "preview": "R, G, B: the colour EXR's linear sRGB "
                            f"({exr_colour('linear sRGB', exr_adapt)})", "exr_adapt": exr_adapt,
                 "render_time_s": meta["render_time_s"]})
    with Stage(stats, "write_png"):
        write_png(png, frame.display, {**png_base, "settings": settings(scene)})
        if gamut_warning is not None:
            write_png(gamut_warning, gamut_warning_image(frame),
                      {**png_base, "schema": "gonio.render-gamut-warning",
                       "settings": settings(scene),
                       "marked": f"pixels outside sRGB painted sRGB {GAMUT_WARNING_RGB}",
                       "out_of_gamut_pixels": stats.counts.get("out_of_gamut_pixels")})


def write_report(path, scene: Scene, stats: Stats, *, total_s: float, png, exr=None,
                 gamut_warning=None, spectral_exr=None) -> dict:
    """The run report (``gonio.render-report`` v1): each stage that ran with its
    ``time_s`` (in order), the frame time and the total (scene loading to images
    written), counters, settings and the inputs with their sha256."""
    order = ["scene", "meshes", "materials", "textures", "sparkles", "lobes", "environment",
             "rasterize", "shadows", "shade", "spectra", "downsample", "tonemap", "write_exr",
             "write_spectral_exr", "write_png"]
    names = [k for k in order if k in stats.time_s]
    names += [k for k in stats.time_s if k not in names and "." not in k]
    stages = [{"stage": k, "time_s": stats.time_s[k]} for k in names]
    substages = [{"stage": k, "time_s": v} for k, v in stats.time_s.items() if "." in k]
    outputs = {"png": str(png), "exr": str(exr) if exr is not None else None,
               "gamut_warning": str(gamut_warning) if gamut_warning is not None else None}
    if spectral_exr is not None:
        outputs["spectral_exr"] = str(spectral_exr)
    doc = make_document(
        REPORT_SCHEMA, REPORT_VERSION,
        {"stages": stages, "substages": substages, "frame_time_s": frame_time(stats),
         "frame_stages": [k for k in FRAME_STAGES if k in stats.time_s],
         "outputs": outputs,
         "image": {"width": scene.camera.width, "height": scene.camera.height},
         "counts": stats.counts},
        inputs=scene.inputs, parameters=settings(scene), time_s=total_s)
    write_json(path, doc)
    return doc
