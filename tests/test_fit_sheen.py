"""``sheen``: a fabric, f = ρ_d(λ)/π + ρ_sheen(λ) D V + k_spec GGX(α), D V the Charlie
sheen of Estevez & Kulla 2017 as glTF ``KHR_materials_sheen`` defines it.

Truth: the distribution's normalisation ∫ D cos θh dω = 1 (quadrature), the visibility's
closed form at normal incidence, reciprocity, and recovery of the parameters from
noiseless data made by the model on a goniometer's configurations (θi 10–70°, θo
−80…85°). The model against a formula written from angles is in tests/test_brdf.py
(``hand_model``).
"""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import brdf
from gonio_cli.brdf_surfaces import charlie_d, sheen_visibility
from gonio_cli.fit import fit
from gonio_cli.fit.common import prepare
from gonio_cli.fit.results import FitOptions
from gonio_cli.geometry import cosines
from gonio_cli.synthetic import synthetic_measurement

from recovery import rgl_like_geometry

MODEL = "sheen"
WL = np.linspace(380.0, 780.0, 41)


def truth(k_spec=0.25):
    """A purple satin: a dim body, a bright bluish-purple sheen (r 0.35) and a sharp
    achromatic highlight (α 0.08)."""
    x = (WL - WL[0]) / (WL[-1] - WL[0])
    return {"r_sheen": 0.35, "alpha": 0.08, "k_spec": k_spec,
            "rho_d": 0.05 + 0.1 * np.exp(-0.5 * ((WL - 450.0) / 50.0) ** 2),
            "rho_sheen": 0.3 + 0.4 * (1 - x) + 0.3 * np.exp(-0.5 * ((WL - 650.0) / 40.0) ** 2)}


def fit_noiseless(p, **options):
    ti, to = rgl_like_geometry()
    m = synthetic_measurement(MODEL, p, ti, to, grid_nm=WL, noise=0.0)
    result = fit(prepare(m, residuals="compressive"), MODEL, FitOptions(**options))
    assert result.result.success
    return result.params


@pytest.mark.parametrize("r", [0.05, 0.2, 0.5, 1.0])
def test_charlie_distribution_is_normalised(r):
    # ∫ D cos θh dω over the hemisphere = 2π ∫ D cos θ sin θ dθ = 1 (Estevez & Kulla 2017);
    # the integrand is a polynomial in sin θ times cos θ: 200 Gauss–Legendre nodes give it
    # to round-off
    x, w = np.polynomial.legendre.leggauss(200)
    theta, weight = np.pi / 4 * (x + 1), np.pi / 4 * w
    total = 2 * np.pi * np.sum(weight * charlie_d(np.cos(theta), r) * np.cos(theta)
                               * np.sin(theta))
    assert total == pytest.approx(1.0, abs=1e-10)


def test_charlie_distribution_vanishes_at_the_normal_and_peaks_at_grazing():
    assert charlie_d(1.0, 0.3) == 0.0
    assert charlie_d(0.0, 0.3) == pytest.approx((2 + 1 / 0.3) / (2 * np.pi))


def test_visibility_closed_form():
    # V = 1/(4 (cos θi + cos θo − cos θi cos θo)): 1/4 whenever one direction is normal
    co = np.linspace(0.0, 1.0, 11)
    np.testing.assert_allclose(sheen_visibility(1.0, co), 0.25, rtol=1e-15)
    np.testing.assert_allclose(sheen_visibility(co, 1.0), 0.25, rtol=1e-15)
    assert sheen_visibility(0.5, 0.5) == pytest.approx(1 / 3)


def test_sheen_is_reciprocal(rng):
    v = rng.normal(size=(2, 1000, 3))
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    v[..., 2] = np.abs(v[..., 2])
    p = truth()
    forward = brdf.evaluate(MODEL, cosines(v[0], v[1]), p)
    backward = brdf.evaluate(MODEL, cosines(v[1], v[0]), p)
    assert np.all(forward > 0)
    np.testing.assert_allclose(forward, backward, rtol=1e-12)


def test_sheen_is_zero_at_grazing_and_finite():
    wi = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    wo = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    p = dict(truth(), rho_d=np.zeros(WL.size))
    f = brdf.evaluate(MODEL, cosines(wi, wo), p)
    assert np.all(np.isfinite(f)) and np.all(f == 0.0)


def test_sheen_recovers_its_parameters_from_noiseless_data():
    # the criterion: 1 %. Measured: every parameter to < 2e-7 relative
    p = truth()
    got = fit_noiseless(p)
    for k in ("r_sheen", "alpha", "k_spec"):
        assert got[k] == pytest.approx(p[k], rel=0.01), k
    for k in ("rho_d", "rho_sheen"):
        assert np.max(np.abs(got[k] / p[k] - 1)) < 0.01, k


def test_a_fabric_without_a_highlight_gets_no_specular_lobe():
    # k_spec = 0: α is then not in the data; the sheen and the body are still recovered
    p = truth(k_spec=0.0)
    got = fit_noiseless(p)
    assert got["k_spec"] < 1e-6
    assert got["r_sheen"] == pytest.approx(p["r_sheen"], rel=0.01)
    for k in ("rho_d", "rho_sheen"):
        assert np.max(np.abs(got[k] / p[k] - 1)) < 0.01, k


def test_alpha_fixed_is_kept_and_the_rest_recovered():
    p = truth()
    got = fit_noiseless(p, alpha=0.08)
    assert got["alpha"] == 0.08
    assert got["r_sheen"] == pytest.approx(p["r_sheen"], rel=0.01)
    assert got["k_spec"] == pytest.approx(p["k_spec"], rel=0.01)
