"""What a render will need before it runs: its memory estimate (checked against the
machine's before anything is allocated) and which G-buffer attributes the scene asks for.

The estimate is the largest of the steps of :func:`gonio_cli.render.pipeline.render_scene`
(meshes, G-buffer, shadows, shading and resolve, output images, the spectral image),
each from the scene's sizes and the constants below; ``tests/test_memory.py`` checks it
against measured peaks.
"""

from __future__ import annotations

import numpy as np

from ..memory import check
from .mesh import builtin_triangles
from .raster import gbuffer_bytes
from .scene_types import Scene
from .shadowmap import MAX_MAP_SIDE, TEXELS_PER_SAMPLE


#: Bytes per covered sample of the shading and the resolve besides the G-buffer: the
#: float32 XYZ row and its place in the float32 supersampled image.
SHADE_BYTES_PER_SAMPLE = 12 + 12
#: Bytes per output pixel: XYZ float64, linear float32, coverage, display uint8 and the
#: encoders' copies.
OUTPUT_BYTES_PER_PIXEL = 24 + 12 + 8 + 3 + 24
#: Peak bytes per triangle of a mesh through loading, transform and the rasterizer's
#: set-up: measured with ru_maxrss on a 64² frame of builtin:sphere?segments=1024 … 3072
#: (1 M … 9.4 M triangles): 185 bytes a triangle above the baseline, linear in the count
#: (tests/test_memory.py checks the estimate against a measured peak).
MESH_BYTES_PER_TRIANGLE = 190


#: Bytes per value (pixel × wavelength) of a spectral image: the float32 image and, while
#: colour-science writes it, OpenImageIO's buffer growing one channel at a time (the old
#: and the new buffer, float32 each).
SPECTRAL_BYTES_PER_VALUE = 4 + 8
#: Bytes per covered sample and wavelength of a pass of :func:`.spectral_pass.spectral_radiance`: the
#: float32 shaded rows, a float64 accumulator of one term and an object's float32 rows.
SPECTRAL_BYTES_PER_ROW_BAND = 4 + 8 + 8
#: Most bytes the shading of one pass may take: wavelengths per pass are as many as fit
#: (all 41 of the default grid up to ~330 k covered samples, e.g. a 480² frame at ssaa 2
#: half covered takes two passes). Each pass repeats the geometry, so fewer is faster.
SPECTRAL_PASS_BYTES = 1 << 28


def memory_estimate(scene: Scene, spectra: bool = False) -> int:
    """Peak bytes of a frame's buffers (:func:`render_scene`), as if every sample were
    covered: the compact float32 G-buffer with its keys and indices
    (:func:`gonio_cli.render.raster.gbuffer_bytes`), the shaded rows, the supersampled
    image of the resolve and the output images, the shadows (:func:`shadow_bytes`), the
    occlusion of the environment (:data:`OCCLUSION_BYTES_PER_SAMPLE`); with
    ``spectra``, plus :func:`spectral_image_bytes`. Built-in meshes count
    :data:`MESH_BYTES_PER_TRIANGLE` (:func:`mesh_triangles`); OBJ files and materials are
    not counted."""
    cam, ssaa = scene.camera, scene.output.ssaa
    samples = cam.width * cam.height * ssaa ** 2
    return (gbuffer_bytes(cam.height, cam.width, ssaa, uv=scene.needs_uvs,
                          position=needs_positions(scene),
                          facet=shadowing_lights(scene) > 0 or occludes(scene))
            + samples * SHADE_BYTES_PER_SAMPLE + cam.width * cam.height * OUTPUT_BYTES_PER_PIXEL
            + mesh_triangles(scene) * MESH_BYTES_PER_TRIANGLE + shadow_bytes(scene)
            + (samples * OCCLUSION_BYTES_PER_SAMPLE if occludes(scene) else 0)
            + (spectral_image_bytes(scene) if spectra else 0))


#: Bytes per sample of the occlusion of the environment (:mod:`.occlusion`): its four
#: nodes (int32) and their weights (float32) while V is carried to the samples, and V
#: (float32) kept for the shading.
OCCLUSION_BYTES_PER_SAMPLE = 4 * 4 + 4 * 4 + 4
#: Bytes per sample and shadowing light: its visibility (float32), kept for the shading.
SHADOW_BYTES_PER_SAMPLE = 4
#: Bytes per texel of a shadow map while it is used: the float32 map, its two bounds and
#: the dilation's two temporaries.
SHADOW_BYTES_PER_TEXEL = 20


def shadow_bytes(scene: Scene) -> int:
    """Bytes of the shadows: the visibilities of the shadowing lights, and the largest
    map (:data:`gonio_cli.render.shadowmap.TEXELS_PER_SAMPLE` texels per sample, at most
    :data:`~gonio_cli.render.shadowmap.MAX_MAP_SIDE` a side; maps are made one at a time)."""
    n = shadowing_lights(scene)
    if not n:
        return 0
    cam = scene.camera
    samples = cam.width * cam.height * scene.output.ssaa ** 2
    texels = min(MAX_MAP_SIDE ** 2, int(TEXELS_PER_SAMPLE * samples))
    return n * samples * SHADOW_BYTES_PER_SAMPLE + texels * SHADOW_BYTES_PER_TEXEL


def spectral_image_bytes(scene: Scene) -> int:
    """Bytes of the spectral image, H × W × n_λ values (:data:`SPECTRAL_BYTES_PER_VALUE`),
    and of its shading passes (at most :data:`SPECTRAL_PASS_BYTES`)."""
    cam = scene.camera
    n = int(np.size(scene.grid_nm))
    samples = cam.width * cam.height * scene.output.ssaa ** 2
    return (cam.width * cam.height * n * SPECTRAL_BYTES_PER_VALUE
            + min(samples * n * SPECTRAL_BYTES_PER_ROW_BAND, SPECTRAL_PASS_BYTES))


def bands_per_pass(rows: int, n_wavelengths: int) -> int:
    """Wavelengths per pass of :func:`.spectral_pass.spectral_radiance` for ``rows`` covered samples:
    as many as :data:`SPECTRAL_PASS_BYTES` holds, at least 1."""
    fit = SPECTRAL_PASS_BYTES // max(1, rows * SPECTRAL_BYTES_PER_ROW_BAND)
    return int(max(1, min(n_wavelengths, fit)))


def mesh_triangles(scene: Scene) -> int:
    """Triangles of the scene's built-in meshes, one copy per object (each is
    transformed into world space)."""
    return sum(builtin_triangles(o.mesh) or 0 for o in scene.objects)


def check_memory(scene: Scene, spectra: bool = False) -> int:
    """Refuse, before allocating anything, a frame whose buffers and meshes exceed the
    memory available (:func:`gonio_cli.memory.check`); the message gives the estimate
    and the options that lower it. With ``spectra`` (a spectral image) the frame is
    checked first, then frame + image. Returns the estimate in bytes."""
    cam = scene.camera
    frame = memory_estimate(scene)
    triangles = mesh_triangles(scene)
    if triangles * MESH_BYTES_PER_TRIANGLE > frame / 2:
        check(frame, f"a {cam.width}x{cam.height} render of {triangles / 1e6:.1f} M "
              "built-in mesh triangles", path=scene.display,
              fix="lower segments= (and rings=) of the builtin: mesh")
    check(frame, f"a {cam.width}x{cam.height} render at ssaa {scene.output.ssaa}",
          path=scene.display, fix="lower --ssaa or --width-px/--height-px")
    if not spectra:
        return frame
    return check(memory_estimate(scene, spectra=True),
                 f"a {cam.width}x{cam.height} spectral image on {np.size(scene.grid_nm)} "
                 "wavelengths with the frame's buffers", path=scene.display,
                 fix="use a coarser --grid-nm, or lower --width-px/--height-px or --ssaa")


def needs_positions(scene: Scene, shadows: bool | None = None) -> bool:
    """World positions are read only by point lights, glints, shadows and the occlusion
    of the environment (``shadows``: whether maps will be made; None: whether any light
    casts shadows or the environment is occluded)."""
    shadows = shadowing_lights(scene) > 0 or occludes(scene) if shadows is None else shadows
    return (shadows or any(light.kind == "point" for light in scene.lights)
            or any(o.glint_density is not None for o in scene.objects))


def occludes(scene: Scene) -> bool:
    """Whether the scene's meshes occlude its environment (``[environment] occlusion``)."""
    return scene.environment is not None and scene.environment.occlusion > 0


def shadowing_lights(scene: Scene) -> int:
    """How many of the scene's lights cast shadows."""
    return sum(1 for light in scene.lights if light.shadow)
