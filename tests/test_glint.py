"""Glints (gonio_cli/glint.py, render/glint_term.py) against independent truth: the
expectation over flakes is the smooth lobe (a quadrature of p22 ∗ cone), a flake that sees
a disc source is as bright as the source times the lobe's reflectance (the source's
radiance E / Ω computed here), flakes are fixed on the surface (a tiny camera move keeps
them), no glint where no flake normal is near the half vector, and the scene keys."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import glint as G
from gonio_cli.brdf import cook_torrance
from gonio_cli.glint import beckmann_p22
from gonio_cli.errors import InputError
from gonio_cli.geometry import Cosines
from gonio_cli.render import GBuffer, Light
from gonio_cli.render.glint_term import GlintView, light_cone, lobe_tables, lobe_xyz
from gonio_cli.render.shade import shade
from gonio_cli.render.surface import Surface
from gonio_cli.schemas import Material
from gonio_cli.spectra import cmf_weights, illuminant, parse_grid

WL = parse_grid("380:780:10")
M = 0.3                                    # the demo paint's flake slope (m ≈ 0.28–0.32)
#: the cone of a 1° flake under the sample sky's 1.87° sun (light_cone), slope units
CONE = (float(np.tan(np.radians(1.0))) - float(np.tan(np.radians(1.87 / 4))),
        float(np.tan(np.radians(1.0))) + float(np.tan(np.radians(1.87 / 4))))
BIN = 2 * CONE[1]
SPACING = 0.004                            # the demo's sample spacing at 512²


def paint(ks=0.07, f0=1.0) -> Material:
    one = np.ones(WL.size)
    return Material("cook-torrance", WL, {"kd": 0.05 * one, "ks": ks * one, "m": M * one,
                                          "f0": f0 * one})


def plane_samples(n: int, gap: float, seed: int = 0):
    """n samples on the plane z = 0, normal +z, ``gap`` apart on a jittered grid (gap ≥ 4
    cells: each sample meets flakes of its own cells only, so samples are independent)."""
    rng = np.random.default_rng(seed)
    k = int(np.ceil(np.sqrt(n)))
    ij = np.stack(np.meshgrid(np.arange(k), np.arange(k)), -1).reshape(-1, 2)[:n]
    xy = (ij + rng.uniform(0, 1, (n, 2))) * gap
    p = np.c_[xy, np.zeros(n)]
    return p, np.tile([0.0, 0.0, 1.0], (n, 1))


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def direction(theta_deg, phi_deg=0.0):
    t, f = np.radians(theta_deg), np.radians(phi_deg)
    return np.array([np.sin(t) * np.cos(f), np.sin(t) * np.sin(f), np.cos(t)])


def smoothed_p22_ratio(sx, sy, m, cone, n=400):
    """(p22 ∗ K)(x̃_h) / p22(x̃_h) by a midpoint quadrature in polar coordinates over the
    cone (flat to r_in, linear to 0 at r_out, normalised here): the expectation of r."""
    r_in, r_out = cone
    r = (np.arange(n) + 0.5) / n * r_out
    t = (np.arange(n) + 0.5) / n * 2 * np.pi
    rr, tt = np.meshgrid(r, t)
    x, y = sx + rr * np.cos(tt), sy + rr * np.sin(tt)
    profile = np.clip((r_out - rr) / (r_out - r_in), 0, 1) if r_out > r_in else 1.0 + 0 * rr
    weight = profile * rr * (r_out / n) * (2 * np.pi / n)
    return np.sum(beckmann_p22(x, y, m) * weight) / np.sum(weight) / beckmann_p22(sx, sy, m)


@pytest.mark.parametrize("theta_h, theta_o", [(0.0, 0.0), (8.0, 20.0), (18.0, 50.0)])
def test_expectation_is_the_smooth_lobe(theta_h, theta_o):
    """E[r] over independent footprints = (p22 ∗ K) / p22 (the smooth lobe, blurred by
    the cone), within 4 standard errors of the mean (≤ 4 %: a wide 3° cone over 300 000
    independent footprints; a 5 % error of the flakes' count or brightness fails)."""
    n = 300000
    cone = (float(np.tan(np.radians(1.5))), float(np.tan(np.radians(3.0))))
    layer = G.GlintLayer(density=1e5, share=0.5, angle_rad=np.radians(3.0), m=M, seed=7)
    p, nrm = plane_samples(n, 4 * layer.cell * 2)          # ≥ 4 cells apart (level ≤ 1)
    h = np.tile(direction(theta_h, 30.0), (n, 1))
    v = np.tile(direction(theta_o, 200.0), (n, 1))
    r, counts = G.glint_ratio(p, nrm, v, h, np.full(n, SPACING), layer, cone, 2 * cone[1])
    assert counts["samples"] == n and counts["glints"] > 5000   # the test sees glints
    sx, sy = -h[0, 0] / h[0, 2], -h[0, 1] / h[0, 2]
    truth = smoothed_p22_ratio(sx, sy, M, cone)
    assert abs(truth - 1.0) < 0.05                            # K blurs p22 by < 5 %
    sem = r.std() / np.sqrt(n)
    assert sem < 0.01                                         # so 4 sem ≤ 4 %
    assert abs(r.mean() - truth) < 4 * sem, (r.mean(), truth, sem)


def test_expectation_broadcasts_over_shapes():
    """The same sample tiled to (6,) rows gives six equal values (deterministic flakes)."""
    layer = G.GlintLayer(3e5, 0.5, np.radians(1.0), M)
    p = np.tile([0.3, 0.2, 0.0], (6, 1))
    n = np.tile([0.0, 0.0, 1.0], (6, 1))
    v = np.tile(direction(10.0), (6, 1))
    h = np.tile(direction(5.0), (6, 1))
    r, _ = G.glint_ratio(p, n, v, h, np.full(6, SPACING), layer, CONE, BIN)
    assert np.all(r == r[0])


def test_a_flake_is_as_bright_as_the_source_times_its_reflectance(monkeypatch):
    """One flake (spread 0) at the filter's centre, its normal on the half vector, at normal
    incidence under a sun of angular diameter δ = 2° (enough expected glints that r is not
    blended towards 1, glint.MIN_GLINTS): the added radiance is
    s · (its share f(0) / N of the footprint) · (the lobe's reflectance 4 ks F) · L_sun,
    L_sun = E / Ω, Ω = 2π (1 − cos δ/2) the sun's solid angle (computed here)."""
    layer = G.GlintLayer(3e5, 1.0, 0.0, M)
    sun = Light("directional", np.ones(WL.size), direction=np.array([0.0, 0.0, 1.0]),
                irradiance=3.0, angular_diameter_deg=2.0)    # a bloomed sun (sky.exr: 1.87°)
    cone = light_cone(layer, sun)
    assert cone[0] == cone[1]                                 # a perfect mirror: the disc
    x = np.array([[0.1, 0.2, 0.0]])
    n = np.array([[0.0, 0.0, 1.0]])

    def one_flake(c0, i0, side, keys, mean, kept, layer, bin_width):
        return np.array([0]), x[:, :2].copy(), np.zeros(1), np.zeros(1), np.ones(1)

    monkeypatch.setattr(G, "_flakes", one_flake)
    r, counts = G.glint_ratio(x, n, n, n, np.array([SPACING]), layer, cone, 2 * cone[1])
    assert counts["glints"] == 1
    ks = 0.07
    cos = Cosines(*(np.ones(1),) * 4)
    lobe = cook_torrance(cos, 0.0, ks, M, 1.0)[0]           # f_lobe at the mirror, sr⁻¹
    added = layer.share * (r[0] - 1.0) * lobe * sun.irradiance   # s (r − 1) f_lobe E cos θi
    expected = layer.density * SPACING ** 2                   # N under the filter (θo = 0)
    share = (3.0 / np.pi) / expected                          # f(0) / N
    omega = 2 * np.pi * (1 - np.cos(np.radians(2.0) / 2))
    truth = share * 4 * ks * 1.0 * sun.irradiance / omega     # F = f0 = 1 at θd = 0
    # the glint replaces s of the smooth lobe there: added + s · f_lobe E is the flake alone;
    # slope-space disc vs spherical cap and tan vs angle differ by O(δ²): (δ/4)² ≈ 8e-5
    assert added + layer.share * lobe * sun.irradiance == pytest.approx(truth, rel=3e-4)


def test_no_glint_far_from_every_flake_normal(monkeypatch):
    """A half vector 60° from the normal (p22 ~ 1e-15 of its peak): no sample is drawn, r =
    1 everywhere; and a flake whose normal lies outside the cone adds nothing (r = 0)."""
    layer = G.GlintLayer(3e5, 0.5, np.radians(1.0), M)
    p, n = plane_samples(2000, 0.01)
    v = np.tile(direction(30.0, 180.0), (2000, 1))
    h = np.tile(direction(60.0), (2000, 1))
    r, counts = G.glint_ratio(p, n, v, h, np.full(2000, SPACING), layer, CONE, BIN)
    assert np.all(r == 1.0) and counts["glints"] == 0
    x = np.array([[0.1, 0.2, 0.0]])
    monkeypatch.setattr(G, "_flakes", lambda *a: (np.array([0]), x[:, :2].copy(),
                                                   np.array([1.5 * CONE[1]]), np.zeros(1),
                                                   np.ones(1)))
    r, counts = G.glint_ratio(x, n[:1], n[:1], n[:1], np.array([SPACING]), layer, CONE, BIN)
    assert counts["glints"] == 0 and r[0] == 0.0


def test_flakes_stay_under_a_tiny_camera_move():
    """Flakes are fixed on the surface: turning the view by 0.1° (h by 0.05°, a 20th of the
    cone) keeps ≥ 90 % of the glinting samples and their summed r within 10 %."""
    layer = G.GlintLayer(3e5, 0.5, np.radians(1.0), M, seed=3)
    k = 300
    c = (np.arange(k) + 0.5) * SPACING
    x, y = np.meshgrid(c, c)
    p = np.c_[x.ravel(), y.ravel(), np.zeros(k * k)]
    n = np.tile([0.0, 0.0, 1.0], (k * k, 1))
    wi = unit([0.2, 0.1, 1.0])
    out = []
    for turn in (0.0, 0.1):
        v = np.tile(direction(10.0 + turn, 190.0), (k * k, 1))
        h = (wi + v) / np.linalg.norm(wi + v, axis=1, keepdims=True)
        out.append(G.glint_ratio(p, n, v, h, np.full(k * k, SPACING), layer, CONE, BIN)[0])
    a, b = out[0] > 1.0, out[1] > 1.0
    assert a.sum() > 50                                       # glints to compare
    assert np.sum(a & b) >= 0.9 * a.sum()
    assert out[1][a].sum() == pytest.approx(out[0][a].sum(), rel=0.1)


def test_turning_object_carries_its_flakes():
    """A flake layer with the object's rotation: the same object points seen through a
    rotated world give the same r as unrotated (flakes in the object's frame)."""
    rot = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])   # 90° about z
    a = G.GlintLayer(3e5, 0.5, np.radians(1.0), M, seed=1)
    b = G.GlintLayer(3e5, 0.5, np.radians(1.0), M, seed=1, rotation=rot,
                     translation=np.array([2.0, 0.0, 0.0]))
    p, n = plane_samples(5000, 0.003)
    v = np.tile(direction(5.0, 40.0), (5000, 1))
    h = np.tile(direction(4.0, 10.0), (5000, 1))
    ra, _ = G.glint_ratio(p, n, v, h, np.full(5000, SPACING), a, CONE, BIN)
    world = lambda x: x @ rot.T                                # noqa: E731
    rb, _ = G.glint_ratio(world(p) + [2.0, 0.0, 0.0], world(n), world(v), world(h),
                          np.full(5000, SPACING), b, CONE, BIN)
    assert np.any(ra != 1.0)
    np.testing.assert_allclose(rb, ra, rtol=1e-9, atol=1e-9)   # round-off of the rotation


def test_lobe_tables_match_the_model():
    """The lobe's XYZ from the tables = the exact Cook–Torrance specular term summed
    against S cmf (linear interpolation over 4097 entries: ≤ 1e-4 relative)."""
    mat = paint(ks=0.08, f0=0.6)
    weights = illuminant("D65", WL)[:, None] * cmf_weights(WL)
    tables = lobe_tables(mat, weights, "test")
    rng = np.random.default_rng(2)
    ci, co = rng.uniform(0.2, 1, 50), rng.uniform(0.2, 1, 50)
    ch, cd = rng.uniform(0.8, 1, 50), rng.uniform(0.5, 1, 50)
    cos = Cosines(ci, co, ch, cd)
    spec = cook_torrance(cos, 0.0, mat.params["ks"], mat.params["m"], mat.params["f0"])
    np.testing.assert_allclose(lobe_xyz(tables, cos), spec @ weights, rtol=1e-4)


def test_render_mean_over_seeds_is_the_render_without_glints():
    """shade() of a lit patch with glints, averaged over 24 seeds, against shade() without:
    the lobe is replaced, not added to (within 4 standard errors of the seeds' mean)."""
    k = 96
    c = (np.arange(k) + 0.5) * SPACING
    x, y = np.meshgrid(c - c.mean(), c - c.mean())
    p = np.stack([x, y, np.zeros_like(x)], -1)
    nrm = np.zeros_like(p)
    nrm[..., 2] = 1.0
    eye = np.array([0.0, -0.2, 1.0])
    view = eye - p
    view /= np.linalg.norm(view, axis=-1, keepdims=True)
    gb = GBuffer(np.zeros((k, k), int), p, nrm, view)
    sun = Light("directional", illuminant("D65", WL), direction=unit([0.05, 0.3, 1.0]),
                irradiance=3.0, angular_diameter_deg=1.0)
    mat = paint()
    smooth = shade(gb, [Surface(material=mat)], [sun], WL)[..., 1].sum()
    glint_view = GlintView(eye, unit(-eye), SPACING / np.linalg.norm(eye))
    totals = []
    for seed in range(24):
        s = Surface(material=mat, glint=G.GlintLayer(3e5, 0.5, np.radians(1.0), M, seed),
                    glint_view=glint_view)
        totals.append(shade(gb, [s], [sun], WL)[..., 1].sum())
    totals = np.asarray(totals)
    assert totals.std() > 0                                   # glints were drawn
    sem = totals.std(ddof=1) / np.sqrt(totals.size)
    # + the cone's blur of p22: ≤ 0.4 % of the lobe, half of it drawn: ≤ 0.2 % of the total
    assert abs(totals.mean() - smooth) < 4 * sem + 0.003 * smooth, \
        (totals.mean(), smooth, sem)


@pytest.mark.parametrize("extra, message", [
    ("glint_share = 0.5\n", "needs glint_density"),
    ('glint_density = 1e5\nsparkle = "SPARKLE"\n', "both draw the flakes"),
    ("glint_density = -1\n", "glint_density"),
    ("glint_density = 1e5\nglint_share = 1.5\n", "glint_share"),
    ("glint_density = 1e5\nglint_seed = 1.5\n", "glint_seed"),
])
def test_scene_keys_are_checked(tmp_path, extra, message):
    from gonio_cli.render.scene import load_scene

    mat = tmp_path / "paint.material.json"
    mat.write_text("{}")
    (tmp_path / "SPARKLE").write_bytes(b"")
    scene = tmp_path / "s.toml"
    scene.write_text('[camera]\neye = [0.0, 0.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\n'
                     'fov_deg = 30.0\nwidth = 8\nheight = 8\n[[object]]\n'
                     f'mesh = "builtin:sphere"\nmaterial = "paint.material.json"\n{extra}')
    with pytest.raises(InputError, match=message):
        load_scene(scene)


def test_glints_need_a_cook_torrance_lobe():
    from gonio_cli.render.glint_term import flake_lobe

    gonio = Material("goniochromatic", WL, {"alpha": 0.2, "rho": np.ones(WL.size),
                                            "c": np.zeros(WL.size)})
    with pytest.raises(InputError, match="cook-torrance"):
        flake_lobe(gonio, "object 1")
    with pytest.raises(InputError, match="share"):
        G.check_layer(G.GlintLayer(1e5, 2.0, 0.0, M))


def test_p22_is_eq9_in_slope_space():
    """p22(tan θh) / cos⁴θh = D(θh) / π of seed 004 eq. 9, and ∫ p22 d²x̃ = 1 (a grid
    over ±8 σ: the Gaussian's tail beyond it is < 1e-27)."""
    from gonio_cli.brdf import beckmann_d

    th = np.radians(np.array([0.0, 10.0, 25.0, 40.0]))
    np.testing.assert_allclose(beckmann_p22(np.tan(th), 0.0, M) / np.cos(th) ** 4,
                               beckmann_d(np.cos(th), M)[:, 0] / np.pi, rtol=1e-12)
    x = np.linspace(-8 * M, 8 * M, 801)
    step = x[1] - x[0]
    total = beckmann_p22(x[:, None], x[None, :], M).sum() * step ** 2
    assert total == pytest.approx(1.0, abs=1e-9)
