"""The shipped sample data: it ingests cleanly, regenerates byte for byte, and holds what
``truth.json`` says (the models of seed 000 eq. 5 and seed 004 eq. 11 with the stated
noise), so the demo and the fit stage can trust it."""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.brdf import cook_torrance, goniochromatic
from gonio_cli.geometry import in_plane_cosines
from gonio_cli.schemas import read_measurement

SAMPLE = Path(__file__).resolve().parent.parent / "sample_data"
TRUTH = json.loads((SAMPLE / "truth.json").read_text())

#: The shipped files and the ingest options each needs (as docs/ingest.md shows them).
CASES = {
    "red": (["ink_red.csv"], []),
    "green": (["ink_green.csv"], ["--quantity", "ratio-to-white", "--white-reflectance",
                                  "0.99"]),
    "blue": (["ink_blue_a.csv", "ink_blue_b.csv"], []),
    "carpaint": (["carpaint_multiangle.csv"], ["--quantity", "reflectance-factor"]),
}


def load_generator(name: str = "make_inks"):
    spec = importlib.util.spec_from_file_location(name, SAMPLE / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def ingest_case(run_gonio, tmp_path, name, *extra):
    files, options = CASES[name]
    out = tmp_path / f"{name}.json"
    res = run_gonio("ingest", *[SAMPLE / f for f in files], "-o", out, *options, *extra)
    assert res.exit_code == 0, res.stderr
    return read_measurement(out), res


def test_regenerating_reproduces_every_file(tmp_path):
    """Every CSV and JSON of sample_data/ comes out of its generator byte for byte (the
    inks, the car paint and truth.json from make_inks.py; the coat paint from
    make_coat_paint.py)."""
    load_generator().main(tmp_path)
    load_generator("make_coat_paint").main(tmp_path)
    made = sorted(p.name for p in tmp_path.iterdir() if p.is_file())
    shipped = sorted(p.name for p in SAMPLE.iterdir() if p.suffix in (".csv", ".json"))
    assert made == shipped
    for name in made:
        assert (tmp_path / name).read_bytes() == (SAMPLE / name).read_bytes(), name


@pytest.mark.parametrize("name", ["red", "green", "blue"])
def test_inks_ingest_cleanly(run_gonio, tmp_path, name):
    m, res = ingest_case(run_gonio, tmp_path, name)
    # on the working grid, nothing negative: no warning, only the one summary line
    assert res.stderr.count("\n") == 1 and "warning" not in res.stderr
    assert m.n_configurations == TRUTH["inks"][name]["configurations"]
    assert sorted(set(m.theta_i_deg)) == TRUTH["geometry"]["theta_i_deg"]
    assert m.wavelength_nm.tolist() == TRUTH["wavelength_nm"]


def test_carpaint_ingests_with_the_resampling_warning(run_gonio, tmp_path):
    m, res = ingest_case(run_gonio, tmp_path, "carpaint")
    # the warning, then the summary line
    assert res.stderr.count("\n") == 2 and "resampled onto the working grid" in res.stderr
    assert m.n_configurations == len(TRUTH["carpaint"]["geometries"])
    assert m.wavelength_nm.size == 41


def test_paper_geometry(run_gonio, tmp_path):
    """θi ≤ 30° only on the far side (seed 000, "Limitations"), nothing within 10° of
    retro-reflection, about 130 configurations per ink."""
    m, _ = ingest_case(run_gonio, tmp_path, "blue")
    assert np.all(m.theta_o_deg[m.theta_i_deg <= 30] >= 0)
    assert np.all(np.abs(m.theta_o_deg + m.theta_i_deg) >= 10)
    assert 110 <= m.n_configurations <= 150
    assert np.any(m.theta_o_deg[m.theta_i_deg >= 40] < 0)


def test_truth_parameters_are_plausible():
    for name, ink in TRUTH["inks"].items():
        rho, c = np.array(ink["rho"]), np.array(ink["c"])
        assert 0.18 <= ink["alpha"] <= 0.20  # seed 000: α = 0.19 for all three
        assert 0.2 <= rho.max() <= 0.3 and 0.015 <= rho.min() <= 0.03
        assert 0 <= c.min() and c.max() <= 6
        peak = int(np.argmax(rho))
        assert c[:peak].mean() > c[peak:].mean()  # c larger below the peak
    peaks = {n: TRUTH["wavelength_nm"][int(np.argmax(i["rho"]))]
             for n, i in TRUTH["inks"].items()}
    assert peaks["blue"] < peaks["green"] < peaks["red"]


def _log_ratio(m, truth_brdf):
    return np.log(m.brdf / truth_brdf)


@pytest.mark.parametrize("name, repeats", [("red", 3), ("green", 1), ("blue", 1)])
def test_inks_follow_eq5_with_the_stated_noise(run_gonio, tmp_path, name, repeats):
    m, _ = ingest_case(run_gonio, tmp_path, name)
    ink = TRUTH["inks"][name]
    f = goniochromatic(in_plane_cosines(m.theta_i_deg, m.theta_o_deg), ink["alpha"],
                       np.array(ink["rho"]), np.array(ink["c"]))
    r = _log_ratio(m, f)
    noise = TRUTH["noise"]
    row70 = m.theta_i_deg == 70
    # Mean of `repeats` log-normal draws: σ/√repeats per value. With ≥ 4000 values the
    # sample std is within ~1.1 % of σ (1/√(2n)), and the mean within σ/√n ≈ 3e-4;
    # 10 % and 0.003 leave room for the 6-digit rounding of the files.
    sigma = noise["sigma_log"] / np.sqrt(repeats)
    assert r[~row70].std() == pytest.approx(sigma, rel=0.10)
    assert abs(r[~row70].mean()) < 0.003
    # θi = 70° is the less reliable row: biased by +10 % (log 1.1 = 0.095) with 8 % noise;
    # ~800 values, so the mean is within 0.08/√800 ≈ 0.003 of the bias.
    bias = np.log(noise["theta_i_70"]["bias"])
    assert r[row70].mean() == pytest.approx(bias, abs=0.01)
    assert r[row70].std() == pytest.approx(noise["theta_i_70"]["sigma_log"] /
                                           np.sqrt(repeats), rel=0.15)


def test_red_repeats_have_a_spread(run_gonio, tmp_path):
    m, _ = ingest_case(run_gonio, tmp_path, "red")
    assert m.n_repeats.tolist() == [3] * m.n_configurations
    rel = (m.brdf_std / m.brdf)[m.theta_i_deg < 70]
    # Sample std of 3 draws with σ = 2 %: its mean is ≈ 0.886 σ (c4 for n = 3).
    assert rel.mean() == pytest.approx(0.886 * 0.02, rel=0.1)


def test_carpaint_follows_cook_torrance(run_gonio, tmp_path):
    m, _ = ingest_case(run_gonio, tmp_path, "carpaint", "--grid-nm", "380:780:5")
    cp = TRUTH["carpaint"]
    assert m.wavelength_nm.tolist() == cp["wavelength_nm"]
    f = cook_torrance(in_plane_cosines(m.theta_i_deg, m.theta_o_deg),
                      *(np.array(cp[k]) for k in ("kd", "ks", "m", "f0")))
    r = _log_ratio(m, f)
    # 9 × 81 values with σ = 1 %: sample std within ~3 % of σ; 15 % is generous.
    assert r.std() == pytest.approx(cp["noise"]["sigma_log"], rel=0.15)
    assert abs(r.mean()) < 0.002
    # A metallic flop: bright near specular (45as-15), dark far from it (45as110).
    near = m.brdf[(m.theta_i_deg == 45) & (m.theta_o_deg == 60)].mean()
    far = m.brdf[(m.theta_i_deg == 45) & (m.theta_o_deg == -65)].mean()
    assert near > 10 * far
