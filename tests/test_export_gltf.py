"""``gonio export --to gltf`` against independent truth.

1. glTF's BRDF (``gonio_cli/export/gltf_brdf.py``) against closed forms: the
   height-correlated Smith visibility against Heitz 2014's Λ form, GGX D's normalisation
   with α = roughness², hand values at normal incidence, white furnace (a white metal
   and a coat over it never reflect more than they receive; the core dielectric does at
   grazing, as glTF 2.0 Appendix B says), reciprocity (the core is, the clear coat is not,
   as KHR_materials_clearcoat writes its Fresnel at the view angle).
2. Round trip: a material that *is* a glTF material comes back from the fit.
3. The ``.glb`` passes the Khronos glTF validator (npm ``gltf-validator``, installed by
   ``make js-tools`` into tests/js; skipped with the reason where node or it is missing).
4. The demo's clear-coated paint: what the export reaches, with its report.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.export import gltf_brdf as gb
from gonio_cli.export.gltf_brdf import GltfMaterial, gltf_brdf
from gonio_cli.export.gltf_fit import fit_gltf
from gonio_cli.export.standard_fit import material_rgb
from gonio_cli.export.judge import in_plane_grid, judge
from gonio_cli.geometry import cosines, in_plane_cosines
from gonio_cli.samples import sample_data_dir
from gonio_cli.schemas import Material, write_material
from gonio_cli.spectra import (parse_grid, reflectance_to_xyz, rgb_reflectance_basis,
                               xyz_to_linear_srgb)

GRID = parse_grid()
ROOT = Path(__file__).resolve().parent.parent
JS = ROOT / "tests" / "js"

#: A plastic under a clear coat, with a tinted dielectric F0: every parameter in play.
TRUTH = GltfMaterial(base_color=(0.6, 0.2, 0.1), metallic=0.0, roughness=0.5,
                     specular=0.8, specular_color=(1.0, 0.8, 0.6), ior=1.7,
                     clearcoat=1.0, clearcoat_roughness=0.2)


def _gauss_hemisphere(n: int = 96):
    """Nodes (u, φ) and weights of Gauss–Legendre in u ∈ [0, 1) × midpoint in φ."""
    x, w = np.polynomial.legendre.leggauss(n)
    u, wu = 0.5 * (x + 1.0), 0.5 * w
    phi = (np.arange(2 * n) + 0.5) * np.pi / n
    return u[:, None], phi[None, :], wu[:, None] * (np.pi / n)


def albedo(m: GltfMaterial, theta_i_deg: float, alpha_sample: float) -> np.ndarray:
    """∫ f cos θo dωo (3,) by quadrature over half vectors drawn by GGX's own CDF (α of
    ``alpha_sample``): tan θh = α √(u / (1 − u)), dωo = 4 (ωi·ωh) dωh and
    D(θh) cos θh dωh = du dφ / 2π, so a narrow lobe is resolved exactly (independent of
    gltf_brdf's own D)."""
    u, phi, w = _gauss_hemisphere()
    th = np.arctan(alpha_sample * np.sqrt(u / (1.0 - u)))
    a2 = alpha_sample ** 2
    d = a2 / (np.pi * (np.cos(th) ** 2 * (a2 - 1.0) + 1.0) ** 2)       # GGX at θh
    wh = np.stack(np.broadcast_arrays(np.sin(th) * np.cos(phi), np.sin(th) * np.sin(phi),
                                      np.cos(th)), axis=-1)
    t = np.radians(theta_i_deg)
    wi = np.array([-np.sin(t), 0.0, np.cos(t)])
    dot = np.sum(wi * wh, axis=-1)
    wo = 2.0 * dot[..., None] * wh - wi
    f = gltf_brdf(cosines(np.broadcast_to(wi, wo.shape), wo), m)
    jac = np.where((dot > 0) & (wo[..., 2] > 0), 4.0 * dot * wo[..., 2]
                   / (d * np.cos(th)) / (2.0 * np.pi), 0.0)
    return np.sum(f * (jac * w)[..., None], axis=(0, 1))


# ------------------------------------------------------------------- closed forms --

@pytest.mark.parametrize("alpha", [0.05, 0.3, 1.0])
def test_visibility_is_heitz_height_correlated_smith(rng, alpha):
    # Heitz 2014 eq. 99: G2 = 1 / (1 + Λ(ωi) + Λ(ωo)), Λ = (√(1 + α² tan²θ) − 1) / 2
    ci, co = rng.uniform(0.05, 1.0, (2, 50))
    lam = lambda c: (np.sqrt(1.0 + alpha ** 2 * (1.0 - c * c) / (c * c)) - 1.0) / 2.0  # noqa: E731
    g2 = 1.0 / (1.0 + lam(ci) + lam(co))
    np.testing.assert_allclose(gb.visibility(ci, co, alpha), g2 / (4.0 * ci * co), rtol=1e-12)
    assert gb.visibility(0.0, 0.5, alpha) == 0.0         # light at the horizon: χ⁺ = 0


@pytest.mark.parametrize("roughness", [0.3, 0.6, 1.0])
def test_ggx_d_of_roughness_squared_is_normalised(roughness):
    # ∫ D cos θh dω = 1 with D = specular_brdf / V, α = roughness² (glTF's mapping)
    x, w = np.polynomial.legendre.leggauss(400)
    c = 0.5 * (x + 1.0)                                    # cos θh ∈ (0, 1)
    one = np.ones_like(c)
    cos = gb.Cosines(one, one, c, one)                     # V(1, 1) = 1/4 exactly
    d = gb.specular_brdf(cos, roughness ** 2) / 0.25
    assert np.sum(d * c * 0.5 * w) * 2.0 * np.pi == pytest.approx(1.0, rel=1e-6)


def test_values_at_normal_incidence_by_hand():
    one = np.ones(1)
    cos = gb.Cosines(one, one, one, one)
    alpha = 0.5 ** 2
    lobe = 1.0 / (np.pi * alpha ** 2) * 0.25               # D(0) V(1, 1)
    metal = GltfMaterial(base_color=(0.9, 0.5, 0.2), metallic=1.0, roughness=0.5)
    np.testing.assert_allclose(gltf_brdf(cos, metal)[0], np.array([0.9, 0.5, 0.2]) * lobe)
    plastic = GltfMaterial(base_color=(0.9, 0.5, 0.2), metallic=0.0, roughness=0.5)
    np.testing.assert_allclose(gltf_brdf(cos, plastic)[0],
                               0.04 * lobe + 0.96 * np.array([0.9, 0.5, 0.2]) / np.pi)
    coated = GltfMaterial(base_color=(0.9, 0.5, 0.2), metallic=1.0, roughness=0.5,
                          clearcoat=1.0, clearcoat_roughness=0.5)
    np.testing.assert_allclose(gltf_brdf(cos, coated)[0],    # Fc(N·V = 1) = 0.04
                               0.96 * np.array([0.9, 0.5, 0.2]) * lobe + 0.04 * lobe)
    # KHR_materials_specular + _ior: F0 = min(F0(ior) · specularColor, 1) · specular
    tinted = GltfMaterial(base_color=(0, 0, 0), metallic=0.0, roughness=0.5, specular=0.5,
                          specular_color=(1.0, 0.5, 30.0), ior=2.0)
    f0 = np.minimum((1.0 / 3.0) ** 2 * np.array([1.0, 0.5, 30.0]), 1.0) * 0.5
    np.testing.assert_allclose(gltf_brdf(cos, tinted)[0], f0 * lobe)


@pytest.mark.parametrize("roughness", [0.2, 0.5, 1.0])
@pytest.mark.parametrize("theta_i_deg", [0.0, 40.0, 80.0])
def test_white_furnace(roughness, theta_i_deg):
    metal = GltfMaterial(base_color=(1, 1, 1), metallic=1.0, roughness=roughness)
    a = albedo(metal, theta_i_deg, roughness ** 2)
    assert np.all(a <= 1.0 + 1e-6)                 # single scattering only loses light
    coated = GltfMaterial(base_color=(1, 1, 1), metallic=1.0, roughness=roughness,
                          clearcoat=1.0, clearcoat_roughness=roughness)
    assert np.all(albedo(coated, theta_i_deg, roughness ** 2) <= 1.0 + 1e-6)
    if roughness == 0.2 and theta_i_deg == 0.0:
        assert a[0] > 0.98                         # smooth: next to nothing is shadowed


def test_dielectric_breaks_energy_at_grazing_as_the_spec_says():
    # glTF 2.0 Appendix B, "Coupling Diffuse and Specular Reflection": fresnel_mix "breaks
    # energy conservation"; at normal incidence the white dielectric keeps to 1
    white = GltfMaterial(base_color=(1, 1, 1), metallic=0.0, roughness=0.5)
    lam = GltfMaterial(base_color=(1, 1, 1), metallic=0.0, roughness=0.5, specular=0.0)
    # the diffuse part alone, by quadrature of (1 − F)/π over the GGX-drawn set
    assert albedo(lam, 0.0, 0.25)[0] == pytest.approx(1.0, abs=2e-3)
    assert albedo(white, 0.0, 0.25)[0] <= 1.0
    assert albedo(white, 80.0, 0.25)[0] > 1.05


def test_reciprocity_of_the_core_not_of_the_coat(rng):
    wi = rng.normal(size=(200, 3))
    wo = rng.normal(size=(200, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]) + 0.1, np.abs(wo[:, 2]) + 0.1
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    core = GltfMaterial(base_color=(0.7, 0.3, 0.2), metallic=0.4, roughness=0.4,
                        specular=0.7, specular_color=(1.0, 0.5, 0.2))
    f, b = gltf_brdf(cosines(wi, wo), core), gltf_brdf(cosines(wo, wi), core)
    np.testing.assert_allclose(f, b, rtol=1e-12)
    f, b = gltf_brdf(cosines(wi, wo), TRUTH), gltf_brdf(cosines(wo, wi), TRUTH)
    assert np.max(np.abs(f - b) / b) > 1e-3         # Fc at N·V: viewer and light differ
    same = in_plane_cosines(np.array([30.0]), np.array([30.0]))
    assert gltf_brdf(same, TRUTH).shape == (1, 3)


def test_shapes_broadcast():
    c = in_plane_cosines(np.array(35.0), np.array(20.0))
    one = gltf_brdf(c, TRUTH)
    tile = lambda s: gb.Cosines(*(np.full(s, float(v)) for v in c))  # noqa: E731
    for shape in [(6,), (2, 3)]:
        np.testing.assert_array_equal(gltf_brdf(tile(shape), TRUTH),
                                      np.broadcast_to(one, shape + (3,)))


def test_material_colour_is_the_conventions_colour():
    # a Lambertian material (Cook–Torrance with ks = 0): π f as linear sRGB equals the
    # conventions' XYZ (D65, 2°) through the sRGB matrix
    kd = 0.1 + 0.6 * np.exp(-0.5 * ((GRID - 600.0) / 50.0) ** 2)
    m = Material("cook-torrance", GRID, {"kd": kd, "ks": np.zeros(GRID.size),
                                         "m": np.full(GRID.size, 0.3),
                                         "f0": np.full(GRID.size, 0.04)})
    rgb = np.pi * material_rgb(m)(in_plane_cosines(np.array([20.0]), np.array([-10.0])))
    truth = xyz_to_linear_srgb(reflectance_to_xyz(kd, GRID, "D65", observer=2))
    np.testing.assert_allclose(rgb[0], truth, rtol=1e-9)


# ------------------------------------------------------------------------ the fit --

def test_round_trip_recovers_a_gltf_material():
    fit = fit_gltf(lambda cos: gltf_brdf(cos, TRUTH))
    got = fit.material
    assert fit.success
    # the fit is judged on what a viewer shows: F0 = F0(ior) · specularColor
    f0 = lambda m: gb.ior_f0(m.ior) * np.asarray(m.specular_color) * m.specular  # noqa: E731
    # tolerances: 1 % of each parameter's range (noise-free data, a smooth optimum)
    assert got.roughness == pytest.approx(TRUTH.roughness, abs=0.01)
    assert got.clearcoat_roughness == pytest.approx(TRUTH.clearcoat_roughness, abs=0.01)
    assert got.clearcoat == pytest.approx(TRUTH.clearcoat, abs=0.01)
    assert got.metallic == pytest.approx(0.0, abs=0.01)
    np.testing.assert_allclose(got.base_color, TRUTH.base_color, atol=0.01)
    np.testing.assert_allclose(f0(got), f0(TRUTH), atol=0.01)
    j = judge_gltf(lambda cos: gltf_brdf(cos, TRUTH), got)
    assert j.mean() < 0.5


class SpectralTruth:
    """An RGB BRDF (..., 3) as a spectral material: rgb → the spectrum (basis @ W⁻¹) rgb of
    the Mallett–Yuksel basis, corrected so that its linear sRGB under D65 is rgb exactly."""

    def __init__(self, rgb_brdf):
        from gonio_cli.export.mitsuba import rgb_weights

        self.wavelength_nm = GRID
        basis = rgb_reflectance_basis(GRID)
        self.to_spectrum = basis @ np.linalg.inv(rgb_weights(GRID) @ basis)   # (n_λ, 3)
        self.rgb_brdf = rgb_brdf

    def evaluate(self, cos):
        return self.rgb_brdf(cos) @ self.to_spectrum.T


def judge_gltf(truth_rgb, m: GltfMaterial) -> np.ndarray:
    """CIEDE2000 of ``m`` against an RGB BRDF on the judgement's in-plane grid."""
    return judge(SpectralTruth(truth_rgb), lambda cos: gltf_brdf(cos, m),
                 *in_plane_grid()).delta_e


# ------------------------------------------------------------------ the command --

def coat_material(tmp_path) -> Path:
    """A clear-coated orange paint inside the sRGB gamut, no colour shift (c = 0)."""
    basis = rgb_reflectance_basis(GRID)
    m = Material("goniochromatic-coat", GRID, {
        "alpha": 0.3, "rho": basis @ np.array([0.5, 0.25, 0.1]), "c": np.zeros(GRID.size),
        "rho_d": basis @ np.array([0.35, 0.12, 0.05]), "alpha_coat": 0.02, "k_coat": 1.0,
        "f0_coat": 0.04})
    path = tmp_path / "orange.material.json"
    write_material(path, m)
    return path


def export_coat(tmp: Path, target: str, suffix: str) -> tuple[Path, dict, str]:
    """(the file, its report, stderr) of ``gonio export orange.material.json --to TARGET``
    run in-process in ``tmp``."""
    import contextlib
    import io

    from gonio_cli import cli

    mat = coat_material(tmp)
    out = tmp / f"orange{suffix}"
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        code = cli.run(["export", str(mat), "-o", str(out), "--to", target])
    assert code == 0, err.getvalue()
    return out, json.loads((tmp / f"orange{suffix}.report.json").read_text()), err.getvalue()


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """(glb, report, stderr) of ``gonio export orange.material.json --to gltf``."""
    return export_coat(tmp_path_factory.mktemp("gltf"), "gltf", ".glb")


def test_export_writes_the_glb_and_its_report(exported):
    import pygltflib

    glb, rep, err = exported
    line = [x for x in err.splitlines() if x.startswith("gonio export: orange.glb")]
    assert len(line) == 1 and "glTF keeps mean CIEDE2000" in line[0]
    assert f"{rep['delta_e2000_mean']:.1f}" in line[0]
    assert rep["schema"] == "gonio.export-report" and rep["schema_version"] == 1
    de = np.asarray(rep["delta_e2000"])
    assert de.size == np.asarray(rep["theta_i_deg"]).size == len(in_plane_grid()[0])
    assert rep["delta_e2000_mean"] == pytest.approx(de.mean())
    assert rep["delta_e2000_worst"] == pytest.approx(de.max())
    assert rep["material_fit"]["source"] == "not recorded"    # made, not fitted
    doc = pygltflib.GLTF2.load(glb)
    mat = doc.materials[0]
    g = rep["gltf"]
    assert mat.pbrMetallicRoughness.baseColorFactor == [*g["base_color"], 1.0]
    assert mat.pbrMetallicRoughness.roughnessFactor == g["roughness"]
    assert mat.extensions["KHR_materials_clearcoat"]["clearcoatFactor"] == g["clearcoat"]
    assert mat.extensions["KHR_materials_ior"]["ior"] == g["ior"]
    # the report judges the file's parameters: re-judge them from the file
    m = GltfMaterial(base_color=tuple(mat.pbrMetallicRoughness.baseColorFactor[:3]),
                     metallic=mat.pbrMetallicRoughness.metallicFactor,
                     roughness=mat.pbrMetallicRoughness.roughnessFactor,
                     specular=mat.extensions["KHR_materials_specular"]["specularFactor"],
                     specular_color=tuple(mat.extensions["KHR_materials_specular"]
                                          ["specularColorFactor"]),
                     ior=mat.extensions["KHR_materials_ior"]["ior"],
                     clearcoat=g["clearcoat"], clearcoat_roughness=g["clearcoat_roughness"])
    from gonio_cli.schemas import read_material

    again = judge(read_material(glb.with_name("orange.material.json")),
                  lambda cos: gltf_brdf(cos, m), *in_plane_grid())
    np.testing.assert_allclose(again.delta_e, de, rtol=1e-9)


@pytest.mark.parametrize("args, says", [
    (["-o", "{tmp}/x.gltf"], "--output"),
    (["-o", "{tmp}/x.glb", "--scene", "{scene}"], "--scene"),
])
def test_bad_options_are_one_line_and_write_nothing(run_gonio, tmp_path, args, says):
    mat = coat_material(tmp_path)
    scene = sample_data_dir() / "scenes" / "spheres.toml"
    args = [a.format(tmp=tmp_path, scene=scene) for a in args]
    r = run_gonio("export", mat, "--to", "gltf", *args)
    assert r.exit_code == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gonio: error:") and says in lines[0]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["orange.material.json",
                                                          "orange.material.run.json"]


def test_a_grid_without_the_visible_is_refused(run_gonio, tmp_path):
    grid = parse_grid("500:600:10")
    m = Material("cook-torrance", grid, {k: np.full(grid.size, v) for k, v in
                                         (("kd", 0.3), ("ks", 0.1), ("m", 0.3), ("f0", 0.04))})
    path = tmp_path / "narrow.material.json"
    write_material(path, m)
    r = run_gonio("export", path, "-o", tmp_path / "narrow.glb", "--to", "gltf")
    assert r.exit_code == 2 and "does not cover 400-700 nm" in r.stderr
    assert "narrow.material.json" in r.stderr
    assert not (tmp_path / "narrow.glb").exists()


# --------------------------------------------------------------- Khronos validator --

def _validator() -> tuple[str, Path]:
    node = shutil.which("node")
    if node is None:
        pytest.skip("node is not installed: the Khronos glTF validator runs on node "
                    "(apt-get install nodejs npm; make js-tools)")
    if not (JS / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("the Khronos glTF validator is not installed: run make js-tools "
                    "(npm ci in tests/js; make test does it where npm is found)")
    return node, JS / "validate_gltf.js"


def test_glb_passes_the_khronos_validator(exported):
    node, script = _validator()
    out = subprocess.run([node, str(script), str(exported[0])], capture_output=True,
                         text=True, timeout=120, check=True)
    report = json.loads(out.stdout)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]
    assert report["issues"]["numWarnings"] == 0, report["issues"]["messages"]
    assert set(report["info"]["extensionsUsed"]) == {
        "KHR_materials_specular", "KHR_materials_ior", "KHR_materials_clearcoat"}
    assert report["info"]["totalTriangleCount"] > 1000


def test_the_validator_sees_a_broken_glb(exported, tmp_path):
    node, script = _validator()          # the check above can fail: a truncated file
    bad = tmp_path / "bad.glb"
    bad.write_bytes(exported[0].read_bytes()[:-64])
    out = subprocess.run([node, str(script), str(bad)], capture_output=True, text=True,
                         timeout=120, check=True)
    assert json.loads(out.stdout)["issues"]["numErrors"] > 0


# ------------------------------------------------------------- the demo coat paint --

def export_demo_coat(tmp: Path, to: str, suffix: str) -> dict:
    """The demo's clear-coated paint (pipelines/carpaint.mk) fitted in ``tmp``, exported
    with ``--to to``; its report (also used by tests/test_export_openpbr.py)."""
    from gonio_cli import cli

    meas, mat = tmp / "coat.measurement.json", tmp / "coat.material.json"
    out = tmp / f"coat{suffix}"
    for args in (["ingest", sample_data_dir() / "coat_paint.csv", "-o", meas],
                 ["fit", meas, "-o", mat, "--model", "goniochromatic-coat"],
                 ["export", mat, "-o", out, "--to", to]):
        assert cli.run([str(a) for a in args]) == 0
    return json.loads(out.with_name(out.name + ".report.json").read_text())


@pytest.fixture(scope="module")
def demo_coat(tmp_path_factory):
    """The demo's clear-coated paint fitted in a scratch folder, exported; its report."""
    return export_demo_coat(tmp_path_factory.mktemp("coat"), "gltf", ".glb")


def test_demo_coat_is_judged_at_its_measurement(demo_coat):
    rep = demo_coat
    assert rep["configurations"].startswith("the configurations of")
    own = rep["material_fit"]
    assert own["delta_e2000_mean"] < 0.5                # the gonio fit itself is good
    # what glTF reaches (docs/export.md): 3.7 on 2026-12; the paint's blue lies outside
    # sRGB (no glTF colour can come closer than 1.5 on average at these configurations)
    # and eq. 5 darkens off the normal as no microfacet lobe does
    assert rep["delta_e2000_mean"] < 4.2
    assert rep["delta_e2000_mean"] > own["delta_e2000_mean"]


@pytest.mark.xfail(strict=True, reason="glTF reaches mean CIEDE2000 3.7 on the demo's coat "
                   "paint, with or without KHR_materials_iridescence (the film does not "
                   "lower it), and 3.55 even fitted at the 195 judged configurations "
                   "themselves: its blue is outside sRGB (floor 1.5) and seed 000 eq. 5's "
                   "highlight at grazing (worst 18 at θi 60° θo 85°) has no microfacet "
                   "lobe's shape (docs/export.md, 'What glTF loses')")
def test_demo_coat_reaches_the_issue_target(demo_coat):
    assert demo_coat["delta_e2000_mean"] < 3.0
