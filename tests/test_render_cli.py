"""``gonio render`` from the command line: PNG 8-bit, EXR linear with metadata, the run
report, options, and input errors (one stderr line, exit 2, nothing written)."""

from __future__ import annotations

import hashlib
import json
import textwrap
from pathlib import Path

import numpy as np
import pytest

import gonio_cli

from gonio_cli.imageio import read_image
from gonio_cli.schemas import Material, write_material
from gonio_cli.spectra import parse_grid

GRID = parse_grid()

SCENE = """
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_deg = 35.0
width = 48
height = 32

[[object]]
mesh = "builtin:sphere?segments=48"
material = "red.json"

[[light]]
type = "directional"
direction = [1.0, 1.0, 1.0]
irradiance = 3.0
spectrum = "D65"

[[light]]
type = "point"
position = [-2.0, 0.0, 2.0]
intensity = 8.0
spectrum = "A"

[output]
ssaa = 2
tonemap = "reinhard"
exposure = 1.0
"""


@pytest.fixture
def scene(tmp_path):
    n = GRID.size
    write_material(tmp_path / "red.json", Material(
        "goniochromatic", GRID, {"alpha": 0.2, "rho": np.linspace(0.02, 0.3, n),
                                 "c": np.linspace(5.0, 0.4, n)}))
    path = tmp_path / "scene.toml"
    path.write_text(textwrap.dedent(SCENE))
    return path


def test_png_exr_and_report(run_gonio, scene, tmp_path):
    png, exr, rep = tmp_path / "o.png", tmp_path / "o.exr", tmp_path / "run.json"
    r = run_gonio("render", scene, "-o", png, "--exr", exr, "--report", rep)
    assert r.exit_code == 0, r.stderr
    assert r.stdout == ""
    # PNG: 8-bit sRGB, the camera's size
    img = read_image(png)
    assert img.format == "uint8" and img.pixels.shape == (32, 48, 3)
    # EXR: float32 scene-linear sRGB, before exposure; settings (never a time) in metadata
    lin = read_image(exr)
    assert lin.format == "float" and lin.pixels.shape == (32, 48, 3)
    assert lin.pixels.max() > 0 and np.all(np.isfinite(lin.pixels))
    meta = lin.metadata
    assert meta["schema"] == "gonio.render" and "render_time_s" not in meta   # the report's
    assert "DateTime" not in meta             # nor a date (no SOURCE_DATE_EPOCH): same bytes
    assert int(meta["schema_version"]) == 1 and meta["gonio_version"] == gonio_cli.__version__
    inputs = json.loads(meta["inputs"])
    assert inputs[0] == {"path": "scene.toml",          # relative to the image's folder
                         "sha256": hashlib.sha256(Path(scene).read_bytes()).hexdigest()}
    png_meta = read_image(png).metadata       # the same envelope, inputs left out (why:
    assert png_meta["schema_version"] == "1" and "inputs" not in png_meta   # write_outputs)
    settings = json.loads(meta["settings"])
    assert settings["ssaa"] == 2 and settings["spectral"] == "table"
    assert settings["exposure"] == 1.0 and settings["tonemap"] == "reinhard"
    assert settings["camera"]["width"] == 48 and settings["camera"]["fov_deg"] == 35.0
    # the PNG is the EXR after the display's adaptation (the EXR is scene-referred:
    # docs/conventions.md), +1 stop, Reinhard and sRGB encoding (same pixels)
    from gonio_cli.render.tonemap import display, xyz_to_exr_matrix, xyz_to_linear_matrix

    assert meta["exr_adapt"] == "none" and settings["adapt"] == "bradford"
    white = np.array(settings["scene_white_xyz"])
    adapt = xyz_to_linear_matrix("bradford", white) @ np.linalg.inv(xyz_to_exr_matrix())
    expected = display((lin.pixels @ adapt.T).astype(np.float32), 1.0, "reinhard")
    assert np.abs(np.round(img.pixels * 255).astype(int) - expected).max() <= 1
    # report (a run record: it keeps its times): each stage that ran, with time_s; the
    # total covers them
    doc = json.loads(rep.read_text())
    assert doc["schema"] == "gonio.render-report" and doc["schema_version"] == 1
    stages = [s["stage"] for s in doc["stages"]]
    assert stages == ["scene", "meshes", "materials", "rasterize", "shadows", "shade",
                      "downsample", "tonemap", "write_exr", "write_png"]
    lights = doc["counts"]["shadows"]    # lights cast shadows by default; a lone sphere
    assert [l["skipped"] for l in lights] == ["one convex solid"] * 2      # needs no map
    assert "textures" not in stages and "environment" not in stages  # not needed here
    assert all(s["time_s"] >= 0 for s in doc["stages"])
    assert doc["time_s"] >= sum(s["time_s"] for s in doc["stages"])
    assert doc["frame_time_s"] == pytest.approx(sum(
        s["time_s"] for s in doc["stages"] if s["stage"] in doc["frame_stages"]))
    assert {i["path"] for i in doc["inputs"]} == {"scene.toml", "red.json"}
    assert all(len(i["sha256"]) == 64 for i in doc["inputs"])
    assert doc["counts"]["shade"]["spectral"] == "table"
    assert doc["outputs"] == {"png": "o.png", "exr": "o.exr", "gamut_warning": None}
    assert "frame" in r.stderr and "total" in r.stderr


def test_overrides_size_ssaa_spectral(run_gonio, scene, tmp_path):
    png, exr, rep = tmp_path / "o.png", tmp_path / "o.exr", tmp_path / "run.json"
    r = run_gonio("render", scene, "-o", png, "--exr", exr, "--report", rep, "--width", 20,
                  "--height", 10, "--ssaa", 1, "--spectral", "exact", "--tonemap", "clip",
                  "--exposure", 0)
    assert r.exit_code == 0, r.stderr
    assert read_image(png).pixels.shape == (10, 20, 3)
    doc = json.loads(rep.read_text())
    assert doc["parameters"]["ssaa"] == 1 and doc["parameters"]["spectral"] == "exact"
    assert doc["counts"]["shade"]["spectral"] == "exact"
    assert not any(n.startswith(".") for n in (p.name for p in tmp_path.iterdir()))


def test_table_and_exact_paths_agree(run_gonio, scene, tmp_path):
    """The tabulated spectral sum is an interpolation of the exact one (1e-5 relative)."""
    for mode in ("table", "exact"):
        r = run_gonio("render", scene, "-o", tmp_path / f"{mode}.png", "--exr",
                      tmp_path / f"{mode}.exr", "--spectral", mode)
        assert r.exit_code == 0, r.stderr
    a = read_image(tmp_path / "table.exr").pixels
    b = read_image(tmp_path / "exact.exr").pixels
    # table interpolation 1e-5 relative; float32 storage 6e-8
    np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-7)


def test_mask_on_a_mesh_without_uvs_is_one_line(run_gonio, scene, tmp_path):
    obj = tmp_path / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "mask.png").write_bytes(b"")
    text = textwrap.dedent(SCENE).replace(
        'mesh = "builtin:sphere?segments=48"\nmaterial = "red.json"',
        'mesh = "tri.obj"\ninks = ["red.json", "red.json", "red.json"]\nmask = "mask.png"')
    bad = tmp_path / "print.toml"
    bad.write_text(text)
    before = set(tmp_path.iterdir())
    r = run_gonio("render", bad, "-o", tmp_path / "o.png", "--exr", tmp_path / "o.exr",
                  "--report", tmp_path / "r.json")
    assert r.exit_code == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "texture coordinates" in lines[0] and "mask" in lines[0]
    assert set(tmp_path.iterdir()) == before


def test_broken_material_file_is_one_line(run_gonio, scene, tmp_path):
    (tmp_path / "red.json").write_text("{not json")
    r = run_gonio("render", scene, "-o", tmp_path / "o.png")
    assert r.exit_code == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "red.json" in lines[0] and "JSON" in lines[0]
    assert not (tmp_path / "o.png").exists()


def test_nan_in_a_material_is_refused(run_gonio, scene, tmp_path):
    doc = json.loads((tmp_path / "red.json").read_text())
    doc["rho"][3] = "NaN"
    (tmp_path / "red.json").write_text(json.dumps(doc).replace('"NaN"', "NaN"))
    r = run_gonio("render", scene, "-o", tmp_path / "o.png")
    assert r.exit_code == 2 and "red.json" in r.stderr and "NaN" in r.stderr
    assert len(r.stderr.strip().splitlines()) == 1


def test_lobes_method_without_lobes_is_one_line(run_gonio, scene, tmp_path):
    from gonio_cli.artifact import write_artifact
    from gonio_cli.imageio import write_exr

    sky = tmp_path / "sky"
    sky.mkdir()
    write_exr(sky / "e1.exr", np.ones((4, 8, 3), np.float32))
    write_artifact(sky / "index.json", "gonio.prefilter", 1,
                   {"diffuse": "e1.exr", "maps": [{"exponent": 1.0, "path": "e1.exr",
                                                   "width": 8, "height": 4}]})
    scene.write_text(scene.read_text() + '\n[environment]\nprefiltered = "sky/index.json"\n'
                     'method = "lobes"\n')
    r = run_gonio("render", scene, "-o", tmp_path / "o.png")
    assert r.exit_code == 2, r.stderr
    line = r.stderr.strip()
    assert "\n" not in line and "lobes" in line and "[[object]] 1" in line
    assert not (tmp_path / "o.png").exists()


def test_help_and_tonemap_names_match_the_registry(run_gonio):
    from gonio_cli.commands import render as shell
    from gonio_cli.render.shade import SPECTRAL_PATHS
    from gonio_cli.render.scene_types import Output
    from gonio_cli.render.tonemap import (ADAPTATIONS, DEFAULT_ADAPTATION, DEFAULT_TONEMAP,
                                          TONEMAPS)

    assert shell.TONEMAP_NAMES == tuple(TONEMAPS) and shell.SPECTRAL == SPECTRAL_PATHS
    assert shell.ADAPT_NAMES == tuple(ADAPTATIONS)
    assert (Output().tonemap, Output().adapt) == (DEFAULT_TONEMAP, DEFAULT_ADAPTATION)
    r = run_gonio("render", "--help")
    assert r.exit_code == 0 and "--exr" in r.stdout and "--report" in r.stdout
    assert "--adapt" in r.stdout and "--gamut-warning" in r.stdout


def test_other_grid_resamples_the_material_with_a_warning(run_gonio, scene, tmp_path):
    scene.write_text(scene.read_text().replace('exposure = 1.0',
                                               'exposure = 1.0\ngrid_nm = "400:700:5"'))
    r = run_gonio("render", scene, "-o", tmp_path / "o.png", "--report", tmp_path / "r.json")
    assert r.exit_code == 0, r.stderr
    assert "red.json: material resampled from 41 wavelengths" in r.stderr
    assert json.loads((tmp_path / "r.json").read_text())["parameters"]["grid_nm"] == "400:700:5"


def test_nan_samples_from_shading_are_counted_and_blacked(run_gonio, scene, tmp_path,
                                                          monkeypatch):
    """A shading NaN (a bug upstream, or a degenerate input that slipped through) never
    reaches the files: it is set to black with one warning that counts it."""
    from gonio_cli.render import pipeline as pipeline_module

    real = pipeline_module.shade_rows

    def nan_shade(*args, **kwargs):
        out = real(*args, **kwargs)           # one row per covered sample
        out[5:9] = np.nan
        return out

    monkeypatch.setattr(pipeline_module, "shade_rows", nan_shade)
    rep, exr = tmp_path / "r.json", tmp_path / "o.exr"
    r = run_gonio("render", scene, "-o", tmp_path / "o.png", "--exr", exr, "--report", rep)
    assert r.exit_code == 0, r.stderr
    assert "4 sample(s) shaded to NaN or inf were set to black" in r.stderr
    assert json.loads(rep.read_text())["counts"]["nonfinite_samples"] == 4
    assert np.all(np.isfinite(read_image(exr).pixels))


# ------------------------------------------------------------- errors a newcomer meets --

def test_var_the_scene_does_not_use_is_an_error_naming_its_variables(run_gonio, scene,
                                                                     tmp_path):
    scene.write_text(scene.read_text().replace('material = "red.json"',
                                               'material = "${ink}.json"')
                     + '\n[vars]\nink = "red"\n')
    out = tmp_path / "o.png"
    r = run_gonio("render", scene, "-o", out, "--var", "materal=green")
    assert r.exit_code == 2 and r.stderr.count("\n") == 1
    assert "--var materal: the scene uses no ${materal}" in r.stderr
    assert "its variables are ink" in r.stderr and not out.exists()
    assert run_gonio("render", scene, "-o", out, "--var", "ink=red").exit_code == 0


def test_wrong_artifact_names_the_scene_file_and_key(run_gonio, scene, tmp_path):
    """A measurement where a material is expected: the scene's key is at fault."""
    doc = json.loads((tmp_path / "red.json").read_text())
    doc["schema"] = "gonio.measurement"
    (tmp_path / "meas.json").write_text(json.dumps(doc))
    scene.write_text(scene.read_text().replace('"red.json"', '"meas.json"'))
    r = run_gonio("render", scene, "-o", tmp_path / "o.png")
    assert r.exit_code == 2 and r.stderr.count("\n") == 1
    assert (f"{scene}: [[object]] 1 material = meas.json: schema is 'gonio.measurement', "
            "expected 'gonio.material'") in r.stderr
    assert "point material at the right file" in r.stderr


def test_buffers_beyond_the_machine_are_refused_before_allocating(run_gonio, scene,
                                                                  tmp_path):
    """16384² at ssaa 16 needs petabytes: refused at once with the estimate and the
    options that lower it (if this allocated, the test would not finish)."""
    r = run_gonio("render", scene, "-o", tmp_path / "o.png", "--width", "16384",
                  "--height", "16384", "--ssaa", "16")
    assert r.exit_code == 2 and r.stderr.count("\n") == 1
    assert "a 16384x16384 render at ssaa 16 needs about" in r.stderr
    # the options named as typed (the old spellings here: gonio_cli.commands.as_typed_in)
    assert "lower --ssaa or --width/--height" in r.stderr


def test_memory_estimate_bounds_the_measured_buffers(scene):
    """The estimate is the buffers' size at full coverage: at least the G-buffer and
    shading arrays a frame really holds."""
    from gonio_cli.render.budget import memory_estimate
    from gonio_cli.render.scene import load_scene

    sc = load_scene(scene)
    samples = 48 * 32 * 4
    # keys 8 + object 4 + (position, normal, view) 36 + shaded row 12 + resolve image 12
    assert memory_estimate(sc) >= samples * (8 + 4 + 36 + 12 + 12)


def test_not_a_terminal_gives_one_summary_line_and_quiet_none(run_gonio, scene, tmp_path,
                                                              monkeypatch):
    from gonio_cli import log

    seen = []
    real = log.progress

    def spy(items, description, total=None, expected_s=None):
        seen.append((description, total))
        return real(items, description, total, expected_s)

    monkeypatch.setattr(log, "progress", spy)
    r = run_gonio("render", scene, "-o", tmp_path / "o.png")
    assert r.exit_code == 0
    assert seen == [("rendering scene.toml", 6)]          # the stages go through progress
    assert r.stderr.count("\n") == 1 and "frame" in r.stderr and "total" in r.stderr
    r = run_gonio("--quiet", "render", scene, "-o", tmp_path / "o.png")
    assert r.exit_code == 0 and r.stderr == ""


def test_help_first_sentence_is_whole(run_gonio):
    r = run_gonio("--help")
    line = next(l for l in r.stdout.splitlines() if l.strip().startswith("render "))
    assert line.rstrip().endswith(".") and line.count("(") == line.count(")"), line
    r = run_gonio("render", "--help")
    assert r.exit_code == 0 and "<list[" not in r.stdout
    assert "Render a scene to PNG (and EXR): spectral goniochromatic shading on the CPU." \
        in " ".join(r.stdout.split())


# -------------------------------------------------------------- --grid-nm, 400-700 nm --

@pytest.fixture
def material_400_700(run_gonio, tmp_path):
    """A material gonio fit made from synthetic data on 400-700 nm (as a multi-angle
    instrument measures), and the test's scene pointing at it."""
    from gonio_cli.schemas import write_measurement
    from gonio_cli.synthetic import ink_spectra, paper_geometry, synthetic_measurement

    grid = parse_grid("400:700:10")
    rho, c = ink_spectra("green", grid)
    ti, to = paper_geometry(10.0)
    write_measurement(tmp_path / "g.measurement.json", synthetic_measurement(
        "goniochromatic", {"alpha": 0.2, "rho": rho, "c": c}, ti, to, grid_nm=grid))
    r = run_gonio("fit", tmp_path / "g.measurement.json", "-o", tmp_path / "g.json")
    assert r.exit_code == 0, r.stderr
    scene = tmp_path / "scene.toml"
    scene.write_text(textwrap.dedent(SCENE).replace('"red.json"', '"g.json"'))
    return scene


def test_a_400_700_material_renders_without_editing_the_scene(run_gonio, material_400_700,
                                                              tmp_path):
    rep = tmp_path / "r.json"
    r = run_gonio("render", material_400_700, "-o", tmp_path / "a.png", "--exr",
                  tmp_path / "a.exr", "--report", rep)
    assert r.exit_code == 0, r.stderr
    warning, summary = r.stderr.splitlines()
    assert warning == (f"gonio: warning: {material_400_700}: not every material covers the "
                       "scene's grid 380-780 nm (g.json 400-700 nm): rendering on their "
                       "common range 400:700:10 nm (choose another with --grid-nm)")
    assert summary.startswith(f"{tmp_path / 'a.png'}: 48x32")
    assert json.loads(rep.read_text())["parameters"]["grid_nm"] == "400:700:10"
    # --grid-nm: the same grid given explicitly, no warning, the same image
    r = run_gonio("render", material_400_700, "-o", tmp_path / "b.png", "--exr",
                  tmp_path / "b.exr", "--grid-nm", "400:700:10")
    assert r.exit_code == 0 and r.stderr.count("\n") == 1, r.stderr
    np.testing.assert_array_equal(read_image(tmp_path / "a.exr").pixels,
                                  read_image(tmp_path / "b.exr").pixels)
    # a finer grid inside the material's range: resampled with the usual warning
    r = run_gonio("render", material_400_700, "-o", tmp_path / "c.png", "--grid-nm",
                  "420:680:5", "--report", rep)
    assert r.exit_code == 0, r.stderr
    assert "g.json: material resampled from 31 wavelengths onto the render's grid (53 " \
           "samples)" in r.stderr
    assert json.loads(rep.read_text())["parameters"]["grid_nm"] == "420:680:5"


@pytest.mark.parametrize("grid, needle", [
    ("380:780:10", "g.json: covers 400-700 nm, not the render's grid 380-780 nm; choose "
                   "--grid-nm inside its range"),
    ("400:700", "--grid-nm '400:700': '400:700' is not a number or START:STOP:STEP; one "
                "START:STOP:STEP range, in nm"),
])
def test_bad_grid_nm_is_one_line_and_nothing_written(run_gonio, material_400_700, tmp_path,
                                                     grid, needle):
    before = set(tmp_path.iterdir())
    r = run_gonio("render", material_400_700, "-o", tmp_path / "o.png", "--grid-nm", grid)
    assert r.exit_code == 2 and r.stderr.count("\n") == 1, r.stderr
    assert needle in r.stderr
    assert set(tmp_path.iterdir()) == before
