"""gonio ingest on instrument exports as users have them (tests/fixtures/real/README.md):
preamble lines before the header, label columns, several samples in one file, values in
percent, and the multi-angle layout read without ``--quantity``.

Truth is the fixtures' own numbers, read here with the csv module and converted by hand
(f = R/π), and the clean multi-angle file of the same values; bad input (one line, exit
2) is also covered in ``test_ingest_errors.py``.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from gonio_cli import ingest as core
from gonio_cli.errors import InputError
from gonio_cli.percent import PERCENT_MEDIAN_LIMIT
from gonio_cli.schemas import read_measurement

FIXTURES = Path(__file__).resolve().parent / "fixtures" / "real"
EXPORT = FIXTURES / "ma_t12_export.csv"
CLEAN = FIXTURES / "ma_t12_clean.csv"
TWO = FIXTURES / "ma_t12_export_two_samples.csv"
PERCENT = FIXTURES / "ma_t12_export_percent.csv"

#: The MA-T12 measures 400-700 nm: the working grid is that range (no resampling).
GRID = ["--grid-nm", "400:700:10"]
RF = ["--quantity", "reflectance-factor"]

#: "24.2" × 0.01 and "0.242" parse to floats a few ulp apart; ÷ π adds one more.
ROUND_OFF = 1e-12


def clean_truth(path: Path = CLEAN):
    """(θi, θo, R) of a clean multi-angle fixture by hand: θo = θi − aspecular angle,
    rows sorted by (θi, θo) as a measurement is."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    out = []
    for label, *values in rows[1:]:
        theta_i, aspecular = label.split("as")
        out.append((float(theta_i), float(theta_i) - float(aspecular),
                    [float(v) for v in values]))
    out.sort(key=lambda r: (r[0], r[1]))
    return (np.array([r[0] for r in out]), np.array([r[1] for r in out]),
            np.array([r[2] for r in out]))


def ingest_cli(run_gonio, tmp_path, *args, name="m.json"):
    out = tmp_path / name
    res = run_gonio("ingest", *args, "-o", out)
    return res, out


def one_error_line(res) -> str:
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 2, res.stderr
    assert len(lines) == 1 and lines[0].startswith("gonio: error: "), res.stderr
    return lines[0]


# ------------------------------------------------------------- the export itself --

def test_export_ingests_to_the_clean_multiangle_measurement(run_gonio, tmp_path):
    res, out = ingest_cli(run_gonio, tmp_path, EXPORT, *RF, *GRID)
    assert res.exit_code == 0, res.stderr
    assert "warning" not in res.stderr
    m = read_measurement(out)
    ti, to, r = clean_truth()
    np.testing.assert_array_equal(m.theta_i_deg, ti)
    np.testing.assert_array_equal(m.theta_o_deg, to)
    np.testing.assert_array_equal(m.wavelength_nm, np.arange(400.0, 701.0, 10.0))
    np.testing.assert_allclose(m.brdf, r / math.pi, rtol=ROUND_OFF)
    # … and exactly what the clean file gives
    res, clean = ingest_cli(run_gonio, tmp_path, CLEAN, *RF, *GRID, name="clean.json")
    assert res.exit_code == 0, res.stderr
    np.testing.assert_array_equal(m.brdf, read_measurement(clean).brdf)


def test_export_summary_records_preamble_and_labels(tmp_path):
    m = core.ingest([EXPORT], quantity="reflectance-factor", grid_nm="400:700:10")
    info = m.summary["files"][0]
    assert info["header_line"] == 3 and info["preamble_lines"] == 2
    assert info["label_columns"] == ["Name", "Date/Time"]
    assert info["sample_column"] == "Name" and info["sample"] == "GREEN_EARTH_A"
    assert info["rows"] == 12 and info["spectra"] == 12
    text = core.format_summary(m.summary)
    assert "skipped: 2 preamble lines" in text
    assert "label columns set aside: Name, Date/Time; sample GREEN_EARTH_A" in text


def test_padded_preamble_and_more_of_it(tmp_path):
    """Excel pads every line to the widest row with delimiters; other instruments write
    more preamble (and comments, blank lines) before the header."""
    lines = EXPORT.read_text().splitlines()
    width = lines[2].count(",")
    preamble = ["Instrument:,MA-T12", "Illuminant:,D65", "", "# exported", *lines[:2]]
    padded = [p + "," * (width - p.count(",")) for p in preamble if p]
    src = tmp_path / "padded.csv"
    src.write_text("\r\n".join(padded + lines[2:]) + "\r\n")
    m = core.ingest([src], quantity="reflectance-factor", grid_nm="400:700:10")
    np.testing.assert_allclose(m.brdf, clean_truth()[2] / math.pi, rtol=ROUND_OFF)
    info = m.summary["files"][0]
    assert (info["header_line"], info["preamble_lines"], info["comment_lines"]) == (6, 4, 1)


def test_european_export_keeps_its_labels(tmp_path):
    """Semicolons and decimal commas: numbers get '.', labels keep their commas."""
    lines = EXPORT.read_text().splitlines()
    out = []
    for k, line in enumerate(lines):
        cells = line.split(",")
        if k >= 3:
            cells = ["Panel, left", cells[1]] + [c.replace(".", ",") for c in cells[2:]]
        out.append(";".join(cells))
    src = tmp_path / "eu.csv"
    src.write_text("\r\n".join(out) + "\r\n")
    m = core.ingest([src], quantity="reflectance-factor", grid_nm="400:700:10",
                    sample="Panel, left")
    np.testing.assert_allclose(m.brdf, clean_truth()[2] / math.pi, rtol=ROUND_OFF)
    info = m.summary["files"][0]
    assert info["decimal_comma"] and info["samples"] == ["Panel, left"]


@pytest.mark.parametrize("layout", ["wide", "long"])
def test_label_columns_in_the_other_layouts(tmp_path, layout):
    wl = np.arange(380.0, 781.0, 10.0)
    v = [0.1 + 0.2 * (w - 380.0) / 400.0 for w in wl.tolist()]
    if layout == "wide":
        text = ("Sample_ID,theta_i_deg,Comment,theta_o_deg," + ",".join(f"{w:g}" for w in wl)
                + "\nS1,20,first,10," + ",".join(repr(x) for x in v) + "\n")
    else:
        text = "theta_i_deg,theta_o_deg,wavelength_nm,value,Operator\n" + "".join(
            f"20,10,{w:g},{x!r},someone\n" for w, x in zip(wl, v))
    src = tmp_path / "l.csv"
    src.write_text(text)
    m = core.ingest([src])
    np.testing.assert_array_equal(m.brdf[0], v)
    assert m.summary["files"][0]["label_columns"] == (["Sample_ID", "Comment"]
                                                      if layout == "wide" else ["Operator"])


# -------------------------------------------------------------------- samples --

def test_two_samples_need_sample_and_the_error_lists_them(run_gonio, tmp_path):
    res, out = ingest_cli(run_gonio, tmp_path, TWO, *RF, *GRID)
    line = one_error_line(res)
    # the first row of the second sample: header on line 3, 12 rows of A, so line 16
    assert f"{TWO}:16: column Name: holds 2 samples (GREEN_EARTH_A, GREEN_EARTH_B); " \
           "pick one with --sample NAME" in line
    assert not out.exists()


@pytest.mark.parametrize("sample, clean", [("GREEN_EARTH_A", CLEAN),
                                           ("GREEN_EARTH_B", FIXTURES / "ma_t12_clean_b.csv")])
def test_sample_picks_its_rows(run_gonio, tmp_path, sample, clean):
    res, out = ingest_cli(run_gonio, tmp_path, TWO, *RF, *GRID, "--sample", sample)
    assert res.exit_code == 0, res.stderr
    m = read_measurement(out)
    ti, to, r = clean_truth(clean)
    np.testing.assert_array_equal(m.theta_o_deg, to)
    np.testing.assert_allclose(m.brdf, r / math.pi, rtol=ROUND_OFF)
    assert m.n_repeats.tolist() == [1] * 12  # the other sample is not a repeat
    doc = json.loads(out.read_text())
    assert doc["parameters"]["sample"] == sample
    info = m.summary["files"][0]
    assert info["rows_other_samples"] == 12 and info["rows"] == 24


def test_sample_that_names_nothing_lists_the_samples(run_gonio, tmp_path):
    res, _ = ingest_cli(run_gonio, tmp_path, TWO, *RF, *GRID, "--sample", "green_earth_a")
    line = one_error_line(res)
    assert f"{TWO}:3: column Name: holds no sample 'green_earth_a', only GREEN_EARTH_A, " \
           "GREEN_EARTH_B; pick one" in line


def test_sample_in_a_file_without_a_sample_column(run_gonio, tmp_path):
    res, _ = ingest_cli(run_gonio, tmp_path, CLEAN, *RF, *GRID, "--sample", "A")
    line = one_error_line(res)
    assert f"{CLEAN}:1: --sample 'A' is given, but the file has no column naming " \
           "samples" in line


def test_many_samples_are_listed_briefly(tmp_path):
    wl = np.arange(380.0, 781.0, 10.0)
    rows = [f"S{k},20,{10 + k}," + ",".join(["0.2"] * wl.size) for k in range(14)]
    src = tmp_path / "many.csv"
    src.write_text("name,theta_i_deg,theta_o_deg," + ",".join(f"{w:g}" for w in wl) + "\n"
                   + "\n".join(rows) + "\n")
    with pytest.raises(InputError) as err:
        core.ingest([src])
    assert "holds 14 samples (S0, S1, S2, S3, S4, S5, S6, S7, S8, S9, ... (4 more))" \
        in str(err.value)


# -------------------------------------------------------------------- percent --

def test_percent_is_refused_with_the_scale_fix(run_gonio, tmp_path):
    res, out = ingest_cli(run_gonio, tmp_path, PERCENT, *RF, *GRID)
    line = one_error_line(res)
    assert f"{PERCENT}:" in line and "column " in line
    assert "the values look like percent: their median reflectance factor is" in line
    assert line.endswith("; pass --scale 0.01 if they are percent")
    assert not out.exists()


def test_percent_with_scale_equals_the_fractions(run_gonio, tmp_path):
    res, out = ingest_cli(run_gonio, tmp_path, PERCENT, *RF, *GRID, "--scale", "0.01")
    assert res.exit_code == 0, res.stderr
    m = read_measurement(out)
    np.testing.assert_allclose(m.brdf, clean_truth()[2] / math.pi, rtol=ROUND_OFF)
    assert json.loads(out.read_text())["parameters"]["scale"] == 0.01
    assert "values x 0.01 (--scale)" in core.format_summary(m.summary)


def test_percent_multiangle_without_quantity_names_both_options(run_gonio, tmp_path):
    res, _ = ingest_cli(run_gonio, tmp_path, PERCENT, *GRID)
    line = one_error_line(res)
    assert "median BRDF (sr^-1) is" in line
    assert "pass --quantity reflectance-factor --scale 0.01 if they are reflectance " \
           "factors in percent" in line


def glossy_reflectance_factor():
    """An in-plane sweep of a glossy sample as reflectance factors R (n, n_λ): a matte base
    of 0.04 and a specular lobe of peak 25 and 4° width, sampled every 5° plus ±1, 2, 3°
    around the mirror (as the RGL sweeps are), θi = 20…60°."""
    ti, to = [], []
    for theta_i in (20.0, 40.0, 60.0):
        offsets = sorted(set(np.arange(-80.0, 81.0, 5.0) - theta_i) | {-3, -2, -1, 0, 1, 2, 3})
        for d in offsets:
            if abs(theta_i + d) < 90:
                ti.append(theta_i)
                to.append(theta_i + d)
    ti, to = np.array(ti), np.array(to)
    wl = np.arange(380.0, 781.0, 10.0)
    lobe = 25.0 * np.exp(-((to - ti) / 4.0) ** 2)
    tint = 0.8 + 0.2 * (wl - 380.0) / 400.0
    return ti, to, (0.04 + lobe[:, None]) * tint


def write_wide(path, ti, to, values):
    wl = np.arange(380.0, 781.0, 10.0)
    path.write_text("theta_i_deg,theta_o_deg," + ",".join(f"{w:g}" for w in wl) + "\n"
                    + "".join(f"{float(a)!r},{float(b)!r},"
                              + ",".join(repr(float(x)) for x in v) + "\n"
                              for a, b, v in zip(ti, to, values)))
    return path


def test_glossy_peak_above_the_limit_is_not_refused(tmp_path):
    ti, to, r = glossy_reflectance_factor()
    above = np.mean(r > PERCENT_MEDIAN_LIMIT, axis=1) > 0
    # the test means something: R > 1.5 (up to ~25) at some configurations, not most
    assert r.max() > 15 and 8 <= above.sum() < 0.5 * above.size
    m = core.ingest([write_wide(tmp_path / "g.csv", ti, to, r)],
                    quantity="reflectance-factor")
    order = np.lexsort((to, ti))
    np.testing.assert_allclose(m.brdf, r[order] / math.pi, rtol=ROUND_OFF)


def test_glossy_in_percent_is_refused(tmp_path):
    ti, to, r = glossy_reflectance_factor()
    with pytest.raises(InputError, match="look like percent"):
        core.ingest([write_wide(tmp_path / "g.csv", ti, to, 100 * r)],
                    quantity="reflectance-factor")


#: A matte sample of reflectance factor R = 0.5 in each quantity's units, by hand:
#: brdf R/π; ratio-to-white R / R_white (0.99, the default); flux ratio f cos θo Δω
#: (seed 004 eqs. 5, 7: w = 4 mm, d = 400 mm).
OMEGA = math.pi * 4.0 ** 2 / (4 * 400.0 ** 2)
MATTE = {
    "brdf": ([], lambda to: 0.5 / math.pi),
    "reflectance-factor": ([], lambda to: 0.5),
    "ratio-to-white": ([], lambda to: 0.5 / 0.99),
    "flux-ratio": (["--aperture-mm", "4", "--distance-mm", "400"],
                   lambda to: 0.5 / math.pi * math.cos(math.radians(to)) * OMEGA),
}


@pytest.mark.parametrize("quantity", sorted(MATTE))
@pytest.mark.parametrize("factor, refused", [(1.0, False), (100.0, True)])
def test_every_quantity_refuses_percent_of_a_matte_sample(run_gonio, tmp_path, quantity,
                                                          factor, refused):
    options, value = MATTE[quantity]
    ti = np.array([20.0, 20.0, 45.0, 45.0])
    to = np.array([-30.0, 10.0, 0.0, 60.0])
    values = np.array([[value(b)] * 41 for b in to]) * factor
    src = write_wide(tmp_path / "matte.csv", ti, to, values)
    res, out = ingest_cli(run_gonio, tmp_path, src, "--quantity", quantity, *options)
    if refused:
        assert "look like percent" in one_error_line(res)
    else:
        assert res.exit_code == 0, res.stderr
        np.testing.assert_allclose(read_measurement(out).brdf, 0.5 / math.pi, rtol=1e-12)


@pytest.mark.parametrize("median, refused", [(1.49, False), (1.51, True)])
def test_the_limit_is_the_median(tmp_path, median, refused):
    """Half the values at 3.0 and half just below (above) the limit: only the median
    decides, not the peak."""
    ti = np.full(6, 30.0)
    to = np.array([-40.0, -20.0, 0.0, 20.0, 30.0, 45.0])
    values = np.array([[median]] * 3 + [[3.0]] * 2 + [[median]]) * np.ones((1, 41))
    src = write_wide(tmp_path / "m.csv", ti, to, values)
    if refused:
        with pytest.raises(InputError, match="look like percent"):
            core.ingest([src], quantity="reflectance-factor")
    else:
        assert core.ingest([src], quantity="reflectance-factor").brdf.max() == \
            pytest.approx(3.0 / math.pi, rel=1e-12)


def test_far_too_large_values_are_not_called_percent(tmp_path):
    ti, to = np.array([20.0, 20.0]), np.array([0.0, 30.0])
    src = write_wide(tmp_path / "big.csv", ti, to, np.full((2, 41), 0.3))
    with pytest.raises(InputError, match="far too large") as err:
        core.ingest([src], quantity="flux-ratio", aperture_mm=4.0, distance_mm=400.0)
    assert "check --quantity and its options" in str(err.value)


# ------------------------------------------------- multi-angle read as BRDF --

def test_multiangle_without_quantity_warns(run_gonio, tmp_path):
    res, out = ingest_cli(run_gonio, tmp_path, CLEAN, *GRID)
    assert res.exit_code == 0, res.stderr
    warnings = [w for w in res.stderr.splitlines() if w.startswith("gonio: warning: ")]
    assert len(warnings) == 1
    assert f"{CLEAN}: a multi-angle file read as BRDF in sr^-1" in warnings[0]
    assert "pass --quantity reflectance-factor" in warnings[0]
    m = read_measurement(out)
    assert m.quantity == "brdf"
    np.testing.assert_allclose(m.brdf, clean_truth()[2], rtol=ROUND_OFF)  # unconverted
    assert m.summary["warnings"] == [warnings[0].removeprefix("gonio: warning: ")]


@pytest.mark.parametrize("quantity", ["brdf", "reflectance-factor"])
def test_multiangle_with_a_quantity_does_not_warn(run_gonio, tmp_path, quantity):
    res, _ = ingest_cli(run_gonio, tmp_path, CLEAN, *GRID, "--quantity", quantity)
    assert res.exit_code == 0 and "warning" not in res.stderr, res.stderr


def test_wide_file_without_quantity_does_not_warn(run_gonio, tmp_path):
    ti, to, r = glossy_reflectance_factor()
    res, _ = ingest_cli(run_gonio, tmp_path, write_wide(tmp_path / "g.csv", ti, to, r / 10))
    assert res.exit_code == 0 and "warning" not in res.stderr, res.stderr
