"""Fitting a model back from synthetic data made by it (1 % noise), shared by the tests
of the layered models and ``--model auto``: the fitted parameters, how far a fitted BRDF
is from the truth, and an RGL slice's grid of configurations."""

from __future__ import annotations

import numpy as np

from gonio_cli import brdf
from gonio_cli.fit import fit
from gonio_cli.fit.common import prepare
from gonio_cli.fit.results import FitOptions
from gonio_cli.synthetic import synthetic_measurement


def fit_back(model: str, truth: dict, theta_i_deg, theta_o_deg, seed: int):
    """(data, fitted parameters) of ``model`` fitted to its own data at 1 % noise; the fit
    must succeed."""
    m = synthetic_measurement(model, truth, theta_i_deg, theta_o_deg, noise=0.01, seed=seed)
    data = prepare(m, residuals="compressive")
    r = fit(data, model, FitOptions())
    assert r.result.success
    return data, r.params


def brdf_error(data, truth_model: str, truth: dict, model: str | None = None,
               params: dict | None = None) -> float:
    """RMS relative error of ``model``'s BRDF at the data's configurations against the
    truth's; with ``params`` None, ``model`` (default the truth's) is fitted to ``data``."""
    model = model or truth_model
    if params is None:
        params = fit(data, model, FitOptions()).params
    f_true = brdf.evaluate(truth_model, data.cos, truth)
    f = brdf.evaluate(model, data.cos, params)
    return float(np.sqrt(np.mean((f / f_true - 1) ** 2)))


def rgl_like_geometry():
    """An RGL slice's grid (tests/fixtures/real/README.md): θi 10-70° by 10, θo −80-85° by
    5 plus θi ± 1, 2, 3° around the mirror."""
    ti, to = [], []
    for t in range(10, 80, 10):
        for o in sorted(set(range(-80, 90, 5)) | {t + d for d in (-3, -2, -1, 0, 1, 2, 3)}):
            ti.append(float(t))
            to.append(float(o))
    return np.array(ti), np.array(to)
