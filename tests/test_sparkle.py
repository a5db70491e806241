"""Sparkles (seed 004 §6): eq. 16 packing, the texture from synthetic flake photographs,
eq. 17's term, and the sparkle lobe in shading (only where bits are set, nothing else
changed)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from gonio_cli import sparkle as sp
from gonio_cli.errors import InputError
from gonio_cli.imageio import read_image
from gonio_cli.render import GBuffer, Light, Stats
from gonio_cli.render.shade import shade
from gonio_cli.render.surface import Surface
from gonio_cli.render.sparkle_term import mirror_peak
from gonio_cli.schemas import Material
from gonio_cli.spectra import illuminant, parse_grid

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"
WL = parse_grid()
SEED_TH = np.radians(sp.theta_h_deg(sp.SEED_THETA_I_DEG))        # 35, 30, …, 5 degrees


def load_generator():
    spec = importlib.util.spec_from_file_location("make_sparkle_photos",
                                                  SAMPLE / "make_sparkle_photos.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def shipped_photos():
    gen = load_generator()
    return gen, [read_image(SAMPLE / "sparkle" / f"photo_ti{t:02d}.png").pixels
                 for t in gen.THETA_I_DEG]


# ---------------------------------------------------------------------------- eq. 16 --

def test_pack_unpack_round_trip(rng):
    bits = rng.random((7, 9, 11)) < 0.3
    t = sp.pack_bits(bits)
    assert t.dtype == np.uint8
    expected = sum(bits[k].astype(int) * 2 ** k for k in range(7))     # eq. 16 written out
    assert np.array_equal(t, expected)
    assert np.array_equal(sp.unpack_bits(t, 7), bits)
    assert np.array_equal(sp.pack_bits(sp.unpack_bits(np.arange(256, dtype=np.uint8)
                                                      .reshape(16, 16))),
                          np.arange(256).reshape(16, 16))


def test_bit_k_is_the_kth_largest_angle():
    """Seed 004 §6: bit k ↔ θi = 70 − 10k, whatever order the photos come in."""
    angles = [30.0, 70.0, 10.0, 50.0, 20.0, 60.0, 40.0]
    photos = []
    for j, a in enumerate(angles):
        img = np.full((8, 8), 0.05)
        img[j, 0] = 0.9                              # photo j lights pixel (j, 0)
        photos.append(img)
    r = sp.build_texture(photos, angles)
    assert r.theta_i_deg == [70.0, 60.0, 50.0, 40.0, 30.0, 20.0, 10.0]
    for j, a in enumerate(angles):
        assert r.texture[j, 0] == 2 ** int((70 - a) / 10)
    assert np.count_nonzero(r.texture) == 7


def test_segmentation_rules():
    rng = np.random.default_rng(7)
    img = 0.1 + 0.01 * rng.standard_normal((100, 100))
    img[10:13, 20:23] = 0.9                          # 9 bright pixels
    b, thr = sp.segment_mad(img)
    assert b.sum() == 9 and 0.12 < thr < 0.2         # 5 σ of 0.01 above 0.1
    b, _ = sp.segment_percentile(img, 0.09)          # the top 9 of 10 000
    assert b.sum() == 9 and b[10:13, 20:23].all()
    with pytest.raises(InputError, match="mad, percentile"):
        sp.build_texture([img], [10.0], rule="otsu")


def test_synthetic_photos_recover_the_flakes():
    """The shipped photos give back the truth of make_sparkle_photos (≥ 95 % of the
    pixels that are a sparkle in either, bit for bit)."""
    gen, photos = shipped_photos()
    flakes = json.loads((SAMPLE / "sparkle" / "flakes.json").read_text())["flakes"]
    truth = gen.truth_texture(flakes)
    t = sp.build_texture(photos, list(gen.THETA_I_DEG)).texture
    either = (t > 0) | (truth > 0)
    assert either.sum() > 1000
    assert np.mean(t[either] == truth[either]) >= 0.95
    for k in range(7):                               # every bit is used, as in the truth
        assert 0.5 < (t >> k & 1).sum() / (truth >> k & 1).sum() < 1.5


def test_sample_data_regenerates_and_matches_the_demo_texture(tmp_path):
    gen = load_generator()
    gen.main(tmp_path)
    for p in sorted((SAMPLE / "sparkle").iterdir()):
        assert (tmp_path / p.name).read_bytes() == p.read_bytes(), p.name
    _, photos = shipped_photos()
    demo = read_image(SAMPLE / "sparkle.png")
    t, th = sp.texture_from_image(demo.pixels, demo.metadata)
    assert np.array_equal(t, sp.build_texture(photos, list(gen.THETA_I_DEG)).texture)
    assert np.allclose(th, SEED_TH)


@pytest.mark.parametrize("photos,angles,match", [
    ([np.zeros((4, 4))] * 2, [10.0], "2 photos but 1 angles"),
    ([np.zeros((4, 4)), np.zeros((5, 4))], [10.0, 20.0], "differ in size"),
    ([np.zeros((4, 4))] * 9, list(range(5, 95, 10)), "1 to 8"),
    ([np.zeros((4, 4))] * 2, [10.0, 10.0], "repeat"),
    ([np.zeros((4, 4))], [90.0], r"\(0, 90\)"),
    ([np.full((4, 4), np.nan)], [10.0], "NaN"),
])
def test_build_texture_refuses_bad_input(photos, angles, match):
    with pytest.raises(InputError, match=match):
        sp.build_texture(photos, angles)


# ---------------------------------------------------------------------------- eq. 17 --

def term_at(t: int, alpha_deg, exact=False):
    alpha = np.radians(np.asarray(alpha_deg, float))
    tex = np.full((4, 4), t, np.uint8)
    uv = np.full(alpha.shape + (2,), 0.3)
    return sp.sparkle_term(tex, uv, np.cos(alpha)[..., None], SEED_TH, exact=exact)[..., 0]


@pytest.mark.parametrize("exact", [False, True])
def test_term_is_one_at_theta_h_and_cos_power_off_it(exact):
    for k in range(7):
        th = 35.0 - 5.0 * k                           # bit k ↔ θh = 35 − 5k (eq. 15)
        assert term_at(1 << k, th, exact) == pytest.approx(1.0, abs=1e-12)
        for d in (-4.0, 1.0, 3.0, 10.0):
            if th + d >= 0:
                assert term_at(1 << k, th + d, exact) == pytest.approx(
                    np.cos(np.radians(d)) ** 24, rel=1e-9)
    assert np.all(term_at(0, np.linspace(0, 90, 50), exact) == 0.0)   # no bit: nothing


def test_term_takes_the_nearest_set_bit():
    t = (1 << 0) | (1 << 4)                           # θh = 35° and 15°
    assert term_at(t, 20.0) == pytest.approx(np.cos(np.radians(5)) ** 24, rel=1e-9)
    assert term_at(t, 28.0) == pytest.approx(np.cos(np.radians(7)) ** 24, rel=1e-9)
    assert term_at(t, 25.0) == pytest.approx(np.cos(np.radians(10)) ** 24, rel=1e-9)


def test_table_equals_the_bit_loop_for_every_texel_value():
    alpha = np.linspace(0.0, 0.5 * np.pi, 4001)
    cos = np.repeat(np.cos(alpha)[:, None], 2, axis=1)
    table = sp.SparkleTable(SEED_TH)
    for t in range(256):
        tt = np.full(alpha.size, t, np.uint8)
        a = table(tt, cos)
        b = sp.sparkle_term_exact(tt, cos, SEED_TH)
        assert np.max(np.abs(a - b)) < 1e-12, t      # round-off of cos(a−b) expanded


def test_term_broadcasts_over_leading_axes(rng):
    tex = rng.integers(0, 128, (16, 16)).astype(np.uint8)
    uv = rng.random((2, 3, 2))
    cos = rng.uniform(0.7, 1.0, (2, 3, 2))
    whole = sp.sparkle_term(tex, uv, cos, SEED_TH)
    assert whole.shape == (2, 3, 2)
    flat = sp.sparkle_term(tex, uv.reshape(6, 2), cos.reshape(6, 2), SEED_TH)
    assert np.array_equal(whole.reshape(6, 2), flat)
    assert np.all((whole >= 0) & (whole <= 1))
    odd = np.array([-1.0, np.nan, 2.0]).reshape(1, 1, 3) * np.ones((2, 3, 1))
    for exact in (False, True):
        r = sp.sparkle_term(np.full((2, 2), 127, np.uint8), uv, odd, SEED_TH, exact=exact)
        assert np.all(r[..., 1] == 0.0)                # NaN: no sparkle
        assert np.allclose(r[..., 0], np.cos(0.5 * np.pi - SEED_TH[0]) ** 24)  # N·H < 0: 90°
        assert np.allclose(r[..., 2], np.cos(SEED_TH[-1]) ** 24)   # N·H > 1 is 1: α = 0


def test_texture_lookup_is_opengl_repeat():
    tex = np.arange(12, dtype=np.uint8).reshape(3, 4)
    for r in range(3):
        for c in range(4):
            uv = np.array([(c + 0.5) / 4, 1 - (r + 0.5) / 3])
            assert sp.sample_texture(tex, uv) == tex[r, c]
            assert sp.sample_texture(tex, uv + [2.0, -1.0]) == tex[r, c]
            assert sp.sample_texture(tex, (uv + [1.0, 3.0]) / 2, scale=2.0) == tex[r, c]


# ---------------------------------------------------------------------------- shading --

def paint() -> Material:
    n = WL.size
    return Material("cook-torrance", WL, {"kd": np.full(n, 0.1), "ks": np.full(n, 0.5),
                                          "m": np.full(n, 0.2), "f0": np.full(n, 0.05)})


def flat_gbuffer(n: int, n_objects: int = 1) -> GBuffer:
    """n × n samples of a plane facing +z, seen along −z; uv spans [0, 1]²."""
    c = (np.arange(n) + 0.5) / n
    u, v = np.meshgrid(c, c[::-1])
    z = np.zeros((n, n))
    pos = np.stack([2 * u - 1, 2 * v - 1, z], -1)
    nrm = np.stack([z, z, z + 1], -1)
    obj = np.zeros((n, n), int)
    if n_objects == 2:
        obj[:, n // 2:] = 1
    return GBuffer(obj, pos, nrm, nrm.copy(), np.stack([u, v], -1), np.full((n, n), 1.0 / n))


def sparkle_texture(rng, size=16):
    tex = np.where(rng.random((size, size)) < 0.2, rng.integers(1, 128, (size, size)), 0)
    return sp.SparkleTexture(tex.astype(np.uint8), SEED_TH)


def light_at(theta_i_deg: float, spectrum=None):
    a = np.radians(theta_i_deg)
    s = illuminant("D65", WL) if spectrum is None else spectrum
    return Light("directional", s, direction=np.array([-np.sin(a), 0.0, np.cos(a)]),
                 irradiance=2.0)


def test_object_without_sparkles_is_unchanged(rng):
    """Object 1 has no sparkles: its pixels are the same bits whether object 0 sparkles
    or not, and so is everything when no object does (no sparkle work, no counters)."""
    g = flat_gbuffer(32, 2)
    lights = [light_at(30.0), light_at(50.0)]
    plain = [Surface(material=paint()), Surface(material=paint())]
    stats = Stats()
    a = shade(g, plain, lights, WL, stats=stats)
    assert "sparkle_pixels" not in stats.counts["shade"]
    assert "shade.sparkle" not in stats.time_s
    b = shade(g, [Surface(material=paint(), sparkle=sparkle_texture(rng)),
                  Surface(material=paint())], lights, WL)
    one = g.object_id == 1
    assert np.array_equal(a[one], b[one])
    assert not np.array_equal(a[~one], b[~one])


def test_sparkles_add_light_only_where_bits_are_set(rng):
    g = flat_gbuffer(48)
    spark = sparkle_texture(rng)
    lights = [light_at(30.0), light_at(55.0)]
    stats = Stats()
    base = shade(g, [Surface(material=paint())], lights, WL)
    with_sp = shade(g, [Surface(material=paint(), sparkle=spark)], lights, WL, stats=stats)
    added = with_sp - base
    set_ = sp.sample_texture(spark.texture, g.uv) > 0
    assert np.all(added[~set_] == 0.0)
    assert np.all(added[set_][:, 1] > 0)               # Y > 0: every light lights them
    assert np.all(added >= -1e-12 * np.abs(base))      # only added light (XYZ of white)
    counts = stats.counts["shade"]
    assert counts["sparkle_pixels"] == int(set_.sum())
    assert counts["sparkle_lit_pixel_lights"] == 2 * int(set_.sum())
    assert stats.time_s["shade.sparkle"] > 0


def test_a_full_sparkle_is_as_bright_as_the_mirror_highlight():
    """At α = θh of a set bit (light at θi = 2 θh, camera along N): added radiance
    Y = f_mirror · E cos θi for C_s = (1, 1, 1) under an equal-Y spectrum."""
    g = flat_gbuffer(4)
    for k in (0, 3, 6):
        th = 35.0 - 5.0 * k
        spark = sp.SparkleTexture(np.full((4, 4), 1 << k, np.uint8), SEED_TH)
        light = light_at(2 * th)
        m = paint()
        added = (shade(g, [Surface(material=m, sparkle=spark)], [light], WL)
                 - shade(g, [Surface(material=m)], [light], WL))
        expected = mirror_peak(m, WL) * 2.0 * np.cos(np.radians(2 * th))
        assert np.allclose(added[..., 1], expected, rtol=1e-4)   # basis sums to 1 ± 1e-5
    # the colour scales the lobe: black sparkles add nothing
    spark = sp.SparkleTexture(np.full((4, 4), 1, np.uint8), SEED_TH, color=np.zeros(3))
    assert np.array_equal(shade(g, [Surface(material=paint(), sparkle=spark)],
                                [light_at(70.0)], WL),
                          shade(g, [Surface(material=paint())], [light_at(70.0)], WL))


def test_unlit_sparkles_stay_dark(rng):
    g = flat_gbuffer(16)
    spark = sp.SparkleTexture(np.full((4, 4), 127, np.uint8), SEED_TH)
    below = Light("directional", illuminant("D65", WL), direction=np.array([0.0, 0.3, -1.0]),
                  irradiance=2.0)
    xyz = shade(g, [Surface(material=paint(), sparkle=spark)], [below], WL)
    assert np.all(xyz == 0.0)


def test_sparkles_on_a_print_are_refused():
    s = Surface(inks=[paint()] * 3, coverage=lambda uv, fp: np.zeros(uv.shape[:-1] + (3,)),
                sparkle=sp.SparkleTexture(np.ones((2, 2), np.uint8), SEED_TH))
    with pytest.raises(InputError, match="sparkles need a material"):
        shade(flat_gbuffer(4), [s], [light_at(30.0)], WL)


def test_texture_from_image_checks_the_file():
    t, th = sp.texture_from_image(np.full((3, 3, 1), 5 / 255.0))
    assert t.dtype == np.uint8 and np.all(t == 5) and np.allclose(th, SEED_TH)
    t, th = sp.texture_from_image(np.full((3, 3, 1), 3 / 255.0),
                                  {"theta_i_deg": "[40, 20]"})
    assert np.allclose(np.degrees(th), [20.0, 10.0])
    with pytest.raises(InputError, match="8-bit"):
        sp.texture_from_image(np.full((3, 3, 1), 0.5))
    with pytest.raises(InputError, match="one-channel"):
        sp.texture_from_image(np.random.default_rng(1).random((3, 3, 3)))
    with pytest.raises(InputError, match="only 2 angles"):
        sp.texture_from_image(np.full((3, 3, 1), 4 / 255.0), {"theta_i_deg": "[40, 20]"})
