"""``gonio render``: a CPU numpy rasterizer with spectral shading (seeds 000, 001, 004).

The frame is computed in stages, each a module with a pure numpy core; the data passed
between them are the dataclasses below, so each stage can be tested on its own:

1. :mod:`.scene`    TOML scene file → :class:`Scene` (camera, objects, lights,
                    environment, output), every path relative to the scene file,
                    unknown keys and wrong types refused with the key and the file.
2. :mod:`.mesh`     OBJ (:mod:`.obj`) and built-ins (``builtin:sphere``, ``builtin:plane``)
                    → :class:`Mesh` in world space (transform applied, smooth normals).
3. :mod:`.raster`   :class:`Camera` + meshes → :class:`GBuffer` (per pixel of the
                    supersampled image: object, position, normal, view direction, uv and
                    its footprint, facet normal), by a batched z-buffer (many triangles per
                    array op).
   :mod:`.shadow`   GBuffer + meshes + lights → each light's visibility per sample, from
                    shadow maps (:mod:`.shadowmap`, :mod:`.depthmap`), soft-edged by the
                    light's size; skipped for a lone convex solid (:mod:`.solid`).
4. :mod:`.texture`  halftone masks → area-filtered coverage pyramid (mipmaps) and the
                    coverage of R, G, B ink and bare substrate per pixel.
5. :mod:`.shade`    GBuffer + materials + :class:`Light` list (+ environment) → XYZ per
                    pixel (docs/conventions.md: XYZ = Σ L cmf / Σ ȳ), via the tabulated spectral
                    sum (eq. 5 depends on the angles only through x for one light
                    spectrum) or the exact 41-wavelength path.
6. :mod:`.tonemap`  XYZ → linear sRGB → exposure → tone map → sRGB-encoded 8-bit.
7. :mod:`.run`      the whole ``gonio render`` as a library call: :class:`.options.RenderOptions`
                    → :func:`.run.run` (scene, frames, PNG and EXR out, ``--report``), the
                    stages in order in :mod:`.pipeline`; :mod:`gonio_cli.commands.render`
                    is its typer shell.

Conventions (``docs/conventions.md``): right-handed world; camera ``eye``, ``target``, ``up``,
``fov_deg`` = full vertical field of view; pixel centres at (col + ½, row + ½), row 0 the
top; BRDFs never include cos θi; a directional light has irradiance E at normal incidence,
a point light intensity I (E = I/d²), each times the visibility V its shadows leave; light
spectra are scaled so Σ S ȳ / Σ ȳ = 1.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class Camera:
    """Pinhole camera. ``eye``, ``target``, ``up``: (3,) world; ``fov_deg``: full vertical
    field of view in degrees; ``width``, ``height``: output pixels (before supersampling)."""

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov_deg: float
    width: int
    height: int


@dataclass
class Mesh:
    """A triangle mesh in world space.

    vertices : (V, 3) float64 ; faces : (F, 3) int64 (counter-clockwise = front)
    normals : (V, 3) unit vertex normals (smooth) ; uvs : (V, 2) or None
    (OpenGL convention: v = 0 is the bottom row of a texture image).
    closed : the faces form closed surfaces facing outwards
    (:func:`gonio_cli.render.solid.closed_surface`), so from outside only front faces can
    be seen; False when unknown (the rasterizer then tests every face).
    """

    vertices: np.ndarray
    faces: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray | None = None
    name: str = ""
    closed: bool = False


@dataclass
class GBuffer:
    """What the rasterizer leaves at each pixel (H, W) of the supersampled image.

    object_id : (H, W) int, index into the scene's objects, −1 where nothing was hit
    position : (H, W, 3) world position (None if not asked for: only point lights and
        shadows need it) ; normal : (H, W, 3) unit shading normal, flipped towards the
        viewer on back faces ; view : (H, W, 3) unit direction to the eye (ωo)
    uv : (H, W, 2) or None (perspective-correct) ; uv_footprint : (H, W) the size of the
        pixel in texture space (uv units), for the mip level ; ssaa : the supersampling
        factor (H = ssaa × camera.height)
    pixels : None (dense: the arrays above are whole images, background pixels hold
        zeros, never NaN) or (n,) ascending flat indices into (H, W) of the covered
        samples (compact: position … uv_footprint hold one row per covered sample,
        (n, 3), (n, 2), (n,), in this order; the render pipeline's layout).
    facet_normal : (H, W, 3) or (n, 3), or None (not asked for: only shadows read it):
        the unit normal of each sample's triangle (world, either sign).
    """

    object_id: np.ndarray
    position: np.ndarray | None
    normal: np.ndarray
    view: np.ndarray
    uv: np.ndarray | None = None
    uv_footprint: np.ndarray | None = None
    ssaa: int = 1
    pixels: np.ndarray | None = None
    facet_normal: np.ndarray | None = None

    @property
    def covered(self) -> np.ndarray:
        return self.object_id >= 0

    @property
    def rows(self) -> int:
        """Rows of the attribute arrays: covered samples (compact) or all pixels (dense)."""
        return self.object_id.size if self.pixels is None else len(self.pixels)

    def row_object_id(self) -> np.ndarray:
        """(rows,) the object of each row of the attribute arrays."""
        flat = self.object_id.reshape(-1)
        return flat if self.pixels is None else flat[self.pixels]


#: Default angular diameter of a directional light (degrees): the sun's, seen from the
#: earth (0.53°), for the width of its shadows' penumbrae (:mod:`.shadow`).
SUN_ANGULAR_DIAMETER_DEG = 0.53
#: Default radius of a point light (scene units): a small lamp (1 cm in a scene in metres,
#: 1 % of the unit sphere's radius), for its shadows' penumbrae.
POINT_LIGHT_RADIUS = 0.01


@dataclass
class Light:
    """A light. ``kind``: "directional" (``direction``: (3,) unit vector from the surface
    towards the light, ``irradiance`` E at normal incidence) or "point" (``position`` (3,),
    ``intensity`` I, E = I/d²). ``spectrum``: (L,) on the working grid, Σ S ȳ / Σ ȳ = 1.

    ``shadow``: whether the scene's meshes block it (:mod:`.shadow`, applied by the
    render pipeline; :func:`.shade.shade_rows` takes the visibility it computes). Its
    size, for the penumbrae: ``angular_diameter_deg`` (directional) and ``radius``
    (point, scene units)."""

    kind: str
    spectrum: np.ndarray
    direction: np.ndarray | None = None
    irradiance: float = 0.0
    position: np.ndarray | None = None
    intensity: float = 0.0
    name: str = ""
    shadow: bool = True
    angular_diameter_deg: float = SUN_ANGULAR_DIAMETER_DEG
    radius: float = POINT_LIGHT_RADIUS


#: How an ``[environment]`` lights an object (``[environment] method``; docs/render.md).
ENVIRONMENT_METHODS = {
    "auto": "model, or lobes for an object that names a lobes file (and for a measured one)",
    "model": "every lobe of the object's own model reads the prefiltered chain at its own "
             "sharpness (gonio_cli.render.env_model)",
    "lobes": "seed 001 eqs. 7-9: the object's cosine-lobe weights (gonio lobes fit), one "
             "prefiltered map per lobe exponent",
}


@dataclass
class Stats:
    """Per-stage wall times (s) and counters for the run report (``--report``)."""

    time_s: dict[str, float] = field(default_factory=dict)
    counts: dict[str, Any] = field(default_factory=dict)
