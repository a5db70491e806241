"""Mitsuba 3's path tracer as an independent reference for ``gonio render`` under an HDR
environment map, and the comparison of the two pictures (issue 26, docs/reference.md).

1. :class:`ReferenceScene`: what both renderers get — a camera, one object (sphere, plane
   or OBJ, gonio's transform), a fitted ``material`` (or, for Mitsuba, an RGL ``.bsdf``
   in its place), an HDR lat-long map and optional lights (:func:`scene_from_toml`).
2. gonio: :func:`write_gonio_scene` with any ``[environment]`` table; seed 001's chain
   (:func:`gonio_environment`: lobes basis and fit ``--samples hemisphere``, prefilter
   ``--lobes``) and :func:`render_gonio`, run as commands.
3. Mitsuba: :func:`render_mitsuba` — ``path`` integrator, max_depth 2 (camera → surface →
   light: gonio has no inter-reflection), ``envmap`` untransformed on gonio's pixels
   (:func:`mitsuba_envmap`: same columns, rows half a texel apart at the poles), the
   material through the exported plugin or the ``.bsdf`` through ``measured``, into XYZ
   (Mitsuba's film divides by ∫ ȳ as gonio by Σ ȳ). Two seeds give its noise.
4. :mod:`.reference_compare` compares the two pictures (``compare``).

Colour: gonio makes the map's linear sRGB D65(λ) Σ rgb_c B_c(λ) (Mallett–Yuksel,
docs/conventions.md), Mitsuba's spectral variants D65(λ) × Jakob–Hanika's upsampling: the
same light colour, a different metamerism in its product with a reflectance.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Mapping, Sequence

import numpy as np

from ..errors import GonioError, InputError
from ..imageio import read_image
from ..ingest.rgl import check_bsdf
from ..render.mesh import rotation_matrix
from ..render.scene import load_scene
from ..schemas import Material, read_material, write_material
from .mitsuba import export_mitsuba
from .mitsuba_render import llvm_works

#: Mitsuba's path length: 1 sees emitters, 2 adds direct light at the first surface.
#: gonio renders one bounce (no inter-reflection), so the reference stops there too.
MAX_DEPTH = 2

#: Samples per pixel of a reference render unless asked: the demo's car paint under a
#: 1k sky with its sun has a CIEDE2000 noise of ~1 per pixel at this count (docs/reference.md).
DEFAULT_SPP = 256

#: Variants tried, spectral or RGB: LLVM (vectorised, ~100× faster with a Python BSDF)
#: when a probe kernel compiles (:func:`gonio_cli.export.mitsuba_render.llvm_works`).
VARIANTS = {"spectral": ("llvm_ad_spectral", "scalar_spectral"),
            "rgb": ("llvm_ad_rgb", "scalar_rgb")}


# ------------------------------------------------------------------------- the scene --

@dataclass(frozen=True)
class ReferenceScene:
    """What both renderers see. ``camera``: :class:`gonio_cli.render.Camera`; ``mesh``:
    ``builtin:sphere``, ``builtin:plane`` or an OBJ path; ``translate``, ``rotate_deg``,
    ``scale`` (3,) as gonio's (p′ = R (s ⊙ p) + t); ``material``: a gonio.material (gonio
    renders it; Mitsuba too, through the exported plugin, unless ``bsdf``); ``bsdf``: an RGL
    ``.bsdf`` Mitsuba's ``measured`` plugin renders instead; ``envmap``: an HDR lat-long
    map (EXR or Radiance HDR, linear sRGB); ``lights``: :class:`gonio_cli.render.Light`
    (directional or point) with spectra on ``grid_nm``; ``ssaa``: gonio's supersampling;
    ``floor_y``: None, or a Lambertian floor of albedo :data:`FLOOR_ALBEDO` at that height
    (a square of side 2 × :data:`FLOOR_HALF_SIZE` facing +y), for shadows on it."""

    camera: object
    material: Path
    envmap: Path
    mesh: str = "builtin:sphere"
    translate: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotate_deg: np.ndarray = field(default_factory=lambda: np.zeros(3))
    scale: np.ndarray = field(default_factory=lambda: np.ones(3))
    bsdf: Path | None = None
    lights: tuple = ()
    grid_nm: np.ndarray = field(default_factory=lambda: np.arange(380.0, 781.0, 10.0))
    ssaa: int = 2
    floor_y: float | None = None


def scene_from_toml(scene_path, envmap, *, bsdf=None, variables=None, width=None,
                    height=None) -> ReferenceScene:
    """The :class:`ReferenceScene` of a gonio scene file with one ``material`` object
    (its camera, mesh, transform, lights, grid and ssaa; its ``[environment]`` and
    ``lobes`` are left out: the reference gets ``envmap`` itself)."""
    sc = load_scene(scene_path, variables=variables,
                    overrides={"width": width, "height": height})
    if len(sc.objects) != 1 or sc.objects[0].material is None:
        raise InputError(f"has {len(sc.objects)} objects; the reference needs exactly one, "
                         "with a material", path=scene_path,
                         fix="keep one [[object]] with material = ...")
    o = sc.objects[0]
    return ReferenceScene(sc.camera, Path(o.material), Path(envmap), o.mesh, o.translate,
                          o.rotate_deg, o.scale, Path(bsdf) if bsdf else None,
                          tuple(sc.lights), sc.grid_nm, sc.output.ssaa)


def _toml(value) -> str:
    """A TOML value: string (JSON escapes are TOML's), bool, number or list of them."""
    if isinstance(value, (str, os.PathLike)):
        return json.dumps(os.fspath(value))
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    return f"{float(value):.9g}" if isinstance(value, (float, np.floating)) else str(value)


def write_gonio_scene(ref: ReferenceScene, path, environment: Mapping, *, lobes=None,
                      exposure: float = 0.0) -> Path:
    """Write ``ref`` as a ``gonio render`` scene at ``path`` with ``environment`` as its
    ``[environment]`` table (e.g. ``{"prefiltered": "…/index.json"}``, or another method's
    keys) and ``lobes`` on the object; lights' spectra as CSV files beside it. Output: no
    tone map, no chromatic adaptation (the EXR is the scene's colorimetry), black
    background. Paths are written absolute. Returns ``path``."""
    path = Path(path)
    c = ref.camera
    lines = ["# written by gonio_cli.export.mitsuba_reference", "[camera]"]
    lines += [f"{k} = {_toml(getattr(c, k))}" for k in ("eye", "target", "up", "fov_deg",
                                                      "width", "height")]
    lines += ["", "[[object]]", 'name = "object"', f"mesh = {_toml(ref.mesh)}",
              f"translate = {_toml(ref.translate)}", f"rotate_deg = {_toml(ref.rotate_deg)}",
              f"scale = {_toml(ref.scale)}", f"material = {_toml(Path(ref.material).resolve())}"]
    if lobes is not None:
        lines.append(f"lobes = {_toml(Path(lobes).resolve())}")
    lines += _floor_lines(ref, path.parent)
    for k, light in enumerate(ref.lights, 1):
        csv = path.with_name(f"{path.stem}.light{k}.csv")
        csv.write_text("wavelength_nm,value\n" + "".join(
            f"{w:g},{v:.9g}\n" for w, v in zip(ref.grid_nm, light.spectrum)))
        lines += ["", "[[light]]", f'type = "{light.kind}"', f"spectrum = {_toml(csv)}"]
        lines += ([f"direction = {_toml(light.direction)}",
                   f"irradiance = {_toml(light.irradiance)}"] if light.kind == "directional"
                  else [f"position = {_toml(light.position)}",
                        f"intensity = {_toml(light.intensity)}"])
    lines += ["", "[environment]"] + [f"{k} = {_toml(v)}" for k, v in environment.items()]
    g = ref.grid_nm
    lines += ["", "[output]", 'tonemap = "none"', 'adapt = "none"', f"ssaa = {ref.ssaa}",
              f"exposure = {_toml(float(exposure))}",
              f'grid_nm = "{g[0]:g}:{g[-1]:g}:{g[1] - g[0]:g}"']
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


# ------------------------------------------------------------------------ gonio side --

def run_gonio_process(args: Sequence) -> None:
    """Run ``gonio ARGS…`` as a process of this interpreter; a failure is a GonioError
    with the command's last stderr line."""
    done = subprocess.run([sys.executable, "-m", "gonio_cli", "-q", *map(str, args)],
                          capture_output=True, text=True)
    if done.returncode != 0:
        tail = done.stderr.strip().splitlines()
        raise GonioError(f"gonio {' '.join(map(str, args[:2]))} failed ({done.returncode}): "
                         f"{tail[-1] if tail else ''}")


def gonio_environment(ref: ReferenceScene, folder, *, n_lobes: int = 8,
                      exponents: str | None = None, samples: str = "hemisphere",
                      solver: str = "nnls", run: Callable = run_gonio_process
                      ) -> tuple[Path, dict]:
    """Seed 001's chain for ``ref.material`` under ``ref.envmap``, in ``folder``:
    ``gonio lobes basis`` (``n_lobes``, unless ``exponents`` "E1,E2,…" are given),
    ``gonio lobes fit --samples hemisphere`` (lights off the plane: docs/lobes.md),
    ``gonio prefilter --lobes``. Returns (lobes path, the ``[environment]`` table) and
    ``run`` runs each command (default: a process)."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    lobes = folder / "material.lobes.json"
    if exponents is None:
        run(["lobes", "basis", ref.material, "--max-lobes", n_lobes, "--samples", samples,
             "-o", folder / "basis.json"])
        chosen = ["--basis", folder / "basis.json"]
    else:
        chosen = ["--exponents", exponents]
    run(["lobes", "fit", ref.material, *chosen, "--samples", samples, "--solver", solver,
         "-o", lobes])
    run(["prefilter", ref.envmap, "--lobes", lobes, "-o", folder / "prefiltered"])
    return lobes, {"prefiltered": (folder / "prefiltered" / "index.json").resolve()}


def render_gonio(ref: ReferenceScene, folder, environment: Mapping, *, lobes=None,
                 run: Callable = run_gonio_process, name: str = "gonio") -> Path:
    """``gonio render`` of ``ref`` with ``environment`` (:func:`write_gonio_scene`) into
    ``folder``/NAME.exr (CIE XYZ, ``--exr-space xyz``) and NAME.png; returns the EXR."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    scene = write_gonio_scene(ref, folder / f"{name}.toml", environment, lobes=lobes)
    exr = folder / f"{name}.exr"
    run(["render", scene, "-o", folder / f"{name}.png", "--exr", exr, "--exr-space", "xyz"])
    return exr


# ---------------------------------------------------------------------- Mitsuba side --

def mitsuba_envmap(path, layout: str = "gonio") -> np.ndarray:
    """The map Mitsuba's ``envmap`` is given: (H', W, 3) float32 linear sRGB, read by
    gonio's reader (so both see the same pixels, whatever RGBE decoding Mitsuba uses).

    Mitsuba puts column c at φ = 2π (c + ½)/W, as gonio does, but row r at
    θ = π r/(H − 1) (``envmap.cpp``, ``eval_spectrum``: v · (H − 1)), where gonio has
    θ = π (r + ½)/H (docs/conventions.md): the same at the horizon, half a row apart at
    the poles (0.18° on a 1k map, 2.8° on a 32-row one). ``layout="gonio"`` gives Mitsuba
    2H + 1 rows whose bilinear interpolation is gonio's exactly (:func:`gonio_cli.envmap.
    lookup`: texel centres at the odd rows, midpoints between them, the clamped poles);
    ``"file"`` the pixels as they are (Mitsuba's reading of the file)."""
    img = read_image(path)
    if not img.is_float:
        raise InputError(f"is {img.format}, not a float (HDR) map", path=path,
                         fix="use the EXR or HDR lat-long map")
    px = np.ascontiguousarray(img.pixels[..., :3], dtype=np.float32)
    if layout == "file":
        return px
    if layout != "gonio":
        raise InputError(f"layout {layout!r} is unknown", fix="use gonio or file")
    out = np.empty((2 * px.shape[0] + 1,) + px.shape[1:], np.float32)
    out[1::2] = px
    out[2:-1:2] = 0.5 * (px[:-1] + px[1:])
    out[0], out[-1] = px[0], px[-1]
    return out


@dataclass
class MitsubaRender:
    """``xyz`` (H, W, 3) float64, the mean of the passes; ``noise`` (H, W, 3) the
    half-difference of two passes (its RMS is the mean's standard error), or None;
    ``variant``, ``spp`` (all passes), ``time_s`` (rendering, scene loading excluded)."""

    xyz: np.ndarray
    noise: np.ndarray | None
    variant: str
    spp: int
    time_s: float


def choose_variant(kind: str = "spectral") -> str:
    """LLVM if Dr.Jit can compile kernels here, else scalar, of ``kind`` (VARIANTS)."""
    import mitsuba as mi

    llvm, scalar = VARIANTS[kind]
    return llvm if llvm in mi.variants() and llvm_works() else scalar


def _register_plugin(ref: ReferenceScene, folder: Path) -> Path:
    """Export ``ref.material`` (``gonio export --to mitsuba``) into ``folder`` and register
    its BSDF for the active variant; returns its ``bsdf_params.json``."""
    out = folder / "mitsuba_plugin"
    export_mitsuba(read_material(ref.material), ref.material, out)
    spec = importlib.util.spec_from_file_location("gonio_bsdf", out / "gonio_bsdf.py")
    plugin = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(plugin)
    plugin.register()
    return (out / "bsdf_params.json").resolve()


def _to_world(ref: ReferenceScene, mi):
    m = np.eye(4)
    m[:3, :3] = rotation_matrix(ref.rotate_deg) * np.asarray(ref.scale, float)[None, :]
    m[:3, 3] = ref.translate
    return mi.ScalarTransform4f(m.tolist())


def _shape(ref: ReferenceScene, bsdf: dict, mi) -> dict:
    """The object: Mitsuba's analytic sphere, its rectangle ([−1, 1]² at z = 0 facing +z,
    gonio's plane) or the OBJ, with gonio's transform."""
    kind = ref.mesh.partition("?")[0]
    if kind == "builtin:sphere" and np.ptp(ref.scale) > 0:
        raise InputError(f"scale {list(ref.scale)}: Mitsuba's sphere takes a uniform scale",
                         fix="give one scale, or the sphere as an OBJ")
    shape = {"builtin:sphere": {"type": "sphere"}, "builtin:plane": {"type": "rectangle"}
             }.get(kind, {"type": "obj", "filename": os.fspath(ref.mesh)})
    return {**shape, "to_world": _to_world(ref, mi), "bsdf": bsdf}


#: The reference floor: a grey Lambertian square (Cook–Torrance with ks = 0 in gonio,
#: ``diffuse`` in Mitsuba), large enough for a unit sphere's shadow under a low sun.
FLOOR_ALBEDO = 0.3
FLOOR_HALF_SIZE = 6.0


def floor_material(path) -> Path:
    """The floor's gonio material (f = :data:`FLOOR_ALBEDO`/π exactly)."""
    g = np.arange(380.0, 781.0, 10.0)
    write_material(path, Material("cook-torrance", g, {
        "kd": np.full(g.size, FLOOR_ALBEDO), "ks": np.zeros(g.size),
        "m": np.full(g.size, 0.3), "f0": np.full(g.size, 0.04)}))
    return Path(path)


def _floor_lines(ref: ReferenceScene, folder: Path) -> list[str]:
    if ref.floor_y is None:
        return []
    mat = floor_material(folder / "floor.material.json").resolve()
    return ["", "[[object]]", 'name = "floor"', 'mesh = "builtin:plane"',
            f"material = {_toml(mat)}", "rotate_deg = [-90.0, 0.0, 0.0]",
            f"scale = {_toml(FLOOR_HALF_SIZE)}", f"translate = [0.0, {ref.floor_y!r}, 0.0]"]


def _floor(ref: ReferenceScene, mi) -> dict:
    t = (mi.ScalarTransform4f().translate([0.0, float(ref.floor_y), 0.0])
         @ mi.ScalarTransform4f().rotate([1.0, 0.0, 0.0], -90.0)
         @ mi.ScalarTransform4f().scale(FLOOR_HALF_SIZE))
    return {"type": "rectangle", "to_world": t,
            "bsdf": {"type": "diffuse", "reflectance": _spectrum(
                ref.grid_nm, np.full(len(ref.grid_nm), FLOOR_ALBEDO))}}


def _spectrum(grid, values) -> dict:
    return {"type": "spectrum", "value": [(float(w), float(v)) for w, v in zip(grid, values)]}


def mitsuba_scene_dict(ref: ReferenceScene, bsdf: dict, envmap: np.ndarray, spp: int,
                       seed: int = 0) -> dict:
    """The ``mi.load_dict`` scene: ``path`` integrator (:data:`MAX_DEPTH`, emitters hidden
    as gonio's black background), pinhole camera (vertical fov, box filter as gonio's
    supersampling, scrambled Sobol samples: ``spp`` a power of 2), the object with ``bsdf``, an ``envmap`` of the
    pixels ``envmap`` (:func:`mitsuba_envmap`) untransformed and the lights as E · S(λ)
    (docs/export.md)."""
    import mitsuba as mi

    c = ref.camera
    scene = {"type": "scene",
             "integrator": {"type": "path", "max_depth": MAX_DEPTH, "hide_emitters": True},
             "sensor": {"type": "perspective", "fov": float(c.fov_deg), "fov_axis": "y",
                        "to_world": mi.ScalarTransform4f().look_at(
                            origin=list(map(float, c.eye)), target=list(map(float, c.target)),
                            up=list(map(float, c.up))),
                        "sampler": {"type": "ldsampler", "sample_count": int(spp),
                                    "seed": int(seed)},
                        "film": {"type": "hdrfilm", "width": int(c.width),
                                 "height": int(c.height), "pixel_format": "xyz",
                                 "rfilter": {"type": "box"}}},
             "object": _shape(ref, bsdf, mi),
             "environment": {"type": "envmap", "bitmap": mi.Bitmap(envmap)}}
    if ref.floor_y is not None:
        scene["floor"] = _floor(ref, mi)
    for k, light in enumerate(ref.lights):
        if light.kind == "directional":
            scene[f"light{k}"] = {"type": "directional",
                                  "direction": [-float(x) for x in light.direction],
                                  "irradiance": _spectrum(ref.grid_nm,
                                                          light.irradiance * light.spectrum)}
        else:
            scene[f"light{k}"] = {"type": "point", "position": list(map(float, light.position)),
                                  "intensity": _spectrum(ref.grid_nm,
                                                         light.intensity * light.spectrum)}
    return scene


def render_mitsuba(ref: ReferenceScene, folder, *, spp: int = DEFAULT_SPP,
                   variant: str | None = None, colour: str = "spectral", passes: int = 2,
                   layout: str = "gonio") -> MitsubaRender:
    """Mitsuba's path-traced XYZ of ``ref``: ``passes`` renders of spp/passes samples with
    seeds 0, 1, …, averaged; with two or more, ``noise`` estimates the mean's error. The
    variant: ``variant``, else :func:`choose_variant` of ``colour`` (RGB for an RGB
    ``.bsdf``, which Mitsuba's ``measured`` plugin reads only there). Spectral variants
    interpolate a map's upsampled spectra and its scales apart, which darkens a sun of
    about one texel (−9 % on ``sample_data/sky.exr``, none seen on a 1k sky): ``"rgb"``
    then (docs/reference.md). ``layout``: of the map's rows, :func:`mitsuba_envmap`."""
    import mitsuba as mi

    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    if variant is None:
        kind = colour
        if ref.bsdf is not None:
            kind = check_bsdf(ref.bsdf)[0].name
        variant = choose_variant(kind)
    mi.set_variant(variant)
    bsdf = ({"type": "measured", "filename": os.fspath(ref.bsdf)} if ref.bsdf is not None
            else {"type": "gonio", "params": os.fspath(_register_plugin(ref, folder))})
    envmap = mitsuba_envmap(ref.envmap, layout)
    per_pass = max(1, spp // passes)
    images, elapsed = [], 0.0
    for seed in range(passes):
        scene = mi.load_dict(mitsuba_scene_dict(ref, bsdf, envmap, per_pass, seed))
        start = time.perf_counter()
        images.append(np.array(mi.render(scene), dtype=np.float64)[..., :3])
        elapsed += time.perf_counter() - start
    xyz = np.mean(images, axis=0)
    noise = (images[0] - images[1]) / 2.0 if passes >= 2 else None
    if passes > 2:
        noise *= np.sqrt(2.0 / passes)          # the mean of `passes` passes, not of two
    return MitsubaRender(xyz, noise, variant, per_pass * passes, elapsed)


__all__ = ["ReferenceScene", "scene_from_toml", "write_gonio_scene", "gonio_environment",
           "render_gonio", "mitsuba_envmap", "MitsubaRender", "choose_variant",
           "mitsuba_scene_dict", "render_mitsuba"]
