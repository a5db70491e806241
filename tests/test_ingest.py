"""gonio ingest: layouts, quantities, resampling, merging, repeats, dark, artifact.

Every number is checked against analytic truth: the conversions of seed 004 eqs. 5, 7, 8
are exact products, so they are asserted to float round-off; resampling of linear spectra
is exact, of smooth ones within the discretisation bound stated beside the assertion.
Test CSVs are written into ``tmp_path``; bad input lives in ``test_ingest_errors.py``.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from gonio_cli import ingest as core
from gonio_cli.artifact import read_artifact
from gonio_cli.csvlayouts import aspecular_angles, read_spectra
from gonio_cli.ingest.quantities import DEFAULT_WHITE_REFLECTANCE, QUANTITIES, receptor_solid_angle
from gonio_cli.schemas import read_measurement
from gonio_cli.spectra import DEFAULT_GRID_NM, parse_grid

GRID = parse_grid()  # 380..780 nm, 10 nm, 41 samples

#: Conversions are a product or quotient of a few float64 numbers written with repr():
#: relative round-off of a few ulp.
EXACT = 1e-12


def only_the_summary_line(stderr: str, out) -> bool:
    """A clean run's stderr: no warning, just the one summary line naming the output."""
    lines = stderr.splitlines()
    return len(lines) == 1 and lines[0].startswith(f"{out}: ") and " configuration" in lines[0]


def write(tmp_path, name, text, encoding="utf-8"):
    path = tmp_path / name
    path.write_bytes(text.encode(encoding))
    return path


def wide_text(theta_i, theta_o, values, wl=GRID, delimiter=",", decimal_comma=False):
    """A wide-layout CSV: one row per (θi, θo), one column per wavelength (repr floats)."""
    fmt = (lambda x: repr(float(x)).replace(".", ",")) if decimal_comma else \
        (lambda x: repr(float(x)))
    head = delimiter.join(["theta_i_deg", "theta_o_deg"] + [f"{w:g}" for w in wl])
    rows = [delimiter.join([fmt(a), fmt(b)] + [fmt(x) for x in v])
            for a, b, v in zip(theta_i, theta_o, values)]
    return "\n".join([head] + rows) + "\n"


def long_text(theta_i, theta_o, values, wl=GRID):
    rows = ["theta_i_deg,theta_o_deg,wavelength_nm,value"]
    rows += [f"{float(a)!r},{float(b)!r},{w:g},{float(x)!r}"
             for a, b, v in zip(theta_i, theta_o, values) for w, x in zip(wl, v)]
    return "\n".join(rows) + "\n"


def smooth(wl, k=0):
    """An analytic positive spectrum (n_λ,) — a different one for each k."""
    return 0.2 + 0.1 * np.sin(np.asarray(wl) / (40.0 + 7 * k)) + 0.01 * k


def ingest(*paths, **options):
    return core.ingest([str(p) for p in paths], **options)


ANGLES = (np.array([20.0, 20.0, 45.0, 45.0, 60.0]), np.array([0.0, 20.0, -30.0, 45.0, 70.0]))


def table(wl=GRID):
    ti, to = ANGLES
    return ti, to, np.stack([smooth(wl, k) for k in range(ti.size)])


# ----------------------------------------------------------------------- layouts --

def test_wide_layout_reads_values_unchanged(tmp_path):
    ti, to, v = table()
    m = ingest(write(tmp_path, "w.csv", wide_text(ti, to, v)))
    assert m.wavelength_nm.tolist() == GRID.tolist()
    # Configurations come out sorted by θi then θo; ANGLES already are.
    np.testing.assert_array_equal(m.theta_i_deg, ti)
    np.testing.assert_array_equal(m.theta_o_deg, to)
    np.testing.assert_array_equal(m.brdf, v)  # same grid: no resampling, no arithmetic
    assert m.brdf_std is None and m.n_repeats.tolist() == [1] * 5
    assert m.quantity == "brdf"


def test_long_layout_equals_wide(tmp_path):
    ti, to, v = table()
    wide = ingest(write(tmp_path, "w.csv", wide_text(ti, to, v)))
    # Long rows in scrambled order: the layout must not depend on row order.
    lines = long_text(ti, to, v).splitlines()
    rng = np.random.default_rng(7)
    body = [lines[0]] + [lines[1:][k] for k in rng.permutation(len(lines) - 1)]
    long = ingest(write(tmp_path, "l.csv", "\n".join(body) + "\n"))
    np.testing.assert_array_equal(long.brdf, wide.brdf)
    np.testing.assert_array_equal(long.theta_o_deg, wide.theta_o_deg)
    assert long.summary["files"][0]["layout"] == "long"


def test_long_layout_column_order_and_case_are_free(tmp_path):
    text = "VALUE,wavelength_nm,Theta_O_deg,theta_i_deg\n" + "".join(
        f"{float(x)!r},{w:g},10,30\n" for w, x in zip(GRID, smooth(GRID)))
    m = ingest(write(tmp_path, "l.csv", text))
    assert (m.theta_i_deg[0], m.theta_o_deg[0]) == (30.0, 10.0)
    np.testing.assert_array_equal(m.brdf[0], smooth(GRID))


@pytest.mark.parametrize("label, theta_i, theta_o", [
    ("45as15", 45.0, 30.0),      # 15° from specular towards the light
    ("45as-15", 45.0, 60.0),     # beyond specular
    ("45as110", 45.0, -65.0),    # on the light's side
    ("45as45", 45.0, 0.0),       # the normal
    ("15AS-15", 15.0, 30.0),     # case-insensitive
    ("45°as25°", 45.0, 20.0),    # degree signs tolerated
    ("45as0", 45.0, 45.0),       # the specular direction
])
def test_aspecular_labels(label, theta_i, theta_o):
    assert aspecular_angles(label) == (theta_i, theta_o)


@pytest.mark.parametrize("label", ["45", "as15", "45as", "45x15", "45as15as3", ""])
def test_not_aspecular_labels(label):
    assert aspecular_angles(label) is None


def test_multiangle_layout(tmp_path):
    labels = ["45as-15", "45as15", "45as110", "15as45"]
    r = np.stack([smooth(GRID, k) for k in range(4)])
    text = "geometry," + ",".join(f"{w:g}" for w in GRID) + "\n" + "".join(
        g + "," + ",".join(repr(float(x)) for x in v) + "\n" for g, v in zip(labels, r))
    m = ingest(write(tmp_path, "ma.csv", text), quantity="reflectance-factor")
    # Sorted by (θi, θo): 15as45 → (15, −30); 45as110 → (45, −65); 45as15 → (45, 30);
    # 45as-15 → (45, 60).
    assert m.theta_i_deg.tolist() == [15.0, 45.0, 45.0, 45.0]
    assert m.theta_o_deg.tolist() == [-30.0, -65.0, 30.0, 60.0]
    np.testing.assert_allclose(m.brdf, r[[3, 2, 1, 0]] / np.pi, rtol=EXACT)
    assert m.summary["files"][0]["layout"] == "multi-angle"


# -------------------------------------------------------------------- quantities --

def test_quantity_registry_drives_the_help(run_gonio):
    res = run_gonio("ingest", "--help")
    text = "".join(res.stdout.split())  # help wraps lines, even inside names
    for name in QUANTITIES:
        assert name in text
    assert f"[default:{DEFAULT_GRID_NM}]" in text
    assert f"[default:{DEFAULT_WHITE_REFLECTANCE}]" in text


def test_brdf_is_identity(tmp_path):
    ti, to, v = table()
    m = ingest(write(tmp_path, "a.csv", wide_text(ti, to, v)), quantity="brdf")
    np.testing.assert_array_equal(m.brdf, v)


def test_reflectance_factor_is_pi_times_brdf(tmp_path):
    ti, to, v = table()
    m = ingest(write(tmp_path, "a.csv", wide_text(ti, to, v)), quantity="reflectance-factor")
    np.testing.assert_allclose(m.brdf, v / np.pi, rtol=EXACT)


def test_ratio_to_white_default_099(tmp_path):
    ti, to, v = table()
    m = ingest(write(tmp_path, "a.csv", wide_text(ti, to, v)), quantity="ratio-to-white")
    # docs/conventions.md: BRDF = ratio × R_white / π with R_white = 0.99 unless given.
    np.testing.assert_allclose(m.brdf, v * 0.99 / np.pi, rtol=EXACT)


def test_ratio_to_white_number(tmp_path):
    ti, to, v = table()
    m = ingest(write(tmp_path, "a.csv", wide_text(ti, to, v)), quantity="ratio-to-white",
               white_reflectance=0.5)
    np.testing.assert_allclose(m.brdf, v * 0.5 / np.pi, rtol=EXACT)


def test_ratio_to_white_spectrum_csv(tmp_path):
    """A white spectrum on a coarser, wider grid, linear in λ: interpolation is exact."""
    ti, to, v = table()
    wl_white = np.arange(300.0, 901.0, 50.0)
    r_white = 0.9 + 0.08 * (wl_white - 300.0) / 600.0
    white = write(tmp_path, "white.csv", "wavelength_nm,value\n" + "".join(
        f"{w:g},{float(r)!r}\n" for w, r in zip(wl_white, r_white)))
    m = ingest(write(tmp_path, "a.csv", wide_text(ti, to, v)), quantity="ratio-to-white",
               white_reflectance=str(white))
    expected_white = 0.9 + 0.08 * (GRID - 300.0) / 600.0
    # Linear interpolation of a linear function: exact up to round-off in the weights.
    np.testing.assert_allclose(m.brdf, v * expected_white / np.pi, rtol=1e-12)


def test_flux_ratio_seed004_eqs_5_and_7(tmp_path):
    ti, to, v = table()
    v = v * 1e-4  # a flux ratio into 7.9e-5 sr: reflectance factors pi*f of 0.3-1
    w_mm, d_mm = 4.0, 400.0  # seed 004 §4.1: w = 0.4 cm, d = 40 cm
    m = ingest(write(tmp_path, "a.csv", wide_text(ti, to, v)), quantity="flux-ratio",
               aperture_mm=w_mm, distance_mm=d_mm)
    omega = math.pi * w_mm ** 2 / (4 * d_mm ** 2)            # eq. 7
    expected = v / (np.cos(np.radians(to))[:, None] * omega)  # eq. 5
    np.testing.assert_allclose(m.brdf, expected, rtol=EXACT)
    assert receptor_solid_angle(w_mm, d_mm) == pytest.approx(7.853981633974483e-05,
                                                                  rel=EXACT)


def test_flux_ratio_on_the_command_line(tmp_path, run_gonio):
    ti, to, v = table()
    v = v * 1e-4  # a flux ratio into 7.9e-5 sr: reflectance factors pi*f of 0.3-1
    src = write(tmp_path, "a.csv", wide_text(ti, to, v))
    out = tmp_path / "m.json"
    res = run_gonio("ingest", src, "-o", out, "--quantity", "flux-ratio", "--aperture-mm",
                    "4", "--distance-mm", "400")
    assert res.exit_code == 0, res.stderr
    m = read_measurement(out)
    omega = math.pi * 16 / (4 * 400.0 ** 2)
    np.testing.assert_allclose(m.brdf, v / (np.cos(np.radians(to))[:, None] * omega),
                               rtol=EXACT)
    doc = json.loads(out.read_text())
    assert doc["parameters"]["aperture_mm"] == 4.0
    assert doc["parameters"]["distance_mm"] == 400.0
    assert doc["quantity"] == "flux-ratio"


# ---------------------------------------------------------------------- dark --

def test_dark_is_subtracted_in_input_units_before_conversion(tmp_path):
    ti, to, v = table()
    dark_wl = np.arange(370.0, 791.0, 20.0)  # coarser: interpolated, linear → exact
    dark_v = 0.001 + 0.00001 * (dark_wl - 370.0)
    dark = write(tmp_path, "dark.csv", "wavelength_nm,value\n" + "".join(
        f"{w:g},{float(x)!r}\n" for w, x in zip(dark_wl, dark_v)))
    m = ingest(write(tmp_path, "a.csv", wide_text(ti, to, v)), quantity="ratio-to-white",
               dark=str(dark))
    dark_on_grid = 0.001 + 0.00001 * (GRID - 370.0)
    np.testing.assert_allclose(m.brdf, (v - dark_on_grid) * 0.99 / np.pi, rtol=1e-12)


def test_dark_provenance_in_artifact(tmp_path, run_gonio):
    ti, to, v = table()
    src = write(tmp_path, "a.csv", wide_text(ti, to, v))
    dark = write(tmp_path, "dark.csv", "wavelength_nm,value\n380,0.001\n780,0.001\n")
    white = write(tmp_path, "white.csv", "wavelength_nm,value\n380,0.98\n780,0.98\n")
    out = tmp_path / "m.json"
    res = run_gonio("ingest", src, "-o", out, "--quantity", "ratio-to-white", "--dark", dark,
                    "--white-reflectance", white)
    assert res.exit_code == 0, res.stderr
    doc = json.loads(out.read_text())
    # paths relative to the artifact's folder (here the same one: reproducible bytes)
    assert [i["path"] for i in doc["inputs"]] == ["a.csv", "dark.csv", "white.csv"]
    assert all(len(i["sha256"]) == 64 for i in doc["inputs"])
    assert doc["parameters"]["dark"] == "dark.csv"
    assert doc["parameters"]["white_reflectance"] == "white.csv"
    np.testing.assert_allclose(read_measurement(out).brdf, (v - 0.001) * 0.98 / np.pi,
                               rtol=1e-12)


# ---------------------------------------------------------------- resampling --

@pytest.mark.parametrize("wl, period, tolerance", [
    # 2 nm input over 360–800 nm, averaged under the grid's symmetric hats: linear spectra
    # are exact; for a smooth one the hat average is f(g) + f''/2 · E[(w−g)²] with
    # E[(w−g)²] = 16 nm² for 2 nm samples under a 10 nm half-width hat, and
    # |f''| ≤ 0.1/30² → error ≤ 8.9e-4.
    (np.arange(360.0, 801.0, 2.0), 30.0, 9e-4),
    # 20 nm input, linearly interpolated: linear spectra exact; the error of a smooth
    # one is ≤ h²/8 · max|f''| = 20²/8 · 0.1/60² = 1.4e-3.
    (np.arange(380.0, 781.0, 20.0), 60.0, 1.4e-3),
])
def test_resampling_against_analytic_spectra(tmp_path, wl, period, tolerance):
    linear = 0.1 + 0.001 * (wl - 360.0)
    curved = 0.3 + 0.1 * np.sin(wl / period)
    m = ingest(write(tmp_path, "in.csv", wide_text([30.0, 30.0], [10.0, 20.0],
                                                   [linear, curved], wl=wl)))
    np.testing.assert_allclose(m.brdf[0], 0.1 + 0.001 * (GRID - 360.0), rtol=1e-12)
    np.testing.assert_allclose(m.brdf[1], 0.3 + 0.1 * np.sin(GRID / period), atol=tolerance)
    assert m.summary["resampled"] is True


def test_coarser_input_keeps_its_samples(tmp_path):
    """Grid wavelengths that are input samples are reproduced exactly by interpolation."""
    wl = np.arange(380.0, 781.0, 20.0)
    v = 0.3 + 0.1 * np.sin(wl / 60.0)
    m = ingest(write(tmp_path, "in.csv", wide_text([30.0], [10.0], [v], wl=wl)))
    np.testing.assert_allclose(m.brdf[0, ::2], v, rtol=1e-12)


def test_resampling_warns_once_per_file(tmp_path, run_gonio):
    wl = np.arange(380.0, 781.0, 5.0)
    src = write(tmp_path, "five.csv", wide_text([30.0], [10.0], [smooth(wl)], wl=wl))
    res = run_gonio("ingest", src, "-o", tmp_path / "m.json")
    assert res.exit_code == 0
    lines = res.stderr.strip().splitlines()
    warnings = [line for line in lines if line.startswith("gonio: warning: ")]
    assert len(warnings) == 1 and len(lines) == 2  # the warning, then the summary line
    assert lines[-1].startswith(f"{tmp_path / 'm.json'}: 1 configuration ")
    assert warnings[0].startswith("gonio: warning: ") and "five.csv" in warnings[0]
    assert "resampled onto the working grid 380:780:10" in warnings[0]
    quiet = run_gonio("--quiet", "ingest", src, "-o", tmp_path / "q.json")
    assert quiet.exit_code == 0 and quiet.stderr == ""


def test_same_grid_gives_no_warning(tmp_path, run_gonio):
    ti, to, v = table()
    res = run_gonio("ingest", write(tmp_path, "a.csv", wide_text(ti, to, v)), "-o",
                    tmp_path / "m.json")
    assert res.exit_code == 0
    assert only_the_summary_line(res.stderr, tmp_path / "m.json")


def test_wider_input_is_trimmed_without_changing_values(tmp_path, run_gonio):
    """300–900 nm at 5 nm gives the same result as its 370–790 nm part alone (the grid
    plus one grid step each side, all resampling looks at; seed 000 trims to 380–780 nm);
    the dropped wavelengths are counted."""
    wl = np.arange(300.0, 901.0, 5.0)
    ti, to = ANGLES
    v = np.stack([smooth(wl, k) for k in range(ti.size)])
    full = ingest(write(tmp_path, "full.csv", wide_text(ti, to, v, wl=wl)))
    keep = (wl >= 370.0) & (wl <= 790.0)
    part = ingest(write(tmp_path, "part.csv", wide_text(ti, to, v[:, keep], wl=wl[keep])))
    np.testing.assert_array_equal(full.brdf, part.brdf)
    assert full.summary["files"][0]["wavelengths_dropped"] == wl.size - keep.sum()


def test_other_working_grid(tmp_path):
    ti, to, v = table()
    m = ingest(write(tmp_path, "a.csv", wide_text(ti, to, v)), grid_nm="400:700:20")
    assert m.wavelength_nm.tolist() == list(range(400, 701, 20))
    # 10 nm input under 20 nm hats: weights ¼, ½, ¼ on the neighbours (the input reaches
    # a full grid step beyond both ends, 380 and 720 nm, so every hat lies inside it).
    j = np.arange(2, 33, 2)
    expected = 0.25 * v[:, j - 1] + 0.5 * v[:, j] + 0.25 * v[:, j + 1]
    np.testing.assert_allclose(m.brdf, expected, rtol=1e-12)


# ------------------------------------------------------------ repeats, merging --

def test_repeats_mean_and_sample_std(tmp_path, rng):
    ti, to, v = table()
    reps = np.array([3, 1, 2, 4, 1])
    rows_ti, rows_to, rows_v = [], [], []
    for a, b, spec, n in zip(ti, to, v, reps):
        for _ in range(n):
            rows_ti.append(a)
            rows_to.append(b)
            rows_v.append(spec * np.exp(0.05 * rng.standard_normal(spec.size)))
    order = rng.permutation(len(rows_v))  # repeats need not be adjacent
    rows_ti, rows_to = np.array(rows_ti)[order], np.array(rows_to)[order]
    rows_v = np.array(rows_v)[order]
    m = ingest(write(tmp_path, "r.csv", wide_text(rows_ti, rows_to, rows_v)))
    assert m.n_repeats.tolist() == reps.tolist()
    for k, (a, b) in enumerate(zip(ti, to)):
        sel = (rows_ti == a) & (rows_to == b)
        # Sums of ≤ 4 values: a few ulp of round-off.
        np.testing.assert_allclose(m.brdf[k], rows_v[sel].mean(axis=0), rtol=1e-13)
        expected = rows_v[sel].std(axis=0, ddof=1) if sel.sum() > 1 else 0.0
        np.testing.assert_allclose(m.brdf_std[k], expected, rtol=1e-10, atol=1e-15)


def test_repeats_in_long_layout(tmp_path):
    """Three blocks of the same configurations: repeat k is the k-th row of a (θi, θo, λ)."""
    ti, to, v = table()
    blocks = [v * f for f in (0.9, 1.0, 1.1)]
    text = long_text(ti, to, blocks[0]) + "".join(
        long_text(ti, to, b).split("\n", 1)[1] for b in blocks[1:])
    m = ingest(write(tmp_path, "l.csv", text))
    assert m.n_repeats.tolist() == [3] * 5
    np.testing.assert_allclose(m.brdf, v, rtol=1e-13)                 # mean of 0.9, 1, 1.1
    np.testing.assert_allclose(m.brdf_std, 0.1 * v, rtol=1e-10)       # their sample std


def test_merging_files_equals_one_file(tmp_path):
    ti, to, v = table()
    one = ingest(write(tmp_path, "all.csv", wide_text(ti, to, v)))
    a = write(tmp_path, "a.csv", wide_text(ti[:2], to[:2], v[:2]))
    b = write(tmp_path, "b.csv", wide_text(ti[2:], to[2:], v[2:], delimiter="\t"))
    merged = ingest(b, a)  # order of files does not matter
    np.testing.assert_array_equal(merged.brdf, one.brdf)
    np.testing.assert_array_equal(merged.theta_o_deg, one.theta_o_deg)
    assert [f["path"] for f in merged.summary["files"]] == [str(b), str(a)]


def test_merging_long_and_wide(tmp_path):
    ti, to, v = table()
    a = write(tmp_path, "a.csv", long_text(ti[:3], to[:3], v[:3]))
    b = write(tmp_path, "b.csv", wide_text(ti[3:], to[3:], v[3:]))
    m = ingest(a, b)
    np.testing.assert_array_equal(m.brdf, v)


def test_same_configuration_in_two_files_is_a_repeat(tmp_path):
    ti, to, v = table()
    a = write(tmp_path, "a.csv", wide_text(ti, to, v))
    b = write(tmp_path, "b.csv", wide_text(ti, to, 3 * v))
    m = ingest(a, b)
    assert m.n_repeats.tolist() == [2] * 5
    np.testing.assert_allclose(m.brdf, 2 * v, rtol=1e-13)
    np.testing.assert_allclose(m.brdf_std, np.sqrt(2) * v, rtol=1e-12)


# ------------------------------------------------- delimiters, decimal comma, BOM --

def test_semicolon_decimal_comma_bom_crlf_comments(tmp_path):
    ti, to, v = table()
    text = ("# exported by an instrument\r\n# operator: x\r\n"
            + wide_text(ti + 0.5, to, v, delimiter=";", decimal_comma=True)
            .replace("\n", "\r\n") + ";;;\r\n\r\n")
    m = ingest(write(tmp_path, "eu.csv", text, encoding="utf-8-sig"))
    np.testing.assert_array_equal(m.brdf, v)
    np.testing.assert_array_equal(m.theta_i_deg, ti + 0.5)  # "20,5" is 20.5
    info = m.summary["files"][0]
    assert info["delimiter"] == "semicolon" and info["decimal_comma"] is True
    assert info["comment_lines"] == 2 and info["empty_rows"] == 1


def test_tab_delimited(tmp_path):
    ti, to, v = table()
    m = ingest(write(tmp_path, "t.csv", wide_text(ti, to, v, delimiter="\t")))
    np.testing.assert_array_equal(m.brdf, v)
    assert m.summary["files"][0]["delimiter"] == "tab"


def test_trailing_delimiters_and_quotes_and_spaces(tmp_path):
    text = ('"theta_i_deg", "theta_o_deg", 380, 780,\n'
            '20, 10, 0.5, 0.7,\n')
    m = ingest(write(tmp_path, "q.csv", text))
    np.testing.assert_allclose(m.brdf[0], np.interp(GRID, [380, 780], [0.5, 0.7]),
                               rtol=1e-12)


def test_comment_lines_between_rows(tmp_path):
    ti, to, v = table()
    lines = wide_text(ti, to, v).splitlines()
    lines.insert(3, "  # a note in the middle")
    m = ingest(write(tmp_path, "c.csv", "\n".join(lines) + "\n"))
    np.testing.assert_array_equal(m.brdf, v)


# -------------------------------------------------------------------- negatives --

def test_small_negatives_are_clipped_and_counted(tmp_path, run_gonio):
    ti, to, v = table()
    v = v.copy()
    v[1, :3] = -0.001  # 0.5 % of the peak 0.3: noise
    src = write(tmp_path, "n.csv", wide_text(ti, to, v))
    out = tmp_path / "m.json"
    res = run_gonio("ingest", src, "-o", out)
    assert res.exit_code == 0
    assert "clipped 3 small negative values" in res.stderr
    m = read_measurement(out)
    assert m.brdf.min() == 0.0 and m.brdf[1, :3].tolist() == [0.0] * 3
    assert m.summary["clipped_to_zero"] == 3


def test_negative_rows_averaging_to_positive_are_kept(tmp_path):
    """Clipping acts on the mean of the repeats, so noise around a small signal is not
    biased upwards by clipping each repeat."""
    v = np.full((2, GRID.size), 0.3)
    v[0, 0], v[1, 0] = -0.001, 0.003
    m = ingest(write(tmp_path, "n.csv", wide_text([20.0, 20.0], [10.0, 10.0], v)))
    assert m.brdf[0, 0] == pytest.approx(0.001, rel=1e-12)
    assert m.summary["clipped_to_zero"] == 0


# ---------------------------------------------------------- artifact and summary --

def test_artifact_round_trip_and_provenance(tmp_path, run_gonio):
    ti, to, v = table()
    src = write(tmp_path, "a.csv", wide_text(ti, to, v))
    out = tmp_path / "sub" / "m.json"
    res = run_gonio("ingest", src, "-o", out)
    assert res.exit_code == 0 and res.stdout == ""
    doc = json.loads(out.read_text())
    assert doc["schema"] == "gonio.measurement" and doc["schema_version"] == 1
    assert doc["parameters"] == {"quantity": "brdf", "white_reflectance": None,
                                 "aperture_mm": None, "distance_mm": None, "dark": None,
                                 "grid_nm": DEFAULT_GRID_NM, "scale": 1.0, "sample": None}
    assert "time_s" not in doc and "created_utc" not in doc    # in its side record
    assert read_artifact(out, "gonio.measurement", (1,))["time_s"] > 0
    assert doc["brdf_std"] is None
    m = read_measurement(out)
    np.testing.assert_array_equal(m.brdf, v)
    # no temp files; the side record beside the artifact
    assert sorted(p.name for p in out.parent.iterdir()) == ["m.json", "m.run.json"]


def test_summary_on_stdout(tmp_path, run_gonio):
    ti, to, v = table()
    res = run_gonio("ingest", write(tmp_path, "a.csv", wide_text(ti, to, v)), "-o",
                    tmp_path / "m.json", "--summary")
    assert res.exit_code == 0
    out = res.stdout
    assert "wide layout" in out and "comma-delimited" in out
    assert "angles of incidence (deg): 20, 45, 60" in out
    assert "theta_i 45: theta_o -30 to 45 deg, 2 configurations" in out
    assert "configurations: 5 from 5 spectra (no repeats)" in out
    assert "grid: 380:780:10 nm" in out
    assert f"BRDF: {v.min():.4g} to {v.max():.4g} sr^-1" in out
    assert "dropped: nothing" in out


def test_summary_dict_is_json_ready(tmp_path):
    ti, to, v = table()
    m = ingest(write(tmp_path, "a.csv", wide_text(ti, to, v)))
    s = json.loads(json.dumps(m.summary))
    assert s["theta_i_deg"] == [20.0, 45.0, 60.0]
    assert s["configurations"] == 5 and s["repeats_max"] == 1
    assert s["brdf_max_per_sr"] == pytest.approx(v.max(), rel=EXACT)


def test_reading_a_few_thousand_rows_is_vectorised(tmp_path):
    """Not a timing test: the long-layout pivot keeps every row's value and line."""
    rng = np.random.default_rng(3)
    ti = np.repeat([20.0, 40.0, 60.0], 20)
    to = np.tile(np.arange(-70.0, 80.0, 7.5)[:20], 3)
    v = rng.uniform(0.01, 1.0, (60, GRID.size))
    spectra = read_spectra(write(tmp_path, "l.csv", long_text(ti, to, v)))
    assert spectra.values.shape == (60, 41)
    # Line of value (k, j) is 2 + 41 k + j (header on line 1, rows in file order).
    assert spectra.lines[5, 7] == 2 + 41 * 5 + 7


# ------------------------------------------------------------ the library call --

def test_the_library_call_writes_what_gonio_ingest_writes(run_gonio, tmp_path):
    """``gonio batch`` calls :func:`gonio_cli.ingest.run` and ``write`` directly: the same
    artifact as the command, byte for byte (its times live in the side record)."""
    ti, to, v = table()
    csv = write(tmp_path, "w.csv", wide_text(ti, to, v))
    r = run_gonio("ingest", csv, "--grid-nm", "400:700:20", "-o", tmp_path / "cli.json")
    assert r.exit_code == 0, r.stderr
    result = core.run([csv], grid_nm="400:700:20")
    core.write(result, tmp_path / "lib.json")
    assert (tmp_path / "lib.json").read_bytes() == (tmp_path / "cli.json").read_bytes()
    said = result.summary_line(tmp_path / "cli.json")
    assert r.stderr.splitlines()[-1].rsplit(", ", 1)[0] == said.rsplit(", ", 1)[0]  # but time
