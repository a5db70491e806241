"""A scene's environment as the render uses it: each object's method
(:data:`gonio_cli.render.ENVIRONMENT_METHODS`), the lobe tables of those lit through their
own model, the environment's sun among the lights, and the sky behind the objects."""

from __future__ import annotations

import numpy as np

from ..envmap import direction_to_spherical, lookup_angles
from ..errors import InputError
from .env_model import tables_for, warn_blurred
from .environment import sun_light
from .raster import pixel_rays
from .scene_types import Scene


def environment_method(scene: Scene, o) -> str:
    """``model`` or ``lobes`` for one object (:data:`gonio_cli.render.ENVIRONMENT_METHODS`):
    ``auto`` takes the object's lobes file where it names one, and a measured object
    (it has no model lobes) always needs one."""
    method = scene.environment.method
    if method == "auto":
        method = "lobes" if o.lobes is not None or o.measured is not None else "model"
    if method == "model" and o.measured is not None:
        raise InputError(f"[[object]] {o.index + 1} ({o.name}): a measured reference has no "
                         "model lobes for [environment] method = 'model'",
                         path=scene.display,
                         fix="give it lobes (gonio lobes fit) and method = 'lobes' or 'auto'")
    return method


def environment_tables(scene: Scene, surfaces: list, environment) -> None:
    """The lobe tables (:mod:`.env_model`) of every object lit by method ``model``,
    from gonio's disk cache after the first render of a material with a chain."""
    for o, s in zip(scene.objects, surfaces):
        if s.env_method != "model":
            continue
        where = f"{scene.display}: [[object]] {o.index + 1} ({o.name})"
        mats = s.inks if s.printed else [s.material]
        s.env_tables = [tables_for(environment, m, scene.grid_nm) for m in mats]
        for tables in s.env_tables:
            warn_blurred(tables, where, environment)
            for table in tables:                    # read the maps its lobes mix, here
                for level in table.levels:
                    environment.level(int(level))


def background_rgb(scene: Scene, environment) -> np.ndarray | None:
    """Linear sRGB behind the objects: ``[output] background`` (3,), None where it is 0,
    or with ``background = "environment"`` the environment seen through each pixel centre
    (H, W, 3) float32 (its sharpest prefiltered map: the map itself, less a split sun)."""
    if isinstance(scene.output.background, str):
        theta, phi = direction_to_spherical(pixel_rays(scene.camera))
        return lookup_angles(environment.level(len(environment.exponents) - 1), theta, phi)
    background = np.asarray(scene.output.background, float)
    return background if np.any(background != 0) else None


def shading_lights(scene: Scene, environment) -> list:
    """The scene's lights and the environment's sun (``gonio prefilter --sun``), if any:
    what lights the surfaces. The sun is the environment's, so it does not enter the
    scene white (a scene lit only by an environment is not adapted)."""
    sun = None if environment is None else sun_light(environment, scene.grid_nm)
    return list(scene.lights) + ([sun] if sun is not None else [])
