"""Configurations out of the plane of incidence (docs/conventions.md, "Out of the plane of
incidence"): the cosines from (θi, θo, φo), fits of out-of-plane data, reciprocity of every
model, the CSV column through ingest → measurement → eval, and the ``.bsdf`` grid."""

from __future__ import annotations

import json

import numpy as np
import pytest

from gonio_cli import brdf
from gonio_cli.fit import FitOptions, fit
from gonio_cli.fit.common import prepare
from gonio_cli.fit.plot import in_plane_rows
from gonio_cli.fit.verdict import colour_errors, reciprocity
from gonio_cli.geometry import (Cosines, canonical_azimuth, in_plane_cosines, measurement_cosines,
                                measurement_directions, reciprocal_configuration)
from gonio_cli.ingest.hemisphere import hemisphere_grid, mirror_ring, parse_mirror
from gonio_cli.schemas import Measurement, read_material, read_measurement
from gonio_cli.synthetic import ink_spectra, paper_geometry, synthetic_measurement
from test_brdf import model_params

THETA_I = (20.0, 30.0, 40.0, 50.0, 60.0, 70.0)


# ------------------------------------------------------------- (a) the cosines --

def _by_hand(ti, to, po):
    """The four cosines from directions written out: ωi = (−sin θi, 0, cos θi),
    ωo = (sin θo cos φo, sin θo sin φo, cos θo), ωh = (ωi + ωo)/|ωi + ωo|."""
    a, b, p = np.radians(ti), np.radians(to), np.radians(po)
    wi = np.array([-np.sin(a), 0.0, np.cos(a)])
    wo = np.array([np.sin(b) * np.cos(p), np.sin(b) * np.sin(p), np.cos(b)])
    h = (wi + wo) / np.linalg.norm(wi + wo)
    return wi[2], wo[2], h[2], wi @ h


def test_cosines_out_of_plane_are_the_directions_written_by_hand():
    rng = np.random.default_rng(3)
    ti, to = rng.uniform(0, 85, 50), rng.uniform(0, 85, 50)
    po = rng.uniform(-180, 180, 50)
    got = measurement_cosines(ti, to, po)
    want = np.array([_by_hand(*c) for c in zip(ti, to, po)]).T
    for g, w in zip(got, want):
        np.testing.assert_allclose(g, np.clip(w, 0, 1), rtol=0, atol=1e-14)
    # a closed form: cos θh² = (cos θi + cos θo)² / (2 + 2 ωi·ωo),
    # ωi·ωo = −sin θi sin θo cos φo + cos θi cos θo
    a, b, p = np.radians(ti), np.radians(to), np.radians(po)
    dot = -np.sin(a) * np.sin(b) * np.cos(p) + np.cos(a) * np.cos(b)
    np.testing.assert_allclose(got.cos_theta_h,
                               (np.cos(a) + np.cos(b)) / np.sqrt(2 + 2 * dot), atol=1e-14)
    np.testing.assert_allclose(got.cos_theta_d, np.sqrt((1 + dot) / 2), atol=1e-14)


def test_azimuth_zero_is_todays_in_plane_geometry_exactly():
    ti, to = paper_geometry(5.0)
    plane = in_plane_cosines(ti, to)
    for with_zero in (measurement_cosines(ti, to, np.zeros_like(ti)),
                      measurement_cosines(ti, to, None)):
        for a, b in zip(with_zero, plane):
            assert np.array_equal(a, b)
    # the mirror at φo = 0 has cos θh = 1 exactly (as in plane)
    assert np.all(measurement_cosines(ti, ti, np.zeros_like(ti)).cos_theta_h == 1.0)


def test_canonical_form_spells_one_direction_once():
    to, po = canonical_azimuth([30, -30, 30, -30, 0, 20, 20], [0, 0, 180, 90, 45, -90, 270])
    np.testing.assert_array_equal(to, [30, -30, -30, 30, 0, 20, 20])
    np.testing.assert_array_equal(po, [0, 0, 0, -90, 0, -90, -90])
    # every spelling is the same detector direction as its canonical form
    rng = np.random.default_rng(5)
    t, p = rng.uniform(-85, 85, 200), rng.uniform(-180, 180, 200)
    ct, cp = canonical_azimuth(t, p)
    np.testing.assert_allclose(measurement_directions(0.0, ct, cp)[1],
                               measurement_directions(0.0, t, p)[1], atol=1e-12)
    assert np.all((cp == 0) | (ct >= 0)) and np.all((cp > -180) & (cp < 180))


# ----------------------------------------------- (b) out-of-plane data fit alike --

def out_of_plane_geometry():
    """Per θi of seed 000's goniometer: the mirror (φo = 0) and θo = 10…80° by 10 at
    φo = 30, 60, 90, 135° (198 configurations, 6 in plane)."""
    rows = []
    for ti in THETA_I:
        rows.append((ti, ti, 0.0))
        rows += [(ti, to, po) for to in np.arange(10.0, 81.0, 10.0)
                 for po in (30.0, 60.0, 90.0, 135.0)]
    return tuple(np.array(c) for c in zip(*rows))


OUT = out_of_plane_geometry()
PLANE = paper_geometry(5.0, theta_i_deg=THETA_I)


def _fit_both(model, truth, noise=0.01):
    """The fitted parameters on in-plane and on out-of-plane data of the same truth."""
    out = []
    for seed, (ti, to, *po) in enumerate((PLANE, OUT)):
        m = synthetic_measurement(model, truth, ti, to, noise=noise, seed=seed,
                                  phi_o_deg=po[0] if po else None)
        result = fit(prepare(m), model, FitOptions())
        assert result.result.success
        out.append(result.params)
    return out


def _rel(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) / np.asarray(b) - 1.0) ** 2)))


def test_goniochromatic_fits_the_same_parameters_out_of_plane():
    """Seed 000 eq. 5 at 1 % noise: α and ρ from out-of-plane data within 1 % of the
    in-plane fit and of the truth; c (an exponent, near 0 in places) within 0.01."""
    rho, c = ink_spectra("red")
    truth = {"alpha": 0.19, "rho": rho, "c": c}
    plane, out = _fit_both("goniochromatic", truth)
    for p in (plane, out):
        assert abs(p["alpha"] / 0.19 - 1) < 0.01 and _rel(p["rho"], rho) < 0.01
        assert np.sqrt(np.mean((p["c"] - c) ** 2)) < 0.01
    assert abs(out["alpha"] / plane["alpha"] - 1) < 0.01
    assert _rel(out["rho"], plane["rho"]) < 0.01


def test_cook_torrance_fits_the_same_parameters_out_of_plane():
    """Seed 004 eqs. 9-12: kd, m and ks·F0 (ks and F0 trade against each other) from
    out-of-plane data within 1 % of the in-plane fit and of the truth."""
    wl = np.linspace(380.0, 780.0, 41)
    x = (wl - 380.0) / 400.0
    truth = {"kd": 0.02 + 0.15 * np.exp(-0.5 * ((wl - 470.0) / 50.0) ** 2),
             "ks": 0.3 + 0.1 * x, "m": 0.25 + 0.05 * x, "f0": 0.6 + 0.3 * x}
    plane, out = _fit_both("cook-torrance", truth)
    for key, get in (("kd", lambda p: p["kd"]), ("m", lambda p: p["m"]),
                     ("ks f0", lambda p: p["ks"] * p["f0"])):
        want = get(truth)
        assert _rel(get(plane), want) < 0.01, key
        assert _rel(get(out), want) < 0.01, key
        assert _rel(get(out), get(plane)) < 0.01, key


def test_a_fit_that_ignored_the_azimuth_would_be_caught():
    """The same out-of-plane data read as in-plane (φo dropped) fit far from the truth."""
    rho, c = ink_spectra("red")
    m = synthetic_measurement("goniochromatic", {"alpha": 0.19, "rho": rho, "c": c},
                              *OUT[:2], noise=0.0, phi_o_deg=OUT[2])
    flat = Measurement(m.wavelength_nm, m.theta_i_deg, m.theta_o_deg, m.brdf)
    p = fit(prepare(flat), "goniochromatic", FitOptions()).params
    assert abs(p["alpha"] / 0.19 - 1) > 0.05


# ----------------------------------------------------------- (c) reciprocity --

@pytest.mark.parametrize("model", sorted(brdf.MODELS))
def test_every_model_is_reciprocal_out_of_plane(model):
    params = model_params(model, np.random.default_rng(5))   # every model's, test_brdf.py
    rng = np.random.default_rng(11)
    ti, to, po = rng.uniform(0, 85, 300), rng.uniform(-85, 85, 300), rng.uniform(-180, 180, 300)
    to, po = canonical_azimuth(to, po)
    ri, ro, rp = reciprocal_configuration(ti, to, po)
    # the reverse swaps the two directions (up to a rotation about the normal)
    wi, wo = measurement_directions(ti, to, po)
    vi, vo = measurement_directions(ri, ro, rp)
    np.testing.assert_allclose(np.sum(wi * wo, -1), np.sum(vi * vo, -1), atol=1e-12)
    np.testing.assert_allclose(wo[:, 2], vi[:, 2], atol=1e-12)
    np.testing.assert_allclose(wi[:, 2], vo[:, 2], atol=1e-12)
    f = brdf.evaluate(model, measurement_cosines(ti, to, po), params)
    g = brdf.evaluate(model, measurement_cosines(ri, ro, rp), params)
    np.testing.assert_allclose(f, g, rtol=1e-9, atol=1e-300)


def test_reciprocal_configuration_in_plane_is_the_signed_rule():
    ri, ro, rp = reciprocal_configuration([30.0, 30.0, 45.0], [-20.0, 50.0, 45.0])
    np.testing.assert_array_equal(ri, [20.0, 50.0, 45.0])
    np.testing.assert_array_equal(ro, [-30.0, 30.0, 45.0])
    assert rp is None


def test_verdict_pairs_and_mirror_use_the_azimuth():
    """The data's reciprocity check pairs (θi, θo, φo) with (θo, θi, φo); a configuration
    at θo = θi but φo ≠ 0 is not a mirror one."""
    wl = np.linspace(380.0, 780.0, 41)
    ti = np.array([30.0, 50.0, 30.0, 30.0])
    to = np.array([50.0, 30.0, 30.0, 30.0])
    po = np.array([60.0, 60.0, 0.0, 40.0])
    f = np.full((4, wl.size), 0.1)
    f[1] *= 1.5                                        # the reverse of row 0, 50 % off
    gap = reciprocity(wl, ti, to, f, po)
    assert gap is not None and gap.to_dict()["phi_o_deg"] == 60.0
    assert (gap.theta_i_deg, gap.reverse_theta_i_deg) in ((30.0, 50.0), (50.0, 30.0))
    assert gap.delta_e > 5 and not gap.interpolated
    model = f.copy()
    model[3] *= 2.0                                    # off only out of plane
    assert colour_errors(wl, ti, to, f, model, po).peak_ratio == {30.0: 1.0}


# -------------------------------------------- (d) CSV → measurement → eval --

CSV = "tests/fixtures/out_of_plane.csv"


def test_csv_with_azimuths_round_trips_through_ingest_and_eval(run_gonio, tmp_path):
    meas, mat, ev = (tmp_path / n for n in ("m.json", "mat.json", "e.json"))
    r = run_gonio("ingest", CSV, "-o", str(meas))
    assert r.exit_code == 0, r.stderr
    doc = json.loads(meas.read_text())
    assert doc["schema_version"] == 2 and "phi_o_deg" in doc
    m = read_measurement(meas)
    raw = np.genfromtxt(CSV, delimiter=",", names=True, skip_header=1)
    # the file writes θo < 0 at φo ≠ 0 once: read back in canonical form
    to, po = canonical_azimuth(raw["theta_o_deg"], raw["phi_o_deg"])
    got = sorted(zip(m.theta_i_deg, m.theta_o_deg, m.azimuths_deg))
    assert got == sorted(zip(raw["theta_i_deg"], to, po))
    r = run_gonio("fit", str(meas), "--model", "goniochromatic", "-o", str(mat))
    assert r.exit_code == 0, r.stderr
    r = run_gonio("eval", str(mat), "--at", str(meas), "-o", str(ev))
    assert r.exit_code == 0, r.stderr
    e = read_measurement(ev)
    assert json.loads(ev.read_text())["schema_version"] == 2
    np.testing.assert_array_equal(e.phi_o_deg, m.phi_o_deg)
    material = read_material(mat)
    truth = brdf.goniochromatic(_by_hand_cosines(e), *(material.params[k]
                                                       for k in ("alpha", "rho", "c")))
    np.testing.assert_allclose(e.brdf, truth, rtol=1e-12)
    # and the fit found the synthetic truth (1 % noise on 28 configurations)
    assert abs(material.params["alpha"] / 0.19 - 1) < 0.02


def _by_hand_cosines(m):
    """The measurement's cosines from :func:`_by_hand` (directions written out)."""
    return Cosines(*(np.clip(np.array(v), 0, 1) for v in zip(*(
        _by_hand(*c) for c in zip(m.theta_i_deg, m.theta_o_deg, m.phi_o_deg)))))


@pytest.mark.parametrize("bad, what", [("nan", "is not finite"),
                                       ("200", "phi_o_deg=200, outside [-180, 180]")])
def test_bad_azimuth_is_one_line_naming_file_row_and_fix(run_gonio, tmp_path, bad, what):
    lines = open(CSV).read().splitlines()
    cells = lines[4].split(",")
    cells[2] = bad
    lines[4] = ",".join(cells)
    path = tmp_path / "bad.csv"
    path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "m.json"
    r = run_gonio("ingest", str(path), "-o", str(out))
    assert r.exit_code == 2 and not out.exists()
    err = r.stderr.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert f"{path}:5" in err and "phi_o_deg" in err and what in err and ";" in err


def test_an_in_plane_measurement_is_still_written_as_v1(tmp_path):
    m = synthetic_measurement("goniochromatic", {"alpha": 0.2, "rho": 0.1, "c": 1.0},
                              [30.0, 30.0], [10.0, 30.0], grid_nm=[500.0, 600.0],
                              phi_o_deg=[0.0, 0.0])
    assert m.phi_o_deg is None and m.schema_version == 1


# --------------------------------------------------------- (e) the .bsdf grid --

def test_default_bsdf_grid_has_the_mirror_ring_in_canonical_form():
    ti, to = np.arange(10.0, 71.0, 10.0), np.arange(-80.0, 86.0, 5.0)
    gi, go, gp = hemisphere_grid(ti, to, [0.0], parse_mirror("1,2,3"))
    assert gi.size == 7 * (34 + 9) == 301
    assert np.all((gp == 0) | (go >= 0))
    # the ring: at angular distance 1, 2, 3° from the mirror direction, in three directions
    wi, wo = measurement_directions(gi, go, gp)
    mirror = wi * np.array([-1.0, 1.0, 1.0])
    dist = np.degrees(np.arccos(np.clip(np.sum(wo * mirror, -1), -1, 1)))
    for t in ti:
        near = np.sort(dist[(gi == t) & (dist < 4.0) & (dist > 1e-6)])
        np.testing.assert_allclose(near, np.repeat([1.0, 2.0, 3.0], 3), atol=1e-5)
    keys = set(zip(gi.round(6), go.round(6), gp.round(6)))
    assert len(keys) == gi.size                       # every configuration once


def test_grid_azimuths_fold_negative_theta_and_drop_beyond_the_horizon():
    gi, go, gp = hemisphere_grid([70.0], [-10.0, 0.0, 10.0], [0.0, 90.0, 180.0], [])
    assert sorted(zip(go, gp)) == [(-10.0, 0.0), (0.0, 0.0), (10.0, 0.0), (10.0, 90.0)]
    to, po = mirror_ring(85.0, [3.0, 10.0])             # θo = 95° is below the horizon
    np.testing.assert_allclose(np.sort(to)[:3], [75.0, 82.0, 85.0], atol=0.1)
    assert to.size == 5 and np.all(np.abs(to) < 90.0) and np.all(po >= 0)
    assert parse_mirror("none").size == 0


def test_plot_draws_the_in_plane_subset_and_says_what_it_leaves_out():
    m = synthetic_measurement("goniochromatic", {"alpha": 0.2, "rho": 0.1, "c": 1.0},
                              [30.0, 30.0, 30.0], [10.0, 30.0, 30.0], grid_nm=[500.0, 600.0],
                              phi_o_deg=[0.0, 0.0, 45.0])
    rows, note = in_plane_rows(m)
    assert rows.tolist() == [True, True, False] and "1 out of plane not shown" in note
    m.phi_o_deg = None
    assert in_plane_rows(m)[1] == ""


@pytest.mark.parametrize("smooth", [False, True])
def test_a_measured_material_renders_its_in_plane_rows_and_says_what_it_leaves_out(smooth):
    from gonio_cli import log
    from gonio_cli.render.measured import MeasuredMaterial
    from gonio_cli.render.measured_smooth import SmoothMeasured

    rho, c = ink_spectra("red")
    out = OUT[2] != 0                                # the paper's plane, then OUT's others
    ti, to, po = (np.concatenate([a, b[out]])
                  for a, b in zip(PLANE + (np.zeros(PLANE[0].size),), OUT))
    m = synthetic_measurement("goniochromatic", {"alpha": 0.19, "rho": rho, "c": c},
                              ti, to, noise=0.0, phi_o_deg=po)
    in_plane = int(np.count_nonzero(m.phi_o_deg == 0))
    assert 0 < in_plane < m.n_configurations
    warnings: list[str] = []
    with log.collecting(warnings):
        material = (SmoothMeasured if smooth else MeasuredMaterial)(m, "wrap")
    assert material.measurement.n_configurations == in_plane
    assert len(warnings) == 1
    assert (f"wrap: rendered from its {in_plane} configurations in the plane of incidence; "
            f"the {m.n_configurations - in_plane} out of the plane are not used") in warnings[0]
