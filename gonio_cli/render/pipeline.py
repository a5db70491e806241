"""The render pipeline: a validated :class:`~gonio_cli.render.scene.Scene` → images.

Stages, each timed into :class:`~gonio_cli.render.Stats` (``time_s[name]``) and listed
in the run report only if it ran ("leave out what the scene does not need"):

``scene``        the TOML file (:func:`gonio_cli.render.scene.load_scene`, timed by the CLI)
``meshes``       built-ins and OBJ files, placed by each object's transform
``materials``    gonio.material / gonio.measurement files, each read once
``textures``     mask pyramids: printed objects only
``sparkles``     sparkle textures (seed 004 §6): only for objects with ``sparkle``
``lobes``        lobe weights: only with an environment
``environment``  prefiltered maps: only if the scene has an ``[environment]``
``rasterize``    the batched z-buffer at ssaa × the image size
``shadows``      shadow maps and the visibility of each light at each sample
                 (:mod:`.shadow`): only for lights with ``shadow = true`` (the default)
``occlusion``    the share of the environment's diffuse light the meshes let through
                 (:mod:`.occlusion`): only with an ``[environment]`` whose
                 ``occlusion`` is not false; skipped (said so) for a convex solid
``shade``        spectral shading → XYZ (and ``shade.*`` sub-stages of :mod:`.shade`)
``spectra``      only with a spectral image: radiance per wavelength (:func:`.spectral_pass.spectral_radiance`)
``downsample``   box filter of the ssaa (:func:`resolve`), XYZ → linear sRGB (IEC matrix)
                 on output pixels, background
``tonemap``      exposure, tone map, sRGB encoding, 8 bits
``write_exr``, ``write_png``, ``write_spectral_exr``   the files (atomic)

The frame time is rasterize + shadows + occlusion + shade + downsample + tonemap; the total
is scene loading to images written (:func:`gonio_cli.render.run.run` measures it from
before ``load_scene``).

The frame and the stages' clock are :mod:`.frame`; writing the frame out is
:mod:`gonio_cli.render.output`; a whole ``gonio render`` (options, turntable, files,
report) is :func:`gonio_cli.render.run.run`. Loading, the
memory check and the stages share one scene and its caches; each stage is a short call into
its own module (:mod:`.raster`, :mod:`.shade`, …): what is left here is their order.
"""

from __future__ import annotations

import ctypes
import time
from typing import Any

import numpy as np

from .. import log
from ..errors import NumericError
from . import Stats
from .budget import check_memory, needs_positions
from .env_scene import background_rgb, environment_tables, shading_lights
from .environment import load_environment
from .frame import Frame, Stage
from .load import SceneKey, build_surfaces, load_meshes
from .occlusion import occlusion_visibility
from .raster import rasterize
from .resolve import resolve
from .scene_types import Scene
from .shade import shade_rows
from .shadow import shadow_visibility
from .shadowmap import lone_convex
from .skycut import environment_directions
from .spectral_pass import check_spectral_lobes, spectral_radiance
from .tonemap import display, scene_white, xyz_to_linear_matrix


# ----------------------------------------------------------------------------- render --

#: glibc's malloc returns freed blocks above a threshold that it moves at run time (from
#: 128 kB) to the system, so numpy's large temporaries come back as fresh pages and every
#: array operation pays the page faults again (measured on the 512² frame under a VM:
#: ~1 ns per byte written, a third of the frame). Blocks up to this size are kept in the
#: heap instead, and the heap is trimmed only above twice it.
KEEP_FREED_BYTES = 1 << 28


def keep_freed_memory() -> bool:
    """Ask glibc's malloc (``mallopt``) to keep freed blocks up to
    :data:`KEEP_FREED_BYTES` for reuse; True if it did. Elsewhere (another C library, no
    ``mallopt``) nothing changes. Process-wide and idempotent: freed memory stays with
    this process for reuse, which costs a little peak memory (measured: 686 → 719 MB for
    a 2048² frame at ssaa 2, 130 → 137 MB at 512²) and saved 40 % of that 2048² render."""
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes = (ctypes.c_int, ctypes.c_int)
    M_TRIM_THRESHOLD, M_MMAP_THRESHOLD = -1, -3               # glibc <malloc.h>
    return bool(mallopt(M_MMAP_THRESHOLD, KEEP_FREED_BYTES)
                and mallopt(M_TRIM_THRESHOLD, 2 * KEEP_FREED_BYTES))


def render_scene(scene: Scene, stats: Stats | None = None, *, spectra: bool = False
                 ) -> Frame:
    """Render a scene; every stage's time goes into ``stats``. Returns the :class:`Frame`,
    with its spectral image if ``spectra`` (:func:`.spectral_pass.spectral_radiance`).

    The stages run under :func:`gonio_cli.log.progress`: a bar on a terminal when the
    render is still running after 2 s, nothing otherwise. Freed memory is kept for reuse
    (:func:`keep_freed_memory`)."""
    stats = stats if stats is not None else Stats()
    keep_freed_memory()
    state: dict[str, Any] = {}
    steps = _render_steps(scene, stats, state, spectra)
    for _ in log.progress(steps, f"rendering {scene.path.name}",
                          total=RENDER_STEPS + int(spectra)):
        pass
    return state["frame"]


#: Steps of :func:`_render_steps` (the progress bar's length).
RENDER_STEPS = 6


def _render_steps(scene: Scene, stats: Stats, state: dict, spectra: bool = False):
    """The render as a generator that yields after each of :data:`RENDER_STEPS` steps
    (one more with ``spectra``)."""
    stats.counts["memory_estimate_bytes"] = check_memory(scene, spectra)
    with Stage(stats, "meshes"):
        meshes = load_meshes(scene)
    yield "meshes"
    surfaces = build_surfaces(scene, stats)
    if spectra:
        check_spectral_lobes(scene, surfaces)
    environment = _environment(scene, surfaces, stats)
    yield "materials"
    # the lights are the scene's and the environment's sun (gonio prefilter --sun)
    lights = shading_lights(scene, environment)
    gbuffer = _rasterize(scene, meshes, lights, environment, stats)
    visibility, env_visibility = _visibilities(scene, lights, environment, meshes, gbuffer,
                                               stats)
    del meshes
    yield "rasterize"
    rows = _shade(scene, gbuffer, surfaces, environment, lights, stats, visibility,
                  env_visibility)
    yield "shade"
    background = background_rgb(scene, environment)
    radiance = None
    if spectra:
        with Stage(stats, "spectra"):
            radiance = spectral_radiance(gbuffer, surfaces, scene, lights, environment,
                                         visibility, background, env_visibility)
        yield "spectra"
    object_id, pixels = gbuffer.object_id, gbuffer.pixels
    del gbuffer                                               # its rows are no longer needed
    with Stage(stats, "downsample"):
        # adaptation and colour matrix are linear: applied after the box filter, on output
        # pixels (at ssaa 1, on the covered ones), as one matrix
        matrix = xyz_to_linear_matrix(scene.output.adapt, scene_white(scene))
        xyz, coverage, linear = resolve(rows, pixels, object_id, scene.output.ssaa,
                                        scene.display, stats, matrix=matrix)
        del rows
        if background is not None:
            linear += ((1.0 - coverage)[..., None] * background).astype(np.float32)
    stats.counts["covered_pixels"] = int(np.count_nonzero(coverage > 0))
    yield "resolve"
    with Stage(stats, "tonemap"):
        png, shown = display(linear, scene.output.exposure, scene.output.tonemap, counts=True)
    # what the display could not show: colours outside sRGB, channels clipped at 1
    stats.counts["out_of_gamut_pixels"] = int(np.count_nonzero(shown["out_of_gamut"]))
    stats.counts["clipped_pixels"] = int(np.count_nonzero(shown["clipped"]))
    state["frame"] = Frame(linear, png, xyz, coverage, shown["out_of_gamut"], radiance,
                           background)
    yield "tonemap"


def _environment(scene: Scene, surfaces: list, stats: Stats):
    """The scene's prefiltered environment (None without an ``[environment]``), and the
    lobe tables of the objects it lights by their own model."""
    if scene.environment is None:
        return None
    with Stage(stats, "environment"), SceneKey(scene, "[environment] prefiltered",
                                                scene.environment.prefiltered):
        environment = load_environment(scene.environment.prefiltered)
    if any(s.env_method == "model" for s in surfaces):
        with Stage(stats, "environment.lobes"):
            environment_tables(scene, surfaces, environment)
    return environment


def _rasterize(scene: Scene, meshes: list, lights: list, environment, stats: Stats):
    """The G-buffer at ssaa × the image size: compact float32 rows of covered samples;
    texture coordinates only when a mask or a sparkle texture will read them, positions
    only for point lights and shadow maps, facet normals only for shadow maps (made
    unless no light casts shadows or the scene is one convex solid)."""
    occlusion = environment is not None and scene.environment.occlusion > 0
    maps = ((any(light.shadow for light in lights) or occlusion)
            and not lone_convex(meshes))
    with Stage(stats, "rasterize"):
        return rasterize(scene.camera, meshes, scene.output.ssaa, uv=scene.needs_uvs,
                         compact=True, dtype=np.float32,
                         position=needs_positions(scene, maps), facet=maps)


def _shade(scene: Scene, gbuffer, surfaces: list, environment, lights: list, stats: Stats,
           visibility, env_visibility):
    """The shaded rows (:func:`_shade_without_overflow`), timed, and the count of measured
    reference samples outside the measured range (a smooth measured reference,
    docs/render.md)."""
    t0 = time.perf_counter()
    rows = _shade_without_overflow(scene, gbuffer, surfaces, environment, lights, stats,
                                   visibility, env_visibility)
    stats.time_s.setdefault("shade", time.perf_counter() - t0)
    outside = [getattr(s.material, "outside_samples", None) for s in surfaces]
    if any(n is not None for n in outside):
        stats.counts["measured_outside_samples"] = int(sum(n or 0 for n in outside))
    return rows


def _visibilities(scene: Scene, lights: list, environment, meshes: list, gbuffer,
                  stats: Stats):
    """Per light its shadows' visibility (:func:`.shadow.shadow_visibility`; None when no
    light casts shadows) and the share of the environment's diffuse light the meshes let
    through (:func:`.occlusion.occlusion_visibility`; None without an occluded
    ``[environment]``)."""
    visibility = env_visibility = None
    if any(light.shadow for light in lights):
        visibility = shadow_visibility(lights, meshes, gbuffer, stats)
    if environment is not None and scene.environment.occlusion > 0:
        env_visibility = occlusion_visibility(
            environment_directions(environment, scene.environment.occlusion), meshes,
            gbuffer, stats)
    return visibility, env_visibility


def _shade_without_overflow(scene: Scene, gbuffer, surfaces, environment, lights: list,
                            stats: Stats, visibility=None, env_visibility=None):
    """``shade_rows`` in float32 under ``lights`` (:func:`.env_scene.shading_lights`); an
    overflow (light × reflectance beyond float32's 3.4e38,
    docs/conventions.md "Numeric ranges") is an error naming the scene, never black or
    NaN pixels in the images."""
    try:
        with np.errstate(over="raise"):
            return shade_rows(gbuffer, surfaces, lights, scene.grid_nm,
                              environment=environment, spectral=scene.output.spectral,
                              stats=stats, dtype=np.float32, visibility=visibility,
                              env_visibility=env_visibility)
    except FloatingPointError:
        raise NumericError("shading overflowed float32 (a light's irradiance or intensity "
                           "times a material's reflectance is beyond 3.4e38)",
                           path=scene.display,
                           fix="lower the lights' irradiance or intensity; check the "
                               "materials for huge values") from None

