"""Environment light (gonio_cli.render.environment): loading, closed forms, brute force."""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import envmap
from gonio_cli.artifact import make_document, write_json
from gonio_cli.errors import ArtifactError, InputError
from gonio_cli.geometry import cosines
from gonio_cli.imageio import write_exr
from gonio_cli.lobes.samples import sample_set
from gonio_cli.lobes.solve import fit_weight_table
from gonio_cli.prefilter import prefilter
from gonio_cli.render import Stats
from gonio_cli.render.environment import (Environment, environment_xyz, load_environment,
                                          rgb_basis, view_interpolation)
from gonio_cli.render.shade import shade
from gonio_cli.render.surface import Surface
from gonio_cli.schemas import Lobes
from gonio_cli.spectra import cmfs

from test_render_shade import WL, delta_e, ink, sphere_gbuffer

RGB = np.array([0.5, 0.25, 2.0], dtype=np.float32)     # exact in float32


def write_env(folder, exponents, value=RGB, shape=(8, 16)):
    """A prefiltered folder whose every map is the constant ``value`` (what ``gonio
    prefilter`` makes of a constant environment: P_E = c for every E)."""
    folder.mkdir(parents=True, exist_ok=True)
    maps = []
    for e in exponents:
        name = f"prefiltered_E{e:g}.exr".replace(".", "p", 1 if "." in f"{e:g}" else 0)
        write_exr(folder / name, np.broadcast_to(value, shape + (3,)).copy())
        maps.append({"exponent": float(e), "path": name, "width": shape[1], "height": shape[0]})
    doc = make_document("gonio.prefilter", 1, {"diffuse": maps[0]["path"], "maps": maps})
    write_json(folder / "index.json", doc)
    return folder / "index.json"


def lobes_of(kd, kdd, kg, exponents, views=(0.0, 40.0, 80.0)):
    v = len(views)
    return Lobes(np.asarray(exponents, float), "spectral", list(WL), np.asarray(views, float),
                 np.broadcast_to(kd, (v, WL.size)).copy(),
                 np.broadcast_to(kdd, (v, len(exponents), WL.size)).copy(),
                 np.broadcast_to(kg, (v, len(exponents), WL.size)).copy(), {}, "nnls", "test",
                 [0] * v)


def xyz_of_spectrum(s):
    cm = cmfs(WL)
    return s @ cm / cm[:, 1].sum()


def env_spectrum(rgb=RGB):
    """docs/conventions.md: linear sRGB radiance → D65(λ) Σ_c rgb_c B_c(λ)."""
    return np.asarray(rgb, float) @ rgb_basis(WL)


# ------------------------------------------------------------------------------- loading --

def test_load_environment_reads_index_lazily(tmp_path):
    index = write_env(tmp_path / "env", [1.0, 8.0, 64.0])
    env = load_environment(index)
    np.testing.assert_array_equal(env.exponents, [1.0, 8.0, 64.0])
    assert env.maps == {}                                  # nothing read yet
    np.testing.assert_array_equal(env.map(8.0)[3, 5], RGB)
    assert list(env.maps) == [8.0]


def test_load_environment_errors(tmp_path):
    index = write_env(tmp_path / "env", [1.0, 8.0])
    (tmp_path / "env" / "prefiltered_E8.exr").unlink()
    with pytest.raises(ArtifactError, match="does not exist"):
        load_environment(index)
    no_diffuse = write_env(tmp_path / "nodiff", [2.0, 8.0])
    with pytest.raises(ArtifactError, match="no diffuse map"):
        load_environment(no_diffuse)
    env = load_environment(write_env(tmp_path / "ok", [1.0, 8.0]))
    lob = lobes_of(0.0, 0.0, 0.1, [16.0])
    with pytest.raises(InputError, match="exponent 16 has no prefiltered map"):
        environment_xyz(env, lob, np.array([[0, 0, 1.0]]), np.array([[0, 0, 1.0]]), WL)
    bad = write_env(tmp_path / "bad", [1.0], shape=(4, 8))
    (tmp_path / "bad" / "prefiltered_E1.exr").unlink()
    write_exr(tmp_path / "bad" / "prefiltered_E1.exr", np.ones((5, 8, 3), np.float32))
    with pytest.raises(ArtifactError, match="the index says"):
        load_environment(bad).diffuse


def test_rgb_white_is_d65_with_y_one():
    xyz = xyz_of_spectrum(env_spectrum([1.0, 1.0, 1.0]))
    assert xyz[1] == pytest.approx(1.0, rel=1e-3)           # the basis sums to ~1
    assert xyz[0] / xyz.sum() == pytest.approx(0.3127, abs=2e-3)   # D65 chromaticity


# --------------------------------------------------------------------------- closed forms --

def test_constant_environment_lambertian_exact(tmp_path):
    """All maps constant c and K_D only: L = K_D π c(λ), exactly (P_1 = c everywhere)."""
    env = load_environment(write_env(tmp_path / "env", [1.0, 8.0]))
    kd = np.linspace(0.05, 0.3, WL.size)
    lob = lobes_of(kd, 0.0, 0.0, [8.0])
    rng = np.random.default_rng(2)
    n = rng.normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    v = n + 0.5 * rng.normal(size=(50, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    got = environment_xyz(env, lob, n, v, WL)
    expected = xyz_of_spectrum(kd * np.pi * env_spectrum())
    np.testing.assert_allclose(got, np.broadcast_to(expected, got.shape), rtol=1e-12)


def test_constant_environment_lobes_closed_form(tmp_path):
    """Gloss and directional-diffuse lobes under a constant c: Σ K 2π/(E+1) c, the
    directional diffuse one times R·N = N·V (seed 001 eqs. 7-8)."""
    env = load_environment(write_env(tmp_path / "env", [1.0, 4.0, 30.0]))
    kg = np.array([0.2, 0.05])[:, None] * np.ones(WL.size)
    kdd = np.array([0.1, 0.3])[:, None] * np.ones(WL.size)
    lob = lobes_of(0.0, kdd, kg, [4.0, 30.0])
    t = np.radians(35.0)
    n, v = np.array([[0.0, 0.0, 1.0]]), np.array([[np.sin(t), 0.0, np.cos(t)]])
    got = environment_xyz(env, lob, n, v, WL)[0]
    s = 2 * np.pi / (np.array([4.0, 30.0]) + 1)
    k = (s * (np.array([0.2, 0.05]) + np.cos(t) * np.array([0.1, 0.3]))).sum()
    np.testing.assert_allclose(got, k * xyz_of_spectrum(env_spectrum()), rtol=1e-12)


def test_weights_interpolate_linearly_in_view_angle(tmp_path):
    env = load_environment(write_env(tmp_path / "env", [1.0]))
    lob = lobes_of(0.0, 0.0, 0.0, [1.0], views=(0.0, 40.0, 80.0))
    lob.diffuse[:] = np.array([1.0, 2.0, 4.0])[:, None]
    n = np.array([[0.0, 0.0, 1.0]] * 4)
    theta = np.radians([0.0, 20.0, 60.0, 89.0])
    v = np.stack([np.sin(theta), 0 * theta, np.cos(theta)], -1)
    y = environment_xyz(env, lob, n, v, WL)[:, 1]
    y1 = xyz_of_spectrum(np.pi * env_spectrum())[1]
    np.testing.assert_allclose(y / y1, [1.0, 1.5, 3.0, 4.0], rtol=1e-9)  # 89° clamps to 80°
    i0, i1, t = view_interpolation(np.cos(np.radians([10.0])), [0.0, 40.0, 80.0])
    assert (i0[0], i1[0]) == (0, 1) and t[0] == pytest.approx(0.25)


def test_no_environment_work_without_environment():
    stats = Stats()
    shade(sphere_gbuffer(8), [Surface(material=ink(0.2, 620))], [], WL, stats=stats)
    assert stats.counts["shade"]["environment_pixels"] == 0
    assert "shade.environment" not in stats.time_s


def test_printed_object_under_environment(tmp_path):
    """Printed pixels mix the inks' environment light by coverage, over the substrate."""
    env = load_environment(write_env(tmp_path / "env", [1.0, 3.0]))
    kds = [0.1, 0.2, 0.3]
    lobes = [lobes_of(k, 0.0, 0.0, [3.0]) for k in kds]
    cov = np.array([0.2, 0.3, 0.1])
    substrate = {"kd": 0.05, "ks": 0.01, "shininess": 3.0}
    surf = Surface(inks=[ink(0.2, 620)] * 3, lobes=lobes, substrate=substrate,
                   coverage=lambda uv, fp: np.broadcast_to(cov, uv.shape[:-1] + (3,)))
    g = sphere_gbuffer(3)
    got = shade(g, [surf], [], WL, environment=env)[1, 1]
    one = xyz_of_spectrum(env_spectrum())
    # inks: Σ cov K_D π c; substrate: kd c + ks (n+2)/(2π) 2π/(n+1) (N·V) c, N·V = 1
    expected = (np.pi * (cov @ kds) + 0.4 * (0.05 + 0.01 * 5.0 / 4.0)) * one
    np.testing.assert_allclose(got, expected, rtol=1e-12)


# ---------------------------------------------------------------------------- brute force --

def sky(height):
    """A smooth sky (linear sRGB): blue gradient and a soft bright glow."""
    d = envmap.pixel_directions(height, 2 * height)
    y = d[..., 1]
    base = np.clip(np.stack([0.3 + 0.2 * y, 0.4 + 0.2 * y, 0.6 + 0.3 * y], -1), 0.05, None)
    sun = np.array([0.5, 0.6, 0.62]) / np.linalg.norm([0.5, 0.6, 0.62])
    return base + np.exp(8.0 * (d @ sun - 1.0))[..., None] * np.array([3.0, 2.8, 2.4])


#: The basis: the widest lobes for the matte ink up to E = 300 for α = 0.1 (σ ≈ 3°).
EXPONENTS = [3.0, 8.0, 20.0, 50.0, 120.0, 300.0]
#: The view angles of the weight table (``gonio lobes fit``'s default).
VIEWS = np.arange(0.0, 90.0, 10.0)


def hemisphere_lobes(material) -> Lobes:
    """Lobe weights as ``gonio lobes fit --samples hemisphere --solver nnls`` fits them:
    f cos θi at lights all over the hemisphere, per view angle."""
    table = fit_weight_table(material, EXPONENTS, sample_set("hemisphere", VIEWS),
                             solver="nnls", compare=())
    return Lobes(table.exponents, "spectral", table.channels, table.view_angle_deg,
                 table.diffuse, table.directional_diffuse, table.gloss, {}, table.solver,
                 "hemisphere", table.n_samples)


@pytest.fixture(scope="module")
def sky_case():
    height = 64
    radiance = sky(height)
    results = prefilter(radiance, EXPONENTS, check=False)
    env = Environment("memory", np.array([r.exponent for r in results]),
                      [""] * len(results), [r.pixels.shape[:2] for r in results],
                      {float(r.exponent): r.pixels for r in results})
    g = sphere_gbuffer(20)
    inside = g.covered & (g.normal[..., 2] > 0.2)          # interior: θv < 78°
    normals, views = g.normal[inside], g.view[inside]
    dirs = envmap.pixel_directions(height, 2 * height).reshape(-1, 3)
    omega = envmap.solid_angles(height, 2 * height).reshape(-1)
    spectra = radiance.reshape(-1, 3) @ rgb_basis(WL)
    cm = cmfs(WL) / cmfs(WL)[:, 1].sum()
    return env, normals, views, dirs, omega, spectra, cm


def brute_force(material, case):
    """∫ f L cos θi dω over the map's texels (texel centres, exact solid angles)."""
    env, normals, views, dirs, omega, spectra, cm = case
    out = []
    for n, v in zip(normals, views):
        ci = dirs @ n
        up = ci > 0
        f = material.evaluate(cosines(dirs[up], v[None], n[None]))
        out.append(((f * spectra[up]) * (ci[up] * omega[up])[:, None]).sum(0) @ cm)
    return np.array(out)


MATTE, GLOSSY = ink(0.35, 620.0), ink(0.1, 530.0)


@pytest.mark.parametrize("material", [MATTE, GLOSSY], ids=["matte", "glossy"])
def test_environment_matches_brute_force(material, sky_case):
    """The lobe path (eqs. 7-9) against brute-force integration of the BRDF itself.

    Measured on these 300 interior pixels (θv < 78°): mean CIEDE2000 1.81 (matte,
    α = 0.35; p99 4.5, worst at θv ≈ 37°) and 0.72 (glossy, α = 0.1; p99 2.0, worst at
    grazing). What is left is seed 001's own approximations: circular lobes about R,
    (R·N) for L·N in eq. 7, and the prefilter integrating each lobe over the whole sphere,
    light from below the horizon included, which the wide lobes (E = 3, 8) of a matte ink
    feel most; plus the bilinear lookup of 64-row maps. Asserted: the target's mean < 2,
    and p99 < 5 (the measured 4.5 with a margin; the computation is deterministic).
    """
    env, normals, views = sky_case[:3]
    got = environment_xyz(env, hemisphere_lobes(material), normals, views, WL)
    ref = brute_force(material, sky_case)
    de = delta_e(got, ref, ref[:, 1].max())
    assert de.mean() < 2.0
    assert np.percentile(de, 99) < 5.0


@pytest.mark.xfail(strict=True, reason="gonio lobes fit samples only the plane of incidence "
                   "(seed 001 §4): its circular lobes are ~2x too wide out of the plane at "
                   "oblique views (mean CIEDE2000 ~6-8 against brute force); --samples "
                   "hemisphere (test above) meets the target's < 2")
@pytest.mark.parametrize("material", [MATTE, GLOSSY], ids=["matte", "glossy"])
def test_in_plane_lobe_fit_matches_brute_force(material, sky_case):
    env, normals, views = sky_case[:3]
    table = fit_weight_table(material, EXPONENTS, sample_set("seed001", VIEWS), compare=())
    lobes = Lobes(table.exponents, "spectral", table.channels, table.view_angle_deg,
                  table.diffuse, table.directional_diffuse, table.gloss, {}, table.solver,
                  "seed001", table.n_samples)
    got = environment_xyz(env, lobes, normals, views, WL)
    ref = brute_force(material, sky_case)
    assert delta_e(got, ref, ref[:, 1].max()).mean() < 2.0
