"""``gonio halftone`` end to end: files, metadata, report, --split, sizes, and bad input
(one stderr line, exit 2, nothing written)."""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.artifact import read_artifact
from gonio_cli.cache import CACHE_ENV
from gonio_cli.imageio import read_image, write_exr, write_png

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data" / "print_image.png"


@pytest.fixture(autouse=True)
def cache_in_tmp(monkeypatch, tmp_path_factory):
    """The blue-noise cache goes to a temporary folder, never the home or the repository."""
    monkeypatch.setenv(CACHE_ENV, str(tmp_path_factory.getbasetemp() / "cache"))


def mask_of(path) -> np.ndarray:
    img = read_image(path)
    return np.round(img.pixels * 255).astype(np.uint8)


def test_sample_image_to_mask_and_report(run_gonio, tmp_path):
    out, rep = tmp_path / "print.png", tmp_path / "print.json"
    r = run_gonio("halftone", SAMPLE, "-o", out, "--report", rep)
    assert r.exit_code == 0, r.stderr
    assert r.stdout == ""
    mask = mask_of(out)
    assert mask.shape == (256, 256, 3)
    assert set(np.unique(mask)) <= {0, 255} and (mask.astype(int).sum(axis=2) <= 255).all()
    meta = read_image(out).metadata
    assert meta["method"] == "floyd-steinberg" and meta["schema"] == "gonio.halftone-mask"
    assert json.loads(meta["parameters"])["gamut"] == "scale" and meta["gonio_version"]
    doc = json.loads(rep.read_text())
    assert doc["schema"] == "gonio.halftone-report" and doc["schema_version"] == 1
    assert doc["inputs"][0]["sha256"] and doc["input_encoding"] == "srgb"
    # the report's coverage is that of the file written
    np.testing.assert_allclose(doc["coverage_mask"], (mask == 255).mean(axis=(0, 1)))
    np.testing.assert_allclose(doc["coverage_error"],
                               np.subtract(doc["coverage_mask"], doc["coverage_target"]))
    assert 0 < doc["out_of_gamut_fraction"] < 1
    assert 0 < doc["tone_rmse"] < 0.05 and doc["tone_sigma_px"] == 2.0
    back = read_artifact(rep, "gonio.halftone-report", (1,))      # times: its side record
    assert back["halftone_time_s"] >= 0 and back["compile_time_s"] >= 0
    assert "halftone_time_s" not in doc and "time_s" not in meta
    assert "tone RMSE" in r.stderr and "out of gamut" in r.stderr


@pytest.mark.parametrize("method,extra", [("jarvis", []), ("stucki", []),
                                          ("bayer", ["--bayer-size", "4"]),
                                          ("clustered", ["--cell-size", "4"]),
                                          ("blue-noise", ["--mask-size", "32"])])
def test_every_method_from_the_command_line(run_gonio, tmp_path, method, extra):
    out, rep = tmp_path / "m.png", tmp_path / "m.json"
    r = run_gonio("halftone", SAMPLE, "-o", out, "-m", method, "--report", rep, *extra)
    assert r.exit_code == 0, r.stderr
    doc = json.loads(rep.read_text())
    assert doc["method"] == method and (mask_of(out).astype(int).sum(axis=2) <= 255).all()
    if extra:
        assert list(doc["method_parameters"].values()) == [int(extra[1])]


def test_split_writes_one_screen_per_ink(run_gonio, tmp_path):
    out = tmp_path / "print.png"
    r = run_gonio("halftone", SAMPLE, "-o", out, "--split")
    assert r.exit_code == 0, r.stderr
    mask = mask_of(out)
    for k, ink in enumerate(("red", "green", "blue")):
        screen = read_image(tmp_path / f"print.{ink}.png")
        assert screen.pixels.shape == (256, 256, 1)
        assert read_image(tmp_path / f"print.{ink}.png").metadata["ink"] == ink
        np.testing.assert_array_equal(np.round(screen.pixels[:, :, 0] * 255), mask[:, :, k])
        from PIL import Image as PILImage

        assert PILImage.open(tmp_path / f"print.{ink}.png").mode == "1"  # a true 1-bit PNG


def png_header(path) -> tuple[int, int, int]:
    """(bit depth, colour type, zlib FLEVEL) of a PNG (PNG spec §11.2.2, RFC 1950)."""
    data = path.read_bytes()
    depth, colour = data[24], data[25]
    idat = data.index(b"IDAT")
    return depth, colour, data[idat + 5] >> 6


def test_mask_formats_and_compression(run_gonio, tmp_path):
    """The default mask is a 2-bit paletted PNG deflated at level 1; --mask-format rgb is
    8-bit truecolour; both decode to the same RGB image; --compress sets the level."""
    pal, rgb = tmp_path / "pal.png", tmp_path / "rgb.png"
    r = run_gonio("halftone", SAMPLE, "-o", pal, "--split")
    assert r.exit_code == 0, r.stderr
    assert png_header(pal) == (2, 3, 0)          # palette, level 1 (FLEVEL 0)
    assert png_header(tmp_path / "pal.red.png")[2] == 0
    r = run_gonio("halftone", SAMPLE, "-o", rgb, "--mask-format", "rgb", "--compress", "small")
    assert r.exit_code == 0, r.stderr
    assert png_header(rgb) == (8, 2, 3)          # truecolour, level 9 (FLEVEL 3)
    np.testing.assert_array_equal(mask_of(pal), mask_of(rgb))
    meta = read_image(rgb).metadata
    assert json.loads(meta["parameters"])["mask_format"] == "rgb"
    assert meta["schema"] == "gonio.halftone-mask" and int(meta["schema_version"]) == 1
    assert json.loads(meta["inputs"]) == [
        {"path": os.path.relpath(SAMPLE, tmp_path),
         "sha256": hashlib.sha256(Path(SAMPLE).read_bytes()).hexdigest()}]


def test_tone_error_only_with_a_report(run_gonio, tmp_path):
    """Without --report the tone error is not computed (the summary names coverage only);
    the mask is the same either way."""
    r = run_gonio("halftone", SAMPLE, "-o", tmp_path / "a.png")
    assert r.exit_code == 0, r.stderr
    assert "tone RMSE" not in r.stderr and "R=" in r.stderr
    r = run_gonio("halftone", SAMPLE, "-o", tmp_path / "b.png", "--report", tmp_path / "b.json")
    assert r.exit_code == 0, r.stderr
    assert "tone RMSE" in r.stderr
    np.testing.assert_array_equal(mask_of(tmp_path / "a.png"), mask_of(tmp_path / "b.png"))


def test_linear_exr_input_is_coverage(run_gonio, tmp_path):
    """A float image is linear: its values are the coverage (no sRGB decoding)."""
    src = tmp_path / "flat.exr"
    write_exr(src, np.broadcast_to(np.float32([0.2, 0.3, 0.1]), (64, 64, 3)))
    rep = tmp_path / "r.json"
    r = run_gonio("halftone", src, "-o", tmp_path / "m.png", "--report", rep)
    assert r.exit_code == 0, r.stderr
    doc = json.loads(rep.read_text())
    assert doc["input_encoding"] == "linear" and doc["out_of_gamut_fraction"] == 0
    np.testing.assert_allclose(doc["coverage_target"], [0.2, 0.3, 0.1], atol=1e-6)
    # the same numbers in a PNG are sRGB-encoded unless told otherwise
    png = tmp_path / "flat.png"
    write_png(png, np.broadcast_to(np.uint8([51, 76, 25]), (8, 8, 3)))
    for enc, expected in [("auto", 0.0331), ("linear", 0.2)]:
        r = run_gonio("halftone", png, "-o", tmp_path / "p.png", "--report", rep,
                      "--input-encoding", enc)
        assert r.exit_code == 0, r.stderr
        assert json.loads(rep.read_text())["coverage_target"][0] == pytest.approx(
            expected, abs=1e-4)     # sRGB 51/255 decodes to 0.0331


def test_size_and_dpi(run_gonio, tmp_path):
    rep = tmp_path / "r.json"
    r = run_gonio("halftone", SAMPLE, "-o", tmp_path / "a.png", "--size", "300x200",
                  "--report", rep)
    assert r.exit_code == 0, r.stderr
    assert mask_of(tmp_path / "a.png").shape == (200, 300, 3)
    assert json.loads(rep.read_text())["source_width_px"] == 256
    # 50.8 mm at 150 dpi = 2 inches = 300 px, square like the source
    r = run_gonio("halftone", SAMPLE, "-o", tmp_path / "b.png", "--dpi", "150",
                  "--print-width-mm", "50.8")
    assert r.exit_code == 0, r.stderr
    assert mask_of(tmp_path / "b.png").shape == (300, 300, 3)


def test_clip_gamut(run_gonio, tmp_path):
    rep = tmp_path / "r.json"
    r = run_gonio("halftone", SAMPLE, "-o", tmp_path / "a.png", "--gamut", "clip",
                  "--report", rep)
    assert r.exit_code == 0, r.stderr
    assert json.loads(rep.read_text())["gamut"] == "clip"


def _write_bytes(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def _image(path: Path, channels: int, alpha: float = 1.0) -> Path:
    a = np.full((4, 4, channels), 0.5, dtype=np.float32)
    if channels == 4:
        a[:, :, 3] = alpha
    write_exr(path, a)
    return path


BAD = {
    "unreadable": (lambda d: _write_bytes(d / "broken.png", b"\x89PNG not really"), [],
                   "broken.png"),
    "missing": (lambda d: d / "nope.png", [], "no such image file"),
    "grey": (lambda d: _image(d / "grey.exr", 1), [], "1 channel"),
    "two channels": (lambda d: _image(d / "ga.exr", 2), [], "2 channels"),
    "transparent": (lambda d: _image(d / "rgba.exr", 4, 0.5), [], "transparent"),
    "unknown method": (lambda d: SAMPLE, ["-m", "atkinson"],
                       "floyd-steinberg, jarvis, stucki, bayer, clustered, clustered-3x3, "
                       "blue-noise"),
    "size zero": (lambda d: SAMPLE, ["--size", "0x100"], "no pixels"),
    "size zero height": (lambda d: SAMPLE, ["--size", "100x0"], "no pixels"),
    "size garbage": (lambda d: SAMPLE, ["--size", "big"], "WIDTHxHEIGHT"),
    "dpi zero": (lambda d: SAMPLE, ["--dpi", "0", "--print-width-mm", "10"], "--dpi"),
    "dpi alone": (lambda d: SAMPLE, ["--dpi", "300"], "go together"),
    "size and dpi": (lambda d: SAMPLE, ["--size", "9x9", "--dpi", "300",
                                        "--print-width-mm", "10"], "both set"),
    "foreign option": (lambda d: SAMPLE, ["--cell-size", "4"], "does not apply"),
    "bad bayer": (lambda d: SAMPLE, ["-m", "bayer", "--bayer-size", "6"], "power of two"),
    "bad gamut": (lambda d: SAMPLE, ["--gamut", "squash"], "scale, clip"),
    "bad encoding": (lambda d: SAMPLE, ["--input-encoding", "gamma"], "auto, srgb, linear"),
    "not png": (lambda d: SAMPLE, ["-o", "OUT/mask.tif"], "must be a PNG"),
    "bad compress": (lambda d: SAMPLE, ["--compress", "max"], "none, fast, balanced, small"),
    "bad mask format": (lambda d: SAMPLE, ["--mask-format", "gif"], "palette, rgb"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_one_line_exit_2_nothing_written(run_gonio, tmp_path, case):
    make, extra, needle = BAD[case]
    src_dir = tmp_path / "src"
    src_dir.mkdir()
    src = make(src_dir)
    out_dir = tmp_path / "out"
    extra = [a.replace("OUT", str(out_dir)) for a in extra]
    args = ["halftone", src, "--report", out_dir / "r.json", "--split"]
    if "-o" not in extra:
        args += ["-o", out_dir / "mask.png"]
    r = run_gonio(*args, *extra)
    assert r.exit_code == 2, r.stderr
    assert r.stderr.startswith("gonio: error: ") and r.stderr.count("\n") == 1, r.stderr
    assert needle in r.stderr
    assert not out_dir.exists() or not any(out_dir.iterdir())


def test_nan_exr_is_refused(run_gonio, tmp_path):
    src = tmp_path / "nan.exr"
    a = np.full((4, 4, 3), 0.2, dtype=np.float32)
    a[1, 2, 0] = np.nan
    write_exr(src, a, allow_nonfinite=True)
    r = run_gonio("halftone", src, "-o", tmp_path / "m.png")
    assert r.exit_code == 2 and "1 pixels with NaN" in r.stderr
    assert not (tmp_path / "m.png").exists()


def test_help_lists_methods(run_gonio):
    r = run_gonio("halftone", "--help")
    assert r.exit_code == 0
    for name in ("floyd-steinberg", "blue-noise", "--split", "--gamut", "--input-encoding"):
        assert name in r.stdout


def test_help_method_names_match_the_registry():
    from gonio_cli.commands.halftone import COMPRESSION_NAMES, GAMUT_NAMES, METHOD_NAMES
    from gonio_cli.halftone import METHODS
    from gonio_cli.halftone.coverage import GAMUT_MAPPERS
    from gonio_cli.imageio import COMPRESSION

    assert METHOD_NAMES == tuple(METHODS) and GAMUT_NAMES == tuple(GAMUT_MAPPERS)
    assert COMPRESSION_NAMES == tuple(COMPRESSION)
