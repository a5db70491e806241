"""A fitted material as a Mitsuba 3 plugin, parameters and scene (``gonio export --to
mitsuba``).

The folder written (:func:`export_mitsuba`):

* ``gonio_bsdf.py`` — the BSDF (``mi.register_bsdf("gonio", …)``), a copy of
  :mod:`gonio_cli.export.mitsuba_plugin`;
* ``gonio_drjit_brdf.py`` — the models it evaluates, a copy of
  :mod:`gonio_cli.export.drjit_brdf` (the Dr.Jit port of :mod:`gonio_cli.brdf`);
* ``bsdf_params.json`` (``gonio.mitsuba-bsdf`` v1) — the model, its parameters on the
  material's grid, the sampling lobes with their probabilities (:func:`sampling_lobes`)
  and the RGB weights of :func:`rgb_weights`;
* ``scene.xml`` — the material on the unit sphere under the lights and camera of a gonio
  scene (:func:`scene_xml`), integrator ``direct``; ``render.py`` renders it;
* ``gonio_scene.toml`` + ``material.json`` (+ one CSV per light) — the same scene for
  ``gonio render``, so the two renderers can be put side by side.

Light units: a gonio directional light's spectrum is E · S(λ) with Σ S ȳ / Σ ȳ = 1 on
the working grid (docs/conventions.md); Mitsuba's ``directional`` takes the irradiance
spectrum itself, so the XML holds E · S(λ) on the grid (zero beyond it, where gonio does
not integrate either). Point lights likewise carry I · S(λ). Mitsuba's XYZ film divides
by ∫ ȳ as gonio divides by Σ ȳ, so a white Lambertian under E = π is Y = 1 in both.
"""

from __future__ import annotations

import os
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from ..artifact import atomic_path, write_artifact
from ..brdf import MODELS, UNDERCOAT_INDEX, goniochromatic_exponent_arg
from ..folders import make_folder
from ..errors import InputError
from ..render.scene import load_scene, read_scene_toml
from ..samples import sample_data_dir
from ..spectra import cmf_weights, illuminant, xyz_to_linear_srgb_matrix

SCHEMA = "gonio.mitsuba-bsdf"
SCHEMA_VERSION = 1

#: Share of the samples spread evenly over the lobes whatever their albedo estimates, so
#: a lobe estimated dark is still sampled (bounded weights where it is not dark after all).
UNIFORM_SHARE = 0.1

#: The incidence angle (mirror configuration) at which a goniochromatic lobe's albedo is
#: estimated: ρ exp(c x) varies with x = 1 − cos θi there; 45° is mid-range.
ESTIMATE_THETA_DEG = 45.0

#: Cap of c x in an albedo estimate (exp(50) ~ 5e21): a wild c only makes that lobe the
#: one sampled, never an overflow.
ESTIMATE_EXP_MAX = 50.0

#: Relative spread of the grid's steps accepted as a regular grid (the plugin interpolates
#: on a regular grid; gonio's grids are START:STOP:STEP, float round-off only).
REGULAR_GRID_RTOL = 1e-6

#: The scene whose camera and lights are used when no ``--scene`` is given: seed 000
#: Figure 5's sphere, with the exported material on it (in the sample data).
DEFAULT_SCENE = "scenes/spheres.toml"


# ------------------------------------------------------------------------- sampling --

@dataclass(frozen=True)
class Lobe:
    """One sampling lobe: ``kind`` diffuse | ggx | beckmann, its roughness α (GGX α, or
    Beckmann m = Mitsuba's Beckmann α), and an estimate of its albedo (unitless)."""

    kind: str
    alpha: float
    albedo: float


def _mirror_x() -> float:
    c = np.cos(np.radians(ESTIMATE_THETA_DEG))
    return float(goniochromatic_exponent_arg(c, c))


def _gonio_lobe(p) -> Lobe:
    """Seed 000 eq. 5: D/4 integrates to ~1 against cos θo, so the albedo is ~ρ exp(c x)."""
    rho, c = np.asarray(p["rho"]), np.asarray(p["c"])
    return Lobe("ggx", float(p["alpha"]), float(np.mean(rho * np.exp(np.minimum(
        c * _mirror_x(), ESTIMATE_EXP_MAX)))))


def _ct_lobe(ks, m, f0) -> Lobe:
    """Seed 004 eq. 11: ks F D G / (π cos θi cos θo) = 4 ks × a Torrance–Sparrow lobe."""
    return Lobe("beckmann", float(np.mean(m)), 4.0 * float(np.mean(np.asarray(ks) * f0)))


#: Each supported model's lobes for importance sampling, from its parameters.
LOBES: dict[str, Callable[[dict], list[Lobe]]] = {
    "goniochromatic": lambda p: [_gonio_lobe(p)],
    "torrance-sparrow": lambda p: [Lobe("ggx", float(p["alpha"]), float(np.mean(p["f0"])))],
    "cook-torrance": lambda p: [Lobe("diffuse", 1.0, float(np.mean(p["kd"]))),
                                _ct_lobe(p["ks"], p["m"], np.asarray(p["f0"]))],
    "goniochromatic-diffuse": lambda p: [Lobe("diffuse", 1.0, float(np.mean(p["rho_d"]))),
                                         _gonio_lobe(p)],
    "goniochromatic-coat": lambda p: [
        Lobe("diffuse", 1.0, float(np.mean(p["rho_d"]))), _gonio_lobe(p),
        Lobe("ggx", float(p["alpha_coat"]), float(p["k_coat"]) * float(p["f0_coat"]))],
    # the opposition effect multiplies the diffuse term by 1 + B ≤ 1 + B0, smoothly:
    # sampled with it (an albedo estimate of ρ_d (1 + B0/2))
    "goniochromatic-backscatter": lambda p: [
        Lobe("diffuse", 1.0, float(np.mean(p["rho_d"])) * (1.0 + 0.5 * float(p["b0"]))),
        _gonio_lobe(p),
        Lobe("ggx", float(p["alpha_coat"]), float(p["k_coat"]) * float(p["f0_coat"]))],
    # under the coat: the layer's lobe seen through it is ~n times wider than α (Snell
    # near the normal); the lobes only importance-sample, the plugin evaluates the model
    "goniochromatic-undercoat": lambda p: [
        Lobe("diffuse", 1.0, float(np.mean(p["rho_d"]))),
        _gonio_lobe(dict(p, alpha=min(1.0, UNDERCOAT_INDEX * float(p["alpha"])))),
        Lobe("ggx", float(p["alpha_coat"]), float(p["k_coat"]) * float(p["f0_coat"]))],
    # the second lobe is a Torrance–Sparrow lobe with F = ρ_2(λ): its albedo is ~ρ_2
    "goniochromatic-two-lobe": lambda p: [
        Lobe("diffuse", 1.0, float(np.mean(p["rho_d"]))), _gonio_lobe(p),
        Lobe("ggx", float(p["alpha_2"]), float(np.mean(p["rho_2"])))],
    "cook-torrance-2": lambda p: [Lobe("diffuse", 1.0, float(np.mean(p["kd"])))] + [
        _ct_lobe(p[f"ks_{j}"], p[f"m_{j}"], np.asarray(p["f0"])) for j in (1, 2)],
    "cook-torrance-3": lambda p: [Lobe("diffuse", 1.0, float(np.mean(p["kd"])))] + [
        _ct_lobe(p[f"ks_{j}"], p[f"m_{j}"], np.asarray(p["f0"])) for j in (1, 2, 3)],
}


def sampling_lobes(model: str, params: dict) -> list[dict]:
    """The lobes ``sample`` draws from and their probabilities: proportional to the albedo
    estimates, plus :data:`UNIFORM_SHARE` spread evenly. A list of dicts (kind, alpha,
    albedo_estimate, probability)."""
    lobes = LOBES[model](params)
    albedo = np.array([max(l.albedo, 0.0) for l in lobes])
    share = albedo / albedo.sum() if albedo.sum() > 0 else np.full(len(lobes), 1 / len(lobes))
    prob = (1.0 - UNIFORM_SHARE) * share + UNIFORM_SHARE / len(lobes)
    return [{"kind": l.kind, "alpha": l.alpha, "albedo_estimate": l.albedo,
             "probability": float(p)} for l, p in zip(lobes, prob)]


def supported_models() -> list[str]:
    return list(LOBES)


def check_model(model: str, path) -> None:
    """Refuse a model the plugin has no port or lobes for, listing those it has."""
    # lazy: drjit_brdf imports drjit, the optional extra gonio[mitsuba]
    from .drjit_brdf import MODELS as PORTED

    ok = [m for m in LOBES if m in PORTED]
    if model not in ok:
        raise InputError(f"model {model!r} cannot be exported to Mitsuba", path=path,
                         fix=f"the exportable models are {', '.join(ok)}")


# ---------------------------------------------------------------------------- colour --

def rgb_weights(grid_nm) -> np.ndarray:
    """(3, n_λ): linear sRGB of a spectral reflectance r(λ) under D65 is ``W @ r``:
    W = M_XYZ→sRGB · cmf(λ) S_D65(λ) / Σ S_D65 ȳ (docs/conventions.md's matrix and CMFs).
    What the plugin's RGB variants sum f over the grid with."""
    s = illuminant("D65", grid_nm)                       # Σ S ȳ / Σ ȳ = 1
    return xyz_to_linear_srgb_matrix() @ (cmf_weights(grid_nm) * s[:, None]).T


# ----------------------------------------------------------------------------- files --

def bsdf_params(material) -> dict:
    """The payload of ``bsdf_params.json`` for a :class:`gonio_cli.schemas.Material`."""
    spec = MODELS[material.model]
    grid = np.asarray(material.wavelength_nm, dtype=float)
    return {"model": material.model, "wavelength_nm": grid,
            "scalar_params": {k: float(material.params[k]) for k in spec.scalar_params},
            "spectral_params": {k: np.asarray(material.params[k], dtype=float)
                                for k in spec.spectral_params},
            "lobes": sampling_lobes(material.model, material.params),
            "rgb_weights": rgb_weights(grid)}


def _vec(v) -> str:
    return ", ".join(f"{float(x):.9g}" for x in v)


def _spectrum(name: str, grid, values) -> str:
    pairs = ", ".join(f"{w:g}:{v:.9g}" for w, v in zip(grid, values))
    return f'<spectrum name="{name}" value="{pairs}"/>'


def scene_xml(camera, lights, grid_nm) -> str:
    """Mitsuba 3 scene XML: the ``gonio`` BSDF on the unit sphere at the origin, the
    camera (pinhole, vertical fov, box pixel filter as gonio's supersampling) and the
    lights (E · S(λ) on ``grid_nm``, see the module docstring); ``$spp`` and
    ``$pixel_format`` are parameters (defaults 256, rgb)."""
    emitters = []
    for light in lights:
        if light.kind == "directional":
            emitters.append(
                f'  <emitter type="directional">\n'
                f'    <vector name="direction" value="{_vec(-light.direction)}"/>\n'
                f'    {_spectrum("irradiance", grid_nm, light.irradiance * light.spectrum)}\n'
                f'  </emitter>')
        else:
            emitters.append(
                f'  <emitter type="point">\n'
                f'    <point name="position" value="{_vec(light.position)}"/>\n'
                f'    {_spectrum("intensity", grid_nm, light.intensity * light.spectrum)}\n'
                f'  </emitter>')
    return f"""<scene version="3.0.0">
  <!-- written by gonio export --to mitsuba: the material on the unit sphere -->
  <default name="spp" value="256"/>
  <default name="pixel_format" value="rgb"/>
  <integrator type="direct"/>
  <sensor type="perspective">
    <float name="fov" value="{camera.fov_deg:.9g}"/>
    <string name="fov_axis" value="y"/>
    <transform name="to_world">
      <lookat origin="{_vec(camera.eye)}" target="{_vec(camera.target)}" up="{_vec(camera.up)}"/>
    </transform>
    <sampler type="multijitter"><integer name="sample_count" value="$spp"/></sampler>
    <film type="hdrfilm">
      <integer name="width" value="{camera.width}"/>
      <integer name="height" value="{camera.height}"/>
      <string name="pixel_format" value="$pixel_format"/>
      <rfilter type="box"/>
    </film>
  </sensor>
  <shape type="sphere">
    <bsdf type="gonio"><string name="params" value="bsdf_params.json"/></bsdf>
  </shape>
{chr(10).join(emitters)}
</scene>
"""


def gonio_scene_toml(camera, lights, grid_nm, ssaa: int) -> tuple[str, dict[str, np.ndarray]]:
    """The same scene for ``gonio render`` (``material.json`` on ``builtin:sphere``), and
    the light spectra it names as CSV files {file name: S(λ) on ``grid_nm``}."""
    lines = ["# written by gonio export --to mitsuba: the scene of scene.xml for gonio render",
             "[camera]", f"eye = [{_vec(camera.eye)}]", f"target = [{_vec(camera.target)}]",
             f"up = [{_vec(camera.up)}]", f"fov_deg = {camera.fov_deg:.9g}",
             f"width = {camera.width}", f"height = {camera.height}", "",
             "[[object]]", 'name = "sphere"', 'mesh = "builtin:sphere"',
             'material = "material.json"', ""]
    csvs = {}
    for k, light in enumerate(lights, 1):
        name = f"light{k}.csv"
        csvs[name] = light.spectrum
        lines += ["[[light]]", f'name = "{light.name}"', f'type = "{light.kind}"']
        if light.kind == "directional":
            lines += [f"direction = [{_vec(light.direction)}]",
                      f"irradiance = {light.irradiance:.9g}"]
        else:
            lines += [f"position = [{_vec(light.position)}]",
                      f"intensity = {light.intensity:.9g}"]
        lines += [f'spectrum = "{name}"', ""]
    lines += ["[output]", 'tonemap = "clip"', 'adapt = "none"', f"ssaa = {ssaa}",
              f'grid_nm = "{grid_nm[0]:g}:{grid_nm[-1]:g}:{grid_nm[1] - grid_nm[0]:g}"']
    return "\n".join(lines) + "\n", csvs


def scene_camera_lights(scene_path, variables=None, material_path=None):
    """(camera, lights, grid, ssaa) of a gonio scene file, or of the sample data's
    :data:`DEFAULT_SCENE` with ``material_path`` on its sphere."""
    if scene_path is not None:
        sc = load_scene(scene_path, variables=variables)
    else:
        path = sample_data_dir() / DEFAULT_SCENE
        doc = dict(read_scene_toml(path))
        doc["object"] = [{"mesh": "builtin:sphere",
                          "material": os.path.abspath(material_path)}]
        sc = load_scene(path, doc=doc)
    return sc.camera, sc.lights, sc.grid_nm, sc.output.ssaa


def export_mitsuba(material, material_path, out_dir, scene_path=None, variables=None
                   ) -> list[Path]:
    """Write the Mitsuba folder for a :class:`gonio_cli.schemas.Material` (see the module
    docstring); returns the files written. Raises :class:`InputError` for a model with no
    Mitsuba port or a material on an irregular grid."""
    check_model(material.model, material_path)
    grid = np.asarray(material.wavelength_nm, dtype=float)
    steps = np.diff(grid)
    if grid.size < 2 or not np.allclose(steps, steps[0], rtol=REGULAR_GRID_RTOL, atol=0):
        raise InputError("wavelength_nm is not a regular grid", path=material_path,
                         fix="fit the material on a START:STOP:STEP grid (gonio ingest "
                             "--grid-nm)")
    camera, lights, scene_grid, ssaa = scene_camera_lights(scene_path, variables,
                                                           material_path)
    out = make_folder(Path(out_dir))
    here = Path(__file__).resolve().parent
    written = []
    for source, name in (("mitsuba_plugin.py", "gonio_bsdf.py"),
                         ("drjit_brdf.py", "gonio_drjit_brdf.py"),
                         ("mitsuba_render.py", "render.py")):
        with atomic_path(out / name) as tmp:
            shutil.copyfile(here / source, tmp)
        written.append(out / name)
    write_artifact(out / "bsdf_params.json", SCHEMA, SCHEMA_VERSION, bsdf_params(material),
                   inputs=[material_path], parameters={"target": "mitsuba"})
    written.append(out / "bsdf_params.json")
    with atomic_path(out / "material.json") as tmp:
        shutil.copyfile(material_path, tmp)
    written.append(out / "material.json")
    toml, csvs = gonio_scene_toml(camera, lights, scene_grid, ssaa)
    for name, values in csvs.items():
        with atomic_path(out / name) as tmp:
            tmp.write_text("wavelength_nm,value\n" + "".join(
                f"{w:g},{v:.9g}\n" for w, v in zip(scene_grid, values)))
        written.append(out / name)
    for name, text in (("gonio_scene.toml", toml),
                       ("scene.xml", scene_xml(camera, lights, scene_grid))):
        with atomic_path(out / name) as tmp:
            tmp.write_text(text, encoding="utf-8")
        written.append(out / name)
    return written
