"""Warm starts of ``--model auto``'s folds (gonio_cli/fit/warm.py) and the held-out tie
rule (the c search on nested lattices is checked in tests/test_fit_real.py).

Truth: data made from known parameters (the fit of a fold must recover them as a cold
fit does, and reach as low a cost of its own data); candidates with set held-out errors.
"""

from __future__ import annotations

import numpy as np
import pytest

from gonio_cli import brdf
from gonio_cli.fit import fit
from gonio_cli.fit.auto import HELD_OUT_TIE, folds
from gonio_cli.fit.common import prepare
from gonio_cli.fit.results import FitOptions
from gonio_cli.fit.layered import Layered
from gonio_cli.fit.warm import log_alpha_window, near
from gonio_cli.synthetic import ink_spectra, paper_geometry, synthetic_measurement


def _coat_data(noise=0.01, seed=3):
    rho, c = ink_spectra("green")
    p = {"alpha": 0.15, "rho": rho, "c": c, "rho_d": 0.05 + 0.1 * rho,
         "alpha_coat": 0.03, "k_coat": 1.0, "f0_coat": 0.04}
    ti, to = paper_geometry(5.0, theta_i_deg=(20.0, 40.0, 60.0))
    m = synthetic_measurement("goniochromatic-coat", p, ti, to, noise=noise, seed=seed)
    return p, prepare(m, residuals="compressive")


def _cost(data, params):
    return Layered(data, coat=True).cost(params["alpha"], (params["alpha_coat"],
                                                           params["k_coat"], params["f0_coat"]))


@pytest.mark.parametrize("model", ["goniochromatic-coat", "cook-torrance-2"])
def test_a_warm_fold_fits_its_data_at_least_as_well_as_a_cold_one(model):
    # each fold (θi left out) from the fit to all the data: its own cost within 0.5 % of
    # the cold search's (the warm search stops at 1e-4 in log roughness, the cold one at
    # 1e-6; BOBYQA's last trust region still leaves α ~1e-3 apart, ~1e-3 of this cost
    # on 1 % noise), in fewer evaluations
    truth, data = _coat_data()
    full = fit(data, model, FitOptions())
    _, held = folds(data)
    for label, rows in held:
        part = data.subset(~rows)
        cold = fit(part, model, FitOptions())
        warm = fit(part, model, FitOptions(warm=dict(full.params)))
        assert warm.result.evaluations < cold.result.evaluations, label
        if model == "goniochromatic-coat":
            assert _cost(part, warm.params) <= _cost(part, cold.params) * (1 + 5e-3), label
            # and the parameters the data were made from (1 % noise: α to 2 %)
            assert warm.params["alpha"] == pytest.approx(truth["alpha"], rel=0.02)
            assert warm.params["alpha_coat"] == pytest.approx(truth["alpha_coat"], rel=0.02)
        else:
            y, fw, fc = (part.y, brdf.evaluate(model, part.cos, warm.params),
                         brdf.evaluate(model, part.cos, cold.params))
            assert (np.sum(part.w * (fw - y) ** 2) <=
                    np.sum(part.w * (fc - y) ** 2) * (1 + 5e-3)), label


def test_the_fit_to_all_the_data_never_starts_warm():
    # warm parameters of another model, or none, leave a fit as it was
    _, data = _coat_data()
    cold = fit(data, "goniochromatic-coat", FitOptions())
    other = fit(data, "goniochromatic-coat", FitOptions(warm={"kd": np.ones(3)}))
    assert other.params["alpha"] == cold.params["alpha"]
    assert near(FitOptions(warm={"alpha": float("nan")}), "alpha") is None
    assert near(FitOptions(warm={"alpha": 0.2}), "alpha") == {"alpha": 0.2}


def test_the_warm_alpha_window_holds_the_warm_alpha_inside_the_bounds():
    lo, hi = np.log(1e-3), 0.0
    for alpha in (1e-3, 0.02, 0.5, 1.0):
        a, b, n = log_alpha_window(alpha, lo, hi, 25)
        assert lo <= a <= np.log(alpha) <= b <= hi and n >= 3
        assert (b - a) / (n - 1) == pytest.approx((hi - lo) / 24)


def test_held_out_errors_within_the_tie_keep_the_simpler_candidate(monkeypatch):
    from gonio_cli.fit import auto

    rho, c = ink_spectra("green")
    ti, to = paper_geometry(10.0, theta_i_deg=(20.0, 40.0, 60.0))
    data = prepare(synthetic_measurement("goniochromatic", {"alpha": 0.2, "rho": rho, "c": c},
                                         ti, to, noise=0.0), residuals="compressive")
    fits = {m: fit(data, m, FitOptions()) for m in ("goniochromatic", "goniochromatic-diffuse")}
    for second, chosen in ((1.0 - HELD_OUT_TIE / 2, "goniochromatic"),
                           (1.0 - 2 * HELD_OUT_TIE, "goniochromatic-diffuse")):
        cands = [auto.Candidate(m, f, held_out_delta_e=h)
                 for (m, f), h in zip(fits.items(), (1.0, second))]
        monkeypatch.setattr(auto, "_judge", lambda c, w, j, pr, cs=cands: cs)
        best, _ = auto.fit_auto(data, FitOptions(), fit, candidates=tuple(fits))
        assert best.model == chosen, second


def test_auto_gives_each_fold_the_full_fit_as_its_warm_start(monkeypatch):
    from gonio_cli.fit import auto

    _, data = _coat_data()
    seen = []

    def spy(d, model, options):
        seen.append((d.n_configurations, options.warm))
        return fit(d, model, options)

    auto.fit_auto(data, FitOptions(), spy, candidates=("goniochromatic",))
    (n_full, warm_full), *rest = seen
    assert n_full == data.n_configurations and warm_full is None
    assert rest and all(n < n_full and w is not None and "alpha" in w for n, w in rest)
