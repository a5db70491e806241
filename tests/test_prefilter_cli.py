"""``gonio prefilter``: files, index.json, --lobes, and bad input (one line, exit 2,
nothing written)."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from gonio_cli import envmap
from gonio_cli.artifact import read_artifact, write_artifact
from gonio_cli.imageio import read_image, write_exr, write_png

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"
MAP_KEYS = {"exponent", "path", "width", "height", "method", "error_estimate", "time_s"}
#: float32 storage and ring's float32 FFTs: ~1e-7 relative, with margin.
FLOAT32_RTOL = 1e-5


@pytest.fixture
def sky(tmp_path):
    rng = np.random.default_rng(3)
    img = (1.0 + rng.random((32, 64, 3))).astype(np.float32)
    img[10, 20] = 1e5
    path = tmp_path / "sky.exr"
    write_exr(path, img)
    return path


def assert_nothing_written(tmp_path, out):
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(f".{out.name}")]


def test_writes_one_map_per_exponent_and_the_index(run_gonio, sky, tmp_path):
    out = tmp_path / "pre"
    r = run_gonio("prefilter", sky, "--exponents", "8,64", "-o", out)
    assert r.exit_code == 0, r.stderr
    assert "time_s" not in (out / "index.json").read_text()       # in index.run.json
    index = read_artifact(out / "index.json", "gonio.prefilter", (2,))   # times merged
    assert index["schema"] == "gonio.prefilter" and index["schema_version"] == 2
    assert index["inputs"][0]["sha256"] and index["parameters"]["exponents"] == [1, 8, 64]
    assert [m["exponent"] for m in index["maps"]] == [1.0, 8.0, 64.0]
    assert index["diffuse"] == index["maps"][0]["path"]
    for m in index["maps"]:
        assert MAP_KEYS <= set(m)
        img = read_image(out / m["path"])
        assert img.pixels.shape == (m["height"], m["width"], 3)
        assert img.metadata["schema"] == "gonio.prefilter"
        assert int(img.metadata["schema_version"]) == 2
        assert json.loads(img.metadata["inputs"]) == index["inputs"]   # same hashes
        assert np.all(img.pixels >= 0.0) and np.all(np.isfinite(img.pixels))
        assert m["error_estimate"] < 0.01
    assert sorted(p.name for p in out.iterdir()) == sorted(
        [m["path"] for m in index["maps"]] + ["index.json", "index.run.json"])


def test_lobes_file_gives_the_exponents(run_gonio, sky, tmp_path):
    lobes = tmp_path / "paint.lobes.json"
    write_artifact(lobes, "gonio.lobes", 1, {"exponents": [12.5, 300]})
    out = tmp_path / "pre"
    r = run_gonio("prefilter", sky, "--lobes", lobes, "-o", out, "--method", "brute",
                  "--resolution", "8")
    assert r.exit_code == 0, r.stderr
    index = json.loads((out / "index.json").read_text())
    assert [m["exponent"] for m in index["maps"]] == [1.0, 12.5, 300.0]
    assert {m["method"] for m in index["maps"]} == {"brute"}
    assert (out / "prefiltered_E12p5.exr").is_file()
    assert {m["height"] for m in index["maps"]} == {8}


def test_constant_map_round_trips_through_the_files(run_gonio, tmp_path):
    path = tmp_path / "grey.exr"
    write_exr(path, np.full((16, 32, 3), 0.18, np.float32))
    out = tmp_path / "pre"
    assert run_gonio("prefilter", path, "-e", "1,10,1000,10000", "-o", out).exit_code == 0
    for f in out.glob("*.exr"):
        assert np.allclose(read_image(f).pixels, 0.18, rtol=FLOAT32_RTOL)


def test_fix_invalid_replaces_and_says_so(run_gonio, tmp_path):
    img = np.ones((16, 32, 3), np.float32)
    img[2, 3, 0] = np.nan
    path = tmp_path / "nan.exr"
    write_exr(path, img, allow_nonfinite=True)
    out = tmp_path / "pre"
    r = run_gonio("prefilter", path, "-e", "8", "-o", out, "--fix-invalid")
    assert r.exit_code == 0
    assert "replaced 1 NaN, inf or negative texels" in r.stderr


def bad_cases(tmp_path, sky):
    nan = tmp_path / "nan.exr"
    img = np.ones((16, 32, 3), np.float32)
    img[2, 3, 0], img[4, 4, 1] = np.nan, -2.0
    write_exr(nan, img, allow_nonfinite=True)
    png = tmp_path / "ldr.png"
    write_png(png, np.zeros((8, 16, 3), np.uint8))
    one = tmp_path / "one.exr"
    write_exr(one, np.ones((1, 1, 3), np.float32))
    nolist = tmp_path / "nolist.json"
    write_artifact(nolist, "gonio.lobes", 1, {"lobes": []})
    wrong = tmp_path / "wrong.json"
    write_artifact(wrong, "gonio.material", 1, {"exponents": [8]})
    return {
        "nan texel": ([nan, "-e", "8"], "(row 2, col 3)"),
        "ldr png": ([png, "-e", "8"], "not HDR"),
        "1x1 map": ([one, "-e", "8"], "not a lat-long map"),
        "missing map": ([tmp_path / "nope.exr", "-e", "8"], "no such image file"),
        "exponent below 1": ([sky, "-e", "0.5,8"], "outside [1"),
        "not a number": ([sky, "-e", "8,abc"], "'abc'"),
        "no exponents": ([sky], "give one of --chain, --exponents or --lobes"),
        "both": ([sky, "-e", "8", "--lobes", nolist], "give one of --chain, --exponents or --lobes"),
        "lobes without exponents": ([sky, "--lobes", nolist], "exponents"),
        "lobes of another schema": ([sky, "--lobes", wrong], "gonio.material"),
        "unknown method": ([sky, "-e", "8", "--method", "sh9"], "auto, brute, ring"),
        "bad resolution": ([sky, "-e", "8", "--resolution", "5"], "32, 16"),
    }


@pytest.mark.parametrize("case", ["nan texel", "ldr png", "1x1 map", "missing map",
                                  "exponent below 1", "not a number", "no exponents",
                                  "both", "lobes without exponents",
                                  "lobes of another schema", "unknown method",
                                  "bad resolution"])
def test_bad_input_is_one_line_exit_2_and_nothing_written(run_gonio, sky, tmp_path, case):
    args, needle = bad_cases(tmp_path, sky)[case]
    out = tmp_path / "pre"
    r = run_gonio("prefilter", *args, "-o", out)
    assert r.exit_code == 2, r.stderr
    assert r.stderr.startswith("gonio: error: ") and r.stderr.count("\n") == 1, r.stderr
    assert needle in r.stderr
    assert_nothing_written(tmp_path, out)


def test_nan_message_counts_the_texels(run_gonio, sky, tmp_path):
    args, _ = bad_cases(tmp_path, sky)["nan texel"]
    r = run_gonio("prefilter", *args, "-o", tmp_path / "pre")
    assert "2 texels are NaN, inf or negative" in r.stderr and "--fix-invalid" in r.stderr


def test_the_sample_sky_regenerates_and_prefilters(run_gonio, tmp_path):
    spec = importlib.util.spec_from_file_location("make_sky", SAMPLE / "make_sky.py")
    make_sky = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_sky)
    shipped = read_image(SAMPLE / "sky.exr").pixels
    assert np.array_equal(make_sky.make_sky(), shipped)  # deterministic
    lum = shipped.max(axis=2)
    assert 3e4 < lum.max() / np.median(lum[: lum.shape[0] // 2]) < 3e5  # a sun ~1e5 × sky
    out = tmp_path / "sky"
    r = run_gonio("prefilter", SAMPLE / "sky.exr", "-e", "8,64,512", "-o", out)
    assert r.exit_code == 0, r.stderr
    diffuse = read_image(out / "prefiltered_E1.exr").pixels
    sun = make_sky.sun_direction()
    toward = envmap.lookup(diffuse, sun)
    away = envmap.lookup(diffuse, -sun)
    assert toward.min() > 3 * away.max()  # the sun lights the side facing it


def test_the_library_call_writes_what_gonio_prefilter_writes(run_gonio, sky, tmp_path):
    """``gonio batch`` calls :func:`gonio_cli.prefilter_files.run` and ``write`` directly:
    the same index.json, byte for byte, and the same maps as the command."""
    from gonio_cli import prefilter_files as stage

    cli_out, lib_out = tmp_path / "cli", tmp_path / "lib"
    r = run_gonio("prefilter", sky, "--exponents", "8,64", "-o", cli_out)
    assert r.exit_code == 0, r.stderr
    stage.write(stage.run(sky, [8.0, 64.0]), lib_out)
    assert (lib_out / "index.json").read_bytes() == (cli_out / "index.json").read_bytes()
    for m in json.loads((cli_out / "index.json").read_text())["maps"]:
        np.testing.assert_array_equal(read_image(lib_out / m["path"]).pixels,
                                      read_image(cli_out / m["path"]).pixels)
