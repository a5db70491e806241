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
is scene loading to images written (the CLI measures it from before ``load_scene``).

Writing the frame out is :mod:`gonio_cli.render.output` (re-exported here). Loading, the
memory check and the stages share one scene and its caches; each stage is a short call into
its own module (:mod:`.raster`, :mod:`.shade`, …): what is left here is their order.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .. import log
from ..errors import ArtifactError, GonioError, InputError
from . import Stats
from .budget import check_memory, needs_positions
from .env_scene import (background_rgb, environment_method, environment_tables,
                        shading_lights)
from .resolve import resolve
from .spectral_pass import check_spectral_lobes, spectral_radiance
from .scene import Scene

#: Stages whose sum is the frame time (acceptance: rasterize, shadows, shade, tone map).
FRAME_STAGES = ("rasterize", "shadows", "occlusion", "shade", "downsample", "tonemap")


@dataclass
class Frame:
    """A rendered frame: ``linear`` (H, W, 3) float32 linear sRGB after the display's
    chromatic adaptation (``[output] adapt``: what the PNG shows; the colour EXR is
    :func:`.output.exr_pixels`, by default without adaptation),
    ``display`` (H, W, 3) uint8 sRGB-encoded after exposure and tone map (the PNG),
    ``xyz`` (H, W, 3) float64 CIE XYZ (box-filtered), ``coverage`` (H, W) the fraction of
    each pixel's samples that hit an object, ``out_of_gamut`` (H, W) bool the pixels whose
    colour lies outside sRGB (a negative linear channel, shown clipped to 0), ``spectra``
    (H, W, n_λ) float32 the spectral radiance on the working grid (box-filtered like
    ``xyz``, whose Σλ L cmf / Σ ȳ it is), only when asked for; ``background`` the linear
    sRGB behind the objects ((3,) or (H, W, 3), :func:`background_rgb`) or None."""

    linear: np.ndarray
    display: np.ndarray
    xyz_source: np.ndarray | Callable[[], np.ndarray] = field(repr=False)
    coverage: np.ndarray
    out_of_gamut: np.ndarray | None = None
    spectra: np.ndarray | None = None
    background: np.ndarray | None = None

    @functools.cached_property
    def xyz(self) -> np.ndarray:
        """(H, W, 3) float64 CIE XYZ; made on first use where :func:`resolve` deferred it."""
        return self.xyz_source() if callable(self.xyz_source) else self.xyz_source


class Stage:
    """``with Stage(stats, "name"):`` adds the wall time to ``stats.time_s["name"]``."""

    def __init__(self, stats: Stats, name: str):
        self.stats, self.name = stats, name

    def __enter__(self):
        self.t0 = time.perf_counter()
        return self

    def __exit__(self, *exc):
        self.stats.time_s[self.name] = (self.stats.time_s.get(self.name, 0.0)
                                        + time.perf_counter() - self.t0)
        return False


# ---------------------------------------------------------------------------- loading --

class _SceneKey:
    """``with _SceneKey(scene, "[[object]] 2 material", path):`` turns an error reading the
    artifact at ``path`` into one that names the scene file and its key first, e.g.
    ``scene.toml: [[object]] 2 material = red.lobes.json: schema is 'gonio.lobes',
    expected 'gonio.material'`` (the wrong file in the right place is the scene's fault)."""

    def __init__(self, scene: Scene, key: str, path):
        self.scene, self.key, self.path = scene, key, Path(path)

    def __enter__(self):
        return self

    def __exit__(self, kind, exc, tb):
        if exc is None or not isinstance(exc, GonioError):
            return False
        where = self.path.name + (f":{exc.row}" if exc.row is not None else "")
        column = f"{exc.column}: " if exc.column else ""
        fix = exc.fix
        if isinstance(exc, ArtifactError):  # and the command that makes the right one
            fix = f"point {self.key.split()[-1]} at the right file" + (
                f", or {exc.fix}" if (exc.fix or "").startswith("make ") else "")
        raise InputError(f"{self.key} = {where}: {column}{exc.message}",
                         path=self.scene.display, fix=fix) from None


def load_meshes(scene: Scene) -> list:
    """Each object's mesh in world space; a mask needs texture coordinates."""
    from .mesh import load_mesh, require_uvs, transform

    cache: dict[str, Any] = {}
    meshes = []
    for o in scene.objects:
        if o.mesh not in cache:
            try:
                cache[o.mesh] = load_mesh(o.mesh, scene.path.parent)
            except InputError as exc:
                if not o.is_builtin:
                    raise  # names the mesh file
                raise InputError(f"[[object]] {o.index + 1} mesh: {exc.message}",
                                 path=scene.display, fix=exc.fix) from None
        mesh = transform(cache[o.mesh], o.translate, o.rotate_deg, o.scale)
        if o.mask is not None:
            require_uvs(mesh, f"the mask of [[object]] {o.index + 1} ({o.name}) in "
                              f"{scene.path.name}")
        if o.sparkle is not None:
            require_uvs(mesh, f"the sparkle texture of [[object]] {o.index + 1} ({o.name}) "
                              f"in {scene.path.name}")
        meshes.append(mesh)
    return meshes


#: The fix of a material that does not cover the render's grid: only a grid given with
#: ``--grid-nm`` can do that (otherwise :func:`.scene_grid.choose_grid` follows the materials).
GRID_FIX = ("choose --grid-nm inside its range, or leave --grid-nm out and the grid "
            "follows the materials")


def on_grid(material, grid_nm: np.ndarray, path: Path):
    """A fitted material with its spectral parameters on the render's grid: resampled
    with a warning when its grid differs (docs/conventions.md), refused when it does not cover."""
    from ..brdf import MODELS
    from ..spectra import covers, resample, same_grid

    if same_grid(material.wavelength_nm, grid_nm):
        return material
    if not covers(material.wavelength_nm, grid_nm):
        raise InputError(f"covers {material.wavelength_nm.min():g}-"
                         f"{material.wavelength_nm.max():g} nm, not the render's grid "
                         f"{grid_nm[0]:g}-{grid_nm[-1]:g} nm", path=path,
                         fix=GRID_FIX)
    log.warn(f"{path}: material resampled from {material.wavelength_nm.size} wavelengths "
             f"onto the render's grid ({grid_nm.size} samples)")
    params = dict(material.params)
    for name in MODELS[material.model].spectral_params:
        params[name] = resample(material.wavelength_nm, params[name], grid_nm)
    return type(material)(material.model, np.asarray(grid_nm, float), params,
                          material.status, material.fit)


def build_surfaces(scene: Scene, stats: Stats) -> list:
    """One :class:`~gonio_cli.render.shade.Surface` per object: materials read once per
    file, mask pyramids for printed objects only, lobes only with an environment."""
    from ..schemas import read_lobes, read_material
    from .glint_term import glint_surface
    from .shade import Surface

    materials: dict[Path, Any] = {}

    def material(path: Path, key: str):
        if path not in materials:
            with _SceneKey(scene, key, path):
                m = read_material(path)
            if m.status == "failed":  # a poor one was said so when it was fitted
                log.warn(f"{path}: a fit with status {m.status!r} is rendered")
            materials[path] = on_grid(m, scene.grid_nm, path)
        return materials[path]

    surfaces = []
    with Stage(stats, "materials"):
        for o in scene.objects:
            s = Surface(name=o.name)
            where = f"[[object]] {o.index + 1}"
            if o.material is not None:
                s.material = material(o.material, f"{where} material")
                glint_surface(s, o, scene, f"{scene.display}: {where} ({o.name})")
            elif o.measured is not None:
                with _SceneKey(scene, f"{where} measured", o.measured):
                    s.material = load_measured(o.measured, scene.grid_nm, o.interpolation)
            else:
                s.inks = [material(p, f"{where} inks[{k}]") for k, p in enumerate(o.inks)]
                sub = o.substrate
                s.substrate = (None if sub is None or (sub.kd == 0 and sub.ks == 0) else
                               {"kd": sub.kd, "ks": sub.ks, "shininess": sub.shininess})
            surfaces.append(s)
    printed = [(o, s) for o, s in zip(scene.objects, surfaces) if o.mask is not None]
    if printed:
        with Stage(stats, "textures"):
            pyramids: dict[Path, Any] = {}
            for o, s in printed:
                if o.mask not in pyramids:
                    with _SceneKey(scene, f"[[object]] {o.index + 1} mask", o.mask):
                        pyramids[o.mask] = load_mask_pyramid(o.mask)
                s.coverage = functools.partial(pyramids[o.mask].coverage, wrap=o.wrap)
    sparkling = [(o, s) for o, s in zip(scene.objects, surfaces) if o.sparkle is not None]
    if sparkling:
        with Stage(stats, "sparkles"):
            for o, s in sparkling:
                with _SceneKey(scene, f"[[object]] {o.index + 1} sparkle", o.sparkle):
                    s.sparkle = load_sparkle(o)
    if scene.environment is not None:
        with Stage(stats, "lobes"):
            _environment_lobes(scene, surfaces, read_lobes)
    return surfaces


def _environment_lobes(scene: Scene, surfaces: list, read_lobes) -> None:
    """Each object's environment method; the lobe weights of those that use them."""
    lobes: dict[Path, Any] = {}

    def read(p, key):
        from .environment import check_lobes

        if p not in lobes:
            with _SceneKey(scene, key, p):
                lobes[p] = read_lobes(p)
                check_lobes(lobes[p], scene.grid_nm)     # its grid, named here
        return lobes[p]

    for o, s in zip(scene.objects, surfaces):
        s.env_method = environment_method(scene, o)
        if s.env_method == "model":
            continue
        if o.lobes is None:
            raise InputError(f"[[object]] {o.index + 1} ({o.name}): [environment] method = "
                             "'lobes' needs the object's lobes", path=scene.display,
                             fix="add lobes = \"....lobes.json\" (gonio lobes fit), or "
                                 "method = 'model'")
        key = f"[[object]] {o.index + 1} lobes"
        s.lobes = ([read(p, f"{key}[{k}]") for k, p in enumerate(o.lobes)]
                   if isinstance(o.lobes, list) else read(o.lobes, key))


def load_measured(path: Path, grid_nm: np.ndarray, interpolation: str = "smooth"):
    """The measured reference material (seed 000 Figure 5) of :mod:`.measured` by its
    ``interpolation``, its spectra resampled onto the render's grid (with a warning)
    when needed."""
    from dataclasses import replace

    from ..schemas import read_measurement
    from ..spectra import covers, resample, same_grid
    from .measured import measured_material

    m = read_measurement(path)
    if not same_grid(m.wavelength_nm, grid_nm):
        if not covers(m.wavelength_nm, grid_nm):
            raise InputError(f"covers {m.wavelength_nm.min():g}-{m.wavelength_nm.max():g} "
                             f"nm, not the render's grid {grid_nm[0]:g}-{grid_nm[-1]:g} nm",
                             path=path, fix=GRID_FIX)
        log.warn(f"{path}: measurement resampled from {m.wavelength_nm.size} wavelengths "
                 f"onto the render's grid ({grid_nm.size} samples)")
        m = replace(m, wavelength_nm=np.asarray(grid_nm, float),
                    brdf=resample(m.wavelength_nm, m.brdf, grid_nm), brdf_std=None)
    return measured_material(m, name=str(path), interpolation=interpolation)


def load_sparkle(o):
    """The :class:`gonio_cli.sparkle.SparkleTexture` of a scene object with ``sparkle``:
    the 8-bit packed texture (eq. 16) and the θh of each bit from its metadata."""
    from ..imageio import read_image
    from ..sparkle import SparkleTexture, texture_from_image

    img = read_image(o.sparkle)
    texture, theta_h = texture_from_image(img.pixels, img.metadata, str(o.sparkle))
    return SparkleTexture(texture, theta_h, o.sparkle_exponent, o.sparkle_scale,
                          np.asarray(o.sparkle_color, float), str(o.sparkle))


def load_mask_pyramid(path: Path):
    """The area-filtered coverage pyramid of a halftone mask image (:mod:`.texture`),
    which validates the mask and names the file in its errors."""
    from .texture import MaskPyramid

    return MaskPyramid.from_file(path)


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
    import ctypes

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
    environment = None
    if scene.environment is not None:
        from .environment import load_environment

        with Stage(stats, "environment"), _SceneKey(scene, "[environment] prefiltered",
                                                     scene.environment.prefiltered):
            environment = load_environment(scene.environment.prefiltered)
        if any(s.env_method == "model" for s in surfaces):
            with Stage(stats, "environment.lobes"):
                environment_tables(scene, surfaces, environment)
    yield "materials"
    from .raster import rasterize
    from .shadowmap import lone_convex

    ssaa = scene.output.ssaa
    # shadow maps unless no light casts shadows or the scene is one convex solid; the
    # lights are the scene's and the environment's sun (gonio prefilter --sun)
    lights = shading_lights(scene, environment)
    occlusion = environment is not None and scene.environment.occlusion > 0
    maps = ((any(light.shadow for light in lights) or occlusion)
            and not lone_convex(meshes))
    with Stage(stats, "rasterize"):
        # compact float32 rows of covered samples; texture coordinates only when a mask
        # or a sparkle texture will read them, positions only for point lights and
        # shadow maps, facet normals only for shadow maps
        gbuffer = rasterize(scene.camera, meshes, ssaa, uv=scene.needs_uvs, compact=True,
                            dtype=np.float32, position=needs_positions(scene, maps),
                            facet=maps)
    visibility, env_visibility = _visibilities(scene, lights, environment, meshes, gbuffer,
                                               stats)
    del meshes
    yield "rasterize"
    t0 = time.perf_counter()
    rows = _shade_without_overflow(scene, gbuffer, surfaces, environment, lights, stats,
                                   visibility, env_visibility)
    stats.time_s.setdefault("shade", time.perf_counter() - t0)
    outside = [getattr(s.material, "outside_samples", None) for s in surfaces]
    if any(n is not None for n in outside):     # a smooth measured reference (docs/render.md)
        stats.counts["measured_outside_samples"] = int(sum(n or 0 for n in outside))
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
        from .tonemap import xyz_to_linear_matrix

        # adaptation and colour matrix are linear: applied after the box filter, on output
        # pixels (at ssaa 1, on the covered ones), as one matrix
        matrix = xyz_to_linear_matrix(scene.output.adapt, scene_white(scene))
        xyz, coverage, linear = resolve(rows, pixels, object_id, ssaa, scene.display, stats,
                                        matrix=matrix)
        del rows
        if background is not None:
            linear += ((1.0 - coverage)[..., None] * background).astype(np.float32)
    stats.counts["covered_pixels"] = int(np.count_nonzero(coverage > 0))
    yield "resolve"
    with Stage(stats, "tonemap"):
        from .tonemap import display

        png, shown = display(linear, scene.output.exposure, scene.output.tonemap, counts=True)
    # what the display could not show: colours outside sRGB, channels clipped at 1
    stats.counts["out_of_gamut_pixels"] = int(np.count_nonzero(shown["out_of_gamut"]))
    stats.counts["clipped_pixels"] = int(np.count_nonzero(shown["clipped"]))
    state["frame"] = Frame(linear, png, xyz, coverage, shown["out_of_gamut"], radiance,
                           background)
    yield "tonemap"


def _visibilities(scene: Scene, lights: list, environment, meshes: list, gbuffer,
                  stats: Stats):
    """Per light its shadows' visibility (:func:`.shadow.shadow_visibility`; None when no
    light casts shadows) and the share of the environment's diffuse light the meshes let
    through (:func:`.occlusion.occlusion_visibility`; None without an occluded
    ``[environment]``)."""
    visibility = env_visibility = None
    if any(light.shadow for light in lights):
        from .shadow import shadow_visibility

        visibility = shadow_visibility(lights, meshes, gbuffer, stats)
    if environment is not None and scene.environment.occlusion > 0:
        from .occlusion import occlusion_visibility
        from .skycut import environment_directions

        env_visibility = occlusion_visibility(
            environment_directions(environment, scene.environment.occlusion), meshes,
            gbuffer, stats)
    return visibility, env_visibility


def scene_white(scene: Scene) -> np.ndarray | None:
    """The scene's white, XYZ (3,) with Y = 1: the lights' irradiance-weighted spectra
    (:func:`gonio_cli.render.tonemap.scene_white_xyz`); None without lights."""
    from .tonemap import scene_white_xyz

    return scene_white_xyz(scene.lights, scene.grid_nm, scene.camera.target)


def _shade_without_overflow(scene: Scene, gbuffer, surfaces, environment, lights: list,
                            stats: Stats, visibility=None, env_visibility=None):
    """``shade_rows`` in float32 under ``lights`` (:func:`.env_scene.shading_lights`); an
    overflow (light × reflectance beyond float32's 3.4e38,
    docs/conventions.md "Numeric ranges") is an error naming the scene, never black or
    NaN pixels in the images."""
    from ..errors import NumericError
    from .shade import shade_rows

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


# re-exports: writing the frame out is gonio_cli.render.output, which imports Frame (so last)

from .output import (GAMUT_WARNING_RGB, IMAGE_SCHEMA, IMAGE_SCHEMA_VERSION,  # noqa: E402
                     REPORT_SCHEMA, REPORT_VERSION, SPECTRAL_UNITS, TURNTABLE_SCHEMA,
                     TURNTABLE_SCHEMA_VERSION, exr_pixels, frame_time, gamut_warning_image,
                     settings, turntable_metadata, write_outputs, write_report)
