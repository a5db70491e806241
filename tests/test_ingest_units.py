"""gonio ingest's percent check on glossy data sampled around the mirror (issue 32, item 2).

A Torrance–Sparrow surface of GGX α = 0.1 (seed 000 eq. 2, brdf.torrance_sparrow) measured
in sr⁻¹ at θo within ±12° of θi in 1° steps has a median BRDF near 2 sr⁻¹: above the
percent limit of 1.5, yet right. It was refused as percent, even with ``--scale 1``. Truth
is the model itself, evaluated here; percent data (the same × 100 with off-specular
readings) must still be refused.
"""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli.brdf import torrance_sparrow
from gonio_cli.geometry import in_plane_cosines
from gonio_cli.percent import NEAR_SPECULAR_DEG, PERCENT_MEDIAN_LIMIT
from gonio_cli.schemas import read_measurement

WL = np.arange(380.0, 781.0, 10.0)

#: CSV values are written with repr (17 digits): read back to round-off.
ROUND_OFF = 1e-12


def glossy(offsets_deg, theta_i_deg=(20.0, 30.0, 40.0, 50.0)):
    """(θi, θo, f (n, 41) in sr⁻¹) of an α = 0.1 Torrance–Sparrow surface whose F0 rises
    from 0.04 to 0.54 (a gold-like tint), at θo = θi + each offset."""
    ti = np.repeat(np.asarray(theta_i_deg), len(offsets_deg))
    to = ti + np.tile(np.asarray(offsets_deg, float), len(theta_i_deg))
    keep = np.abs(to) < 90
    ti, to = ti[keep], to[keep]
    f0 = 0.04 + 0.5 / (1.0 + np.exp(-(WL - 550.0) / 30.0))
    return ti, to, torrance_sparrow(in_plane_cosines(ti, to), 0.1, f0)


NEAR = np.arange(-12.0, 13.0)                                   # ±12° at 1° steps
#: Every 0.5° near the mirror plus six readings 20–60° off it (most readings in the lobe).
SWEEP = np.union1d(np.arange(-12.0, 12.5, 0.5), [-60.0, -40.0, -20.0, 20.0, 40.0, 60.0])


def write(path, ti, to, values):
    path.write_text("theta_i_deg,theta_o_deg," + ",".join(f"{w:g}" for w in WL) + "\n"
                    + "".join(f"{float(a)!r},{float(b)!r},"
                              + ",".join(repr(float(x)) for x in v) + "\n"
                              for a, b, v in zip(ti, to, values)))
    return path


def test_the_case_means_something():
    """The dense near-mirror data lie above the limit at their median, and every
    configuration is within the near-specular band."""
    ti, to, f = glossy(NEAR)
    assert np.median(f) > PERCENT_MEDIAN_LIMIT
    assert np.all(np.abs(to - ti) < NEAR_SPECULAR_DEG)


def test_glossy_near_the_mirror_ingests_with_one_warning(run_gonio, tmp_path):
    ti, to, f = glossy(NEAR)
    src = write(tmp_path / "glossy.csv", ti, to, f)
    out = tmp_path / "glossy.measurement.json"
    res = run_gonio("ingest", src, "-o", out)
    assert res.exit_code == 0, res.stderr
    warnings = [line for line in res.stderr.splitlines() if line.startswith("gonio: warning")]
    assert len(warnings) == 1, res.stderr
    assert str(src) in warnings[0] and "--scale 1" in warnings[0] \
        and "--scale 0.01" in warnings[0], warnings[0]
    m = read_measurement(out)
    order = np.lexsort((to, ti))
    np.testing.assert_allclose(m.brdf, f[order], rtol=ROUND_OFF)


def test_an_explicit_scale_1_confirms_the_units_silently(run_gonio, tmp_path):
    ti, to, f = glossy(NEAR)
    src = write(tmp_path / "glossy.csv", ti, to, f)
    out = tmp_path / "glossy.measurement.json"
    res = run_gonio("ingest", src, "--scale", "1", "-o", out)
    assert res.exit_code == 0, res.stderr
    assert "warning" not in res.stderr, res.stderr
    np.testing.assert_allclose(read_measurement(out).brdf, f[np.lexsort((to, ti))],
                               rtol=ROUND_OFF)


def test_glossy_with_a_sweep_is_judged_off_the_mirror(run_gonio, tmp_path):
    """Dense near the mirror plus a few off it: most readings are in the lobe (median above
    the limit), the off-specular ones are not, so the file is read without a word."""
    ti, to, f = glossy(SWEEP)
    assert np.median(f) > PERCENT_MEDIAN_LIMIT
    src = write(tmp_path / "glossy.csv", ti, to, f)
    res = run_gonio("ingest", src, "-o", tmp_path / "g.json")
    assert res.exit_code == 0 and "warning" not in res.stderr, res.stderr


def test_the_same_in_percent_is_still_refused(run_gonio, tmp_path):
    ti, to, f = glossy(SWEEP)
    src = write(tmp_path / "glossy.csv", ti, to, 100 * f)
    out = tmp_path / "g.json"
    res = run_gonio("ingest", src, "-o", out)
    lines = res.stderr.strip().splitlines()
    assert res.exit_code == 2 and len(lines) == 1, res.stderr
    assert lines[0].startswith(f"gonio: error: {src}:") and "look like percent" in lines[0]
    assert "--scale 0.01" in lines[0] and "--scale 1" in lines[0], lines[0]
    assert not out.exists()
    # the value the message points at is an off-specular one
    row = int(lines[0].split(f"{src}:")[1].split(":")[0])
    assert abs(to[row - 2] - ti[row - 2]) >= NEAR_SPECULAR_DEG


def test_an_explicit_other_scale_is_still_checked(run_gonio, tmp_path):
    """--scale 0.01 on values in per-ten-thousand: still percent after it, refused."""
    ti, to, f = glossy(SWEEP)
    src = write(tmp_path / "glossy.csv", ti, to, 1e4 * f)
    res = run_gonio("ingest", src, "--scale", "0.01", "-o", tmp_path / "g.json")
    assert res.exit_code == 2 and "after --scale 0.01" in res.stderr, res.stderr


@pytest.mark.parametrize("scale, code", [(None, 2), ("1", 0)])
def test_percent_of_a_matte_sample_is_taken_when_the_user_says_so(run_gonio, tmp_path,
                                                                    scale, code):
    """The option is a statement, documented as such: a matte reflectance factor of 50
    (percent) is refused by default and read as given with --scale 1."""
    ti, to = np.array([20.0, 45.0]), np.array([-30.0, 0.0])
    src = write(tmp_path / "matte.csv", ti, to, np.full((2, WL.size), 50.0))
    args = ["--quantity", "reflectance-factor"] + (["--scale", scale] if scale else [])
    res = run_gonio("ingest", src, *args, "-o", tmp_path / "m.json")
    assert res.exit_code == code, res.stderr
