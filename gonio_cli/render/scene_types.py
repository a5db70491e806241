"""What a scene file describes, as the renderer reads it: :class:`Scene` and its
:class:`SceneObject`, :class:`Substrate`, :class:`Environment` and :class:`Output` (read
and checked by :func:`gonio_cli.render.scene.load_scene`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import Camera, Light
from .occlusion import DEFAULT_DIRECTIONS

#: Built-in meshes (``mesh = "builtin:NAME"``); anything else is an OBJ path.
#: Options after "?" (``builtin:sphere?segments=48``) are checked by :mod:`.mesh`.
BUILTIN_PREFIX = "builtin:"
BUILTIN_MESHES = ("sphere", "plane")


@dataclass
class Substrate:
    """What shows between the ink dots of a print (seed 000 Figures 8–9).

    ``kd``: Lambertian reflectance in [0, 1] (0: the black paper of seed 000);
    ``ks``: weight of a dim, texture-independent normalised Phong highlight, in [0, 1]
    (f = kd/π + ks (n + 2)/(2π) max(0, R·V)^n, Phong 1975, seed 000 ref. 27);
    ``shininess``: its exponent n ≥ 0 (low, e.g. 2–10, as seed 000 uses).
    """

    kd: float = 0.0
    ks: float = 0.0
    shininess: float = 1.0


@dataclass
class SceneObject:
    """One ``[[object]]``: a mesh, its transform and what it is made of.

    Exactly one of: ``material`` (a gonio.material), ``inks`` (three gonio.material paths,
    R, G, B) with ``mask`` (an RGB halftone mask image, docs/conventions.md) and ``substrate``, or
    ``measured`` (a gonio.measurement, interpolated: the reference of seed 000 Figure 5).
    ``lobes``: gonio.lobes weights for environment light (one path for ``material``,
    three for ``inks``), or None. ``mesh`` is ``builtin:NAME`` or an absolute OBJ path.
    ``sparkle``: a packed sparkle texture (``gonio sparkle``, seed 004 §6) or None, with
    ``sparkle_color`` (linear sRGB reflectance colour C_s), ``sparkle_exponent`` (e of
    eq. 17) and ``sparkle_scale`` (texture repeats over uv); material or measured only.
    ``glint_density`` (flakes per square scene unit) or None: glints (docs/render.md),
    with ``glint_share`` (s, the flake lobe's share drawn as flakes), ``glint_angle_deg``
    (a flake's angular spread) and ``glint_seed``; a material object only.
    ``wrap``: the mask's addressing, a key of :data:`gonio_cli.render.texture.WRAP_MODES`
    (``clamp``: a sheet with edges, the default; ``repeat``: the mask tiles); prints only.
    ``interpolation``: how a measured object is interpolated, a key of
    :data:`gonio_cli.render.measured.INTERPOLATIONS`; measured only.
    """

    index: int
    mesh: str
    translate: np.ndarray
    rotate_deg: np.ndarray
    scale: np.ndarray
    name: str = ""
    material: Path | None = None
    inks: list[Path] | None = None
    mask: Path | None = None
    substrate: Substrate | None = None
    lobes: Path | list[Path] | None = None
    measured: Path | None = None
    sparkle: Path | None = None
    sparkle_color: np.ndarray = field(default_factory=lambda: np.ones(3))
    sparkle_exponent: float = 24.0
    sparkle_scale: float = 1.0
    wrap: str = "clamp"
    glint_density: float | None = None
    glint_share: float = 0.5
    glint_angle_deg: float = 1.0
    glint_seed: int = 0
    interpolation: str = "smooth"

    @property
    def kind(self) -> str:
        """"material", "print" or "measured"."""
        return "print" if self.inks else ("measured" if self.measured else "material")

    @property
    def is_builtin(self) -> bool:
        return self.mesh.startswith(BUILTIN_PREFIX)


@dataclass
class Environment:
    """Prefiltered environment light: a ``gonio prefilter`` index.json (its maps hold
    linear sRGB radiance; brightness is set by ``[output] exposure``). ``occlusion``:
    the directions (sky regions) of its occlusion by the scene's meshes
    (:mod:`gonio_cli.render.occlusion`), 0 for none."""

    prefiltered: Path
    method: str = "auto"
    occlusion: int = DEFAULT_DIRECTIONS


@dataclass
class Output:
    """``exposure``: stops (PNG only, × 2^exposure before the tone map); ``tonemap``: a key
    of :data:`gonio_cli.render.tonemap.TONEMAPS`; ``adapt``: a key of
    :data:`gonio_cli.render.tonemap.ADAPTATIONS` (the lights' white → the display's D65,
    or ``none``); ``ssaa``: supersampling factor per axis;
    ``spectral``: "table" or "exact"; ``grid_nm``: working grid START:STOP:STEP;
    ``background``: linear sRGB (3,) of pixels no object covers, or "environment"."""

    exposure: float = 0.0
    tonemap: str = "neutral"
    adapt: str = "bradford"
    ssaa: int = 2
    spectral: str = "table"
    grid_nm: str = "380:780:10"
    background: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass
class Scene:
    """A validated scene; every path absolute. ``grid_nm``: (n_λ,) the working grid,
    every light spectrum is on it. ``inputs``: every file the scene reads (provenance)."""

    path: Path
    camera: Camera
    objects: list[SceneObject]
    lights: list[Light]
    environment: Environment | None
    output: Output
    grid_nm: np.ndarray
    variables: dict[str, str] = field(default_factory=dict)
    inputs: list[Path] = field(default_factory=list)
    display: str = ""  # the path as the user gave it, for messages

    @property
    def needs_uvs(self) -> bool:
        return any(o.mask is not None or o.sparkle is not None for o in self.objects)
