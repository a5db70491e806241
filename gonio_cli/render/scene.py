"""The scene file of ``gonio render``: TOML → :class:`Scene`, validated at the boundary.

Every path in a scene file is relative to the scene file. Unknown keys, wrong types,
non-finite numbers and missing files are :class:`~gonio_cli.errors.InputError` s of one
line that name the file and the key (STYLE 7), e.g.::

    scene.toml: [[object]] 2: unknown key 'materal'; did you mean 'material'? allowed: ...

A scene may be a template: ``${name}`` in any string is replaced by the variable
``name``, defined in the scene's ``[vars]`` table (defaults) or on the command line
(``gonio render --var name=value``, which wins; a ``--var`` name that no ``${name}`` of
the scene uses is an error listing the names it does use). After substitution a relative path is
still relative to the scene file. The sample scenes use this to reach the demo's
artifacts (``material = "${out}/rgbink/${ink}.material.json"`` with ``out = "../../out"``).

Sections (see ``docs/render.md``)::

    [vars]         name = "string" ...                      (optional)
    [camera]       eye, target, up, fov_deg, width, height
    [[object]]     mesh, translate, rotate_deg, scale, name and one of
                   material (+ lobes) | inks + mask (+ substrate, lobes, wrap) | measured
                   (+ sparkle, sparkle_color, sparkle_exponent, sparkle_scale)
    [[light]]      type = "directional" (direction, irradiance, angular_diameter_deg) |
                   "point" (position, intensity, radius); spectrum = CIE name or CSV;
                   shadow = true | false; name
    [environment]  prefiltered (a gonio prefilter index.json), method, occlusion (optional)
    [output]       exposure (stops), tonemap, adapt, ssaa, spectral, grid_nm, background

The working spectral grid (:func:`choose_grid`): ``--grid-nm`` when given; else the
scene's ``[output] grid_nm`` (default 380:780:10) when every material covers it; else the
materials' common range at the step of the scene's grid, with one warning saying so (a
material measured on 400–700 nm renders without editing the scene). Materials that share
no range are refused.

Light spectra are CIE illuminants by name (colour-science: ``D65``, ``A``, ``FL2`` …) or
a CSV ``wavelength_nm,value``, resampled onto the working grid (with a warning when the
CSV is on another grid) and scaled so that Σ S ȳ / Σ ȳ = 1 (docs/conventions.md).

Here the loader, section by section; beside it the checker every key goes through
(:mod:`.scene_check`), the types it fills (:mod:`.scene_types`), an ``[[object]]``
(:mod:`.scene_object`), the grid choice (:mod:`.scene_grid`) and the turntable
(:mod:`.turntable`).
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from .. import log
from ..artifact import read_toml
from ..csvio import read_spectrum
from ..errors import InputError
from ..names import SPECTRAL_PATHS as SPECTRAL_MODES
from ..schemas import EXPOSURE_MAX_STOPS, MAX_MAGNITUDE
from ..spectra import (covers, grid_spec, illuminant, illuminant_names, luminance,
                       parse_grid, resample, same_grid, unit_luminance)
from . import ENVIRONMENT_METHODS, POINT_LIGHT_RADIUS, SUN_ANGULAR_DIAMETER_DEG, Camera, Light
from .occlusion import DEFAULT_DIRECTIONS, MAX_DIRECTIONS
from .scene_check import MIN_VECTOR_NORM, Checker, names_used, substitute, type_name
from .scene_grid import choose_grid, spectral_ranges
from .scene_object import scene_object
from .scene_types import Environment, Output, Scene
from .tonemap import ADAPTATIONS, TONEMAPS

LIGHT_TYPES = ("directional", "point")

#: Supersampling factors above this multiply memory by > 256 per pixel: refused.
MAX_SSAA = 16

CAMERA_KEYS = ("eye", "target", "up", "fov_deg", "width", "height")
LIGHT_KEYS = ("type", "name", "direction", "irradiance", "position", "intensity", "spectrum",
              "shadow", "angular_diameter_deg", "radius")
#: The keys each light type takes beyond the common ones (the others' are refused).
LIGHT_TYPE_KEYS = {"directional": ("direction", "irradiance", "angular_diameter_deg"),
                   "point": ("position", "intensity", "radius")}
#: Largest angular diameter of a directional light (degrees): its shadows' penumbrae are
#: modelled as seen through a small cone (tan(α/2) ≈ α/2 within 1 % up to 20°, and the
#: filter is cut at :data:`gonio_cli.render.shadow.MAX_FILTER_TEXELS` anyway).
MAX_ANGULAR_DIAMETER_DEG = 20.0
ENVIRONMENT_KEYS = ("prefiltered", "method", "occlusion")
OUTPUT_KEYS = ("exposure", "tonemap", "adapt", "ssaa", "spectral", "grid_nm", "background")
TOP_KEYS = ("vars", "camera", "object", "light", "environment", "output")

# ------------------------------------------------------------------------------ loader --

def read_scene_toml(path: str | os.PathLike, display: str | None = None) -> dict[str, Any]:
    """A scene file as data (``tomllib``), or one line naming the file."""
    return read_toml(path, "scene", InputError, display)


def load_scene(path: str | os.PathLike, *, variables: Mapping[str, str] | None = None,
               overrides: Mapping[str, Any] | None = None,
               doc: Mapping[str, Any] | None = None,
               flags: Mapping[str, str] | None = None) -> Scene:
    """Read and validate a scene file.

    Parameters
    ----------
    path : the TOML file; every relative path in it is relative to its folder.
    variables : ``${name}`` values that override the scene's ``[vars]`` (``--var``).
    overrides : command-line settings that replace the file's: ``width``, ``height``
        (camera), ``ssaa``, ``spectral``, ``exposure``, ``tonemap``, ``adapt``, ``grid_nm`` (output;
        a ``grid_nm`` given here is used as it is, :func:`choose_grid`); None = keep.
    flags : the option each override came from (``{"width": "--width-px"}``), for
        messages (the CLI names it as the user typed it,
        :func:`gonio_cli.commands.as_typed_in`); an override not named here is ``--<key>``.
    doc : the scene as data (what ``tomllib`` gives for the file, e.g. a template edited
        by a program); None reads ``path``, which in both cases names the scene in errors
        and anchors its relative paths.

    Raises
    ------
    InputError : one line naming the file and the key, for every problem.
    """
    display = os.fspath(path)
    path = Path(path)
    chk = Checker(path.resolve(), display)
    if doc is None:
        doc = read_scene_toml(path, display)
    chk.keys(doc, TOP_KEYS, "")
    doc, merged = _substituted(chk, doc, variables or {})
    overrides = {k: v for k, v in (overrides or {}).items() if v is not None}
    overrides = _Overrides(overrides, flags or {})

    camera = _camera(chk, doc, overrides)
    output = _output(chk, doc, overrides)
    explicit_grid = "grid_nm" in overrides
    try:
        grid = parse_grid(output.grid_nm)
    except InputError as exc:
        if explicit_grid:
            raise                                   # names --grid-nm and its value
        raise chk.error("[output] grid_nm", exc.message, exc.fix) from None

    objects_raw = doc.get("object")
    if objects_raw is None:
        raise chk.error("", "no [[object]]", fix="add at least one [[object]] with a mesh")
    if not isinstance(objects_raw, list):
        raise chk.error("object", "is a table, expected [[object]] (an array of tables)")
    objects = [scene_object(chk, o, k + 1) for k, o in enumerate(objects_raw)]
    if not explicit_grid:
        chosen, note = choose_grid(grid, spectral_ranges(objects), where=display)
        if note:
            log.warn(note)
            grid = chosen
            output = replace(output, grid_nm=grid_spec(grid))

    lights_raw = doc.get("light", [])
    if not isinstance(lights_raw, list):
        raise chk.error("light", "is a table, expected [[light]] (an array of tables)")
    lights = [_light(chk, l, k + 1, grid) for k, l in enumerate(lights_raw)]
    environment = _environment(chk, doc) if "environment" in doc else None
    if isinstance(output.background, str) and environment is None:
        raise chk.error("[output] background", "is 'environment' but the scene has no "
                        "[environment]", fix="add an [environment] or give 3 numbers")
    if not lights and environment is None:
        raise chk.error("", "no [[light]] and no [environment]: the picture would be black",
                        fix="add a [[light]] or an [environment]")
    return Scene(chk.path, camera, objects, lights, environment, output, grid,
                 dict(merged), _inputs(chk, objects, environment, lights_raw), display)


def _substituted(chk: Checker, doc, variables: Mapping[str, str]) -> tuple[dict, dict]:
    """The scene without ``[vars]``, every ``${NAME}`` replaced, and the variables used:
    ``[vars]`` overridden by ``variables`` (``--var``), each of which the scene must use."""
    defaults = chk.table(doc.get("vars", {}), "[vars]")
    merged = {}
    for k, v in defaults.items():
        merged[k] = chk.string(v, f"[vars] {k}")
    used = sorted(set(names_used({k: v for k, v in doc.items() if k != "vars"})))
    for name in variables:
        if name not in used:
            raise chk.error("", f"--var {name}: the scene uses no ${{{name}}}",
                            fix=(f"its variables are {', '.join(used)}" if used else
                                 "it has no ${NAME} variables"))
    merged.update(variables)
    return substitute({k: v for k, v in doc.items() if k != "vars"}, merged, chk, ""), merged


def _environment(chk: Checker, doc) -> Environment:
    """``[environment]``: the prefiltered index, the method, the occlusion."""
    env = chk.table(doc["environment"], "[environment]")
    chk.keys(env, ENVIRONMENT_KEYS, "[environment]")
    return Environment(
        chk.file(chk.required(env, "prefiltered", "[environment]"),
                 "[environment] prefiltered"),
        chk.choice(env.get("method", "auto"), "[environment] method",
                   tuple(ENVIRONMENT_METHODS)),
        _occlusion(chk, env.get("occlusion", True)))


def _inputs(chk: Checker, objects: list, environment, lights_raw: list) -> list[Path]:
    """Every file the scene reads, once each in order: the scene, each object's mesh,
    materials, mask, measurement, sparkle texture and lobes, the environment, the lights'
    spectrum files."""
    inputs = [chk.path]
    for o in objects:
        if not o.is_builtin:
            inputs.append(Path(o.mesh))
        for p in (o.material, o.mask, o.measured, o.sparkle, *(o.inks or [])):
            if p is not None:
                inputs.append(p)
        if o.lobes is not None:
            inputs += o.lobes if isinstance(o.lobes, list) else [o.lobes]
    if environment is not None:
        inputs.append(environment.prefiltered)
    for l in lights_raw:
        s = l.get("spectrum")
        if isinstance(s, str) and s.lower().endswith(".csv"):
            inputs.append(chk.file(s, "spectrum"))
    return list(dict.fromkeys(inputs))


class _Overrides(dict):
    """Command-line overrides by key, and the option each came from (:meth:`flag`)."""

    def __init__(self, values: Mapping[str, Any], flags: Mapping[str, str]):
        super().__init__(values)
        self.flags = dict(flags)

    def flag(self, key: str) -> str:
        """The option's name (``--width-px``), else ``--<key>`` with dashes."""
        return self.flags.get(key, f"--{key.replace('_', '-')}")


def _camera(chk: Checker, doc, overrides) -> Camera:
    where = "[camera]"
    cam = chk.table(chk.required(doc, "camera", ""), where)
    chk.keys(cam, CAMERA_KEYS, where)
    eye = chk.vector(chk.required(cam, "eye", where), f"{where} eye")
    target = chk.vector(chk.required(cam, "target", where), f"{where} target")
    up = chk.vector(cam.get("up", [0.0, 1.0, 0.0]), f"{where} up", nonzero=True)
    fov = chk.number(chk.required(cam, "fov_deg", where), f"{where} fov_deg", lo=0.0,
                     hi=180.0, lo_open=True, hi_open=True)
    size = {}
    for key in ("width", "height"):
        if key in overrides:
            size[key] = chk.integer(overrides[key], overrides.flag(key), lo=1, hi=16384)
        else:
            size[key] = chk.integer(chk.required(cam, key, where), f"{where} {key}",
                                    lo=1, hi=16384)
    forward = target - eye
    if np.linalg.norm(forward) < MIN_VECTOR_NORM:
        raise chk.error(f"{where} target", "equals eye: the camera looks nowhere")
    if np.linalg.norm(np.cross(forward, up)) < MIN_VECTOR_NORM * np.linalg.norm(forward):
        raise chk.error(f"{where} up", f"{up.tolist()} is parallel to the view direction",
                        fix="choose an up vector not along target - eye")
    return Camera(eye, target, up, fov, size["width"], size["height"])


def _output(chk: Checker, doc, overrides) -> Output:
    where = "[output]"
    out = chk.table(doc.get("output", {}), where)
    chk.keys(out, OUTPUT_KEYS, where)
    d = Output()
    src = {**out, **{k: v for k, v in overrides.items() if k in OUTPUT_KEYS}}
    label = (lambda k: overrides.flag(k) if k in overrides  # noqa: E731
             else f"{where} {k}")
    return Output(
        exposure=chk.number(src.get("exposure", d.exposure), label("exposure"),
                            lo=-EXPOSURE_MAX_STOPS, hi=EXPOSURE_MAX_STOPS),
        tonemap=chk.choice(src.get("tonemap", d.tonemap), label("tonemap"), tuple(TONEMAPS)),
        adapt=chk.choice(src.get("adapt", d.adapt), label("adapt"), tuple(ADAPTATIONS)),
        ssaa=chk.integer(src.get("ssaa", d.ssaa), label("ssaa"), lo=1, hi=MAX_SSAA),
        spectral=chk.choice(src.get("spectral", d.spectral), label("spectral"), SPECTRAL_MODES),
        grid_nm=chk.string(src.get("grid_nm", d.grid_nm), label("grid_nm")),
        background=_background(chk, out, where, d.background))


def _background(chk: Checker, out: dict, where: str, default):
    """``[output] background``: linear sRGB (3 numbers), or "environment" (the
    ``[environment]`` seen through each pixel; checked against the scene by its parser)."""
    if "background" not in out:
        return default
    if isinstance(out["background"], str):
        chk.choice(out["background"], f"{where} background", ("environment",))
        return "environment"
    return chk.vector(out["background"], f"{where} background")


def _occlusion(chk: Checker, value) -> int:
    """``[environment] occlusion``: true (:data:`~.occlusion.DEFAULT_DIRECTIONS` sky
    regions), false (none: 0) or a number of regions in [1, :data:`~.occlusion.MAX_DIRECTIONS`]."""
    if isinstance(value, bool):
        return DEFAULT_DIRECTIONS if value else 0
    if not isinstance(value, int):
        raise chk.error("[environment] occlusion", f"{value!r} is a {type_name(value)}, "
                        "expected true, false or a number of directions",
                        fix=f"use true, false or an integer in [1, {MAX_DIRECTIONS}]")
    return chk.integer(value, "[environment] occlusion", lo=1, hi=MAX_DIRECTIONS)


def _light(chk: Checker, raw, number: int, grid: np.ndarray) -> Light:
    where = f"[[light]] {number}"
    l = chk.table(raw, where)
    chk.keys(l, LIGHT_KEYS, where)
    kind = chk.choice(chk.required(l, "type", where), f"{where} type", LIGHT_TYPES)
    for other in LIGHT_TYPE_KEYS["point" if kind == "directional" else "directional"]:
        if other in l:
            raise chk.error(f"{where} {other}", f"is not a key of a {kind} light",
                            fix=f"a {kind} light has {', '.join(LIGHT_TYPE_KEYS[kind])}")
    spectrum = light_spectrum(chk, l.get("spectrum", "D65"), f"{where} spectrum", grid)
    name = chk.string(l.get("name", f"light{number}"), f"{where} name")
    shadow = chk.boolean(l.get("shadow", True), f"{where} shadow")
    if kind == "directional":
        d = chk.vector(chk.required(l, "direction", where), f"{where} direction", nonzero=True)
        return Light("directional", spectrum, direction=d / np.linalg.norm(d),
                     irradiance=chk.number(chk.required(l, "irradiance", where),
                                           f"{where} irradiance", lo=0.0, hi=MAX_MAGNITUDE),
                     name=name, shadow=shadow,
                     angular_diameter_deg=chk.number(
                         l.get("angular_diameter_deg", SUN_ANGULAR_DIAMETER_DEG),
                         f"{where} angular_diameter_deg", lo=0.0,
                         hi=MAX_ANGULAR_DIAMETER_DEG))
    return Light("point", spectrum,
                 position=chk.vector(chk.required(l, "position", where), f"{where} position"),
                 intensity=chk.number(chk.required(l, "intensity", where),
                                      f"{where} intensity", lo=0.0, hi=MAX_MAGNITUDE),
                 name=name, shadow=shadow,
                 radius=chk.number(l.get("radius", POINT_LIGHT_RADIUS), f"{where} radius",
                                   lo=0.0, hi=MAX_MAGNITUDE))


def light_spectrum(chk: Checker, value, where: str, grid: np.ndarray) -> np.ndarray:
    """A light spectrum S (n_λ,) on ``grid``, Σ S ȳ / Σ ȳ = 1 (:func:`gonio_cli.spectra.
    unit_luminance`): a CIE illuminant name or a CSV ``wavelength_nm,value`` (relative to
    the scene file), read by :func:`gonio_cli.csvio.read_spectrum` (the reader of
    ``gonio ingest``'s white standard and dark: the same delimiters, comments and errors
    naming the CSV's line)."""
    s = chk.string(value, where)
    if not s.lower().endswith(".csv"):
        if s not in illuminant_names():
            raise chk.error(where, f"{s!r} is neither a CIE illuminant nor a .csv file",
                            fix="use e.g. D65, A, FL2 (colour-science names) or a CSV "
                                "wavelength_nm,value")
        return illuminant(s, grid)
    path = chk.file(s, where)
    w, v, table = read_spectrum(path, "light")
    if w.size < 2:
        raise chk.error(where, f"{s}: has {w.size} row; a spectrum needs at least 2",
                        fix="give the light's power at two or more wavelengths")
    negative = np.flatnonzero(v < 0)
    if negative.size:
        k = int(negative[0])
        raise InputError(f"value {v[k]:g} at {w[k]:g} nm is negative", path=table.path,
                         row=int(table.lines[k]), column=table.header[1],
                         fix="a light's spectrum is a power, 0 or more at every wavelength")
    if not covers(w, grid):
        raise chk.error(where, f"{s}: covers {w.min():g}-{w.max():g} nm, not the working "
                        f"grid {grid[0]:g}-{grid[-1]:g} nm",
                        fix="extend the CSV or choose [output] grid_nm")
    if not same_grid(w, grid):
        log.warn(f"{path}: light spectrum resampled from {w.size} wavelengths onto the "
                 f"working grid ({grid.size} samples)")
    spec = resample(w, v, grid)
    if not float(luminance(spec, grid)) > 0:
        raise chk.error(where, f"{s}: has no visible power (Σ S ȳ = 0)")
    return unit_luminance(spec, grid)


