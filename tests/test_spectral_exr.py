"""``gonio render --spectral-exr`` and ``--exr-space``: the spectral OpenEXR layout
(Fichet et al. 2021) read back by colour-science, its spectra against a closed form, their
colour against the colour EXR, and the colour EXR's spaces against colour-science.

colour-science is the independent truth here: its reader, its CMF table, its illuminant
table, its Bradford transform and its RGB colour spaces (gonio computes its own from the
cached tables, :mod:`gonio_cli.spectra`)."""

from __future__ import annotations

import json
import os
import textwrap

import numpy as np
import pytest

from gonio_cli.imageio import read_image
from gonio_cli.schemas import Material, write_material
from gonio_cli.spectra import parse_grid

import colour

GRID = parse_grid()

#: Two spheres (goniochromatic: the table path; Torrance-Sparrow: its closed form) under a
#: D65 directional light and an illuminant-A point light, so the scene white is not D65
#: and the adaptation matters.
SCENE = """
[camera]
eye = [0.0, 0.0, 6.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_deg = 35.0
width = 40
height = 24

[[object]]
mesh = "builtin:sphere?segments=48"
material = "ink.json"
translate = [-1.1, 0.0, 0.0]

[[object]]
mesh = "builtin:sphere?segments=48"
material = "ts.json"
translate = [1.1, 0.0, 0.0]

[[light]]
type = "directional"
direction = [1.0, 1.0, 1.0]
irradiance = 3.0
spectrum = "D65"

[[light]]
type = "point"
position = [-2.0, 0.0, 3.0]
intensity = 20.0
spectrum = "A"

[output]
ssaa = 2
"""

#: A plane filling the view, lit at normal incidence by E = π: a Lambertian material
#: (Cook-Torrance with ks = 0, f = kd / π) then has L(λ) = kd(λ) S(λ) at every pixel.
PLANE = """
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_deg = 10.0
width = 8
height = 6

[[object]]
mesh = "builtin:plane"
material = "lambert.json"

[[light]]
type = "directional"
direction = [0.0, 0.0, 1.0]
irradiance = 3.141592653589793
spectrum = "D65"

[output]
ssaa = 2
"""

KD = np.linspace(0.1, 0.9, GRID.size)
#: A green ink narrow enough to lie outside sRGB (but mostly inside ACEScg's AP1).
SATURATED = 0.01 + 0.4 * np.exp(-(((GRID - 540.0) / 25.0) ** 2))


@pytest.fixture
def scene(tmp_path):
    n = GRID.size
    write_material(tmp_path / "ink.json", Material(
        "goniochromatic", GRID, {"alpha": 0.2, "rho": SATURATED,
                                 "c": np.linspace(5.0, 0.4, n)}))
    write_material(tmp_path / "ts.json", Material(
        "torrance-sparrow", GRID, {"alpha": 0.3, "f0": np.linspace(0.9, 0.05, n)}))
    path = tmp_path / "scene.toml"
    path.write_text(textwrap.dedent(SCENE))
    return path


def cmfs_colour(wavelength_nm) -> np.ndarray:
    """colour-science's CIE 1931 2° table at the grid's wavelengths (10 nm samples of its
    1 nm table: no interpolation), (n_λ, 3)."""
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    return np.array([cmfs[float(w)] for w in wavelength_nm])


def integrate(spectra, wavelength_nm) -> np.ndarray:
    """XYZ = Σλ L cmf / Σλ ȳ (docs/conventions.md) with colour-science's table."""
    cm = cmfs_colour(wavelength_nm)
    return np.asarray(spectra, dtype=float) @ cm / cm[:, 1].sum()


def relative(a, b) -> np.ndarray:
    """Per pixel: the largest channel difference over the pixel's largest |value| (a
    channel near 0 by cancellation, as in sRGB, does not blow it up); lit pixels only."""
    scale = np.abs(b).max(axis=-1)
    lit = scale > 1e-6 * scale.max()
    return np.abs(a - b).max(axis=-1)[lit] / scale[lit]


def render(run_gonio, scene, tmp_path, *args, name="o"):
    out = {"png": tmp_path / f"{name}.png", "exr": tmp_path / f"{name}.exr",
           "spectra": tmp_path / f"{name}.spectra.exr"}
    r = run_gonio("render", scene, "-o", out["png"], "--exr", out["exr"], "--spectral-exr",
                  out["spectra"], *args)
    assert r.exit_code == 0, r.stderr
    return out


def read_spectra(path):
    components, spec = colour.io.read_spectral_image_Fichet2021(path, additional_data=True)
    assert list(components) == ["S0"]                 # emissive, not polarised
    wavelength_nm, values = components["S0"]
    return np.asarray(wavelength_nm, float), np.asarray(values, float), spec


def test_lambertian_plane_has_the_closed_form_spectrum(run_gonio, tmp_path):
    """f = kd/π under E = π at normal incidence: L(λ) = kd(λ) S(λ), S the D65 table
    scaled so that Σ S ȳ / Σ ȳ = 1 (docs/conventions.md), at every pixel. float32 values
    and the float32 G-buffer's cosines (~1e-7): 1e-5 relative."""
    write_material(tmp_path / "lambert.json", Material(
        "cook-torrance", GRID, {"kd": KD, "ks": np.zeros(GRID.size),
                                "m": np.full(GRID.size, 0.3), "f0": np.full(GRID.size, 0.04)}))
    scene = tmp_path / "plane.toml"
    scene.write_text(textwrap.dedent(PLANE))
    out = render(run_gonio, scene, tmp_path)
    wl, values, _ = read_spectra(out["spectra"])
    np.testing.assert_allclose(wl, GRID)
    d65 = np.array([colour.SDS_ILLUMINANTS["D65"][float(w)] for w in GRID])
    ybar = cmfs_colour(GRID)[:, 1]
    expected = KD * d65 * ybar.sum() / (d65 @ ybar)
    assert values.shape == (6, 8, GRID.size)
    np.testing.assert_allclose(values, np.broadcast_to(expected, values.shape), rtol=1e-5)


def test_spectra_read_back_and_integrate_to_the_colour_exr(run_gonio, scene, tmp_path):
    """The issue's acceptance: colour-science reads the spectra gonio computed (relative
    error < 1e-4: float32 storage is 6e-8) and Σλ L cmf / Σ ȳ is the XYZ EXR's XYZ
    (< 1e-3; measured ~1e-5: the goniochromatic table holds 1e-5, the rest is float32)."""
    from gonio_cli.render import Stats
    from gonio_cli.render.pipeline import render_scene
    from gonio_cli.render.scene import load_scene

    out = render(run_gonio, scene, tmp_path, "--exr-space", "xyz", "--adapt", "none")
    wl, values, spec = read_spectra(out["spectra"])
    frame = render_scene(load_scene(scene), Stats(), spectra=True)
    assert np.all(np.isfinite(values)) and values.min() >= 0 and values.max() > 0
    assert relative(values, frame.spectra).max() < 1e-4
    exr = read_image(out["exr"])
    assert exr.channel_names == ["X", "Y", "Z"] and exr.metadata["exr_space"] == "xyz"
    assert (exr.pixels > 0).any() and exr.pixels.min() >= 0         # XYZ is never negative
    assert relative(integrate(values, wl), exr.pixels).max() < 1e-3
    # the header: the layout's attributes (colour-science's), units and the grid (gonio's)
    attrs = {a.name: a.value for a in spec.attributes}
    assert attrs["spectralLayoutVersion"] == "1.0"
    assert attrs["emissiveUnits"] == "W.m^-2.sr^-1"
    assert attrs["gonio:grid_nm"] == "380:780:10"
    assert "Σλ L cmf / Σλ ȳ" in attrs["gonio:radiance_units"]
    assert attrs["gonio:schema"] == "gonio.render-spectra"
    assert json.loads(attrs["gonio:settings"])["adapt"] == "none"
    inputs = json.loads(attrs["gonio:inputs"])                       # provenance
    assert {i["path"] for i in inputs} == {os.path.relpath(p, out["exr"].parent) for p in
                                           (scene, tmp_path / "ink.json", tmp_path / "ts.json")}
    assert all(len(i["sha256"]) == 64 for i in inputs)
    assert attrs["gonio:gonio_version"]


def test_exact_path_gives_the_same_spectra_as_the_per_band_tables(run_gonio, scene,
                                                                   tmp_path):
    """``--spectral exact`` evaluates every wavelength; the default keeps the
    goniochromatic table with one column per wavelength: both within the table's 1e-5."""
    table = read_spectra(render(run_gonio, scene, tmp_path, name="t")["spectra"])[1]
    exact = read_spectra(render(run_gonio, scene, tmp_path, "--spectral", "exact",
                                name="e")["spectra"])[1]
    assert relative(table, exact).max() < 1e-4


def test_srgb_exr_is_the_adapted_xyz_of_the_spectra(run_gonio, scene, tmp_path):
    """The colour EXR with ``--exr-adapt bradford`` (linear sRGB after Bradford adaptation
    of the lights' white to D65, as the PNG) equals colour-science's Bradford transform
    and sRGB matrix applied to the spectra's XYZ (< 1e-3 relative: float32 and the table's
    1e-5). The default EXR, scene-referred, is the sRGB matrix alone."""
    out = render(run_gonio, scene, tmp_path, "--exr-adapt", "bradford")
    wl, values, _ = read_spectra(out["spectra"])
    xyz = integrate(values, wl)
    # the scene white: the lights' spectra weighted by E at normal incidence (point: I/d²
    # at the camera target), each with Y = 1
    cm = cmfs_colour(wl)
    white = np.zeros(3)
    for name, weight in (("D65", 3.0), ("A", 20.0 / 13.0)):
        s = np.array([colour.SDS_ILLUMINANTS[name][float(w)] for w in wl])
        white += weight * (s @ cm) / (s @ cm[:, 1])
    white /= white[1]
    srgb = colour.RGB_COLOURSPACES["sRGB"]
    d65 = np.linalg.solve(srgb.matrix_XYZ_to_RGB, np.ones(3))      # the matrix's white
    cat = colour.adaptation.matrix_chromatic_adaptation_VonKries(white, d65, "Bradford")
    expected = xyz @ (srgb.matrix_XYZ_to_RGB @ cat).T
    exr = read_image(out["exr"])
    assert exr.metadata["exr_space"] == "srgb" and exr.metadata["exr_adapt"] == "bradford"
    assert relative(exr.pixels, expected).max() < 1e-3
    # the preview R, G, B of the spectral file are the same linear sRGB
    preview = read_image(out["spectra"])
    rgb = [preview.channel_names.index(c) for c in "RGB"]
    np.testing.assert_array_equal(preview.pixels[..., rgb], exr.pixels)
    # the default: no adaptation (docs/conventions.md), the spectra's XYZ through the
    # IEC matrix; its preview too
    plain = render(run_gonio, scene, tmp_path, name="plain")
    exr = read_image(plain["exr"])
    assert exr.metadata["exr_adapt"] == "none"
    assert relative(exr.pixels, xyz @ srgb.matrix_XYZ_to_RGB.T).max() < 1e-3
    assert relative(exr.pixels, expected).max() > 1e-2        # the adaptation matters here
    preview = read_image(plain["spectra"])
    np.testing.assert_array_equal(preview.pixels[..., rgb], exr.pixels)


def test_exr_spaces_against_colour_science(run_gonio, scene, tmp_path):
    """ACEScg = colour-science's sRGB → ACEScg with Bradford (2e-4 relative: its sRGB
    matrix is the IEC one rounded to 4 decimals, whose white lies 4e-5 from the xy white
    point it adapts from); each header names its space."""
    import OpenImageIO as oiio

    srgb = read_image(render(run_gonio, scene, tmp_path, name="s")["exr"])
    paths = {}
    for space in ("acescg", "xyz"):
        paths[space] = tmp_path / f"{space}.exr"
        r = run_gonio("render", scene, "-o", tmp_path / "o.png", "--exr", paths[space],
                      "--exr-space", space)
        assert r.exit_code == 0, r.stderr
    aces = read_image(paths["acescg"])
    expected = colour.RGB_to_RGB(srgb.pixels, "sRGB", "ACEScg",
                                 chromatic_adaptation_transform="Bradford")
    assert relative(aces.pixels, expected).max() < 2e-4
    assert (srgb.pixels < 0).sum() > (aces.pixels < 0).sum()     # AP1 holds more colours

    def chromaticities(path):
        inp = oiio.ImageInput.open(str(path))
        try:
            return np.asarray(inp.spec().getattribute("chromaticities"), float)
        finally:
            inp.close()

    for space, name in (("srgb", "sRGB"), ("acescg", "ACEScg")):
        cs = colour.RGB_COLOURSPACES[name]
        path = tmp_path / "s.exr" if space == "srgb" else paths[space]
        np.testing.assert_allclose(chromaticities(path),
                                   np.r_[cs.primaries.ravel(), cs.whitepoint], atol=1e-7)
    # OpenEXR's convention for XYZ data: red (1, 0), green (0, 1), blue (0, 0), white ⅓
    np.testing.assert_allclose(chromaticities(paths["xyz"]),
                               [1, 0, 0, 1, 0, 0, 1 / 3, 1 / 3], atol=1e-7)
    # the display white is (1, 1, 1) in every RGB space
    from gonio_cli.render.tonemap import EXR_SPACES, xyz_to_exr_matrix
    from gonio_cli.spectra import srgb_white_xyz

    for space in ("srgb", "acescg"):
        np.testing.assert_allclose(xyz_to_exr_matrix(space) @ srgb_white_xyz(), 1.0,
                                   atol=1e-12)
    from gonio_cli.commands import render as shell

    assert shell.EXR_SPACE_NAMES == tuple(EXR_SPACES)


def test_spectral_image_beyond_the_machine_is_refused(run_gonio, scene, tmp_path,
                                                      monkeypatch):
    """Memory for the frame but not for H × W × n_λ: one line with the estimate and the
    options that lower it, exit 2, nothing written (and the same frame without
    --spectral-exr still renders)."""
    from gonio_cli.render import budget
    from gonio_cli.render.scene import load_scene

    sc = load_scene(scene)
    plain, spectral = budget.memory_estimate(sc), budget.memory_estimate(sc, True)
    assert spectral - plain >= sc.camera.width * sc.camera.height * GRID.size * 4
    from gonio_cli import memory

    have = int((plain + spectral) / 2 / memory.MARGIN)
    monkeypatch.setattr(memory, "available_bytes", lambda: (have, "test memory"))
    png, spec = tmp_path / "o.png", tmp_path / "s.exr"
    r = run_gonio("render", scene, "-o", png, "--spectral-exr", spec)
    assert r.exit_code == 2 and r.stderr.count("\n") == 1, r.stderr
    assert ("a 40x24 spectral image on 41 wavelengths with the frame's buffers needs about"
            in r.stderr)
    assert "coarser --grid-nm" in r.stderr
    assert not png.exists() and not spec.exists()
    assert run_gonio("render", scene, "-o", png).exit_code == 0


@pytest.mark.parametrize("args, message", [
    (["--exr-space", "rec2020"], "--exr-space 'rec2020' is unknown"),
    (["--spectral-exr", "s.png"], "not an .exr name"),
])
def test_bad_options_are_one_line(run_gonio, scene, tmp_path, args, message):
    r = run_gonio("render", scene, "-o", tmp_path / "o.png", *args)
    assert r.exit_code == 2 and r.stderr.count("\n") == 1 and message in r.stderr
    assert not (tmp_path / "o.png").exists()


# ----------------------------------------------------- the shading's spectral channels --

def test_environment_and_print_give_the_closed_form_spectrum(tmp_path):
    """A printed sphere (three inks by coverage over a Phong substrate) under a constant
    environment c(λ): with one channel per wavelength the shading returns the spectrum
    of the closed form (tests/test_render_environment.py's, per wavelength), and under
    lights too its Σλ L cmf / Σ ȳ is the XYZ path's (float64 throughout: 1e-10)."""
    from gonio_cli.render import Light
    from gonio_cli.render.environment import load_environment
    from gonio_cli.render.shade import shade_rows
    from gonio_cli.render.surface import Surface
    from gonio_cli.spectra import illuminant
    from test_render_environment import env_spectrum, lobes_of, write_env
    from test_render_shade import ink, sphere_gbuffer

    env = load_environment(write_env(tmp_path / "env", [1.0, 3.0]))
    kds = [0.1, 0.2, 0.3]
    cov = np.array([0.2, 0.3, 0.1])
    surface = Surface(inks=[ink(0.2, 620), ink(0.3, 540), ink(0.25, 460)],
                      lobes=[lobes_of(k, 0.0, 0.0, [3.0]) for k in kds],
                      substrate={"kd": 0.05, "ks": 0.01, "shininess": 3.0},
                      coverage=lambda uv, fp: np.broadcast_to(cov, uv.shape[:-1] + (3,)))
    g = sphere_gbuffer(3)
    eye = np.eye(GRID.size)
    spectra = shade_rows(g, [surface], [], GRID, environment=env, observer=eye)
    assert spectra.shape == (9, GRID.size)
    # centre pixel, N·V = 1: Σ cov K_D π c + (1 − Σ cov)(kd + ks (n+2)/(n+1) N·V) c
    expected = (np.pi * (cov @ kds) + 0.4 * (0.05 + 0.01 * 5.0 / 4.0)) * env_spectrum()
    np.testing.assert_allclose(spectra[4], expected, rtol=1e-12)

    lights = [Light("directional", direction=np.array([1.0, 1.0, 1.0]), irradiance=2.0,
                    spectrum=illuminant("D65", GRID)),
              Light("point", position=np.array([-1.0, 0.5, 2.0]), intensity=5.0,
                    spectrum=illuminant("A", GRID))]
    g = sphere_gbuffer(16)
    for spectral in ("table", "exact"):
        xyz = shade_rows(g, [surface], lights, GRID, environment=env, spectral=spectral)
        spectra = shade_rows(g, [surface], lights, GRID, environment=env, spectral=spectral,
                             observer=eye)
        assert np.all(spectra >= 0)
        # the table path's tolerance (1e-5 relative) bounds "table"; "exact" is one sum
        tol = 1e-5 if spectral == "table" else 1e-10
        assert relative(integrate(spectra, GRID), xyz).max() < tol


def test_xyz_lobes_cannot_give_a_spectral_image(tmp_path):
    """Lobe weights fitted in XYZ channels have no spectrum: refused, not guessed."""
    from gonio_cli.errors import InputError
    from gonio_cli.render.environment import environment_xyz, load_environment
    from gonio_cli.schemas import Lobes
    from test_render_environment import write_env

    env = load_environment(write_env(tmp_path / "env", [1.0, 3.0]))
    v = 2
    lobes = Lobes(np.array([3.0]), "xyz", ["X", "Y", "Z"], np.array([0.0, 80.0]),
                  np.full((v, 3), 0.1), np.zeros((v, 1, 3)), np.zeros((v, 1, 3)), {},
                  "nnls", "test", [0] * v)
    n = np.array([[0.0, 0.0, 1.0]])
    assert environment_xyz(env, lobes, n, n, GRID).shape == (1, 3)
    with pytest.raises(InputError, match="XYZ channels have no spectrum"):
        environment_xyz(env, lobes, n, n, GRID, observer=np.eye(GRID.size))


def test_xyz_lobes_are_refused_before_rendering(run_gonio, scene, tmp_path):
    """From the command line: one line naming the object, its lobes file and the fix;
    the same scene renders its colour image."""
    from gonio_cli.schemas import Lobes, write_lobes
    from test_render_environment import write_env

    write_env(tmp_path / "sky", [1.0, 3.0])
    v = 2
    xyz = Lobes(np.array([3.0]), "xyz", ["X", "Y", "Z"], np.array([0.0, 80.0]),
                np.full((v, 3), 0.1), np.zeros((v, 1, 3)), np.zeros((v, 1, 3)), {},
                "nnls", "test", [0] * v)
    write_lobes(tmp_path / "x.lobes.json", xyz)
    text = scene.read_text().replace('material = "ink.json"',
                                     'material = "ink.json"\nlobes = "x.lobes.json"')
    text = text.replace('material = "ts.json"', 'material = "ts.json"\nlobes = "x.lobes.json"')
    scene.write_text(text + '\n[environment]\nprefiltered = "sky/index.json"\n')
    png, spec = tmp_path / "o.png", tmp_path / "s.exr"
    r = run_gonio("render", scene, "-o", png, "--spectral-exr", spec)
    assert r.exit_code == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "[[object]] 1 lobes = x.lobes.json: weights fitted in xyz channels" in r.stderr
    assert "--channels spectral" in r.stderr
    assert not png.exists() and not spec.exists()
    assert run_gonio("render", scene, "-o", png).exit_code == 0
