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
from gonio_cli.export.gltf_fit import fit_gltf, material_rgb
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
