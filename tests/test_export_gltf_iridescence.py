"""KHR_materials_iridescence in ``gonio export --to gltf``, against independent truth.

1. The thin-film Fresnel term (``gonio_cli/export/gltf_iridescence.py``, the extension's
   Belcour & Barla 2017 approximation) against the spectrum it stands for: its Fourier
   series (the m ≤ 2 terms the extension keeps), integrated wavelength by wavelength with
   the CIE 1931 2° functions under an equal-energy light, to linear Rec.709 — the
   extension's closed form replaces exactly that integral by Gaussian fits.
2. Known limits: a very thick film (no interference left: the incoherent sum
   R12 + T121² R23 / (1 − R12 R23), by hand), no film at normal incidence (the base's F0),
   total internal reflection (1), and a factor of 0 (the core material unchanged).
3. Round trip: a glTF material with a film comes back from the fit (thickness, index,
   factor) and the film is left out where it does not help.
4. The ``.glb`` with the extension passes the Khronos validator.
"""

from __future__ import annotations

import json
import subprocess
from dataclasses import replace

import numpy as np
import pytest

from gonio_cli.export import gltf_iridescence as gi
from gonio_cli.export.gltf import glb_bytes
from gonio_cli.export.gltf_brdf import GltfMaterial, gltf_brdf, ior_f0
from gonio_cli.export.gltf_fit import fit_gltf
from gonio_cli.geometry import cosines
from gonio_cli.spectra import cmfs
from test_export_gltf import _validator, judge_gltf  # noqa: E402

#: A dark red plastic under a film of index 1.8, 350 nm thick: a strong, visible shift.
FILM = GltfMaterial(base_color=(0.3, 0.08, 0.05), metallic=0.0, roughness=0.4,
                    specular=1.0, specular_color=(1.0, 1.0, 1.0), ior=1.5,
                    iridescence=1.0, iridescence_ior=1.8, iridescence_thickness_nm=350.0)


def spectral_truth(cos1: float, n_film: float, d_nm: float, f0) -> np.ndarray:
    """F (3,) of the extension's two-interface film from its spectrum: per channel k the
    m ≤ 2 Fourier series R(λ) = C0 + Σ 2 C_m cos(m (2π OPD/λ + φ_k)) (Belcour & Barla
    2017 §4, with the extension's Schlick interfaces and 0/π phases); the constant C0 as
    is, each interference term integrated against CIE 1931 x̄ȳz̄ every nanometre under an
    equal-energy light (normalised by Σ ȳ) and taken to Rec.709, channel k."""
    lam = np.arange(360.0, 831.0, 1.0)
    cmf = cmfs(lam, 2) / cmfs(lam, 2)[:, 1].sum()
    c2 = np.sqrt(1.0 - (1.0 - cos1 ** 2) / n_film ** 2)
    schlick = lambda f, c: f + (1 - f) * (1 - c) ** 5  # noqa: E731
    r12 = schlick(((n_film - 1) / (n_film + 1)) ** 2, cos1)
    t121 = 1 - r12
    n_b = (1 + np.sqrt(np.asarray(f0))) / (1 - np.sqrt(np.asarray(f0)))
    r23 = schlick(((n_b - n_film) / (n_b + n_film)) ** 2, c2)
    phi = np.pi + np.where(n_b < n_film, np.pi, 0.0)      # film denser than air: φ21 = π
    opd = 2 * n_film * d_nm * c2
    rs = t121 ** 2 * r23 / (1 - r12 * r23)
    out = r12 + rs
    for k in range(3):
        for m in (1, 2):
            wave = np.cos(m * (2 * np.pi * opd / lam + phi[k])) @ cmf          # XYZ
            c_m = (rs[k] - t121) * np.sqrt(r12 * r23[k]) ** m
            out[k] += 2 * c_m * (gi.XYZ_TO_REC709 @ wave)[k]
    return out


@pytest.mark.parametrize("cos1, n_film, d_nm, f0", [
    (1.0, 1.8, 250.0, (0.04, 0.04, 0.04)),
    (0.8, 1.3, 400.0, (0.04, 0.04, 0.04)),
    (0.5, 2.0, 150.0, (0.9, 0.5, 0.2)),      # a coloured metal's F0 under a film
    (0.9, 1.6, 600.0, (0.08, 0.07, 0.06)),   # every channel's base denser
])
def test_film_fresnel_is_its_spectrum_integrated(cos1, n_film, d_nm, f0):
    got = gi.iridescent_fresnel(np.array([cos1]), n_film, d_nm, np.array(f0))[0]
    # tolerance: the Gaussian fits of x̄ȳz̄ in Fourier space (up to ~0.1 of a unit
    # sensitivity at these path differences) times the series' coefficients (≤ 0.3)
    np.testing.assert_allclose(got, spectral_truth(cos1, n_film, d_nm, f0), atol=0.03)


def test_sensitivity_at_zero_path_is_the_equal_energy_white():
    # S(0, 0) = the Rec.709 of XYZ (1, 1, 1): Σ x̄ = Σ ȳ = Σ z̄ (CIE 1931, equal energy)
    lam = np.arange(360.0, 831.0, 1.0)
    cmf = cmfs(lam, 2)
    white = gi.XYZ_TO_REC709 @ (cmf.sum(axis=0) / cmf[:, 1].sum())
    np.testing.assert_allclose(gi.eval_sensitivity(np.array(0.0), np.zeros(3)), white,
                               atol=2e-3)


def test_a_thick_film_is_the_incoherent_sum():
    # 100 µm: every interference term has died out (exp(−var phase²) ~ 0), what is left
    # is the incoherent Airy sum of the two interfaces
    cos1, n_film, f0 = 0.7, 1.6, np.array([0.04, 0.3, 0.9])
    got = gi.iridescent_fresnel(np.array([cos1]), n_film, 1e5, f0)[0]
    c2 = np.sqrt(1 - (1 - cos1 ** 2) / n_film ** 2)
    r12 = ((n_film - 1) / (n_film + 1)) ** 2
    r12 = r12 + (1 - r12) * (1 - cos1) ** 5
    n_b = (1 + np.sqrt(f0)) / (1 - np.sqrt(f0))
    r1 = ((n_b - n_film) / (n_b + n_film)) ** 2
    r23 = r1 + (1 - r1) * (1 - c2) ** 5
    np.testing.assert_allclose(got, r12 + (1 - r12) ** 2 * r23 / (1 - r12 * r23),
                               rtol=1e-9)


def test_no_film_at_normal_incidence_is_the_base():
    f0 = np.array([0.04, 0.3, 0.9])
    got = gi.iridescent_fresnel(np.array([1.0]), 1.8, 0.0, f0)[0]
    # the reference clamps R12·R23 to ≥ 1e-5, which leaves 2·√1e-5·S ≈ 0.008 (1 − F0)
    assert np.all(np.abs(got - f0) <= 0.01 * (1 - f0))


def test_total_internal_reflection_is_one():
    # light from a denser medium (n 2) into the film (n 1.2) beyond the critical angle
    got = gi.iridescent_fresnel(np.array([0.2, 1.0]), 1.2, 300.0, np.full(3, 0.04),
                                outside_ior=2.0)
    np.testing.assert_array_equal(got[0], np.ones(3))
    assert np.all(got[1] < 1.0)


def test_factor_zero_is_the_core_material(rng):
    wi, wo = rng.normal(size=(2, 100, 3))
    wi[:, 2], wo[:, 2] = np.abs(wi[:, 2]) + 0.1, np.abs(wo[:, 2]) + 0.1
    cos = cosines(wi / np.linalg.norm(wi, axis=1, keepdims=True),
                  wo / np.linalg.norm(wo, axis=1, keepdims=True))
    off = replace(FILM, iridescence=0.0)
    core = GltfMaterial(**{k: getattr(FILM, k) for k in (
        "base_color", "metallic", "roughness", "specular", "specular_color", "ior")})
    np.testing.assert_array_equal(gltf_brdf(cos, off), gltf_brdf(cos, core))
    assert np.max(np.abs(gltf_brdf(cos, FILM) - gltf_brdf(cos, off))) > 0.01
    # a metal's film uses its baseColor as F0; at the mirror of normal incidence the
    # 350 nm film changes the colour of a white-ish metal
    metal = replace(FILM, metallic=1.0, base_color=(0.9, 0.9, 0.9))
    c0 = cosines(np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]]))
    f = gltf_brdf(c0, metal)[0] / gltf_brdf(c0, replace(metal, iridescence=0.0))[0]
    assert np.ptp(f) > 0.05


# ------------------------------------------------------------------------ the fit --

def test_round_trip_recovers_a_film():
    fit = fit_gltf(lambda cos: gltf_brdf(cos, FILM))
    got = fit.material
    assert got.iridescence == pytest.approx(1.0, abs=0.05)
    assert got.iridescence_thickness_nm == pytest.approx(350.0, rel=0.03)
    assert got.iridescence_ior == pytest.approx(1.8, abs=0.05)
    assert got.roughness == pytest.approx(FILM.roughness, abs=0.01)
    np.testing.assert_allclose(got.base_color, FILM.base_color, atol=0.01)
    f0 = lambda m: ior_f0(m.ior) * np.asarray(m.specular_color) * m.specular  # noqa: E731
    np.testing.assert_allclose(f0(got), f0(FILM), atol=0.01)
    assert judge_gltf(lambda cos: gltf_brdf(cos, FILM), got).mean() < 0.5


# --------------------------------------------------------------- Khronos validator --

def test_glb_with_a_film_passes_the_khronos_validator(tmp_path):
    node, script = _validator()
    glb = tmp_path / "film.glb"
    glb.write_bytes(glb_bytes(FILM))
    out = subprocess.run([node, str(script), str(glb)], capture_output=True, text=True,
                         timeout=120, check=True)
    report = json.loads(out.stdout)
    assert report["issues"]["numErrors"] == 0, report["issues"]["messages"]
    assert report["issues"]["numWarnings"] == 0, report["issues"]["messages"]
    assert "KHR_materials_iridescence" in report["info"]["extensionsUsed"]
