"""``gonio eval``: a material's model at a measurement's configurations, written as a
``gonio.measurement``.

Truth: :func:`gonio_cli.brdf.evaluate` on the measurement's angles with the material's
parameters (read back from its file), and the hand-written eq. 5 of seed 000; the
output's provenance against SHA-256 computed here; bad input is one stderr line, exit
2, nothing written.
"""

from __future__ import annotations

import ast
import hashlib
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from gonio_cli import brdf
from gonio_cli.artifact import read_artifact
from gonio_cli.geometry import in_plane_cosines
from gonio_cli.schemas import (Material, read_material, read_measurement, write_material,
                               write_measurement)
from gonio_cli.spectra import parse_grid
from gonio_cli.synthetic import ink_spectra, paper_geometry, synthetic_measurement

ALPHA = 0.19


@pytest.fixture
def fitted(run_gonio, tmp_path):
    """A synthetic red-ink measurement (2 % noise) and the material gonio fit makes of it."""
    rho, c = ink_spectra("red")
    ti, to = paper_geometry(10.0)
    m = synthetic_measurement("goniochromatic", {"alpha": ALPHA, "rho": rho, "c": c},
                              ti, to, seed=7)
    meas, mat = tmp_path / "red.measurement.json", tmp_path / "red.material.json"
    write_measurement(meas, m)
    r = run_gonio("fit", meas, "-o", mat)
    assert r.exit_code == 0, r.stderr
    return meas, mat


def sha256(path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def test_eval_reproduces_the_model_exactly(run_gonio, fitted, tmp_path):
    meas, mat = fitted
    out = tmp_path / "red.model.json"
    r = run_gonio("eval", mat, "--at", meas, "-o", out)
    assert r.exit_code == 0, r.stderr
    model, data, material = read_measurement(out), read_measurement(meas), read_material(mat)
    np.testing.assert_array_equal(model.theta_i_deg, data.theta_i_deg)
    np.testing.assert_array_equal(model.theta_o_deg, data.theta_o_deg)
    np.testing.assert_array_equal(model.wavelength_nm, data.wavelength_nm)
    truth = brdf.evaluate("goniochromatic", in_plane_cosines(data.theta_i_deg,
                                                             data.theta_o_deg),
                          material.params)
    # the same function on the same float64 numbers, through JSON (repr round-trips)
    np.testing.assert_array_equal(model.brdf, truth)
    # and seed 000 eq. 5 written out here: D(θh)/4 · ρ exp(c (1 − cos((θi+θo)/2))) with
    # the GGX D of eq. 3; equal to the round-off of the log form (1e-12 relative)
    ti, to = np.radians(data.theta_i_deg), np.radians(data.theta_o_deg)
    a2 = material.params["alpha"] ** 2
    cos_h = np.cos((to - ti) / 2)[:, None]          # in plane: θh = (θo − θi)/2
    d = a2 / (np.pi * ((a2 - 1) * cos_h ** 2 + 1) ** 2)
    half = np.cos((ti + np.abs(to)) / 2)[:, None]   # eq. 6 takes |θo| (first quadrant)
    eq5 = d / 4 * material.params["rho"] * np.exp(material.params["c"] * (1 - half))
    np.testing.assert_allclose(model.brdf, eq5, rtol=1e-12)
    assert model.brdf_std is None and np.all(model.n_repeats == 1)
    assert model.quantity == "brdf"
    # the fit is good: the model is within the 2 % noise of the data (log RMSE ≈ 0.02)
    assert np.sqrt(np.mean(np.log(model.brdf / data.brdf) ** 2)) < 0.03


def test_envelope_names_both_inputs_and_the_model(run_gonio, fitted, tmp_path):
    meas, mat = fitted
    out = tmp_path / "red.model.json"
    assert run_gonio("eval", mat, "--at", meas, "-o", out).exit_code == 0
    doc = json.loads(out.read_text())
    assert doc["schema"] == "gonio.measurement" and doc["schema_version"] == 1
    # paths relative to the output's folder (reproducible bytes, docs/conventions.md)
    rel = {p: os.path.relpath(p, out.parent) for p in (mat, meas)}
    assert [i["path"] for i in doc["inputs"]] == [rel[mat], rel[meas]]
    assert [i["sha256"] for i in doc["inputs"]] == [sha256(mat), sha256(meas)]
    p = doc["parameters"]
    assert p["model"] == "goniochromatic" and p["material"] == rel[mat]
    assert p["at"] == rel[meas] and p["citation"] == brdf.MODELS["goniochromatic"].citation
    material = json.loads(mat.read_text())
    assert p["params"]["alpha"] == material["alpha"]
    assert p["params"]["rho"] == material["rho"] and p["params"]["c"] == material["c"]
    assert doc["quantity"] == "brdf" and "time_s" not in doc
    assert read_artifact(out, "gonio.measurement", (1,))["time_s"] >= 0   # the side record
    assert doc["summary"]["model"] == "goniochromatic"


def test_the_output_is_a_measurement_the_fit_reads(run_gonio, tmp_path):
    """Noise-free model output fitted again gives the material back (α to 1e-6)."""
    rho, c = ink_spectra("blue")
    grid = parse_grid()
    mat = tmp_path / "blue.material.json"
    write_material(mat, Material("goniochromatic", grid, {"alpha": 0.3, "rho": rho, "c": c}))
    ti, to = paper_geometry(10.0)
    write_measurement(tmp_path / "geometry.json",
                      synthetic_measurement("goniochromatic",
                                            {"alpha": 0.5, "rho": rho, "c": c}, ti, to))
    out, refit = tmp_path / "model.json", tmp_path / "refit.json"
    assert run_gonio("eval", mat, "--at", tmp_path / "geometry.json", "-o", out).exit_code == 0
    r = run_gonio("fit", out, "-o", refit)
    assert r.exit_code == 0, r.stderr
    assert read_material(refit).params["alpha"] == pytest.approx(0.3, rel=1e-6)


def test_plot_beside_the_output(run_gonio, fitted, tmp_path):
    meas, mat = fitted
    out, png = tmp_path / "m.json", tmp_path / "m.png"
    r = run_gonio("eval", mat, "--at", meas, "-o", out, "--plot", png)
    assert r.exit_code == 0, r.stderr
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and out.is_file()


# --------------------------------------------------------------------------- errors --

def other_grid_material(tmp_path):
    grid = parse_grid("400:700:10")
    rho, c = ink_spectra("red", grid)
    path = tmp_path / "red400.material.json"
    write_material(path, Material("goniochromatic", grid, {"alpha": 0.2, "rho": rho, "c": c}))
    return path


@pytest.mark.parametrize("case, needles", [
    ("measurement as material", ["red.measurement.json: schema is 'gonio.measurement', "
                                 "expected 'gonio.material'"]),
    ("material as measurement", ["red.material.json: schema is 'gonio.material', "
                                 "expected 'gonio.measurement'"]),
    ("grid mismatch", ["red.measurement.json: spectral grid 380-780 nm (41 wavelengths) is "
                       "not the material's", "400-700 nm (31 wavelengths)",
                       "re-ingest the measurement with --grid-nm 400:700:10"]),
    ("-o is the material", ["-o", "is the material", "choose another -o"]),
    ("-o is the measurement", ["is --at", "choose another -o"]),
    ("--plot is the measurement", ["--plot", "is --at", "choose another --plot"]),
    ("--plot is -o", ["--plot", "is also -o"]),
    ("missing material", ["nope.json: no such file", "gonio fit"]),
])
def test_bad_input_is_one_line_exit_2_nothing_written(run_gonio, fitted, tmp_path, case,
                                                      needles):
    meas, mat = fitted
    out = tmp_path / "out.json"
    args = {
        "measurement as material": [meas, "--at", meas, "-o", out],
        "material as measurement": [mat, "--at", mat, "-o", out],
        "grid mismatch": [other_grid_material(tmp_path), "--at", meas, "-o", out],
        "-o is the material": [mat, "--at", meas, "-o", mat],
        "-o is the measurement": [mat, "--at", meas, "-o", meas],
        "--plot is the measurement": [mat, "--at", meas, "-o", out, "--plot", meas],
        "--plot is -o": [mat, "--at", meas, "-o", out, "--plot", out],
        "missing material": [tmp_path / "nope.json", "--at", meas, "-o", out],
    }[case]
    before = {p: p.read_bytes() for p in tmp_path.iterdir()}
    r = run_gonio("eval", *args)
    assert r.exit_code == 2, r.stderr
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("gonio: error: "), r.stderr
    for needle in needles:
        assert needle in r.stderr, r.stderr
    # nothing written or changed, no temporary file left
    assert {p: p.read_bytes() for p in tmp_path.iterdir()} == before


def test_eval_without_plot_does_not_import_matplotlib(fitted, tmp_path):
    meas, mat = fitted
    args = ["eval", str(mat), "--at", str(meas), "-o", str(tmp_path / "m.json")]
    code = ("import sys\nfrom gonio_cli import cli\n"
            f"code = cli.run({args!r})\n"
            "print(sorted({m.split('.')[0] for m in sys.modules}))\n"
            "sys.exit(code)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       cwd=tmp_path, timeout=120)
    assert r.returncode == 0, r.stderr
    loaded = set(ast.literal_eval(r.stdout.strip().splitlines()[-1]))
    assert "gonio_cli" in loaded and "numpy" in loaded  # the check sees what was imported
    assert not loaded & {"matplotlib", "scipy", "colour", "numba", "nlopt"}, loaded
