"""``gonio sparkle`` and sparkles in ``gonio render`` from the command line: the texture
with its metadata, one-line errors with nothing written, scene keys, the run report."""

from __future__ import annotations

import hashlib
import json
import os
import textwrap
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.imageio import read_image, write_png
from gonio_cli.schemas import Material, write_material
from gonio_cli.spectra import parse_grid

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"
PHOTOS = [SAMPLE / "sparkle" / f"photo_ti{t:02d}.png" for t in range(10, 80, 10)]
GRID = parse_grid()


def test_sparkle_writes_the_packed_texture(run_gonio, tmp_path):
    out = tmp_path / "s.png"
    res = run_gonio("sparkle", *PHOTOS, "-o", out)
    assert res.exit_code == 0, res.stderr
    img = read_image(out)
    assert img.pixels.shape == (128, 128, 1) and img.format == "uint8"
    assert json.loads(img.metadata["theta_i_deg"]) == [70, 60, 50, 40, 30, 20, 10]
    assert json.loads(img.metadata["theta_h_deg"]) == [35, 30, 25, 20, 15, 10, 5]
    assert img.metadata["rule"] == "mad" and float(img.metadata["parameter"]) == 5.0
    # the envelope of gonio_cli.artifact.image_metadata: each photo with its own hash
    assert img.metadata["schema"] == "gonio.sparkle-texture"
    assert int(img.metadata["schema_version"]) == 1 and img.metadata["gonio_version"]
    inputs = json.loads(img.metadata["inputs"])
    assert [r["path"] for r in inputs] == [os.path.relpath(p, out.parent) for p in PHOTOS]
    assert [r["sha256"] for r in inputs] == [hashlib.sha256(p.read_bytes()).hexdigest()
                                             for p in PHOTOS]
    shipped = read_image(SAMPLE / "sparkle.png").pixels
    assert np.array_equal(img.pixels, shipped)
    assert "sparkle pixels" in res.stderr


def test_rule_and_angle_order(run_gonio, tmp_path):
    out = tmp_path / "s.png"
    res = run_gonio("sparkle", *PHOTOS[::-1], "-o", out, "--theta-i", "70,60,50,40,30,20,10",
                    "--rule", "percentile", "--parameter", "2")
    assert res.exit_code == 0, res.stderr
    img = read_image(out)
    assert img.metadata["rule"] == "percentile"
    bits = np.round(img.pixels[..., 0] * 255).astype(np.uint8)
    for k in range(7):                               # 2 % of the pixels per photo
        assert (bits >> k & 1).mean() == pytest.approx(0.02, abs=0.002)


def _bad_photo(tmp_path):
    p = tmp_path / "broken.png"
    p.write_text("not an image")
    return p


def _small_photo(tmp_path):
    p = tmp_path / "small.png"
    write_png(p, np.zeros((64, 64)))
    return p


@pytest.mark.parametrize("args,match", [
    (lambda d: [*PHOTOS[:6], _bad_photo(d), "--theta-i", "10,20,30,40,50,60,70"],
     "broken.png: cannot read it"),
    (lambda d: [*PHOTOS[:6], d / "missing.png"], "missing.png: no such image file"),
    (lambda d: [*PHOTOS[:6], _small_photo(d)], "small.png: is 64x64 px"),
    (lambda d: [*PHOTOS, *PHOTOS[:2], "--theta-i", "5,10,20,30,40,50,60,70,80"],
     "9 photos; a sparkle texture holds at most 8"),
    (lambda d: [*PHOTOS[:3]], "3 photos but 7 angles"),
    (lambda d: [*PHOTOS[:2], "--theta-i", "10,x"], "'x' is not a number"),
    (lambda d: [*PHOTOS[:2], "--theta-i", "10,10"], "repeat a value"),
    (lambda d: [*PHOTOS[:2], "--theta-i", "10,20", "--rule", "otsu"], "use one of mad"),
])
def test_bad_input_is_one_line_and_writes_nothing(run_gonio, tmp_path, args, match):
    out = tmp_path / "s.png"
    res = run_gonio("sparkle", *args(tmp_path), "-o", out)
    assert res.exit_code == 2
    assert res.stderr.startswith("gonio: error:") and res.stderr.count("\n") == 1
    assert match in res.stderr
    assert not out.exists()


# ----------------------------------------------------------------------------- render --

SCENE = """
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
fov_deg = 35.0
width = 40
height = 40

[[object]]
mesh = "builtin:sphere?segments=48"
material = "paint.json"
{sparkle}

[[light]]
type = "directional"
direction = [-1.0, 1.0, 1.2]
irradiance = 3.0

[output]
ssaa = 2
tonemap = "clip"
"""


@pytest.fixture
def paint_scene(tmp_path):
    n = GRID.size
    write_material(tmp_path / "paint.json", Material(
        "cook-torrance", GRID, {"kd": np.full(n, 0.05), "ks": np.full(n, 0.3),
                                "m": np.full(n, 0.25), "f0": np.full(n, 0.05)}))

    def make(sparkle: str) -> Path:
        path = tmp_path / "scene.toml"
        path.write_text(textwrap.dedent(SCENE).replace("{sparkle}", sparkle))
        return path

    return make


def test_render_with_sparkles_reports_them(run_gonio, paint_scene, tmp_path):
    spark = f'sparkle = "{SAMPLE / "sparkle.png"}"\nsparkle_scale = 4\n' \
            'sparkle_color = [1.0, 0.9, 0.8]'
    reports = {}
    for name, extra in (("plain", ""), ("sparkle", spark)):
        res = run_gonio("render", paint_scene(extra), "-o", tmp_path / f"{name}.png",
                        "--exr", tmp_path / f"{name}.exr", "--report", tmp_path / f"{name}.json")
        assert res.exit_code == 0, res.stderr
        reports[name] = json.loads((tmp_path / f"{name}.json").read_text())
    stages = {n: [s["stage"] for s in reports[n]["stages"]] for n in reports}
    assert "sparkles" in stages["sparkle"] and "sparkles" not in stages["plain"]
    shade = reports["sparkle"]["counts"]["shade"]
    assert shade["sparkle_pixels"] > 0
    assert "sparkle_pixels" not in reports["plain"]["counts"]["shade"]
    assert os.path.relpath(SAMPLE / "sparkle.png", tmp_path) in [
        i["path"] for i in reports["sparkle"]["inputs"]]
    a = read_image(tmp_path / "plain.exr").pixels
    b = read_image(tmp_path / "sparkle.exr").pixels
    assert np.all(b >= a - 1e-6) and np.any(b > a + 1e-3)       # light is only added


@pytest.mark.parametrize("extra,match", [
    ('sparkle = "nope.png"', "[[object]] 1 sparkle: no such file 'nope.png'"),
    ("sparkle_scale = 2.0", "[[object]] 1 sparkle_scale: needs a sparkle texture"),
    (f'sparkle = "{SAMPLE / "sparkle.png"}"\nsparkle_scale = 0',
     "sparkle_scale: 0 is below or at 0.0"),
    (f'sparkle = "{SAMPLE / "sparkle.png"}"\nsparkle_color = [1.0, -1.0, 0.0]',
     "sparkle_color: [1.0, -1.0, 0.0] has a negative channel"),
    (f'sparkle = "{SAMPLE / "sparkle.png"}"\nsparkle_exponent = "24"',
     "sparkle_exponent: '24' is a string, expected a number"),
    (f'sparkle = "{SAMPLE / "sparkle" / "photo_ti10.png"}"',
     "photo_ti10.png: is a gonio.sparkle-photo, not a sparkle texture"),
    (f'sparkle = "{SAMPLE / "scenes" / "sheet.obj"}"', "sheet.obj: cannot read it"),
])
def test_bad_sparkle_keys_are_one_line(run_gonio, paint_scene, tmp_path, extra, match):
    out = tmp_path / "x.png"
    res = run_gonio("render", paint_scene(extra), "-o", out)
    assert res.exit_code == 2, res.stderr
    assert res.stderr.count("\n") == 1 and match in res.stderr, res.stderr
    assert not out.exists()
