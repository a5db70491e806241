"""Shading (gonio_cli.render.shade): spectral paths, units, linearity, printed mixing."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli.errors import InputError
from gonio_cli.geometry import cosines
from gonio_cli.render import GBuffer, Light, Stats
from gonio_cli.geometry import cosines_from_dots
from gonio_cli.render.kernels import (TABLE_REL_TOL, goniochromatic_table, table_lookup,
                                      xyz_weights)
from gonio_cli.render.shade import shade
from gonio_cli.render.surface import Surface
from gonio_cli.schemas import Material
from gonio_cli.spectra import illuminant, parse_grid

WL = parse_grid()


def sphere_gbuffer(n: int, n_objects: int = 1) -> GBuffer:
    """An orthographic view of the unit sphere from +z, n × n pixels (analytic).

    With ``n_objects`` = 2 the left half of the sphere is object 0, the right object 1.
    """
    c = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    x, y = np.meshgrid(c, -c)
    r2 = x * x + y * y
    inside = r2 < 1.0
    z = np.sqrt(np.clip(1.0 - r2, 0.0, None))
    p = np.stack([x, y, z], -1) * inside[..., None]
    view = np.zeros_like(p)
    view[..., 2] = inside
    obj = np.where(inside, 0, -1)
    if n_objects == 2:
        obj = np.where(inside & (x > 0), 1, obj)
    uv = np.stack([0.5 * x + 0.5, 0.5 * y + 0.5], -1) * inside[..., None]
    return GBuffer(obj, p, p.copy(), view, uv, np.full((n, n), 2.0 / n) * inside)


def ink(alpha: float, peak_nm: float) -> Material:
    """A synthetic goniochromatic ink like seed 000's (ρ peaked, c up to ~6)."""
    rho = 0.05 + 0.6 * np.exp(-0.5 * ((WL - peak_nm) / 40.0) ** 2)
    c = 0.5 + 5.5 * np.exp(-0.5 * ((WL - (peak_nm - 60.0)) / 50.0) ** 2)
    return Material("goniochromatic", WL, {"alpha": alpha, "rho": rho, "c": c})


def white_lambert() -> Material:
    """f = 1/π exactly: Cook–Torrance with kd = 1 and no specular term."""
    one, zero = np.ones(WL.size), np.zeros(WL.size)
    return Material("cook-torrance", WL, {"kd": one, "ks": zero, "m": 0.3 * one, "f0": zero})


class Stub:
    """A material given by ``evaluate_directions`` only (as the measured reference)."""

    wavelength_nm = WL

    def __init__(self, value=1.0 / np.pi, fail=False):
        self.value, self.fail, self.calls = value, fail, 0

    def evaluate_directions(self, wi, wo, normal):
        if self.fail:
            raise AssertionError("this material must not be evaluated")
        self.calls += 1
        return np.full(np.shape(wi)[:-1] + (WL.size,), self.value)


def lights_two(spectrum="D65"):
    s = illuminant(spectrum, WL)
    return [Light("directional", s, direction=np.array([1.0, 1.0, 1.0]) / np.sqrt(3.0),
                  irradiance=3.0, name="key"),
            Light("directional", s, direction=np.array([-1.0, 0.2, 0.5]), irradiance=1.0,
                  name="fill")]


def lab(xyz, white_y):
    import colour

    return colour.XYZ_to_Lab(np.asarray(xyz) / white_y)


def delta_e(a, b, white_y):
    import colour

    return colour.delta_E(lab(a, white_y), lab(b, white_y), method="CIE 2000")


# ------------------------------------------------------------------------------ units --

def test_white_lambertian_gives_y_one():
    """docs/conventions.md: f = 1/π lit at normal incidence by E = π under equal energy: Y = 1."""
    g = sphere_gbuffer(3)                       # the centre pixel faces +z exactly
    light = Light("directional", np.ones(WL.size), direction=np.array([0.0, 0.0, 1.0]),
                  irradiance=np.pi)
    for material in (white_lambert(), Stub()):
        for spectral in ("table", "exact"):
            xyz = shade(g, [Surface(material=material)], [light], WL, spectral=spectral)
            assert xyz[1, 1, 1] == pytest.approx(1.0, rel=1e-12)


def test_point_light_inverse_square():
    """A point light of intensity I at distance d gives E = I/d²: I = 4π at d = 2 is E = π."""
    g = sphere_gbuffer(3)
    light = Light("point", np.ones(WL.size), position=np.array([0.0, 0.0, 3.0]),
                  intensity=4.0 * np.pi)
    xyz = shade(g, [Surface(material=white_lambert())], [light], WL)
    assert xyz[1, 1, 1] == pytest.approx(1.0, rel=1e-12)


def test_background_stays_black_and_pixels_counted():
    g = sphere_gbuffer(16)
    stats = Stats()
    xyz = shade(g, [Surface(material=ink(0.2, 620))], lights_two(), WL, stats=stats)
    assert np.all(xyz[~g.covered] == 0)
    assert stats.counts["shade"]["pixels"] == int(g.covered.sum())
    assert "shade" in stats.time_s


# ----------------------------------------------------------------------- spectral paths --

@pytest.mark.parametrize("alpha,peak", [(0.19, 620.0), (0.19, 530.0), (0.05, 450.0)])
def test_table_matches_exact_goniochromatic(alpha, peak):
    """The tabulated sum against the 41-wavelength sum on a sphere under two lights.

    The table is built to TABLE_REL_TOL = 1e-5 relative error (linear interpolation,
    checked at the midpoints); that is ~1e-3 CIEDE2000 at most, so 0.01 is a bound with
    a margin of ten, and relative XYZ 2e-5 allows twice the construction tolerance.
    """
    g = sphere_gbuffer(48)
    surf = [Surface(material=ink(alpha, peak))]
    table = shade(g, surf, lights_two(), WL, spectral="table")
    exact = shade(g, surf, lights_two(), WL, spectral="exact")
    m = g.covered & (exact[..., 1] > 0)
    rel = np.abs(table[m] - exact[m]) / np.maximum(exact[m], 1e-300)
    assert rel.max() < 2 * TABLE_REL_TOL
    assert delta_e(table[m], exact[m], exact[m, 1].max()).max() < 0.01


def test_table_size_is_chosen_by_error():
    w = xyz_weights(illuminant("D65", WL), WL)
    m = ink(0.2, 620)
    t = goniochromatic_table(m.params["rho"], m.params["c"], w)
    x = np.random.default_rng(3).uniform(0, 1, 5000)
    exact = np.exp(np.outer(x, m.params["c"])) @ (m.params["rho"][:, None] * w)
    assert np.max(np.abs(table_lookup(t, x) / exact - 1)) <= TABLE_REL_TOL
    # a flat c (no colour shift) needs the smallest table only
    flat = goniochromatic_table(m.params["rho"], np.zeros(WL.size), w)
    assert flat.shape[0] <= t.shape[0]


@pytest.mark.parametrize("model", ["torrance-sparrow", "cook-torrance"])
def test_separable_models_match_exact(model):
    """Torrance–Sparrow (Schlick F linear in f0) and Cook–Torrance with a constant slope
    are separable: the fast path equals the exact sum to round-off."""
    f0 = np.linspace(0.04, 0.6, WL.size)
    if model == "torrance-sparrow":
        params = {"alpha": 0.15, "f0": f0}
    else:
        params = {"kd": np.linspace(0.1, 0.3, WL.size), "ks": np.full(WL.size, 0.8),
                  "m": np.full(WL.size, 0.25), "f0": f0}
    surf = [Surface(material=Material(model, WL, params))]
    g = sphere_gbuffer(32)
    table = shade(g, surf, lights_two(), WL, spectral="table")
    exact = shade(g, surf, lights_two(), WL, spectral="exact")
    np.testing.assert_allclose(table, exact, rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize("model", ["goniochromatic-diffuse", "goniochromatic-coat"])
def test_layered_goniochromatic_table_matches_exact(model):
    """The body, eq. 5's table and the achromatic coat (kernels._goniochromatic_layers_kernel)
    against the 41-wavelength sum of brdf.goniochromatic_coat: only eq. 5's table
    interpolates (TABLE_REL_TOL relative on its share), the body and the coat are exact,
    so 2 × TABLE_REL_TOL bounds the relative error of the sum; the coat (α = 0.03) is
    sharp enough that a wrong factor in its Fresnel or masking would show far above it."""
    from gonio_cli.render.kernels import TABLE_KERNELS

    params = {"alpha": 0.2, "rho": ink(0.2, 530.0).params["rho"],
              "c": np.linspace(-1.0, 2.0, WL.size),
              "rho_d": 0.02 + 0.2 * np.exp(-0.5 * ((WL - 460.0) / 40.0) ** 2)}
    if model == "goniochromatic-coat":
        params.update(alpha_coat=0.03, k_coat=0.9, f0_coat=0.04)
    material = Material(model, WL, params)
    assert model in TABLE_KERNELS
    g = sphere_gbuffer(48)
    surf = [Surface(material=material)]
    table = shade(g, surf, lights_two(), WL, spectral="table")
    exact = shade(g, surf, lights_two(), WL, spectral="exact")
    m = g.covered & (exact[..., 1] > 0)
    rel = np.abs(table[m] - exact[m]) / np.maximum(exact[m], 1e-300)
    assert rel.max() < 2 * TABLE_REL_TOL
    assert exact[m, 1].max() > 20 * np.median(exact[m, 1])       # the coat's highlight


def test_light_cosines_equal_geometry():
    rng = np.random.default_rng(7)
    n = rng.normal(size=(500, 3))
    wi, wo = rng.normal(size=(500, 3)), rng.normal(size=(500, 3))
    n, wi, wo = (a / np.linalg.norm(a, axis=1, keepdims=True) for a in (n, wi, wo))
    wo[0] = -wi[0]                                              # the undefined half vector
    ref = cosines(wi, wo, n)
    got = cosines_from_dots(np.sum(n * wi, 1), np.sum(n * wo, 1), np.sum(wi * wo, 1))
    for a, b in zip(got, ref):
        np.testing.assert_allclose(a[1:], b[1:], atol=1e-12)
    # ωo = −ωi: never lit and seen at once; the half vector is the normal (cos θh = 1;
    # geometry.half_vector returns +z instead, the normal of its own frame)
    assert got.cos_theta_h[0] == 1.0 and np.all(np.isfinite([a[0] for a in got]))


# ---------------------------------------------------------------------------- linearity --

def test_lights_add_linearly():
    g = sphere_gbuffer(24, n_objects=2)
    surfaces = [Surface(material=ink(0.2, 620)), Surface(material=Stub(0.1))]
    a, b = lights_two()
    point = Light("point", illuminant("A", WL), position=np.array([0.5, 2.0, 2.0]),
                  intensity=5.0)
    both = shade(g, surfaces, [a, b, point], WL)
    parts = sum(shade(g, surfaces, [L], WL) for L in (a, b, point))
    np.testing.assert_allclose(both, parts, rtol=1e-12, atol=1e-15)
    # and scale with irradiance
    a2 = Light("directional", a.spectrum, direction=a.direction, irradiance=2 * a.irradiance)
    np.testing.assert_allclose(shade(g, surfaces, [a2], WL),
                               2 * shade(g, surfaces, [a], WL), rtol=1e-12)


def test_unlit_side_is_black():
    g = sphere_gbuffer(16)
    light = Light("directional", np.ones(WL.size), direction=np.array([1.0, 0.0, 0.0]),
                  irradiance=1.0)
    xyz = shade(g, [Surface(material=ink(0.2, 620))], [light], WL)
    x = g.position[..., 0]
    assert np.all(xyz[g.covered & (x < 0)] == 0)
    assert np.all(xyz[g.covered & (x > 0.05)][:, 1] > 0)


# ------------------------------------------------------------------------------ printed --

SUBSTRATE = {"kd": 0.04, "ks": 0.02, "shininess": 3.0, "spectrum": np.full(WL.size, 0.9)}


def test_printed_mix_is_coverage_weighted_sum():
    """f = Σ cov_k f_k + (1 − Σ cov) f_substrate, checked against single-material renders."""
    g = sphere_gbuffer(24)
    inks = [ink(0.2, 620), ink(0.2, 530), ink(0.2, 450)]
    cov = np.array([0.2, 0.3, 0.1])
    printed = Surface(inks=inks, coverage=lambda uv, fp: np.broadcast_to(cov, uv.shape[:-1] + (3,)),
                      substrate=SUBSTRATE)
    lights = lights_two()
    got = shade(g, [printed], lights, WL)
    bare = Surface(inks=inks, coverage=lambda uv, fp: np.zeros(uv.shape[:-1] + (3,)),
                   substrate=SUBSTRATE)
    expected = sum(c * shade(g, [Surface(material=m)], lights, WL) for c, m in zip(cov, inks))
    expected = expected + (1 - cov.sum()) * shade(g, [bare], lights, WL)
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-15)
    # black paper: no substrate term at all
    black = Surface(inks=inks, coverage=printed.coverage)
    np.testing.assert_allclose(shade(g, [black], lights, WL),
                               expected - (1 - cov.sum()) * shade(g, [bare], lights, WL),
                               rtol=1e-10, atol=1e-14)


def test_phong_substrate_is_normalised_phong():
    """The substrate alone at one pixel: spectrum · (kd/π + ks (n+2)/(2π) cos^n) E cos θi."""
    g = sphere_gbuffer(3)
    bare = Surface(inks=[Stub(fail=True)] * 3, coverage=lambda uv, fp: np.zeros(uv.shape[:-1] + (3,)),
                   substrate=SUBSTRATE)
    t = np.radians(30.0)
    light = Light("directional", np.ones(WL.size), direction=np.array([np.sin(t), 0, np.cos(t)]),
                  irradiance=2.0)
    y = shade(g, [bare], [light], WL)[1, 1, 1]
    cos_rv = np.cos(t)                               # R_L·V with V = N = +z
    f = 0.9 * (0.04 / np.pi + 0.02 * 5.0 / (2 * np.pi) * cos_rv ** 3.0)
    assert y == pytest.approx(f * 2.0 * np.cos(t), rel=1e-12)


def test_zero_coverage_skips_an_ink():
    g = sphere_gbuffer(16)
    skipped = Stub(fail=True)                       # raises if it is ever evaluated
    used = Stub(0.2)
    cov = lambda uv, fp: np.stack([np.full(uv.shape[0], 0.5), np.zeros(uv.shape[0]),
                                   (uv[:, 0] > 0.5) * 0.5], -1)
    stats = Stats()
    xyz = shade(g, [Surface(inks=[used, skipped, used], coverage=cov)], lights_two(), WL,
                stats=stats)
    c = stats.counts["shade"]
    assert c["inks_skipped"] == 1 and c["ink_pixels"]["0.1"] == 0
    assert c["ink_pixels"]["0.0"] == int(g.covered.sum())
    assert 0 < c["ink_pixels"]["0.2"] < c["ink_pixels"]["0.0"]
    assert np.all(np.isfinite(xyz))


# ------------------------------------------------------------------------------- errors --

def test_errors_name_the_problem():
    g = sphere_gbuffer(8)
    with pytest.raises(InputError, match="spectral path"):
        shade(g, [Surface(material=Stub())], lights_two(), WL, spectral="fast")
    no_uv = GBuffer(g.object_id, g.position, g.normal, g.view)
    printed = Surface(inks=[Stub()] * 3, coverage=lambda uv, fp: np.ones(uv.shape[:-1] + (3,)))
    with pytest.raises(InputError, match="no uv"):
        shade(no_uv, [printed], lights_two(), WL)
    with pytest.raises(InputError, match="neither a material nor inks"):
        shade(g, [Surface()], lights_two(), WL)
    with pytest.raises(InputError, match="unknown substrate"):
        shade(g, [Surface(inks=[Stub()] * 3, coverage=printed.coverage,
                          substrate={"kd": 0.1, "gloss": 1})], lights_two(), WL)
    other_grid = Material("goniochromatic", parse_grid("400:700:10"),
                          {"alpha": 0.2, "rho": np.ones(31), "c": np.ones(31)})
    with pytest.raises(InputError, match="spectral grid"):
        shade(g, [Surface(material=other_grid)], lights_two(), WL)


def test_environment_without_lobes_is_an_error():
    from gonio_cli.render.environment import Environment

    env = Environment("index.json", np.array([1.0]), [""], [(8, 16)],
                      {1.0: np.ones((8, 16, 3), np.float32)})
    with pytest.raises(InputError, match="has no lobes; environment light needs gonio lobes fit"):
        shade(sphere_gbuffer(8), [Surface(material=ink(0.2, 620))], [], WL, environment=env)


# ------------------------------------------------------------------ in-place per-pixel forms

def sweep_cosines(n=4000, seed=11):
    """N·ωi, N·ωo, ωi·ωo of random unit vectors, with the extremes put in: normal
    incidence and view (1, 1, 1), grazing (0), the mirror and retro-reflection, and
    ωo = −ωi (the undefined half vector)."""
    rng = np.random.default_rng(seed)
    nrm, wi, wo = (a / np.linalg.norm(a, axis=1, keepdims=True)
                   for a in rng.normal(size=(3, n, 3)))
    nrm[:5] = [0.0, 0.0, 1.0]
    wi[:5] = [[0, 0, 1], [1, 0, 0], [0.6, 0, 0.8], [0.6, 0, 0.8], [0.6, 0, 0.8]]
    wo[:5] = [[0, 0, 1], [0, 1, 0], [-0.6, 0, 0.8], [0.6, 0, 0.8], [-0.6, 0, -0.8]]
    return (np.sum(nrm * wi, 1), np.sum(nrm * wo, 1), np.sum(wi * wo, 1))


@pytest.mark.parametrize("dtype,tol", [(np.float64, 1e-13), (np.float32, 3e-6)])
def test_in_place_forms_equal_the_shared_equations(dtype, tol):
    """The direct-light loop's float32 in-place forms of seed 000 eqs. 1, 3 and 6 equal
    geometry.cosines_from_dots, brdf.ggx_d and brdf.goniochromatic_exponent_arg on the
    same (rounded) inputs, to round-off of the dtype (float32: ~25 ulp of the arithmetic,
    relative to D's peak 1/(π α²) for D), on random directions with the extremes and
    ωo = −ωi put in."""
    from gonio_cli.brdf import ggx_d, goniochromatic_exponent_arg
    from gonio_cli.brdf import ggx_d_into as _ggx_d_into
    from gonio_cli.brdf import goniochromatic_exponent_arg_into as _exponent_arg_into
    from gonio_cli.geometry import cosines_from_dots_into as _cosines_into
    from gonio_cli.render.kernels import Scratch

    dots = [d.astype(dtype) for d in sweep_cosines()]
    ref = cosines_from_dots(*(d.astype(float) for d in dots))
    got = _cosines_into(*dots, Scratch(dtype, dots[0].size))
    # 2 + 2 ωi·ωo loses relative precision as ωo → −ωi: round-off / (2 + 2 ωi·ωo)
    sq = np.maximum(2.0 + 2.0 * dots[2].astype(float), 1e-12)
    for a, b in zip(got, ref):
        assert a.dtype == dtype
        assert np.all(np.abs(a - b) <= tol * (1.0 + 1.0 / sq))
    # ωo = −ωi: the normal stands in for the half vector (cos θh = 1, cos θd = cos θi)
    assert got.cos_theta_h[4] == 1.0 and got.cos_theta_d[4] == got.cos_theta_i[4]
    scratch = Scratch(dtype, dots[0].size)
    x = _exponent_arg_into(got.cos_theta_i, got.cos_theta_o, scratch)
    np.testing.assert_allclose(x, goniochromatic_exponent_arg(ref.cos_theta_i, ref.cos_theta_o),
                               atol=tol, rtol=0)
    for alpha in (0.05, 0.2, 1.0):
        d = _ggx_d_into(got.cos_theta_h, alpha, scratch)
        peak = 1.0 / (np.pi * alpha**2)
        np.testing.assert_allclose(d / peak, ggx_d(got.cos_theta_h.astype(float), alpha) / peak,
                                   atol=tol, rtol=0)
        assert d[0] == pytest.approx(peak, rel=tol)           # cos θh = 1: the peak


def test_float32_shading_matches_float64():
    """The pipeline shades a float32 G-buffer in float32 (α ≥ FLOAT32_MIN_ALPHA) and
    sharper lobes in float64: both within float32 round-off of the float64 shading of
    the same buffer, relative to the brightest pixel: the float32 normal and dot products
    move sin²θh by ~4e-7, so D's peak by ≤ 4e-7 / α² = 1.6e-4 at α = 0.05 (measured:
    6e-6 at α = 0.3, 6.5e-5 at α = 0.05 in float32, 1.3e-4 at α = 0.02 in float64 —
    the float32 normals' own rounding dominates), far below a colour difference."""
    from gonio_cli.render.kernels import FLOAT32_MIN_ALPHA, work_dtype
    from gonio_cli.render.shade import shade_rows

    g64 = sphere_gbuffer(64)
    cov = g64.covered
    g32 = GBuffer(g64.object_id, *(a.astype(np.float32) for a in
                                   (g64.position, g64.normal, g64.view, g64.uv, g64.uv_footprint)))
    for alpha in (0.3, FLOAT32_MIN_ALPHA, 0.02):
        m = ink(alpha, 600.0)
        single = alpha >= FLOAT32_MIN_ALPHA
        assert work_dtype(m, "table", np.float32) == (np.float32 if single else np.float64)
        assert work_dtype(m, "table", np.float64) == np.float64
        assert work_dtype(m, "exact", np.float32) == np.float64
        ref = shade_rows(g64, [Surface(material=m)], lights_two(), WL).reshape(64, 64, 3)
        got = shade_rows(g32, [Surface(material=m)], lights_two(), WL,
                         dtype=np.float32).reshape(64, 64, 3)
        assert got.dtype == np.float32
        scale = ref[cov].max()
        np.testing.assert_allclose(got[cov] / scale, ref[cov] / scale, atol=2e-4, rtol=0)
        assert np.all(got[~cov] == 0)
