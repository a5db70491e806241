"""The colour EXR is scene-referred: no chromatic adaptation unless asked (issue 32, 5).

docs/conventions.md: linear sRGB has "no chromatic adaptation unless asked for" and EXR
files are scene-referred; the PNG, for display, is adapted (``--adapt``, Bradford by
default). A flat grey under illuminant A is the independent truth: unadapted, its linear
sRGB is proportional to the sRGB of A's white (colour-science's matrix); adapted, it is
neutral (R = G = B).
"""

from __future__ import annotations

import textwrap

import colour
import numpy as np
import pytest

from gonio_cli.imageio import read_image
from gonio_cli.schemas import Material, write_material
from gonio_cli.spectra import parse_grid

GRID = parse_grid()

#: A plane of flat grey facing the camera under one directional light of ${illuminant}.
SCENE = """
[camera]
eye = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_deg = 35.0
width = 24
height = 24

[[light]]
type = "directional"
direction = [0.3, 0.2, 1.0]
irradiance = 2.0
spectrum = "${illuminant}"

[[object]]
mesh = "builtin:plane"
material = "grey.json"

[output]
ssaa = SSAA
"""

#: float32 storage of the same XYZ through the same 3 × 3 matrix by two summation orders
#: (the rows' float32 product at ssaa 1, float64 then float32 otherwise): ~6e-8 relative;
#: 1e-6 leaves room and is far below any adaptation's effect (~10 % under A).
ROUND_OFF = 1e-6


@pytest.fixture(params=[1, 2], ids=["ssaa1", "ssaa2"])
def grey(tmp_path, request):
    n = GRID.size
    write_material(tmp_path / "grey.json", Material(
        "goniochromatic", GRID, {"alpha": 0.5, "rho": np.full(n, 0.3), "c": np.zeros(n)}))
    path = tmp_path / "grey.toml"
    path.write_text(textwrap.dedent(SCENE).replace("SSAA", str(request.param)))
    return path


def render(run_gonio, scene, tmp_path, name, *args):
    png, exr = tmp_path / f"{name}.png", tmp_path / f"{name}.exr"
    r = run_gonio("render", scene, "-o", png, "--exr", exr, "--var", "illuminant=A", *args)
    assert r.exit_code == 0, r.stderr
    return png.read_bytes(), read_image(exr)


def centre(img) -> np.ndarray:
    h, w = img.pixels.shape[:2]
    return img.pixels[h // 2 - 3:h // 2 + 3, w // 2 - 3:w // 2 + 3, :3].reshape(-1, 3)


def test_the_exr_is_scene_referred_and_the_png_adapted(run_gonio, grey, tmp_path):
    png, exr = render(run_gonio, grey, tmp_path, "default")
    png_none, exr_none = render(run_gonio, grey, tmp_path, "none", "--adapt", "none")
    # the EXR is --adapt none's: the PNG's adaptation does not reach it
    np.testing.assert_allclose(exr.pixels, exr_none.pixels, rtol=ROUND_OFF, atol=0)
    if "ssaa = 2" in grey.read_text():              # the same code path: bit for bit
        np.testing.assert_array_equal(exr.pixels, exr_none.pixels)
    # ... and it holds the light's colour: proportional to A's white in linear sRGB
    # (sums on the working grid, gonio's XYZ = Σ S cmf / Σ ȳ, with colour-science's tables;
    # 1e-4: float32 and the goniochromatic table's 1e-5, against ~0.1 for adapted grey)
    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    a_white = np.array([colour.SDS_ILLUMINANTS["A"][w] for w in GRID]) @ \
        np.array([cmfs[w] for w in GRID])
    a_rgb = colour.RGB_COLOURSPACES["sRGB"].matrix_XYZ_to_RGB @ a_white
    ratio = centre(exr) / (a_rgb / a_rgb[1])
    assert np.abs(ratio / ratio[:, 1:2] - 1).max() < 1e-4
    # the PNG is adapted: grey under A shows grey, not orange as unadapted
    assert png != png_none
    assert exr.metadata["exr_adapt"] == "none"
    assert "without chromatic adaptation" in exr.metadata["colour"]


def test_exr_adapt_asks_for_the_png_s_adaptation(run_gonio, grey, tmp_path):
    png, exr = render(run_gonio, grey, tmp_path, "default")
    png_b, exr_b = render(run_gonio, grey, tmp_path, "bradford", "--exr-adapt", "bradford")
    assert png_b == png                                     # the PNG path is unchanged
    rgb = centre(exr_b)
    assert np.abs(rgb / rgb[:, 1:2] - 1).max() < 1e-3        # adapted grey is neutral
    assert np.abs(centre(exr) / centre(exr)[:, 1:2] - 1).max() > 0.1  # unadapted is not
    assert exr_b.metadata["exr_adapt"] == "bradford"
    assert "after chromatic adaptation (bradford" in exr_b.metadata["colour"]


def test_exr_adapt_without_an_exr_is_refused(run_gonio, grey, tmp_path):
    out = tmp_path / "o.png"
    r = run_gonio("render", grey, "-o", out, "--var", "illuminant=A", "--exr-adapt", "cat16")
    lines = r.stderr.strip().splitlines()
    assert r.exit_code == 2 and len(lines) == 1 and "--exr-adapt" in lines[0], r.stderr
    assert "--exr" in lines[0].split("; ", 1)[1] and not out.exists()
    r = run_gonio("render", grey, "-o", out, "--exr", tmp_path / "o.exr", "--exr-adapt",
                  "bradfrd")
    assert r.exit_code == 2 and "did you mean 'bradford'?" in r.stderr, r.stderr
