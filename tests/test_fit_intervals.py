"""Confidence intervals of every fit (gonio_cli/fit/uncertainty.py), the colour band of
``gonio eval`` (gonio_cli/evaluate.py) and the verdict line that shows them.

Truth: synthetic measurements from known parameters with known log-normal noise
(gonio_cli/synthetic.py), fitted with log residuals, whose weighted residuals are then
exactly the Gaussian noise the Gauss-Newton covariance assumes."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from gonio_cli.brdf import MODELS, evaluate
from gonio_cli.evaluate import colour_band
from gonio_cli.fit import fit, judge, to_material
from gonio_cli.fit.common import prepare
from gonio_cli.fit.run import RunOptions, fit_intervals, run
from gonio_cli.fit import uncertainty
from gonio_cli.geometry import in_plane_cosines
from gonio_cli.schemas import read_material, read_measurement, write_material, write_measurement
from gonio_cli.synthetic import ink_spectra, paper_geometry, synthetic_measurement

FIXTURES = Path(__file__).parent / "fixtures" / "real"
GRID = np.arange(400.0, 701.0, 25.0)          # 13 wavelengths: 200 fits in ~3 s
TI, TO = paper_geometry(10.0)                 # 97 configurations
RHO, C = ink_spectra("red", GRID)
TRUTH = {"alpha": 0.15, "rho": RHO, "c": C}


def _fit(noise, seed, geometry=(TI, TO)):
    m = synthetic_measurement("goniochromatic", TRUTH, *geometry, grid_nm=GRID, noise=noise,
                              seed=seed)
    data = prepare(m, residuals="log")
    result = fit(data, "goniochromatic")
    return data, result, fit_intervals(data, result)


def _width(record, name, j=None):
    e = record["parameters"][name]
    lo, hi = (e["low"], e["high"]) if j is None else (e["low"][j], e["high"][j])
    return hi - lo


def test_95_percent_intervals_cover_the_truth_in_90_to_99_percent_of_200_trials():
    """The issue's criterion: α, and ρ and c at 600 nm, each covered by its 95 % interval
    in [0.90, 0.99] of 200 seeded trials (binomial sd of the rate at 0.95: 0.015, so the
    band is ±3 sd)."""
    j = int(np.flatnonzero(GRID == 600.0)[0])
    hits = {"alpha": 0, "rho": 0, "c": 0}
    for seed in range(200):
        _, _, rec = _fit(0.05, seed)
        p = rec["parameters"]
        hits["alpha"] += p["alpha"]["low"] <= TRUTH["alpha"] <= p["alpha"]["high"]
        for k in ("rho", "c"):
            hits[k] += p[k]["low"][j] <= TRUTH[k][j] <= p[k]["high"][j]
    for k, h in hits.items():
        assert 0.90 <= h / 200 <= 0.99, (k, h)


def test_sigma_is_the_noise_and_the_width_scales_with_it_and_with_one_over_root_n():
    """σ² from the residuals is the noise's variance (log residuals, weights 1); the width
    is ∝ noise (4x noise: 4x width) and ∝ 1/√n (every configuration read twice, as new
    configurations: 1/√2 the width). Tolerances: σ̂ from ~1200 residuals is within ~2 %."""
    _, _, r1 = _fit(0.01, 3)
    _, _, r4 = _fit(0.04, 3)
    assert np.sqrt(r1["sigma2"]) == pytest.approx(0.01, rel=0.06)
    assert np.sqrt(r4["sigma2"]) == pytest.approx(0.04, rel=0.06)
    assert _width(r4, "alpha") / _width(r1, "alpha") == pytest.approx(4.0, rel=0.08)
    twice = (np.concatenate([TI, TI]), np.concatenate([TO, TO]))
    _, _, r2 = _fit(0.04, 3, twice)
    assert _width(r2, "alpha") / _width(r4, "alpha") == pytest.approx(2 ** -0.5, rel=0.08)
    assert _width(r2, "rho", 8) / _width(r4, "rho", 8) == pytest.approx(2 ** -0.5, rel=0.08)


def test_the_block_inverse_is_the_dense_inverse_and_spectral_columns_stay_at_their_wavelength():
    """The arrow-block inversion (Schur complement) equals the dense (JᵀJ)⁻¹; a spectral
    parameter moved at one wavelength moves only that wavelength's f, for every model (the
    structure the one-evaluation-per-parameter Jacobian relies on)."""
    data, result, _ = _fit(0.02, 1)
    sides = {n: uncertainty.at_bound(n, result.params[n]) for n in ("alpha", "rho", "c")}
    used = data.w > 0
    js, jl = uncertainty.jacobian("goniochromatic", data.cos, result.params, sides,
                                  lambda f: uncertainty._residuals(
                                      data, f, np.ones(data.n_configurations), used))
    (c_ss, c_sl, c_ll), *_ = uncertainty._covariance(js, jl)
    n_l, k = data.wavelength_nm.size, jl.shape[0]
    cols = [js[0].ravel()] + [np.where(np.arange(n_l)[None, :] == lam, jl[q], 0.0).ravel()
                              for lam in range(n_l) for q in range(k)]
    dense = np.linalg.inv(np.array(cols) @ np.array(cols).T)
    assert c_ss[0, 0] == pytest.approx(dense[0, 0], rel=1e-8)
    assert np.allclose(c_sl[0], dense[0, 1:].reshape(n_l, k), rtol=1e-7, atol=0)
    blocks = np.array([dense[1 + lam * k:1 + (lam + 1) * k, 1 + lam * k:1 + (lam + 1) * k]
                       for lam in range(n_l)])
    assert np.allclose(c_ll, blocks, rtol=1e-7, atol=0)
    cos = in_plane_cosines(TI[:20], TO[:20])
    for name, spec in MODELS.items():
        params = {p: 0.3 for p in spec.scalar_params}
        params.update({p: np.full(GRID.size, 0.4) for p in spec.spectral_params})
        if spec.table_params:                  # tabulated-colour's table and its nodes
            params.update(colour_table=np.full((3, 2, GRID.size), 0.4),
                          theta_h_nodes_deg=np.array([0.0, 10.0, 90.0]),
                          theta_d_nodes_deg=np.array([0.0, 90.0]))
        f0 = evaluate(name, cos, params)
        for p in spec.spectral_params:
            moved = dict(params, **{p: params[p] * np.where(np.arange(GRID.size) == 5, 1.1, 1)})
            changed = np.any(evaluate(name, cos, moved) != f0, axis=0)
            assert not changed[np.arange(GRID.size) != 5].any(), (name, p)


def test_a_parameter_at_its_bound_gets_a_one_sided_interval_never_nan():
    """ρ_d fitted to data without a diffuse term sits at 0: its interval is [0, high], the
    element named in one_sided_at; nothing in the record is NaN."""
    m = synthetic_measurement("goniochromatic", TRUTH, TI, TO, grid_nm=GRID, noise=0.02, seed=2)
    data = prepare(m, residuals="log")
    result = fit(data, "goniochromatic-diffuse")
    rec = fit_intervals(data, result)
    e = rec["parameters"]["rho_d"]
    at0 = np.flatnonzero(np.asarray(result.params["rho_d"]) == 0.0)
    assert at0.size and set(at0.tolist()) <= set(e["one_sided_at"])
    assert np.all(np.asarray(e["low"])[at0] == 0.0) and np.all(np.asarray(e["high"])[at0] > 0)
    flat = np.concatenate([np.ravel(v[b]) for v in rec["parameters"].values()
                           for b in ("low", "high")])
    assert np.all(np.isfinite(flat))


def _material(record_scale: float):
    """The synthetic fit as a material whose covariance is scaled by ``record_scale``."""
    data, result, rec = _fit(0.05, 4)
    rec = copy.deepcopy(rec)
    cov = rec["covariance"]
    for key in ("scalar", "cross", "spectral"):
        cov[key] = (np.asarray(cov[key]) * record_scale).tolist()
    return to_material(result, judge(data, result), {"intervals": rec})


def test_eval_band_is_zero_for_zero_width_intervals_and_grows_with_them():
    """The band (95th percentile of CIEDE2000 of drawn models against the fitted one) is 0
    with a zero covariance, and doubles (to ~10 %: CIEDE2000 is near linear in small
    changes) when every standard deviation doubles (covariance x4)."""
    m = synthetic_measurement("goniochromatic", TRUTH, TI, TO, grid_nm=GRID, noise=0.0)
    bands = {}
    for scale in (0.0, 1.0, 4.0):
        mat = _material(scale)
        f = mat.evaluate(in_plane_cosines(TI, TO))
        bands[scale] = colour_band(mat, m, f)
        assert bands[scale]["available"]
    assert np.max(bands[0.0]["delta_e2000_p95"]) == 0.0
    one, four = (np.asarray(bands[s]["delta_e2000_p95"]) for s in (1.0, 4.0))
    assert np.all(one > 0)
    assert np.median(four / one) == pytest.approx(2.0, rel=0.1)


def test_eval_of_a_material_without_intervals_says_the_band_is_not_available(
        run_gonio, tmp_path):
    meas = tmp_path / "m.measurement.json"
    m = synthetic_measurement("goniochromatic", TRUTH, TI, TO, grid_nm=GRID, noise=0.02)
    write_measurement(meas, m)
    mat = _material(1.0)
    del mat.fit["intervals"]
    write_material(tmp_path / "old.material.json", mat)
    res = run_gonio("eval", tmp_path / "old.material.json", "--at", meas, "-o",
                    tmp_path / "e.json")
    assert res.exit_code == 0, res.stderr
    assert "colour band not available: the material has no intervals" in res.stderr
    band = read_measurement(tmp_path / "e.json").summary["colour_band"]  # validated
    assert band["available"] is False


def test_the_light_source_gains_get_intervals_and_eval_draws_them(run_gonio, tmp_path):
    """An MA-T12 file is fitted with one gain per lamp: each gain's interval holds it, and
    eval's band with the gains applied is available and finite."""
    meas = tmp_path / "ma.measurement.json"
    assert run_gonio("-q", "ingest", FIXTURES / "ma_t12_clean.csv", "-o", meas, "--grid-nm",
                     "400:700:10").exit_code == 0
    result = run(meas, RunOptions(model="cook-torrance"))
    rec = result.material.fit["intervals"]
    gains = result.material.fit["sweep_gain"]["gain"]
    assert rec["sweep_gain"]["theta_i_deg"] == [15.0, 45.0]
    for lo, g, hi in zip(rec["sweep_gain"]["low"], gains, rec["sweep_gain"]["high"]):
        assert lo < g < hi
    assert rec["covariance"]["scalar_names"] == ["log_gain_15", "log_gain_45"]
    from gonio_cli.evaluate import run as evaluate_run
    from gonio_cli.schemas import read_measurement as read
    ev = evaluate_run(result.material, read(meas))
    band = ev.model.summary["colour_band"]
    assert band["available"] and np.all(np.isfinite(band["delta_e2000_p95"]))


def test_the_verdict_line_of_a_good_fit_gives_alpha_with_its_interval(tmp_path):
    """A good fit: colour first, the verdict, α ± its 95 % half-width (around the truth),
    no relative RMSE; the material keeps the intervals."""
    from gonio_cli.commands.fit import verdict_line
    m = synthetic_measurement("goniochromatic", TRUTH, TI, TO, grid_nm=GRID, noise=0.01,
                              seed=5)
    result = run(m, RunOptions(residuals="log"))
    line = verdict_line("m.json", result.model_fit, result.judgement,
                        result.material.fit["intervals"])
    assert line.startswith("m.json: goniochromatic: colour error CIEDE2000 mean 0.")
    assert ": good; alpha 0.1" in line and line.endswith(" (95 %)")
    half = float(line.split(" ± ")[1].split(" ")[0])
    alpha = float(line.split("; alpha ")[1].split(" ")[0])
    assert abs(alpha - 0.15) <= 2.5 * half and "rel-RMSE" not in line


def test_the_verdict_line_of_a_poor_glossy_fit_has_no_alarming_rel_rmse(run_gonio, tmp_path):
    """The RGL wrap (glossy, colour-shifting): poor by colour, with its worst configuration
    and the peaks; the relative RMSE (hundreds of percent, from the dark tail) stays in the
    material, off the verdict line."""
    meas = tmp_path / "wrap.measurement.json"
    assert run_gonio("-q", "ingest", FIXTURES / "rgl_wrap_inplane.csv", "-o", meas).exit_code == 0
    from gonio_cli.commands.fit import report_lines
    result = run(meas)               # gonio fit's call; its lines without the model hint
    lines = list(report_lines("wrap.material.json", result, lambda r: None))
    line = next(x for x in lines if "colour error CIEDE2000" in x)
    assert ": poor (mean CIEDE2000 " in line and "mirror peak x" in line
    assert "rel-RMSE" not in line and "%)" not in line.split("(95 %)")[0]
    assert "; alpha 0.0" in line and " ± " in line
    mat = result.material
    assert mat.fit["methods"][mat.fit["final"]]["relative_rmse_percent"] > 100
    assert mat.fit["intervals"]["available"]


def test_every_model_gets_finite_intervals_in_range_that_the_material_schema_reads(tmp_path):
    """Each model of FITTERS, fitted to a synthetic diffuse + eq. 5 sample: intervals
    available, every element finite, low <= value <= high within the parameter's range;
    the material is written and read back (fit.intervals validated)."""
    from gonio_cli.fit import FITTERS
    from gonio_cli.schemas.material import PARAM_RANGES
    from gonio_cli.schemas.spec import NON_NEGATIVE
    truth = {**TRUTH, "rho_d": np.full(GRID.size, 0.02)}
    m = synthetic_measurement("goniochromatic-diffuse", truth, TI, TO, grid_nm=GRID,
                              noise=0.02, seed=0)
    data = prepare(m, residuals="compressive")
    for name in FITTERS:
        result = fit(data, name)
        rec = fit_intervals(data, result)
        assert rec["available"], name
        for k, e in rec["parameters"].items():
            p = np.atleast_1d(result.params[k])
            lo, hi = np.atleast_1d(e["low"]), np.atleast_1d(e["high"])
            assert np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)), (name, k)
            assert np.all(lo <= p) and np.all(p <= hi), (name, k)
            ranges = PARAM_RANGES.get(k, NON_NEGATIVE)          # the colour table: T >= 0
            assert not ranges.outside(np.r_[lo.ravel(), hi.ravel()]).any(), (name, k)
        write_material(tmp_path / f"{name}.json", to_material(result, judge(data, result),
                                                               {"intervals": rec}))
        assert read_material(tmp_path / f"{name}.json").fit["intervals"]["available"]


@pytest.mark.parametrize("entry, text", [
    ({"low": 0.176, "high": 0.184, "transform": "logit"}, "alpha 0.180 ± 0.004"),
    ({"low": 0.12, "high": 0.27, "transform": "logit"}, "alpha 0.18 (0.12-0.27)"),
    ({"low": 0.002, "high": 0.3, "transform": "logit"},
     "alpha 0.18 (poorly determined: 0.002-0.3)"),
    ({"low": 0.001, "high": 1.0, "transform": "logit"}, "alpha 0.18 (not determined by the data)"),
    ({"low": 0.18, "high": 0.2, "transform": "logit", "one_sided_at": [0]},
     "alpha 0.18 (at its lower bound; 95 % <= 0.2)"),
])
def test_a_parameter_on_the_verdict_line_reads_as_its_interval_says(entry, text):
    """Symmetric within 20 %: ± the half-width to its first significant digit; else the
    range; wider than two decades, reaching the search's bound or one-sided: in words."""
    assert uncertainty.half_width_text("alpha", 0.18, entry) == text
