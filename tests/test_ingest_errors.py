"""gonio ingest on bad input: every case gets exit status 2, ONE
line on stderr naming the file and the row or column and saying what to do, no
traceback, and no output file (not even a temporary one)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from bad_inputs import refused_ingest_line
from gonio_cli.spectra import parse_grid

GRID = parse_grid()
HEADER_WIDE = "theta_i_deg,theta_o_deg," + ",".join(f"{w:g}" for w in GRID)


def row(theta_i, theta_o, value=0.2, n=GRID.size):
    return f"{theta_i},{theta_o}," + ",".join([str(value)] * n)


def wide(*rows, header=HEADER_WIDE):
    return "\n".join([header, *rows]) + "\n"


GOOD = wide(row(20, 10), row(20, 30), row(45, -20))


@pytest.fixture
def refuse(tmp_path, run_gonio):
    """``refuse(files, *options, expect=[...])``: write ``files`` ({name: text}), run
    ingest on them and assert the one-line refusal containing every ``expect`` text."""

    def _refuse(files: dict, *options, expect=(), inputs=None):
        paths = []
        for name, text in files.items():
            p = tmp_path / name
            p.write_bytes(text if isinstance(text, bytes) else text.encode("utf-8"))
            paths.append(p)
        inputs = paths if inputs is None else [tmp_path / n for n in inputs]
        out = tmp_path / "out" / "m.json"
        options = [tmp_path / o if o in files else o for o in options]
        res = run_gonio("ingest", *inputs, "-o", out, *options)
        line = refused_ingest_line(res, tmp_path, out)
        for text in expect:
            assert text in line, line
        return line

    return _refuse


# ------------------------------------------------------------------ the file --

def test_empty_file(refuse):
    refuse({"e.csv": ""}, expect=["e.csv: empty file"])


def test_only_comments_and_blank_lines(refuse):
    refuse({"e.csv": "# nothing\n\n   \n# still nothing\n"}, expect=["e.csv: empty file"])


def test_header_without_rows(refuse):
    refuse({"h.csv": "# c\n" + HEADER_WIDE + "\n"}, expect=["h.csv:2: ", "no data rows"])


def test_missing_file(refuse):
    refuse({}, inputs=["nope.csv"], expect=["nope.csv: no such file"])


def test_not_utf8(refuse):
    refuse({"b.csv": HEADER_WIDE.encode() + b"\n20,10,\xff\xfe\n"},
           expect=["b.csv:2: ", "not UTF-8"])


@pytest.mark.parametrize("name, head, kind", [
    ("ink.png", b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "PNG image"),
    ("ink.jpg", b"\xff\xd8\xff\xe0\x00\x10JFIF\x00", "JPEG image"),
    ("sky.exr", b"\x76\x2f\x31\x01\x02\x00\x00\x00", "OpenEXR image"),
    ("ink.xlsx", b"PK\x03\x04\x14\x00\x06\x00", "ZIP archive, e.g. an Excel .xlsx workbook"),
    ("ink.pdf", b"%PDF-1.7\n%\xe2\xe3\xcf\xd3", "PDF document"),
    ("ink.csv.gz", b"\x1f\x8b\x08\x00\x00\x00\x00\x00", "gzip-compressed file"),
])
def test_binary_file_is_named_not_a_utf8_hint(refuse, name, head, kind):
    """A file that is not text gets what it is (from its first bytes), not 'not UTF-8'."""
    line = refuse({name: head + bytes(range(256))},
                  expect=[f"{name}: not a CSV file ({kind}); ", "save it as CSV UTF-8"])
    assert "UTF-8 text" not in line and "byte 0x" not in line


def test_binary_white_spectrum_is_named(refuse):
    refuse({"a.csv": GOOD, "white.png": b"\x89PNG\r\n\x1a\n" + bytes(32)},
           "--quantity", "ratio-to-white", "--white-reflectance", "white.png",
           inputs=["a.csv"], expect=["white.png: not a CSV file (PNG image)"])


def test_no_delimiter(refuse):
    refuse({"d.csv": "theta_i_deg theta_o_deg\n1 2\n"}, expect=["d.csv:1: ", "delimiter"])


def test_row_with_too_few_cells(refuse):
    refuse({"r.csv": wide(row(20, 10), row(20, 30, n=GRID.size - 1))},
           expect=["r.csv:3: ", "has 42 cells, the header has 43"])


def test_decimal_comma_with_comma_delimiter(refuse):
    line = refuse({"r.csv": wide("20,10," + ",".join(["0,2"] * GRID.size))},
                  expect=["r.csv:2: ", "cells"])
    assert "separate columns with ';'" in line


# ---------------------------------------------------------------- the header --

@pytest.mark.parametrize("header, missing", [
    ("theta_i_deg,theta_o_deg,wavelength_nm", "value"),
    ("theta_i_deg,wavelength_nm,value", "theta_o_deg"),
    ("theta_o_deg,380,390", "theta_i_deg"),
])
def test_missing_column(refuse, header, missing):
    refuse({"m.csv": header + "\n1,2,3\n"}, expect=["m.csv:1: ", f"missing column '{missing}'"])


@pytest.mark.parametrize("header, unknown", [
    ("theta_i,theta_o_deg,wavelength_nm,value,theta_i_deg", "theta_i"),
    ("theta_i_deg,theta_o_deg,wavelength_nm,value,temperature", "temperature"),
    ("theta_i_deg,theta_o_deg,signal,380,390", "signal"),  # not a label (Name, Sample …)
    ("geometry,theta_i_deg,380,390", "theta_i_deg"),
    ("theta_i_deg,theta_o_deg,380nm,390nm,400", "380nm"),
])
def test_unknown_column(refuse, header, unknown):
    n = header.count(",") + 1
    refuse({"u.csv": header + "\n" + ",".join(["1"] * n) + "\n"},
           expect=["u.csv:1: ", f"column {unknown}: unknown column"])


def test_duplicated_angle_column(refuse):
    refuse({"u.csv": "theta_i_deg,theta_o_deg,theta_o_deg,380\n1,2,3,4\n"},
           expect=["u.csv:1: ", "'theta_o_deg' appears twice"])


def test_decreasing_wavelength_columns(refuse):
    header = "theta_i_deg,theta_o_deg,380,400,390,410"
    refuse({"d.csv": wide("20,10,1,1,1,1", header=header)},
           expect=["d.csv:1: column 390: ", "decreases"])


def test_duplicated_wavelength_columns(refuse):
    header = "theta_i_deg,theta_o_deg,380,390,390.0,400"
    refuse({"d.csv": wide("20,10,1,1,1,1", header=header)},
           expect=["d.csv:1: column 390.0: ", "repeats"])


# ------------------------------------------------------------------- the cells --

@pytest.mark.parametrize("cell, what", [("abc", "cell 'abc' is not a number"),
                                        ("", "cell is empty"),
                                        ("0.2.1", "cell '0.2.1' is not a number")])
def test_non_numeric_cell(refuse, cell, what):
    bad = "20,30," + ",".join(["0.2"] * 5 + [cell] + ["0.2"] * (GRID.size - 6))
    refuse({"n.csv": wide(row(20, 10), bad)}, expect=["n.csv:3: column 430: ", what])


def test_non_numeric_angle(refuse):
    refuse({"n.csv": wide(row(20, 10), row("twenty", 10))},
           expect=["n.csv:3: column theta_i_deg: ", "not a number"])


@pytest.mark.parametrize("cell", ["nan", "NaN", "inf", "-inf", "Infinity"])
def test_nan_or_inf(refuse, cell):
    bad = "20,30," + ",".join([cell] + ["0.2"] * (GRID.size - 1))
    refuse({"n.csv": wide(row(20, 10), bad)},
           expect=["n.csv:3: column 380: ", f"value {cell} is not finite"])


def test_nan_in_long_layout(refuse):
    text = "theta_i_deg,theta_o_deg,wavelength_nm,value\n" + "".join(
        f"20,10,{w:g},{'nan' if w == 500 else 0.2}\n" for w in GRID)
    refuse({"l.csv": text}, expect=["l.csv:14: column value: ", "NaN or inf"])


# ------------------------------------------------------------------- the angles --

@pytest.mark.parametrize("theta_i, theta_o, column, value", [
    (90, 10, "theta_i_deg", "theta_i_deg=90, outside [0, 90)"),
    (-5, 10, "theta_i_deg", "theta_i_deg=-5, outside [0, 90)"),
    (20, 90, "theta_o_deg", "theta_o_deg=90, outside (-90, 90)"),
    (20, -95, "theta_o_deg", "theta_o_deg=-95, outside (-90, 90)"),
])
def test_angles_out_of_range(refuse, theta_i, theta_o, column, value):
    refuse({"a.csv": wide(row(20, 10), row(theta_i, theta_o))},
           expect=[f"a.csv:3: column {column}: ", value])


def test_angle_out_of_range_in_long_layout(refuse):
    text = "theta_i_deg,theta_o_deg,wavelength_nm,value\n20,10,380,0.1\n95,10,380,0.1\n"
    refuse({"l.csv": text}, expect=["l.csv:3: column theta_i_deg: ", "theta_i_deg=95"])


def test_angles_that_look_like_radians(refuse):
    refuse({"r.csv": wide(row(0.349, 0.175), row(0.349, 0.524), row(0.785, -0.35))},
           expect=["r.csv: column theta_i_deg, theta_o_deg: ", "look like radians",
                   "degrees"])


def test_multiangle_label_out_of_range(refuse):
    header = "geometry," + ",".join(f"{w:g}" for w in GRID)
    refuse({"m.csv": wide("45as15," + ",".join(["0.2"] * 41),
                          "45as150," + ",".join(["0.2"] * 41), header=header)},
           expect=["m.csv:3: column geometry: ", "45as150 gives theta_o_deg=-105"])


def test_multiangle_bad_label(refuse):
    header = "geometry," + ",".join(f"{w:g}" for w in GRID)
    refuse({"m.csv": wide("45/15," + ",".join(["0.2"] * 41), header=header)},
           expect=["m.csv:2: column geometry: ", "'45/15' is not an aspecular label",
                   "45as15"])


# --------------------------------------------------------------- wavelengths --

def test_grid_not_covering_the_working_grid(refuse):
    header = "theta_i_deg,theta_o_deg," + ",".join(str(w) for w in range(400, 701, 10))
    line = refuse({"g.csv": wide(row(20, 10, n=31), header=header)},
                  expect=["g.csv:1: column 400: ", "400-700 nm do not cover the working grid "
                          "380-780 nm"])
    assert "--grid-nm 400:700:10" in line


def test_grid_not_covering_in_long_layout(refuse):
    text = "theta_i_deg,theta_o_deg,wavelength_nm,value\n" + "".join(
        f"20,10,{w},0.1\n" for w in range(380, 701, 10))
    refuse({"l.csv": text}, expect=["l.csv: column wavelength_nm: ", "380-700 nm do not cover"])


def test_grid_covered_only_by_another_grid_option_is_fine(tmp_path, run_gonio):
    header = "theta_i_deg,theta_o_deg," + ",".join(str(w) for w in range(400, 701, 10))
    src = tmp_path / "g.csv"
    src.write_text(wide(row(20, 10, n=31), header=header))
    res = run_gonio("ingest", src, "-o", tmp_path / "m.json", "--grid-nm", "400:700:10")
    assert res.exit_code == 0  # no warning: only the summary line
    assert re.fullmatch(re.escape(f"{tmp_path / 'm.json'}: 1 configuration (1 angle of "
                                  "incidence) x 31 wavelengths, brdf from 1 file, ")
                        + r"\d+\.\d\d s\n", res.stderr), res.stderr


def test_long_layout_missing_a_wavelength(refuse):
    rows = [f"20,10,{w:g},0.1" for w in GRID] + [f"30,10,{w:g},0.1" for w in GRID
                                                   if w != 500]
    refuse({"l.csv": "theta_i_deg,theta_o_deg,wavelength_nm,value\n" + "\n".join(rows)},
           expect=["l.csv:43: column wavelength_nm: ", "theta_i_deg=30, theta_o_deg=10",
                   "no value at 500 nm"])


def test_long_layout_uneven_repeat(refuse):
    rows = [f"20,10,{w:g},0.1" for w in GRID] + ["20,10,450,0.1"]
    refuse({"l.csv": "theta_i_deg,theta_o_deg,wavelength_nm,value\n" + "\n".join(rows)},
           expect=["l.csv:", "(repeat 2) has no value at 380 nm"])


def test_files_disagreeing_on_their_grid(refuse):
    header5 = "theta_i_deg,theta_o_deg," + ",".join(str(w) for w in range(380, 781, 5))
    refuse({"a.csv": GOOD, "b.csv": wide(row(50, 10, n=81), header=header5)},
           expect=["b.csv:1: column 380: ", "differ from those of", "a.csv",
                   "from 385 nm on"])


def test_files_disagreeing_on_one_wavelength(refuse):
    other = HEADER_WIDE.replace(",550,", ",551,")
    refuse({"a.csv": GOOD, "b.csv": wide(row(50, 10), header=other)},
           expect=["b.csv:1: ", "from 551 nm on"])


def test_bad_grid_option(refuse):
    refuse({"a.csv": GOOD}, "--grid-nm", "380-780", expect=["--grid-nm '380-780'"])


# ------------------------------------------------------------------ negatives --

def test_negative_beyond_noise(refuse):
    bad = "20,30," + ",".join(["0.2"] * 10 + ["-0.05"] + ["0.2"] * (GRID.size - 11))
    refuse({"n.csv": wide(row(20, 10, 1.0), bad)},
           expect=["n.csv:3: column 480: ", "value -0.05 at 480 nm is negative beyond noise",
                   "peak 1"])


def test_negative_beyond_noise_after_dark_subtraction(refuse):
    dark = "wavelength_nm,value\n380,0.5\n780,0.5\n"
    refuse({"a.csv": wide(row(20, 10, 1.0), row(20, 30, 0.2)), "dark.csv": dark},
           "--dark", "dark.csv", inputs=["a.csv"],
           expect=["a.csv:3: column 380: ", "-0.3", "negative beyond noise"])


def test_all_values_negative(refuse):
    refuse({"n.csv": wide(row(20, 10, -0.001))}, expect=["n.csv:2: ", "negative beyond noise"])


# ---------------------------------------------------------------- quantities --

def test_unknown_quantity(refuse):
    line = refuse({"a.csv": GOOD}, "--quantity", "radiance",
                  expect=["a.csv: --quantity 'radiance' is not known"])
    assert "brdf, ratio-to-white, reflectance-factor, flux-ratio" in line


@pytest.mark.parametrize("white, what", [
    ("1.5", "--white-reflectance 1.5 is outside (0, 1]"),
    ("0", "--white-reflectance 0 is outside (0, 1]"),
    ("-0.9", "--white-reflectance -0.9 is outside (0, 1]"),
    ("0,99", "--white-reflectance '0,99' is neither a number nor a file"),
    ("nowhere.csv", "'nowhere.csv' is neither a number nor a file"),
])
def test_unusable_white_reflectance(refuse, white, what):
    refuse({"a.csv": GOOD}, "--quantity", "ratio-to-white", "--white-reflectance", white,
           expect=["a.csv: ", what])


@pytest.mark.parametrize("white, expect", [
    ("wavelength_nm,value\n400,0.99\n700,0.99\n",     # not covering the input
     ["w.csv: column 400: ", "do not cover those of a.csv",
      "white standard spectrum over at least 380-780 nm"]),
    ("wavelength_nm,value\n380,99\n780,99\n",         # in percent
     ["w.csv:2: column value: ", "99 at 380 nm is outside (0, 1]", "0.99, not 99 %"]),
    ("wavelength_nm,value\n380,0.99\n780,0\n",        # a white that does not reflect
     ["w.csv:3: column value: ", "0 at 780 nm is outside (0, 1]"]),
    ("wl,R\n380,0.99\n780,0.99\n",                    # wrong columns
     ["w.csv:1: ", "wavelength_nm,value"]),
])
def test_unusable_white_spectrum(refuse, white, expect):
    refuse({"a.csv": GOOD, "w.csv": white}, "--quantity", "ratio-to-white",
           "--white-reflectance", "w.csv", inputs=["a.csv"], expect=expect)


def test_white_reflectance_with_another_quantity(refuse):
    refuse({"a.csv": GOOD}, "--white-reflectance", "0.98",
           expect=["a.csv: ", "--white-reflectance is only used with --quantity "
                   "ratio-to-white, not brdf"])


@pytest.mark.parametrize("options, missing", [
    ((), "--aperture-mm and --distance-mm"),
    (("--aperture-mm", "4"), "needs --distance-mm"),
    (("--distance-mm", "400"), "needs --aperture-mm"),
])
def test_flux_ratio_without_aperture_or_distance(refuse, options, missing):
    refuse({"a.csv": GOOD}, "--quantity", "flux-ratio", *options,
           expect=["a.csv: ", missing, "seed 004 eq. 7"])


@pytest.mark.parametrize("aperture, distance", [("0", "400"), ("500", "400"),
                                                ("4", "-400"), ("nan", "400")])
def test_flux_ratio_with_unusable_geometry(refuse, aperture, distance):
    refuse({"a.csv": GOOD}, "--quantity", "flux-ratio", "--aperture-mm", aperture,
           "--distance-mm", distance, expect=["a.csv: ", "0 < aperture < distance"])


def test_aperture_with_another_quantity(refuse):
    refuse({"a.csv": GOOD}, "--aperture-mm", "4", expect=["a.csv: ", "--aperture-mm is only "
                                                          "used with --quantity flux-ratio"])


# ---------------------------------------------------------------------- dark --

def test_dark_not_covering(refuse):
    refuse({"a.csv": GOOD, "dark.csv": "wavelength_nm,value\n390,0\n780,0\n"},
           "--dark", "dark.csv", inputs=["a.csv"],
           expect=["dark.csv: column 390: ", "do not cover those of a.csv"])


def test_dark_missing(refuse):
    refuse({"a.csv": GOOD}, "--dark", "dark.csv", expect=["dark.csv: no such file"])


def test_dark_with_nan(refuse):
    refuse({"a.csv": GOOD, "dark.csv": "wavelength_nm,value\n380,0\n780,nan\n"},
           "--dark", "dark.csv", inputs=["a.csv"],
           expect=["dark.csv:3: column value: ", "NaN or inf"])


# -------------------------------------------------------------------- output --

def test_output_is_an_input(tmp_path, run_gonio):
    src = tmp_path / "a.csv"
    src.write_text(GOOD)
    res = run_gonio("ingest", src, "-o", src)
    assert res.exit_code == 2
    assert len(res.stderr.strip().splitlines()) == 1
    assert "a.csv: is both an input and the output" in res.stderr
    assert src.read_text() == GOOD


def test_same_file_twice(refuse):
    refuse({"a.csv": GOOD}, inputs=["a.csv", "a.csv"], expect=["a.csv: is given twice"])


def test_error_after_a_warning_prints_only_the_error(refuse):
    """A file needing resampling, then a bad one: the warning of the first is never shown,
    so a failing run prints exactly one line."""
    header5 = "theta_i_deg,theta_o_deg," + ",".join(str(w) for w in range(380, 781, 5))
    refuse({"a.csv": wide(row(20, 10, n=81), header=header5),
            "b.csv": wide(row(30, 10, n=81), row(95, 10, n=81), header=header5)},
           expect=["b.csv:3: column theta_i_deg: "])


def test_failed_run_keeps_the_previous_artifact(tmp_path, run_gonio):
    good, bad = tmp_path / "good.csv", tmp_path / "bad.csv"
    good.write_text(GOOD)
    bad.write_text(wide(row(20, 10), row(20, "x")))
    out = tmp_path / "m.json"
    assert run_gonio("ingest", good, "-o", out).exit_code == 0
    before = out.read_bytes()
    assert run_gonio("ingest", bad, "-o", out).exit_code == 2
    assert out.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.csv", "good.csv", "m.json",
                                                          "m.run.json"]


# ---------------------------------------------- instrument exports (fixtures) --

REAL = Path(__file__).resolve().parent / "fixtures" / "real"
MA_GRID = ("--grid-nm", "400:700:10")


def real(name: str) -> str:
    return (REAL / name).read_text()


def test_export_with_two_samples_and_no_sample(refuse):
    refuse({"two.csv": real("ma_t12_export_two_samples.csv")}, *MA_GRID,
           expect=["two.csv:16: column Name: holds 2 samples (GREEN_EARTH_A, GREEN_EARTH_B)",
                   "; pick one with --sample NAME"])


def test_export_sample_that_is_not_there(refuse):
    refuse({"two.csv": real("ma_t12_export_two_samples.csv")}, *MA_GRID, "--sample", "C",
           expect=["two.csv:3: column Name: holds no sample 'C', only GREEN_EARTH_A, "
                   "GREEN_EARTH_B"])


def test_sample_without_a_sample_column(refuse):
    refuse({"a.csv": GOOD}, "--sample", "A",
           expect=["a.csv:1: --sample 'A' is given, but the file has no column naming"])


def test_empty_sample(refuse):
    refuse({"a.csv": GOOD}, "--sample", " ", expect=["a.csv: --sample is empty"])


def test_export_in_percent(refuse):
    line = refuse({"pc.csv": real("ma_t12_export_percent.csv")}, *MA_GRID,
                  "--quantity", "reflectance-factor",
                  expect=["the values look like percent", "; pass --scale 0.01"])
    assert re.match(r"gonio: error: pc\.csv:\d+: column \d+: ", line), line


@pytest.mark.parametrize("scale", ["0", "-1", "nan", "inf"])
def test_scale_must_be_positive(refuse, scale):
    refuse({"a.csv": GOOD}, "--scale", scale, expect=[f"a.csv: --scale {scale}"
                                                      if scale != "-1" else "a.csv: --scale -1",
                                                      "is not a positive number"])


def test_export_with_a_misspelt_header(refuse):
    text = real("ma_t12_export.csv").replace("Geometry", "Geometri")
    refuse({"x.csv": text}, *MA_GRID,
           expect=["x.csv:3: column Geometri: unknown column 'Geometri' in the wide layout",
                   "multi-angle layout header: geometry,"])


def test_preamble_without_a_header(refuse):
    refuse({"p.csv": "QC JOB:,Job 1\nSTANDARD:,X\n1,2,3\n"},
           expect=["p.csv:1: has no header", "theta_i_deg,theta_o_deg,wavelength_nm,value"])
