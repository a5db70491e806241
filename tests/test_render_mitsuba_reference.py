"""The Mitsuba 3 reference harness (``gonio_cli/export/mitsuba_reference.py`` and
``reference_compare.py``) against independent truth.

1. Layout: Mitsuba's own ``envmap`` emitter puts a map's columns where gonio does and
   its rows half a texel apart at the poles (row r at θ = π r/(H − 1), gonio's at
   π (r + ½)/H); the map the harness gives it evaluates to gonio's bilinear lookup
   everywhere; mirrored directions see something else.
2. Closed form: a Lambertian sphere in a uniform environment of radiance L reflects
   L_o(λ) = ρ(λ) L D65(λ) at every pixel, so XYZ = L Σ ρ D65 cmf / Σ ȳ; both gonio's chain
   (lobes, prefiltered maps, render) and Mitsuba's path tracer must give it, each within
   its own error.
3. Orientation in pictures: one bright texel lights a Lambertian sphere; the light
   direction recovered from each renderer's picture is the texel's direction.
4. The comparison's figures on synthetic images whose answers are known.

Mitsuba runs a Python BSDF per sample in its scalar variants (no working LLVM here), so
the pictures are 48 × 48 with 16 samples per pixel: ~4 s each.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

mi = pytest.importorskip("mitsuba", reason="mitsuba is not installed (make test installs it)")

from gonio_cli.envmap import lookup, pixel_phi, pixel_theta, spherical_to_direction  # noqa: E402
from gonio_cli.export import mitsuba_reference as ref_  # noqa: E402
from gonio_cli.export import reference_compare as cmp_  # noqa: E402
from gonio_cli.imageio import write_exr  # noqa: E402
from gonio_cli.render import Camera  # noqa: E402
from gonio_cli.schemas import Material, write_material  # noqa: E402
from gonio_cli.spectra import cmf_weights, illuminant, parse_grid  # noqa: E402

GRID = parse_grid()
SIZE = 48
SPP = 16
EYE_Z = 4.0
FOV_DEG = 32.0
#: Rays passing the sphere's centre closer than this are interior (no silhouette pixel).
INTERIOR_IMPACT = 0.9


def lambertian(folder):
    """A Lambertian paint (Cook–Torrance with ks = 0: f = kd/π exactly), kd a smooth
    yellow-orange spectrum, so the closed form tests colour as well as brightness."""
    kd = 0.15 + 0.6 / (1.0 + np.exp(-(GRID - 560.0) / 30.0))
    path = folder / "lambert.material.json"
    write_material(path, Material("cook-torrance", GRID, {
        "kd": kd, "ks": np.zeros(GRID.size), "m": np.full(GRID.size, 0.3),
        "f0": np.full(GRID.size, 0.04)}))
    return path, kd


def camera(size=SIZE):
    return Camera(np.array([0.0, 0.0, EYE_Z]), np.zeros(3), np.array([0.0, 1.0, 0.0]),
                  FOV_DEG, size, size)


def sphere_normals(size=SIZE):
    """Analytic unit normals (size, size, 3) of the unit sphere seen by :func:`camera`
    at pixel centres, and the interior mask (ray–sphere intersection)."""
    f = math.tan(math.radians(FOV_DEG) / 2)
    col, row = np.meshgrid(np.arange(size) + 0.5, np.arange(size) + 0.5)
    x, y = (2 * col / size - 1) * f, (1 - 2 * row / size) * f
    d = np.stack([x, y, -np.ones_like(x)], -1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    eye = np.array([0.0, 0.0, EYE_Z])
    b = d @ eye
    disc = b * b - (eye @ eye - 1.0)
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    normal = eye + t[..., None] * d
    impact = np.sqrt(np.maximum(eye @ eye - b * b, 0.0))
    return normal, (disc > 0) & (impact < INTERIOR_IMPACT)


@pytest.fixture
def chain(run_gonio):
    """Runs the harness's gonio commands in this process (the CLI, not a subprocess)."""

    def run(args):
        r = run_gonio("-q", *args)
        assert r.exit_code == 0, r.stderr

    return run


# ------------------------------------------------------------------------- 1. layout --

#: A 64 × 32 test map: a background and four bright texels (row, col, value), one in
#: each of four octants, with unequal channels.
MAP_H, MAP_W, MAP_BACKGROUND = 32, 64, 0.25
MAP_TEXELS = [(10, 23, 50.0), (5, 50, 70.0), (20, 8, 90.0), (26, 40, 110.0)]


def _test_map(path):
    env = np.full((MAP_H, MAP_W, 3), MAP_BACKGROUND, np.float32)
    for r, c, v in MAP_TEXELS:
        env[r, c] = (v, 2 * v, 3 * v)
    write_exr(path, env)
    return env


def _mitsuba_radiance(emitter, directions):
    """Mitsuba's ``envmap`` eval in each direction (towards the sky), (n, 3)."""
    out = []
    for d in directions:
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-np.asarray(d, float)))     # Mitsuba's wi points back
        out.append(np.array(emitter.eval(si), dtype=float))
    return np.array(out)


def test_mitsuba_reads_columns_as_gonio_and_rows_half_a_texel_apart(tmp_path):
    """What Mitsuba 3 does with the file itself: column c at φ = 2π (c + ½)/W (gonio's),
    row r at θ = π r/(H − 1) (gonio: π (r + ½)/H). At Mitsuba's row angle the texel
    comes back exactly (bilinear weight 1; float32: 1e-4); at gonio's texel centre of row
    10 of 32 (θ = 59.1°, Mitsuba's row 10.17) it is the bilinear blend 0.83 texel + 0.17
    background; the directions mirrored in x or in z see the background. If Mitsuba
    changes its convention this test says so (and ``layout="gonio"`` must follow)."""
    mi.set_variant("scalar_rgb")
    _test_map(tmp_path / "env.exr")
    emitter = mi.load_dict({"type": "envmap", "filename": str(tmp_path / "env.exr")})
    for r, c, v in MAP_TEXELS:
        texel = np.array([v, 2 * v, 3 * v])
        at_mitsuba = spherical_to_direction(np.pi * r / (MAP_H - 1), pixel_phi(MAP_W)[c])
        at_gonio = spherical_to_direction(pixel_theta(MAP_H)[r], pixel_phi(MAP_W)[c])
        got = _mitsuba_radiance(emitter, [at_mitsuba, at_gonio, at_gonio * [-1, 1, 1],
                                          at_gonio * [1, 1, -1]])
        np.testing.assert_allclose(got[0], texel, rtol=1e-4)
        t = (r + 0.5) / MAP_H * (MAP_H - 1) - r             # Mitsuba's row − r
        np.testing.assert_allclose(got[1], (1 - abs(t)) * texel + abs(t) * MAP_BACKGROUND,
                                   rtol=1e-4)
        np.testing.assert_allclose(got[2:], MAP_BACKGROUND, rtol=1e-4)
    assert abs((10 + 0.5) / MAP_H * (MAP_H - 1) - 10 - 0.17) < 0.01


def test_harness_map_is_gonios_layout_in_mitsuba(tmp_path):
    """The map the harness gives Mitsuba (``mitsuba_envmap``, 2H + 1 rows) evaluates,
    through Mitsuba's own ``envmap`` and bilinear filter, to gonio's bilinear lookup
    (``gonio_cli.envmap.lookup``) everywhere: at the bright texels' centres (the texel),
    at their mirrors in x and z (the background), and at 500 random directions,
    poles included (float32: relative 1e-4 of the largest value)."""
    mi.set_variant("scalar_rgb")
    env = _test_map(tmp_path / "env.exr")
    emitter = mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(
        ref_.mitsuba_envmap(tmp_path / "env.exr"))})
    rng = np.random.default_rng(5)
    d = rng.normal(size=(500, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    centres = np.array([spherical_to_direction(pixel_theta(MAP_H)[r], pixel_phi(MAP_W)[c])
                        for r, c, _ in MAP_TEXELS])
    d = np.concatenate([centres, centres * [-1, 1, 1], centres * [1, 1, -1], d,
                        [[0, 1, 0], [0, -1, 0]]])
    got, want = _mitsuba_radiance(emitter, d), lookup(env, d)
    np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-4 * env.max())
    np.testing.assert_allclose(got[:4, 0], [v for _, _, v in MAP_TEXELS], rtol=1e-4)


# -------------------------------------------------------------------- 2. closed form --

def test_lambertian_sphere_in_uniform_environment(tmp_path, chain):
    """L_o = ρ L D65 at every pixel: XYZ = L Σ ρ D65 cmf / Σ ȳ (a map of linear sRGB
    (L, L, L) is L × D65 with Y = 1 in both renderers' conventions).

    gonio: P_1 of a constant map is that constant, the lobe fit of a Lambertian BRDF is
    K_D = ρ/π exactly, so every pixel is exact up to float32 and the LP: relative 1e-4
    (measured 1.5e-7). Mitsuba: each pixel is an independent Monte Carlo estimate of the
    same value, so the mean over the interior's ~1300 pixels must lie within 4 standard
    errors (std over the pixels / √n; ~0.13 % of Y at 16 spp) + 0.5 % (Mitsuba's own
    D65 and colour-matching tables, 1 nm, against gonio's 10 nm sums of colour-science's).
    The comparison's luminance ratio is then 1 within the same bounds, and its mean
    CIEDE2000 is Mitsuba's noise: within 30 % of the noise figure it reports.
    """
    material, kd = lambertian(tmp_path)
    radiance = 2.0
    write_exr(tmp_path / "env.exr", np.full((16, 32, 3), radiance, np.float32))
    scene = ref_.ReferenceScene(camera(), material, tmp_path / "env.exr")
    lobes, env = ref_.gonio_environment(scene, tmp_path / "g", exponents="4", run=chain)
    exr = ref_.render_gonio(scene, tmp_path / "g", env, lobes=lobes, run=chain)
    mitsuba = ref_.render_mitsuba(scene, tmp_path / "m", spp=SPP)
    truth = radiance * (kd * illuminant("D65", GRID)) @ cmf_weights(GRID)

    _, interior = sphere_normals()
    gonio = cmp_.read_xyz(exr)
    np.testing.assert_allclose(gonio[interior], np.broadcast_to(truth, (interior.sum(), 3)),
                               rtol=1e-4)
    pixels = mitsuba.xyz[interior]
    se = pixels.std(axis=0, ddof=1) / math.sqrt(len(pixels))
    assert np.all(np.abs(pixels.mean(axis=0) - truth) <= 4 * se + 5e-3 * truth), (
        pixels.mean(axis=0), truth, se)

    c = cmp_.compare(exr, mitsuba, mask=interior, white_y=truth[1])
    assert abs(c.luminance_ratio - 1.0) <= 4 * se[1] / truth[1] + 5e-3
    assert c.noise_delta_e is not None and 0.7 < c.mean_delta_e / c.noise_delta_e < 1.3


# --------------------------------------------------------------------- 3. orientation --

def _light_direction(y, normal, mask):
    """The direction d of Y = a + k max(0, N·d): least squares of Y = a + N·v over the
    pixels lit above a quarter of the peak (where max(0, N·d) = N·d), d = v/|v|."""
    lit = mask & (y > 0.25 * y[mask].max())
    a = np.column_stack([np.ones(lit.sum()), normal[lit]])
    v = np.linalg.lstsq(a, y[lit], rcond=None)[0][1:]
    return v / np.linalg.norm(v)


def test_bright_texel_lights_the_same_side_in_both(tmp_path, chain):
    """A 64 × 32 map, 0.05 everywhere but one texel of 1000 at θ ≈ 59°, φ ≈ 132°
    (up, right and towards the camera); a Lambertian sphere. The direction recovered from
    each picture is within 3° of the texel's centre (the texel spans 5.6° × 4.8°; the
    fit is exact for a point light, and the dim sky adds a constant) and the two within
    3° of each other; the direction mirrored in x is > 60° away (so a flipped map fails).
    """
    material, _ = lambertian(tmp_path)
    h, w, (r, c) = 32, 64, (10, 23)
    env = np.full((h, w, 3), 0.05, np.float32)
    env[r, c] = 1000.0
    write_exr(tmp_path / "env.exr", env)
    truth = spherical_to_direction(pixel_theta(h)[r], pixel_phi(w)[c])
    scene = ref_.ReferenceScene(camera(), material, tmp_path / "env.exr")
    lobes, environment = ref_.gonio_environment(scene, tmp_path / "g", exponents="4",
                                                run=chain)
    gonio = cmp_.read_xyz(ref_.render_gonio(scene, tmp_path / "g", environment,
                                            lobes=lobes, run=chain))
    mitsuba = ref_.render_mitsuba(scene, tmp_path / "m", spp=SPP, passes=1).xyz
    normal, interior = sphere_normals()
    found = [_light_direction(img[..., 1], normal, interior) for img in (gonio, mitsuba)]
    angle = lambda a, b: math.degrees(math.acos(np.clip(a @ b, -1, 1)))  # noqa: E731
    for d in found:
        assert angle(d, truth) < 3.0, (d, truth)
        assert angle(d, truth * np.array([-1, 1, 1])) > 60.0
    assert angle(*found) < 3.0


# ---------------------------------------------------------------------- 4. comparison --

def _sky_image(size=40, horizon=17, shift=0):
    """A disc on black: bright sky above row ``horizon + shift``, dark ground below,
    a smooth vertical gradient in each (XYZ of a grey)."""
    normal, inside = sphere_normals(size)
    rows = np.arange(size)[:, None] + np.zeros(size)
    y = np.where(rows < horizon + shift, 2.0 + 0.01 * rows, 0.2 + 0.005 * rows)
    xyz = y[..., None] * np.array([0.9505, 1.0, 1.089])
    return np.where(inside[..., None], xyz, 0.0)


def test_comparison_figures_on_known_images():
    """Identical images: CIEDE2000 0, ratio 1, offset 0. Twice as bright: ratio 2 and a
    mean CIEDE2000 > 5. The horizon (a step of log luminance of 2.3) lies at its row edge
    and is sharp; moved down 3 rows, the feature offset is 3 px; without a horizon there
    is no sharp feature. The mask leaves out the 1-px rim."""
    a = _sky_image()
    same = cmp_.compare(a, a.copy())
    assert same.mean_delta_e == 0.0 and same.luminance_ratio == pytest.approx(1.0)
    assert same.feature_offset_px == 0.0
    assert same.feature_row_mitsuba == pytest.approx(17.0, abs=0.5)
    assert not same.mask[a[..., 1] > 0].all() and same.mask.sum() > 0.7 * (a[..., 1] > 0).sum()
    double = cmp_.compare(2.0 * a, a)
    assert double.luminance_ratio == pytest.approx(2.0) and double.mean_delta_e > 5.0
    assert same.feature_sharp and same.feature_step_mitsuba == pytest.approx(
        np.log((2.0 + 0.01 * 16) / (0.2 + 0.005 * 17)), rel=0.05)
    moved = cmp_.compare(_sky_image(shift=3), a)
    assert moved.feature_offset_px == pytest.approx(3.0, abs=0.5)
    smooth = cmp_.compare(_sky_image(horizon=-100), _sky_image(horizon=-100))
    assert not smooth.feature_sharp
    with pytest.raises(Exception, match="one size"):
        cmp_.compare(a[:-1], a)


# ---------------------------------------------------------------------- 5. scene set-up --

def test_scene_set_up_round_trips_through_gonios_reader(tmp_path):
    """A scene with a moved, turned, scaled object and a directional A light: written
    for gonio (``write_gonio_scene``, any ``[environment]`` table) and read back by
    gonio's own scene reader (``scene_from_toml``), camera, transform, light and grid are
    what was given; in Mitsuba's dict the light points the other way (Mitsuba: where the
    light travels; gonio: towards the light) and the object's transform takes a point p
    to R (s ⊙ p) + t as gonio's mesh transform does."""
    from gonio_cli.render import Light
    from gonio_cli.render.mesh import rotation_matrix

    mi.set_variant("scalar_rgb")
    material, _ = lambertian(tmp_path)
    (tmp_path / "index.json").write_text("{}")            # only its existence is checked
    light = Light("directional", illuminant("A", GRID), direction=np.array([0.6, 0.0, 0.8]),
                  irradiance=2.5)
    scene = ref_.ReferenceScene(camera(32), material, tmp_path / "env.exr",
                                translate=np.array([0.1, -0.2, 0.3]),
                                rotate_deg=np.array([10.0, 20.0, 30.0]),
                                scale=np.array([1.5, 1.5, 1.5]), lights=(light,))
    path = ref_.write_gonio_scene(scene, tmp_path / "s.toml",
                                  {"prefiltered": tmp_path / "index.json"}, lobes=material)
    back = ref_.scene_from_toml(path, tmp_path / "env.exr")
    for key in ("eye", "target", "up", "fov_deg", "width", "height"):
        np.testing.assert_allclose(getattr(back.camera, key), getattr(scene.camera, key))
    for key in ("translate", "rotate_deg", "scale", "grid_nm"):
        np.testing.assert_allclose(getattr(back, key), getattr(scene, key))
    assert back.material == material.resolve() and back.mesh == "builtin:sphere"
    (got,) = back.lights
    np.testing.assert_allclose(got.direction, light.direction)
    np.testing.assert_allclose(got.spectrum, light.spectrum, rtol=1e-8)
    assert got.irradiance == light.irradiance

    d = ref_.mitsuba_scene_dict(back, {"type": "diffuse"}, np.ones((4, 8, 3), np.float32), 4)
    np.testing.assert_allclose(d["light0"]["direction"], -light.direction)
    p = np.array([0.3, -0.7, 0.5])
    world = d["object"]["to_world"] @ mi.ScalarPoint3f(*p)
    np.testing.assert_allclose(np.array(world), rotation_matrix(scene.rotate_deg)
                               @ (scene.scale * p) + scene.translate, rtol=1e-5)


def test_the_floor_is_the_same_square_in_both(tmp_path):
    """``floor_y``: gonio's scene gets a second object, builtin:plane turned to face +y,
    scaled and lowered, of albedo FLOOR_ALBEDO (f = ρ/π: its material's kd, no ks);
    Mitsuba's dict a rectangle taking the plane's corners to the same world points."""
    from gonio_cli.render.mesh import rotation_matrix
    from gonio_cli.render.scene import load_scene
    from gonio_cli.schemas import read_material

    mi.set_variant("scalar_rgb")
    material, _ = lambertian(tmp_path)
    (tmp_path / "index.json").write_text("{}")
    scene = ref_.ReferenceScene(camera(32), material, tmp_path / "env.exr", floor_y=-1.0)
    path = ref_.write_gonio_scene(scene, tmp_path / "s.toml",
                                  {"prefiltered": tmp_path / "index.json"}, lobes=material)
    floor = load_scene(path).objects[1]
    assert floor.mesh == "builtin:plane" and floor.translate[1] == -1.0
    kd = read_material(floor.material).params["kd"]
    np.testing.assert_allclose(kd, ref_.FLOOR_ALBEDO)
    d = ref_.mitsuba_scene_dict(scene, {"type": "diffuse"}, np.ones((4, 8, 3), np.float32), 4)
    for corner in ([1.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [1.0, -1.0, 0.0]):
        p = np.array(corner)
        want = (rotation_matrix(floor.rotate_deg) @ (np.asarray(floor.scale) * p)
                + floor.translate)
        got = np.array(d["floor"]["to_world"] @ mi.ScalarPoint3f(*p))
        np.testing.assert_allclose(got, want, atol=1e-5)
        assert abs(want[1] + 1.0) < 1e-9                      # on the floor's plane
