"""Loading what a scene names, before the render: each object's mesh in world space
(:func:`load_meshes`) and its :class:`~gonio_cli.render.surface.Surface`
(:func:`build_surfaces`: materials on the render's grid, measured references, halftone
mask pyramids, sparkle textures, lobe weights), every file read once. An error in a file
the scene names is said as the scene's key (:class:`SceneKey`)."""

from __future__ import annotations

import functools
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from .. import log
from ..brdf import MODELS
from ..errors import ArtifactError, GonioError, InputError
from ..imageio import read_image
from ..schemas import read_lobes, read_material, read_measurement
from ..sparkle import SparkleTexture, texture_from_image
from ..spectra import covers, resample, same_grid
from . import Stats
from .env_scene import environment_method
from .environment import check_lobes
from .frame import Stage
from .glint_term import glint_surface
from .measured import measured_material
from .mesh import load_mesh, require_uvs, transform
from .scene_types import Scene
from .surface import Surface
from .texture import MaskPyramid


class SceneKey:
    """``with SceneKey(scene, "[[object]] 2 material", path):`` turns an error reading the
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
    spec = MODELS[material.model]
    for name in spec.spectral_params + spec.table_params[:1]:   # a table's last axis is λ
        params[name] = resample(material.wavelength_nm, params[name], grid_nm)
    return type(material)(material.model, np.asarray(grid_nm, float), params,
                          material.status, material.fit)


def build_surfaces(scene: Scene, stats: Stats) -> list:
    """One :class:`~gonio_cli.render.surface.Surface` per object: materials read once per
    file, mask pyramids for printed objects only, lobes only with an environment."""
    materials: dict[Path, Any] = {}

    def material(path: Path, key: str):
        if path not in materials:
            with SceneKey(scene, key, path):
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
                with SceneKey(scene, f"{where} measured", o.measured):
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
                    with SceneKey(scene, f"[[object]] {o.index + 1} mask", o.mask):
                        pyramids[o.mask] = load_mask_pyramid(o.mask)
                s.coverage = functools.partial(pyramids[o.mask].coverage, wrap=o.wrap)
    sparkling = [(o, s) for o, s in zip(scene.objects, surfaces) if o.sparkle is not None]
    if sparkling:
        with Stage(stats, "sparkles"):
            for o, s in sparkling:
                with SceneKey(scene, f"[[object]] {o.index + 1} sparkle", o.sparkle):
                    s.sparkle = load_sparkle(o)
    if scene.environment is not None:
        with Stage(stats, "lobes"):
            _environment_lobes(scene, surfaces)
    return surfaces


def _environment_lobes(scene: Scene, surfaces: list) -> None:
    """Each object's environment method; the lobe weights of those that use them."""
    lobes: dict[Path, Any] = {}

    def read(p, key):
        if p not in lobes:
            with SceneKey(scene, key, p):
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
    img = read_image(o.sparkle)
    texture, theta_h = texture_from_image(img.pixels, img.metadata, str(o.sparkle))
    return SparkleTexture(texture, theta_h, o.sparkle_exponent, o.sparkle_scale,
                          np.asarray(o.sparkle_color, float), str(o.sparkle))


def load_mask_pyramid(path: Path):
    """The area-filtered coverage pyramid of a halftone mask image (:mod:`.texture`),
    which validates the mask and names the file in its errors."""
    return MaskPyramid.from_file(path)
