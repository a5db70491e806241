"""gonio_cli.brdf against closed forms, hand formulas and invariants.

Truth used here, all independent of the module's code paths:
- normalisation integrals (∫ D cos θh dω = 1 for GGX, = π for seed 004's Beckmann) by
  Gauss–Legendre quadrature;
- every model re-written by hand from in-plane *angles* (θh = (θo − θi)/2,
  θd = (θi + θo)/2) rather than from the module's cosines, with Smith G1 in Walter's
  tan form 2 / (1 + √(1 + α² tan²θ)) instead of the module's cosine form;
- reciprocity, a white-furnace energy bound and its α = 1 closed form 1 − ln 2.
"""

from __future__ import annotations

import warnings
from fractions import Fraction
import math

import numpy as np
import pytest

from gonio_cli import brdf
from gonio_cli import geometry as geo
from gonio_cli.errors import GonioError

N_LAMBDA = 4

#: Hand formulas vs the module: cos θh from a normalised vector differs from cos of the
#: angle by ~1e-16; D's relative sensitivity to cos θh is 4 / (α² cos²θh + sin²θh) ≤ 4/α²
#: = 1600 at α = 0.05, so ~2e-13; Beckmann's tan²θh/m² and exp(c x) (|c| ≤ 5) add less.
#: 1e-9 leaves three orders of headroom; any wrong factor or exponent is ≥ 1e-3.
HAND_RTOL = 1e-9

#: Operations that are mathematically symmetric but computed in another order
#: (ωi·ωh vs ωo·ωh): a few ulp. 1e-12 is ~5000 ulp.
SYMMETRY_RTOL = 1e-12


# ------------------------------------------------------------------- hand formulas --

def hand_ggx(theta_h, alpha):
    """Seed 000 eq. (3) from the half angle."""
    return alpha ** 2 / (np.pi * ((alpha ** 2 - 1.0) * np.cos(theta_h) ** 2 + 1.0) ** 2)


def hand_smith_g1(theta, alpha):
    """Walter et al. 2007 eq. (34): G1 = 2 / (1 + √(1 + α² tan²θ))."""
    return 2.0 / (1.0 + np.sqrt(1.0 + alpha ** 2 * np.tan(theta) ** 2))


def hand_schlick(theta, f0):
    """Seed 004 eq. (12)."""
    return f0 + (1.0 - f0) * (1.0 - np.cos(theta)) ** 5


def hand_beckmann(theta_h, m):
    """Seed 004 eq. (9) as printed (no 1/π)."""
    return np.exp(-np.tan(theta_h) ** 2 / m ** 2) / (m ** 2 * np.cos(theta_h) ** 4)


def hand_vgroove(ti, to, th, td):
    """Seed 004 eq. (10) from angles."""
    return np.minimum(1.0, np.minimum(2 * np.cos(th) * np.cos(to) / np.cos(td),
                                      2 * np.cos(th) * np.cos(ti) / np.cos(td)))


def hand_model(name, ti, to, p):
    """f (n, n_λ) of a model at in-plane angles (radians, θo signed), from angles only."""
    th, td = ((to - ti) / 2.0)[:, None], ((ti + to) / 2.0)[:, None]
    ci, co = np.cos(ti)[:, None], np.cos(to)[:, None]
    if name == "goniochromatic":
        # eq. (5) = D/4 · eq. (4); polar angles, so a signed θo enters as |θo| (eq. 6).
        e = p["rho"] * np.exp(p["c"] * (1.0 - np.cos((ti + np.abs(to))[:, None] / 2.0)))
        return hand_ggx(th, p["alpha"]) / 4.0 * e
    if name == "torrance-sparrow":
        g = hand_smith_g1(ti, p["alpha"])[:, None] * hand_smith_g1(to, p["alpha"])[:, None]
        return hand_schlick(td, p["f0"]) * g * hand_ggx(th, p["alpha"]) / (4.0 * ci * co)
    if name == "goniochromatic-diffuse":
        return p["rho_d"] / np.pi + hand_model("goniochromatic", ti, to, p)
    if name == "goniochromatic-coat":
        coat = hand_model("torrance-sparrow", ti, to,
                          {"alpha": p["alpha_coat"], "f0": np.array([p["f0_coat"]])})
        return hand_model("goniochromatic-diffuse", ti, to, p) + p["k_coat"] * coat
    if name == "goniochromatic-backscatter":
        # Hapke's B(g) = B0/(1 + tan(g/2)/h), g the phase angle: in plane the directions
        # to light and viewer are θi and θo apart on either side of the normal, g = |θi + θo|
        surge = p["b0"] / (1.0 + np.tan(np.abs(ti + to) / 2.0)[:, None] / p["h"])
        return (hand_model("goniochromatic-coat", ti, to, dict(p, rho_d=0.0))
                + p["rho_d"] / np.pi * (1.0 + surge))
    if name == "goniochromatic-undercoat":
        # the layer at the angles refracted into the coat (Snell, n = 1.5; signed, so the
        # half and difference angles above hold inside too), times the Fresnel
        # transmission (1 − Schlick at F0 = 0.04) in and out, plus the coat outside
        n = 1.5
        ti_r, to_r = np.arcsin(np.sin(ti) / n), np.arcsin(np.sin(to) / n)
        t = lambda a: 1.0 - hand_schlick(a, 0.04)  # noqa: E731
        under = hand_model("goniochromatic-diffuse", ti_r, to_r, p)
        coat = hand_model("torrance-sparrow", ti, to,
                          {"alpha": p["alpha_coat"], "f0": np.array([p["f0_coat"]])})
        return (t(ti) * t(to))[:, None] * under + p["k_coat"] * coat
    if name == "goniochromatic-two-lobe":
        # the second lobe: Torrance–Sparrow (GGX D, Smith G) with F = ρ_2(λ)
        g = hand_smith_g1(ti, p["alpha_2"])[:, None] * hand_smith_g1(to, p["alpha_2"])[:, None]
        second = p["rho_2"] * g * hand_ggx(th, p["alpha_2"]) / (4.0 * ci * co)
        return hand_model("goniochromatic-diffuse", ti, to, p) + second
    if name in ("cook-torrance-2", "cook-torrance-3"):
        # seed 004 eq. 11 summed over the lobes (ks_j, m_j), one F0(λ)
        lobes = sum(p[f"ks_{j}"] * hand_beckmann(th, p[f"m_{j}"])
                    for j in range(1, int(name[-1]) + 1))
        g = hand_vgroove(ti[:, None], to[:, None], th, td)
        return p["kd"] / np.pi + hand_schlick(td, p["f0"]) * lobes * g / (np.pi * ci * co)
    if name == "sheen":
        # Charlie D (2 + 1/r) sin^(1/r) θh / 2π and V = 1/(4 (cos θi + cos θo − cos θi cos θo))
        # of glTF KHR_materials_sheen, plus k_spec × Torrance–Sparrow with Schlick F0 0.04
        d = (2 + 1 / p["r_sheen"]) * np.abs(np.sin(th)) ** (1 / p["r_sheen"]) / (2 * np.pi)
        v = 1 / (4 * (ci + co - ci * co))
        spec = hand_model("torrance-sparrow", ti, to, {"alpha": p["alpha"], "f0": 0.04})
        return p["rho_d"] / np.pi + p["rho_sheen"] * d * v + p["k_spec"] * spec
    if name == "tabulated-colour":
        # the table holds a bilinear function of (θh, θd) in degrees, which bilinear
        # interpolation between the nodes reproduces exactly
        g = hand_smith_g1(ti, p["alpha"])[:, None] * hand_smith_g1(to, p["alpha"])[:, None]
        return (p["rho_d"] / np.pi + bilinear_colour(np.degrees(np.abs(th)),
                                                     np.degrees(np.abs(td)), p["_coef"])
                * g * hand_ggx(th, p["alpha"]) / (4.0 * ci * co))
    assert name == "cook-torrance"
    g = hand_vgroove(ti[:, None], to[:, None], th, td)
    return p["kd"] / np.pi + (p["ks"] * hand_schlick(td, p["f0"]) * hand_beckmann(th, p["m"])
                              * g / (np.pi * ci * co))


def bilinear_colour(th_deg, td_deg, coef):
    """a + b θh + c θd + d θh θd (..., n_λ), each coefficient (n_λ,)."""
    a, b, c, d = coef
    return a + b * th_deg + c * td_deg + d * th_deg * td_deg


def table_params(rng):
    """``tabulated-colour`` parameters whose table is bilinear in (θh, θd) (degrees)."""
    nh, nd = np.array([0.0, 5.0, 15.0, 40.0, 90.0]), np.linspace(0.0, 90.0, 6)
    coef = (rng.uniform(0.2, 1.0, N_LAMBDA), rng.uniform(0.0, 0.005, N_LAMBDA),
            rng.uniform(-0.002, 0.002, N_LAMBDA), rng.uniform(0.0, 1e-4, N_LAMBDA))
    table = bilinear_colour(nh[:, None, None], nd[None, :, None], coef)
    return {"alpha": 0.2, "rho_d": rng.uniform(0.05, 0.8, N_LAMBDA), "colour_table": table,
            "theta_h_nodes_deg": nh, "theta_d_nodes_deg": nd, "_coef": coef}


def model_params(name, rng):
    """Plausible seeded parameters of a registered model, spectra of N_LAMBDA samples."""
    u = lambda lo, hi: rng.uniform(lo, hi, N_LAMBDA)  # noqa: E731
    return {
        "goniochromatic": lambda: {"alpha": 0.19, "rho": u(0.05, 1.0), "c": u(-5.0, 5.0)},
        "torrance-sparrow": lambda: {"alpha": 0.3, "f0": u(0.02, 1.0)},
        "cook-torrance": lambda: {"kd": u(0.0, 0.5), "ks": u(0.1, 1.0), "m": u(0.1, 0.6),
                                  "f0": u(0.02, 1.0)},
        "goniochromatic-diffuse": lambda: {"alpha": 0.19, "rho": u(0.05, 1.0),
                                           "c": u(-5.0, 5.0), "rho_d": u(0.0, 0.8)},
        "goniochromatic-coat": lambda: {"alpha": 0.19, "rho": u(0.05, 1.0), "c": u(-5.0, 5.0),
                                        "rho_d": u(0.0, 0.8), "alpha_coat": 0.04,
                                        "k_coat": 0.7, "f0_coat": 0.05},
        "goniochromatic-backscatter": lambda: {
            "alpha": 0.19, "rho": u(0.05, 1.0), "c": u(-5.0, 5.0), "rho_d": u(0.0, 0.8),
            "alpha_coat": 0.04, "k_coat": 0.7, "f0_coat": 0.05, "b0": 0.6, "h": 0.1},
        "goniochromatic-undercoat": lambda: {
            "alpha": 0.12, "rho": u(0.05, 1.0), "c": u(-5.0, 5.0), "rho_d": u(0.0, 0.8),
            "alpha_coat": 0.04, "k_coat": 0.7, "f0_coat": 0.05},
        "goniochromatic-two-lobe": lambda: {
            "alpha": 0.3, "rho": u(0.05, 1.0), "c": u(-5.0, 5.0), "rho_d": u(0.0, 0.8),
            "alpha_2": 0.06, "rho_2": u(0.0, 1.0)},
        "cook-torrance-2": lambda: {"kd": u(0.0, 0.5), "f0": u(0.02, 1.0), "ks_1": 0.1,
                                    "m_1": 0.05, "ks_2": 0.6, "m_2": 0.3},
        "cook-torrance-3": lambda: {"kd": u(0.0, 0.5), "f0": u(0.02, 1.0), "ks_1": 0.1,
                                    "m_1": 0.05, "ks_2": 0.4, "m_2": 0.2, "ks_3": 0.3,
                                    "m_3": 0.5},
        "sheen": lambda: {"r_sheen": 0.4, "alpha": 0.15, "k_spec": 0.3,
                          "rho_d": u(0.05, 0.8), "rho_sheen": u(0.0, 1.0)},
        "tabulated-colour": lambda: table_params(rng),
    }[name]()


def random_upper_pairs(rng, n):
    """n random direction pairs (n, 3) on the upper hemisphere, isotropic."""
    v = rng.normal(size=(2, n, 3))
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    v[..., 2] = np.abs(v[..., 2])
    return v[0], v[1]


def gauss_legendre_half_pi(n):
    """Nodes and weights of n-point Gauss–Legendre on (0, π/2)."""
    x, w = np.polynomial.legendre.leggauss(n)
    return np.pi / 4.0 * (x + 1.0), np.pi / 4.0 * w


def polar_by_substitution(scale, n):
    """θ nodes and weights d θ for ∫_0^{π/2} g(θ) dθ with tan θ = scale · tan ψ.

    The substitution crowds nodes into θ ≲ scale, where a narrow lobe (GGX α, Beckmann m)
    lives, and maps (0, π/2) onto itself; dθ/dψ = scale / (cos²ψ + scale² sin²ψ).
    """
    psi, w = gauss_legendre_half_pi(n)
    theta = np.arctan(scale * np.tan(psi))
    return theta, w * scale / (np.cos(psi) ** 2 + scale ** 2 * np.sin(psi) ** 2)


def hemisphere_integral_of_cos_weighted(d_of_cos, scale, n=200):
    """∫ D(cos θ) cos θ dω over the hemisphere = 2π ∫ D cos θ sin θ dθ (isotropic D)."""
    theta, w = polar_by_substitution(scale, n)
    return 2.0 * np.pi * np.sum(np.ravel(d_of_cos(np.cos(theta))) * np.cos(theta)
                                * np.sin(theta) * w)


# ------------------------------------------------------------------------- GGX D --

#: The substituted integrand is smooth on (0, π/2) (for GGX it is exactly sin 2ψ), so
#: 200-node Gauss–Legendre is exact to rounding (~1e-15); 1e-10 leaves room for the
#: rounding of D near its peak at α = 0.05 (D ≈ 127). A missing π or α² is off by O(1).
NORMALISATION_TOL = 1e-10


@pytest.mark.parametrize("alpha", [0.05, 0.19, 0.5, 1.0])
def test_ggx_d_is_normalised(alpha):
    total = hemisphere_integral_of_cos_weighted(lambda ch: brdf.ggx_d(ch, alpha), alpha)
    assert total == pytest.approx(1.0, abs=NORMALISATION_TOL)


def exact_log_ggx(cos_theta_h: float, alpha: float) -> float:
    """log of eq. (3) with the denominator in exact rational arithmetic (no cancellation)."""
    a2 = Fraction(alpha) ** 2
    c2 = Fraction(cos_theta_h) ** 2
    denom = (a2 - 1) * c2 + 1
    return math.log(a2) - math.log(math.pi) - 2.0 * math.log(denom)


#: At α = 1e-4 the denominator is ≥ α² = 1e-8 while the module forms sin²θh = 1 − cos²θh
#: with an absolute rounding of 1.1e-16, i.e. a relative error ≤ 1.1e-8 in the
#: denominator and ≤ 2.2e-8 in log D. 1e-7 absolute is that bound with margin.
LOG_D_TOL = 1e-7


@pytest.mark.parametrize("alpha", [1e-4, 1e-3, 0.05, 1.0])
def test_log_ggx_d_is_finite_and_exact_for_tiny_alpha(alpha):
    # cos θh = 1 exactly, then 1, 10, 1000 … ulp below it, then ordinary angles.
    cos_h = np.array([1.0, 1.0 - 2.0 ** -53, 1.0 - 1e-15, 1.0 - 1e-12, 1.0 - 1e-9,
                      1.0 - 1e-6, 0.9, 0.5, 1e-3, 0.0])
    got = brdf.log_ggx_d(cos_h, alpha)
    assert np.all(np.isfinite(got))
    assert got[0] == pytest.approx(-math.log(math.pi * alpha ** 2), rel=1e-14)
    np.testing.assert_allclose(got, [exact_log_ggx(c, alpha) for c in cos_h],
                               rtol=0, atol=LOG_D_TOL)
    # D itself is finite and consistent with its log (up to exp's ulp).
    d = brdf.ggx_d(cos_h, alpha)
    assert np.all(np.isfinite(d)) and np.all(d > 0)
    np.testing.assert_allclose(np.log(d), got, rtol=0, atol=1e-12)


# ----------------------------------------------------------------- eqs. 5, 6, 7 --

def test_eq5_at_the_mirror_equals_eq7(rng):
    theta = np.linspace(0.0, 89.0, 90)
    cos = geo.in_plane_cosines(theta, theta)  # θo = θi: the mirror configuration
    rho, c = rng.uniform(0.01, 1.0, N_LAMBDA), rng.uniform(-8.0, 8.0, N_LAMBDA)
    for alpha in (0.05, 0.19, 1.0):
        eq5 = brdf.goniochromatic(cos, alpha, rho, c)
        eq7 = brdf.goniochromatic_mirror(np.cos(np.radians(theta)), alpha, rho, c)
        # Only rounding separates them (log/exp of products): 1e-12 is ~5000 ulp.
        np.testing.assert_allclose(eq5, eq7, rtol=1e-12)


@pytest.mark.parametrize("which", [
    "eq5",
    "eq7",
])
def test_zero_rho_gives_zero_without_warnings(which):
    rho, c = np.array([0.0, 0.5]), np.array([2.0, 2.0])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        if which == "eq5":
            f = brdf.goniochromatic(geo.in_plane_cosines(30.0, 30.0), 0.19, rho, c)
        else:
            f = brdf.goniochromatic_mirror(np.cos(np.radians(30.0)), 0.19, rho, c)
    assert f[0] == 0.0 and f[1] > 0.0


def test_eq5_equals_d_over_4_times_eq4_by_hand(rng):
    ti = rng.uniform(0.0, 85.0, 300)
    to = rng.uniform(-85.0, 85.0, 300)
    p = model_params("goniochromatic", rng)
    for alpha in (0.05, 0.19, 0.7):
        p["alpha"] = alpha
        got = brdf.goniochromatic(geo.in_plane_cosines(ti, to), alpha, p["rho"], p["c"])
        want = hand_model("goniochromatic", np.radians(ti), np.radians(to), p)
        np.testing.assert_allclose(got, want, rtol=HAND_RTOL)


# ----------------------------------------------------------------- all the models --

@pytest.mark.parametrize("name", sorted(brdf.MODELS))
def test_registry_evaluates_each_model_as_its_hand_formula(name, rng):
    ti = rng.uniform(0.0, 85.0, 200)
    to = rng.uniform(-85.0, 85.0, 200)
    p = model_params(name, rng)
    got = brdf.evaluate(name, geo.in_plane_cosines(ti, to), p)
    assert got.shape == (200, N_LAMBDA)
    want = hand_model(name, np.radians(ti), np.radians(to), p)
    np.testing.assert_allclose(got, want, rtol=HAND_RTOL)


def test_registry_refuses_an_unknown_model_with_the_choices():
    with pytest.raises(GonioError) as exc:
        brdf.evaluate("phong", geo.in_plane_cosines(30.0, 30.0), {"alpha": 0.1})
    assert "phong" in str(exc.value)
    assert all(name in str(exc.value) for name in brdf.MODELS)


@pytest.mark.parametrize("name", sorted(brdf.MODELS))
def test_models_are_reciprocal(name, rng):
    wi, wo = random_upper_pairs(rng, 2000)
    p = model_params(name, rng)
    forward = brdf.evaluate(name, geo.cosines(wi, wo), p)
    backward = brdf.evaluate(name, geo.cosines(wo, wi), p)
    assert np.all(forward > 0)  # the comparison is not between zeros
    np.testing.assert_allclose(forward, backward, rtol=SYMMETRY_RTOL)


def extreme_cosines(rng) -> geo.Cosines:
    """Normal, grazing, exactly 90°, back-scatter, ωo = −ωi and random 3-D pairs."""
    deg = np.array([0.0, 1e-6, 45.0, 89.999999, 90.0])
    ti, to = np.meshgrid(deg, np.concatenate([-deg, deg]))
    wi, wo = geo.in_plane_directions(ti.ravel(), to.ravel())
    ri, ro = random_upper_pairs(rng, 200)
    wi = np.concatenate([wi, ri, ri, [[-1.0, 0.0, 0.0]]])
    wo = np.concatenate([wo, ro, -ri, [[1.0, 0.0, 0.0]]])
    return geo.cosines(wi, wo)


EXTREME_PARAMS = [
    ("goniochromatic", {"alpha": 1e-6, "rho": [0.0, 1.0, 1.0], "c": [1e4, 1e4, -1e4]}),
    ("goniochromatic", {"alpha": 1.0, "rho": [0.0, 1.0, 1e-300], "c": [-1e4, 1e4, 0.0]}),
    ("torrance-sparrow", {"alpha": 1e-6, "f0": [0.0, 0.5, 1.0]}),
    ("torrance-sparrow", {"alpha": 1.0, "f0": [0.0, 0.5, 1.0]}),
    ("cook-torrance", {"kd": [0.0, 0.5, 1.0], "ks": [1.0, 1.0, 0.0], "m": [1e-6, 0.3, 1.0],
                       "f0": [1.0, 0.04, 0.5]}),
    ("goniochromatic-coat", {"alpha": 1e-6, "rho": [0.0, 1.0, 1.0], "c": [1e4, 1e4, -1e4],
                             "rho_d": [0.0, 1.0, 0.5], "alpha_coat": 1e-6, "k_coat": 10.0,
                             "f0_coat": 1.0}),
    ("goniochromatic-coat", {"alpha": 1.0, "rho": [0.0, 1.0, 1e-300], "c": [-1e4, 1e4, 0.0],
                             "rho_d": [0.0, 0.0, 0.0], "alpha_coat": 1.0, "k_coat": 0.0,
                             "f0_coat": 0.02}),
    ("goniochromatic-backscatter", {"alpha": 1e-6, "rho": [0.0, 1.0, 1.0],
                                    "c": [1e4, 1e4, -1e4], "rho_d": [0.0, 1.0, 0.5],
                                    "alpha_coat": 1e-6, "k_coat": 10.0, "f0_coat": 1.0,
                                    "b0": 1.0, "h": 0.01}),
    ("goniochromatic-backscatter", {"alpha": 1.0, "rho": [0.0, 1.0, 1e-300],
                                    "c": [-1e4, 1e4, 0.0], "rho_d": [1.0, 0.0, 1e-300],
                                    "alpha_coat": 1.0, "k_coat": 0.0, "f0_coat": 0.02,
                                    "b0": 0.0, "h": 2.0}),
    ("goniochromatic-undercoat", {"alpha": 1e-6, "rho": [0.0, 1.0, 1.0],
                                  "c": [1e4, 1e4, -1e4], "rho_d": [0.0, 1.0, 0.5],
                                  "alpha_coat": 1e-6, "k_coat": 10.0, "f0_coat": 1.0}),
    ("goniochromatic-undercoat", {"alpha": 1.0, "rho": [0.0, 1.0, 1e-300],
                                  "c": [-1e4, 1e4, 0.0], "rho_d": [1.0, 0.0, 1e-300],
                                  "alpha_coat": 1.0, "k_coat": 0.0, "f0_coat": 0.02}),
    ("goniochromatic-two-lobe", {"alpha": 1e-6, "rho": [0.0, 1.0, 1.0],
                                 "c": [1e4, 1e4, -1e4], "rho_d": [0.0, 1.0, 0.5],
                                 "alpha_2": 1e-6, "rho_2": [1e6, 0.0, 1.0]}),
    ("goniochromatic-two-lobe", {"alpha": 1.0, "rho": [0.0, 1.0, 1e-300],
                                 "c": [-1e4, 1e4, 0.0], "rho_d": [1.0, 0.0, 1e-300],
                                 "alpha_2": 1.0, "rho_2": [0.0, 1e-300, 1.0]}),
]


@pytest.mark.parametrize("name, params", EXTREME_PARAMS)
def test_models_stay_finite_and_non_negative_at_extremes(name, params, rng):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no overflow or invalid-value warnings either
        f = brdf.evaluate(name, extreme_cosines(rng), params)
    assert f.shape[-1] == 3
    assert np.all(np.isfinite(f)) and np.all(f >= 0.0)


def test_huge_c_and_tiny_alpha_are_large_but_finite():
    # eq. 7 at θi = 60°, c = 1e4: log f ≈ 5000 is clamped below float64's overflow.
    f = brdf.goniochromatic_mirror(0.5, 1e-6, np.array([1.0]), np.array([1e4]))
    assert np.isfinite(f[0]) and f[0] > 1e300




@pytest.mark.parametrize("name", [
    "goniochromatic",
    "torrance-sparrow",
    "cook-torrance",
])
def test_nan_geometry_gives_nan_not_a_number(name, rng):
    wi, wo = geo.in_plane_directions(np.array([np.nan, 30.0]), np.array([30.0, np.nan]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # NaN may warn; the point is what comes out
        f = brdf.evaluate(name, geo.cosines(wi, wo), model_params(name, rng))
    assert np.all(np.isnan(f))


# ------------------------------------------------------------------ broadcasting --

@pytest.mark.parametrize("name", sorted(brdf.MODELS))
@pytest.mark.parametrize("shape", [(6,), (2, 3)])
def test_wavelength_last_broadcasting(name, shape, rng):
    p = model_params(name, rng)
    one = brdf.evaluate(name, geo.in_plane_cosines(25.0, 40.0), p)
    assert one.shape == (N_LAMBDA,)
    tiled = brdf.evaluate(name, geo.in_plane_cosines(np.full(shape, 25.0),
                                                     np.full(shape, 40.0)), p)
    assert tiled.shape == shape + (N_LAMBDA,)
    np.testing.assert_array_equal(tiled, np.broadcast_to(one, tiled.shape))


def test_per_configuration_spectra_broadcast_over_leading_axes(rng):
    ti, to = np.array([10.0, 30.0, 50.0]), np.array([10.0, -20.0, 60.0])
    rho = rng.uniform(0.1, 1.0, (3, N_LAMBDA))
    c = rng.uniform(-3.0, 3.0, (3, N_LAMBDA))
    f = brdf.goniochromatic(geo.in_plane_cosines(ti, to), 0.19, rho, c)
    assert f.shape == (3, N_LAMBDA)
    for k in range(3):
        np.testing.assert_array_equal(
            f[k], brdf.goniochromatic(geo.in_plane_cosines(ti[k], to[k]), 0.19, rho[k], c[k]))


# ------------------------------------------------------------- F, G, torrance–sparrow --

def test_schlick_is_f0_at_normal_and_one_at_grazing():
    f0 = np.array([0.0, 0.04, 0.5, 1.0])
    np.testing.assert_array_equal(brdf.schlick_fresnel(1.0, f0), f0)
    np.testing.assert_array_equal(brdf.schlick_fresnel(0.0, f0), np.ones(4))


@pytest.mark.parametrize("alpha", [1e-3, 0.19, 0.5, 1.0])
def test_smith_g1_is_one_at_normal_and_vanishes_at_grazing(alpha):
    assert brdf.smith_g1_ggx(1.0, alpha) == pytest.approx(1.0, abs=1e-15)
    assert brdf.smith_g1_ggx(0.0, alpha) == 0.0
    # Near grazing G1 ≈ 2 cos θ / α (first order in cos θ; the next term is O(cos θ / α)).
    ct = 1e-9
    assert brdf.smith_g1_ggx(ct, alpha) == pytest.approx(2.0 * ct / alpha, rel=1e-5)
    cts = np.linspace(0.0, 1.0, 101)
    assert np.all(np.diff(brdf.smith_g1_ggx(cts, alpha)) > 0)  # monotone in between


def torrance_sparrow_albedo(alpha, theta_i_deg, n_psi=256, n_phi=256):
    """∫ f cos θo dωo with F0 = 1, integrated over the half vector.

    dωo = 4 (ωo·ωh) dωh; ωh on tan θh = α tan ψ (Gauss–Legendre in ψ) × uniform φ
    (midpoint rule, exact to rounding for a periodic integrand).
    """
    theta_h, w_theta = polar_by_substitution(alpha, n_psi)
    phi = 2.0 * np.pi * (np.arange(n_phi) + 0.5) / n_phi
    th, ph = np.meshgrid(theta_h, phi, indexing="ij")
    wh = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
    wi, _ = geo.in_plane_directions(theta_i_deg, 0.0)
    ih = wh @ wi
    wo = 2.0 * ih[..., None] * wh - wi
    f = brdf.torrance_sparrow(geo.cosines(wi, wo), alpha, np.ones(1))[..., 0]
    jacobian = 4.0 * np.maximum(ih, 0.0) * np.sin(th) * w_theta[:, None] * (2 * np.pi / n_phi)
    return float(np.sum(f * np.maximum(wo[..., 2], 0.0) * jacobian))


#: The horizon (ωo·n = 0) is a kink in the half-vector domain, so the quadrature converges
#: only algebraically: doubling the nodes changes the albedo by ≤ 7e-5 over this table.
#: 1e-3 is over ten times that; energy gain from a model bug (missing 4, extra π) is O(1).
FURNACE_TOL = 1e-3


@pytest.mark.parametrize("alpha", [0.05, 0.19, 0.5, 1.0])
@pytest.mark.parametrize("theta_i_deg", [0.0, 30.0, 60.0, 80.0])
def test_torrance_sparrow_white_furnace_bound(alpha, theta_i_deg):
    a = torrance_sparrow_albedo(alpha, theta_i_deg)
    assert a <= 1.0 + FURNACE_TOL
    assert a > 0.25  # not vacuous: the lowest single-scattering albedo here is 1 − ln 2


def test_torrance_sparrow_albedo_closed_form_at_alpha_one():
    # α = 1: D = 1/π, G1(1) = 1, G1(μ) = 2μ/(1+μ); at θi = 0 the albedo is
    # (1/4π) ∫ G1(μ) dω = ∫_0^1 μ/(1+μ) dμ = 1 − ln 2.
    assert torrance_sparrow_albedo(1.0, 0.0) == pytest.approx(1.0 - math.log(2.0),
                                                              abs=FURNACE_TOL)
    # and small roughness loses almost nothing at normal incidence (G1 → 1).
    assert torrance_sparrow_albedo(0.05, 0.0) > 0.99


# -------------------------------------------------------------------- seed 004 --

@pytest.mark.parametrize("m", [0.05, 0.2, 0.5, 1.0])
def test_beckmann_d_integrates_to_pi(m):
    # Seed 004 eq. (9) omits the 1/π (it sits in eq. 11): ∫ D cos θh dω = π.
    total = hemisphere_integral_of_cos_weighted(lambda ch: brdf.beckmann_d(ch, m), m)
    assert total == pytest.approx(np.pi, abs=np.pi * NORMALISATION_TOL)


def test_vgroove_g_is_in_unit_interval_and_one_at_normal(rng):
    wi, wo = random_upper_pairs(rng, 5000)
    g = brdf.vgroove_g(geo.cosines(wi, wo))
    assert np.all((g >= 0.0) & (g <= 1.0))
    assert g.min() < 0.5 and g.max() == 1.0  # both branches of the min are reached
    n = np.array([0.0, 0.0, 1.0])
    assert brdf.vgroove_g(geo.cosines(n, n)) == 1.0
    # θi = 0, θo = 80°: θh = θd = 40°, so G = 2 cos 80° (masking by the detector side).
    g80 = brdf.vgroove_g(geo.in_plane_cosines(0.0, 80.0))
    assert g80 == pytest.approx(2.0 * np.cos(np.radians(80.0)), rel=1e-14)


def test_cook_torrance_without_specular_is_lambertian(rng):
    wi, wo = random_upper_pairs(rng, 500)
    kd = rng.uniform(0.0, 1.0, N_LAMBDA)
    f = brdf.cook_torrance(geo.cosines(wi, wo), kd, np.zeros(N_LAMBDA),
                           rng.uniform(0.1, 0.5, N_LAMBDA), rng.uniform(0.0, 1.0, N_LAMBDA))
    np.testing.assert_allclose(f, np.broadcast_to(kd / np.pi, f.shape), rtol=1e-15)


@pytest.mark.parametrize("name", sorted(brdf.MODELS))
def test_the_lobes_of_each_model_add_up_to_it(name, rng):
    """gonio_cli.brdf_components: every model is the sum of its lobes (environment light
    reads each lobe on its own), to round-off, at random pairs and at the extremes."""
    from gonio_cli.brdf_components import DIFFUSE, GLOSSY, components

    p = model_params(name, rng)
    for cos in (geo.cosines(*random_upper_pairs(rng, 500)), extreme_cosines(rng)):
        want = brdf.evaluate(name, cos, p)
        lobes = components(name, p)
        got = sum(np.broadcast_to(c.evaluate(cos), want.shape) for c in lobes)
        np.testing.assert_allclose(got, want, rtol=1e-12, atol=1e-300)
        assert {c.kind for c in lobes} <= {DIFFUSE, GLOSSY}
