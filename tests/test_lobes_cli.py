"""``gonio lobes basis`` and ``gonio lobes fit``: round trip and bad input (exit 2, one
line on stderr, nothing written)."""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from gonio_cli.artifact import read_artifact
from gonio_cli.schemas import (Material, read_lobe_basis, read_lobes, write_material)
from gonio_cli.synthetic import ink_spectra

WL = np.arange(380.0, 781.0, 10.0)


@pytest.fixture
def inks(tmp_path):
    paths = []
    for ink, alpha in (("red", 0.18), ("green", 0.1), ("blue", 0.25)):
        rho, c = ink_spectra(ink, WL)
        p = tmp_path / f"{ink}.material.json"
        write_material(p, Material("goniochromatic", WL, {"alpha": alpha, "rho": rho, "c": c}))
        paths.append(p)
    return paths


def assert_one_line_error(result, *, contains=""):
    assert result.exit_code == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("gonio: error:"), result.stderr
    assert contains in lines[0]


def test_round_trip(run_gonio, inks, tmp_path):
    basis, png, out = tmp_path / "basis.json", tmp_path / "basis.png", tmp_path / "red.lobes.json"
    r = run_gonio("lobes", "basis", *inks, "--max-lobes", "3", "-o", basis, "--plot", png)
    assert r.exit_code == 0, r.stderr
    assert png.stat().st_size > 1000
    b = read_lobe_basis(basis)
    assert [x["n_lobes"] for x in b.bases] == [1, 2, 3]
    errs = [x["error"] for x in b.bases]
    assert all(e2 <= e1 + 1e-9 for e1, e2 in zip(errs, errs[1:]))
    r = run_gonio("lobes", "fit", inks[0], "--basis", basis, "--lobes", "2", "-o", out,
                  "--view-angles", "10,40,70", "--channels", "xyz")
    assert r.exit_code == 0, r.stderr
    doc = json.loads(out.read_text())
    assert doc["schema"] == "gonio.lobes" and doc["schema_version"] == 1
    assert isinstance(doc["exponents"], list) and all(isinstance(v, float) for v in doc["exponents"])
    np.testing.assert_allclose(doc["exponents"], b.exponents(2))
    assert doc["channels"] == ["X", "Y", "Z"] and doc["view_angle_deg"] == [10.0, 40.0, 70.0]
    lobes = read_lobes(out)
    assert lobes.gloss.shape == (3, 2, 3) and lobes.diffuse.shape == (3, 3)
    for arr in (lobes.diffuse, lobes.directional_diffuse, lobes.gloss):
        assert np.all(arr >= 0)
    assert list(doc["errors"]) == ["lp"]                            # no comparison unasked
    back = read_artifact(out, "gonio.lobes", (1,))                  # times: the side record
    assert back["time_s"] > 0 and len(back["errors"]["lp"]["time_s"]) == 3
    assert doc["errors"]["lp"]["status"] == ["optimal"] * 3
    assert [i["path"] for i in doc["inputs"]] == [os.path.relpath(p, out.parent)
                                                   for p in (inks[0], basis)]
    r = run_gonio("lobes", "fit", inks[0], "--basis", basis, "--lobes", "2", "-o", out,
                  "--view-angles", "10,40,70", "--channels", "xyz", "--compare")
    assert r.exit_code == 0, r.stderr
    both = json.loads(out.read_text())
    assert list(both["errors"]) == ["lp", "highs", "lp-simplex", "nnls", "lsq-clamp"]
    assert both["parameters"]["compare"] is True
    # the same weights (the solver written is unchanged), the same LP optimum as HiGHS
    np.testing.assert_array_equal(both["gloss"], doc["gloss"])
    np.testing.assert_allclose(both["errors"]["lp"]["l1"], both["errors"]["highs"]["l1"],
                               rtol=1e-6)


def test_time_limit_is_recorded_not_fatal(run_gonio, inks, tmp_path):
    """A comparison (or the chosen solver) stopped by --time-limit-s: exit 0, the file is
    written with the status per view, and a warning says which solver and views."""
    out = tmp_path / "l.json"
    r = run_gonio("lobes", "fit", inks[0], "--exponents", "3,30,300", "-o", out,
                  "--view-angles", "10,40", "--solver", "nnls", "--compare",
                  "--time-limit-s", "1e-9")
    assert r.exit_code == 0, r.stderr
    doc = json.loads(out.read_text())
    assert doc["errors"]["nnls"]["status"] == ["optimal", "optimal"]
    for name in ("lp", "highs", "lp-simplex"):
        assert doc["errors"][name]["status"] == ["time_limit", "time_limit"]
        assert "time limit" in doc["errors"][name]["message"][0]
    warnings = [line for line in r.stderr.splitlines() if line.startswith("gonio: warning:")]
    assert len(warnings) == 3 and all("comparison only" in w for w in warnings)
    r = run_gonio("lobes", "fit", inks[0], "--exponents", "3,30,300", "-o", out,
                  "--view-angles", "10,40", "--time-limit-s", "1e-9")
    assert r.exit_code == 0, r.stderr
    assert json.loads(out.read_text())["errors"]["lp"]["status"] == ["time_limit"] * 2
    assert "not optimal there" in r.stderr


def test_fit_with_exponents_spectral(run_gonio, inks, tmp_path):
    out = tmp_path / "l.json"
    r = run_gonio("lobes", "fit", inks[1], "--exponents", "3,30,300", "-o", out,
                  "--solver", "lp-simplex")
    assert r.exit_code == 0, r.stderr
    doc = json.loads(out.read_text())
    assert doc["channels"] == WL.tolist() and len(doc["view_angle_deg"]) == 9
    assert np.array(doc["gloss"]).shape == (9, 3, WL.size)


def test_help_lists_lobes(run_gonio):
    r = run_gonio("--help")
    assert "lobes" in r.stdout and "gonio lobes basis" in r.stdout
    r = run_gonio("lobes", "--help")
    assert "basis" in r.stdout and "fit" in r.stdout


def test_unknown_material_model(run_gonio, inks, tmp_path):
    doc = json.loads(inks[0].read_text())
    doc["model"] = "phong"
    bad = tmp_path / "bad.material.json"
    bad.write_text(json.dumps(doc))
    out = tmp_path / "o.json"
    assert_one_line_error(run_gonio("lobes", "fit", bad, "--exponents", "1,10", "-o", out),
                          contains="phong")
    assert not out.exists()
    assert_one_line_error(run_gonio("lobes", "basis", bad, "-o", out), contains="phong")
    assert not out.exists()


@pytest.mark.parametrize("exponents,message", [("", "empty"), ("0,10", "outside [1, "),
                                               ("-3", "outside [1, "), ("a,b", "numbers")])
def test_bad_exponents(run_gonio, inks, tmp_path, exponents, message):
    out = tmp_path / "o.json"
    assert_one_line_error(run_gonio("lobes", "fit", inks[0], "--exponents", exponents,
                                    "-o", out), contains=message)
    assert not out.exists()


@pytest.mark.parametrize("edit,message", [
    (lambda d: d.update(bases=[]), "empty"),
    (lambda d: d["bases"][0].update(exponents=[]), "empty"),
    (lambda d: d["bases"][0].update(exponents=[-2.0], n_lobes=1), "outside [1, "),
    (lambda d: d["bases"][0].update(exponents=[0.0], n_lobes=1), "outside [1, "),
    (lambda d: d.update(extra=1), "unknown field"),
])
def test_bad_basis_file(run_gonio, inks, tmp_path, edit, message):
    basis = tmp_path / "basis.json"
    assert run_gonio("lobes", "basis", inks[0], "--max-lobes", "1", "-o", basis).exit_code == 0
    doc = json.loads(basis.read_text())
    edit(doc)
    basis.write_text(json.dumps(doc))
    out = tmp_path / "o.json"
    assert_one_line_error(run_gonio("lobes", "fit", inks[0], "--basis", basis, "-o", out),
                          contains=message)
    assert not out.exists()


def test_sample_set_that_leaves_the_lp_undetermined_or_empty(run_gonio, inks, tmp_path):
    out = tmp_path / "o.json"
    retro = tmp_path / "retro.csv"
    retro.write_text("theta_i_deg,theta_o_deg\n60,-60\n50,-60\n")
    assert_one_line_error(run_gonio("lobes", "fit", inks[0], "--exponents", "1,10",
                                    "--samples", retro, "-o", out), contains="no sample sees")
    empty = tmp_path / "empty.csv"
    empty.write_text("theta_i_deg,theta_o_deg\n")
    assert_one_line_error(run_gonio("lobes", "fit", inks[0], "--exponents", "1,10",
                                    "--samples", empty, "-o", out), contains="nothing to fit")
    assert_one_line_error(run_gonio("lobes", "basis", inks[0], "--samples", empty, "-o", out),
                          contains="nothing to fit")
    assert not out.exists()


def test_other_bad_options(run_gonio, inks, tmp_path):
    out = tmp_path / "o.json"
    for args, message in [
        (("--exponents", "1", "--solver", "simplex"), "--solver"),
        (("--exponents", "1", "--channels", "rgb"), "--channels"),
        (("--exponents", "1", "--samples", "nope"), "unknown"),
        (("--exponents", "1", "--view-angles", "95"), "outside"),
        (("--exponents", "1", "--time-limit-s", "0"), "time-limit"),
        ((), "exactly one"),
    ]:
        assert_one_line_error(run_gonio("lobes", "fit", inks[0], *args, "-o", out),
                              contains=message)
    assert_one_line_error(run_gonio("lobes", "basis", inks[0], "--max-lobes", "0", "-o", out),
                          contains="max-lobes")
    assert not out.exists()
