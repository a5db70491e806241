"""``tabulated-colour``: f = ρ_d(λ)/π + T(θh, θd, λ) · GGX lobe (α), T a table over
Rusinkiewicz's half and difference angles, bilinear between its nodes (AxF CPA2's colour
table).

Truth: bilinear interpolation reproduces bilinear functions exactly; the smoothness
penalty vanishes on them; reciprocity; recovery of α, ρ_d and every table entry from
noiseless data made by the model (a table bilinear in (θh, θd), which the penalty leaves
unbiased) on a goniometer's configurations; seed 000 eq. 5's colour shift, which the
table can hold and a model without one cannot; a malformed table in a material file is
one line naming the file and the field, and nothing is written.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from gonio_cli import brdf
from gonio_cli.brdf_surfaces import hat_weights
from gonio_cli.fit import fit
from gonio_cli.fit.common import prepare
from gonio_cli.fit.results import FitOptions
from gonio_cli.fit.tabulated_colour import (THETA_D_NODES_DEG, THETA_H_NODES_DEG,
                                            second_differences)
from gonio_cli.geometry import cosines
from gonio_cli.schemas import read_material
from gonio_cli.synthetic import ink_spectra, synthetic_measurement

from recovery import brdf_error, rgl_like_geometry

MODEL = "tabulated-colour"
WL = np.linspace(380.0, 780.0, 41)
NH, ND = np.array(THETA_H_NODES_DEG), np.array(THETA_D_NODES_DEG)


def truth():
    """A colour-shifting film: a table bilinear in (θh, θd) on the fitter's own nodes, red
    near normal and shifting towards green with θd, dimmer away from the mirror."""
    x = (WL - WL[0]) / (WL[-1] - WL[0])
    a = 0.3 + 0.5 * np.exp(-0.5 * ((WL - 620.0) / 50.0) ** 2)
    b = -1e-3 * (0.5 + 0.5 * x)              # per degree of θh
    c = 4e-3 * np.exp(-0.5 * ((WL - 530.0) / 40.0) ** 2) - 1e-3 * x   # per degree of θd
    table = a + b * NH[:, None, None] + c * ND[None, :, None]
    assert np.all(table > 0)
    return {"alpha": 0.15, "rho_d": 0.02 + 0.04 * x, "colour_table": table,
            "theta_h_nodes_deg": NH, "theta_d_nodes_deg": ND}


def test_hat_weights_interpolate_lines_exactly_and_hold_the_ends():
    nodes = np.array([0.0, 2.0, 5.0, 10.0, 90.0])
    x = np.array([0.0, 1.0, 3.5, 9.999, 50.0, 90.0])
    w = hat_weights(x, nodes)
    np.testing.assert_allclose(w.sum(-1), 1.0, rtol=1e-15)
    np.testing.assert_allclose(w @ (3.0 + 0.5 * nodes), 3.0 + 0.5 * x, rtol=1e-14)
    np.testing.assert_array_equal(hat_weights(np.array([-5.0, 120.0]), nodes),
                                  [[1, 0, 0, 0, 0], [0, 0, 0, 0, 1]])


def test_the_smoothness_penalty_leaves_bilinear_tables_alone():
    R = second_differences(NH, ND)
    h, d = np.meshgrid(NH, ND, indexing="ij")
    for t in (np.ones_like(h), h, d, h * d):           # the penalty's null space
        v = t.ravel()
        assert v @ R @ v == pytest.approx(0.0, abs=1e-9 * (v @ v))
    # a parabola along θd on even nodes (spacing s): second differences 2 s² each (its
    # second derivative 2 times s², the scale of R), n_d − 2 of them per θh row
    s = ND[1] - ND[0]
    curved = (d ** 2).ravel()
    assert curved @ R @ curved == pytest.approx((2 * s * s) ** 2 * (ND.size - 2) * NH.size)


def test_tabulated_colour_is_reciprocal(rng):
    v = rng.normal(size=(2, 1000, 3))
    v /= np.linalg.norm(v, axis=-1, keepdims=True)
    v[..., 2] = np.abs(v[..., 2])
    p = dict(truth(), colour_table=rng.uniform(0.1, 1.0, (NH.size, ND.size, WL.size)))
    forward = brdf.evaluate(MODEL, cosines(v[0], v[1]), p)
    backward = brdf.evaluate(MODEL, cosines(v[1], v[0]), p)
    assert np.all(forward > 0)
    np.testing.assert_allclose(forward, backward, rtol=1e-12)


def test_tabulated_colour_recovers_its_parameters_from_noiseless_data():
    # the criterion: 1 %. Measured: α 6e-10, ρ_d 8e-7, every entry of the table 7e-6
    # relative (the nodes the data do not reach too: the penalty continues the bilinear
    # truth)
    p = truth()
    ti, to = rgl_like_geometry()
    m = synthetic_measurement(MODEL, p, ti, to, grid_nm=WL, noise=0.0)
    r = fit(prepare(m, residuals="compressive"), MODEL, FitOptions())
    assert r.result.success
    got = r.params
    assert got["alpha"] == pytest.approx(p["alpha"], rel=0.01)
    assert np.max(np.abs(got["rho_d"] / p["rho_d"] - 1)) < 0.01
    assert got["colour_table"].shape == (NH.size, ND.size, WL.size)
    assert np.max(np.abs(got["colour_table"] / p["colour_table"] - 1)) < 0.01
    np.testing.assert_array_equal(got["theta_h_nodes_deg"], NH)


def test_the_table_holds_seed_000_eq_5s_colour_shift():
    # eq. 5 over a dim body, the green ink (c up to 6): its colour turns with
    # θd = (θi + θo)/2. Measured (noiseless): the table's BRDF 0.7 % RMS off the truth;
    # Torrance–Sparrow (its colour a Fresnel of fixed form) 95 %
    rho, c = ink_spectra("green")
    p = {"alpha": 0.2, "rho": rho, "c": c, "rho_d": np.full(rho.size, 0.03)}
    ti, to = rgl_like_geometry()
    m = synthetic_measurement("goniochromatic-diffuse", p, ti, to, noise=0.0)
    data = prepare(m, residuals="compressive")
    assert brdf_error(data, "goniochromatic-diffuse", p, MODEL) < 0.02
    assert brdf_error(data, "goniochromatic-diffuse", p, "torrance-sparrow") > 0.5


def test_fit_writes_a_material_that_eval_reads(run_gonio, tmp_path):
    p = truth()
    ti, to = rgl_like_geometry()
    m = synthetic_measurement(MODEL, p, ti, to, grid_nm=WL, noise=0.0)
    from gonio_cli.schemas import write_measurement

    meas, mat = tmp_path / "t.measurement.json", tmp_path / "t.material.json"
    write_measurement(meas, m)
    r = run_gonio("-q", "fit", meas, "-o", mat, "--model", MODEL)
    assert r.exit_code == 0, r.stderr
    back = read_material(mat)
    assert back.params["colour_table"].shape == (NH.size, ND.size, WL.size)
    np.testing.assert_array_equal(back.params["theta_d_nodes_deg"], ND)
    out = tmp_path / "e.measurement.json"
    r = run_gonio("-q", "eval", mat, "--at", meas, "-o", out)
    assert r.exit_code == 0, r.stderr
    f = json.loads(out.read_text())["brdf"]
    np.testing.assert_allclose(f, m.brdf, rtol=1e-4)


#: case → (change to a tabulated-colour material, what the one-line error must name)
BAD_TABLES = {
    "table of the wrong shape": (lambda d: d.update(colour_table=[row[:-1] for row in
                                                                  d["colour_table"]]),
                                 "'colour_table' has shape"),
    "table 2-deep": (lambda d: d.update(colour_table=d["colour_table"][0]), "colour_table"),
    "negative entry": (lambda d: d["colour_table"][0][0].__setitem__(0, -0.1),
                       "colour_table"),
    "NaN entry": (lambda d: d["colour_table"][1][2].__setitem__(3, float("nan")),
                  "colour_table"),
    "nodes not increasing": (lambda d: d.update(theta_h_nodes_deg=d["theta_h_nodes_deg"][::-1]),
                             "theta_h_nodes_deg"),
    "node beyond 90": (lambda d: d["theta_d_nodes_deg"].__setitem__(-1, 120.0),
                       "theta_d_nodes_deg"),
    "no nodes": (lambda d: d.pop("theta_d_nodes_deg"), "theta_d_nodes_deg"),
}


@pytest.mark.parametrize("case", sorted(BAD_TABLES))
def test_a_malformed_table_is_one_line_naming_file_and_field(run_gonio, tmp_path, case):
    from gonio_cli.schemas import Material, write_material, write_measurement

    p = truth()
    good = tmp_path / "good.material.json"
    write_material(good, Material(MODEL, WL, p))
    doc = json.loads(good.read_text())
    change, needle = BAD_TABLES[case]
    change(doc)
    bad = tmp_path / "bad.material.json"
    bad.write_text(json.dumps(doc))              # NaN is written as the token NaN
    ti, to = rgl_like_geometry()
    meas = tmp_path / "m.measurement.json"
    write_measurement(meas, synthetic_measurement(MODEL, p, ti[:5], to[:5], grid_nm=WL,
                                                  noise=0.0))
    out = tmp_path / "out.measurement.json"
    r = run_gonio("eval", bad, "--at", meas, "-o", out)
    assert r.exit_code == 2
    line = r.stderr.strip()
    assert line.count("\n") == 0 and "Traceback" not in line
    assert str(bad) in line and needle in line, line
    assert not out.exists()
