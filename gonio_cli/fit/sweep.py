"""Error against run time for the fit settings a user chooses between.

Runs each method (seed 000's two steps with step 2 on mirror or on all configurations,
the joint refinement) with each optimiser on synthetic measurements of known parameters
and returns one row per combination: parameter errors against the truth, data error and
the median wall time. ``make bench`` prints these rows; ``gonio report`` will plot them.
"""

from __future__ import annotations

import time
import zlib
from dataclasses import dataclass
from typing import Iterable

import numpy as np

from ..synthetic import ink_spectra, paper_geometry, synthetic_measurement
from . import fit
from ..names import OPTIMIZERS_BY_MODEL
from ..spectra import parse_grid
from .common import prepare
from .results import FitOptions

#: (label, options, report key) for each method of the goniochromatic fit.
METHODS = (
    ("paper two-step (step 2 on mirror)", dict(refine=False, step2="mirror"), "paper_two_step"),
    ("two-step, step 2 on all configs", dict(refine=False, step2="all"), "paper_two_step"),
    ("joint refinement (default)", dict(refine=True, step2="mirror"), "refined"),
)


@dataclass
class SweepRow:
    case: str
    method: str
    optimizer: str
    alpha_error_percent: float
    rho_rel_rmse_percent: float
    c_rmse: float
    log_rmse: float
    time_ms: float


#: A first run this long is timed as it is (a single repeat): the first call's own costs
#: (imports, caches, ~10 ms) are lost in it, and the layered models take ~0.3–1 s a fit.
WARM_UP_ENOUGH_S = 0.2


def _timed(fun, repeats: int):
    times, out = [], None
    for _ in range(repeats):
        t = time.perf_counter()
        out = fun()
        times.append(time.perf_counter() - t)
    return out, float(np.median(times))


def goniochromatic_sweep(alphas: Iterable[float] = (0.03, 0.19, 0.5),
                         inks: Iterable[str] = ("red", "green", "blue"),
                         noise: float = 0.02, repeats: int = 5,
                         optimizers: Iterable[str] = OPTIMIZERS_BY_MODEL["goniochromatic"]
                         ) -> list[SweepRow]:
    """One row per (case, method, optimiser); time is the median of ``repeats`` runs of
    the whole fit (preparation included), after one warm-up run."""
    rows = []
    ti, to = paper_geometry(5.0, theta_i_deg=(20.0, 30.0, 40.0, 50.0, 60.0, 65.0))
    for ink in inks:
        rho, c = ink_spectra(ink)
        for alpha in alphas:
            m = synthetic_measurement("goniochromatic", {"alpha": alpha, "rho": rho, "c": c},
                                      ti, to, noise=noise,
                                      seed=zlib.crc32(f"{ink}{alpha}".encode()))
            case = f"{ink} α={alpha:g} ({m.n_configurations}×{m.wavelength_nm.size})"
            for label, kw, key in METHODS:
                for optimizer in optimizers:
                    run = lambda: fit(prepare(m), "goniochromatic",  # noqa: E731
                                      FitOptions(optimizer=optimizer, **kw))
                    run()
                    result, t = _timed(run, repeats)
                    p = result.reports[key].params
                    rows.append(SweepRow(
                        case, label, optimizer,
                        100 * abs(p["alpha"] / alpha - 1),
                        100 * float(np.sqrt(np.mean((p["rho"] / rho - 1) ** 2))),
                        float(np.sqrt(np.mean((p["c"] - c) ** 2))),
                        result.reports[key].errors["log_rmse"], 1e3 * t))
    return rows


def format_rows(rows: list[SweepRow]) -> str:
    """A Markdown table (error and time side by side)."""
    head = ("| case | method | optimizer | α err % | ρ rel-RMSE % | c RMSE | data log-RMSE "
            "| time ms |\n|---|---|---|---:|---:|---:|---:|---:|")
    lines = [head]
    for r in rows:
        lines.append(f"| {r.case} | {r.method} | {r.optimizer} | {r.alpha_error_percent:.3f} "
                     f"| {r.rho_rel_rmse_percent:.2f} | {r.c_rmse:.3f} | {r.log_rmse:.4f} "
                     f"| {r.time_ms:.3g} |")
    return "\n".join(lines)


#: Comparison models on their own synthetic data: (model, truth builder).
def _comparison_truths(wl: np.ndarray) -> dict[str, dict]:
    x = (wl - wl[0]) / (wl[-1] - wl[0])
    return {
        "torrance-sparrow": {"alpha": 0.19,
                             "f0": 0.04 + 0.5 / (1.0 + np.exp(-(wl - 550.0) / 30.0))},
        "cook-torrance": {"kd": 0.02 + 0.15 * np.exp(-0.5 * ((wl - 470.0) / 50.0) ** 2),
                          "ks": 0.3 + 0.1 * x, "m": 0.25 + 0.05 * x, "f0": 0.6 + 0.3 * x},
        "goniochromatic-diffuse": dict(_ink(wl), rho_d=0.05 + 0.1 * x),
        "goniochromatic-coat": dict(_ink(wl), rho_d=0.05 + 0.1 * x, alpha_coat=0.03,
                                    k_coat=1.0, f0_coat=0.04),
        "goniochromatic-backscatter": dict(_ink(wl), rho_d=0.2 + 0.4 * x, alpha_coat=0.03,
                                           k_coat=1.0, f0_coat=0.04, b0=0.6, h=0.2),
        "goniochromatic-undercoat": dict(_ink(wl), rho_d=0.05 + 0.1 * x, alpha_coat=0.03,
                                         k_coat=1.0, f0_coat=0.04),
        "goniochromatic-two-lobe": dict(_ink(wl), rho_d=0.05 + 0.1 * x, alpha_2=0.04,
                                        rho_2=0.1 + 0.4 * (1.0 - x)),
        "cook-torrance-2": dict(_paint(wl), ks_1=0.1, m_1=0.05, ks_2=0.6, m_2=0.3),
        "cook-torrance-3": dict(_paint(wl), ks_1=0.1, m_1=0.05, ks_2=0.4, m_2=0.2,
                                ks_3=0.3, m_3=0.5),
    }


def _paint(wl: np.ndarray) -> dict:
    """A blue metallic paint's spectra for the lobed Cook–Torrance models: a blue base
    kd(λ) and a flake F0(λ) rising towards the red."""
    x = (wl - wl[0]) / (wl[-1] - wl[0])
    return {"kd": 0.02 + 0.15 * np.exp(-0.5 * ((wl - 470.0) / 50.0) ** 2), "f0": 0.5 + 0.4 * x}


def _ink(wl: np.ndarray) -> dict:
    """The green sample ink's eq. 5 parameters at α = 0.15 (the layered models' lobe)."""
    rho, c = ink_spectra("green", wl)
    return {"alpha": 0.15, "rho": rho, "c": c}


#: Models swept once, at their default optimiser, with the compressive residual they are
#: meant for.
_LAYERED = {"goniochromatic-diffuse", "goniochromatic-coat", "goniochromatic-backscatter",
            "goniochromatic-undercoat", "goniochromatic-two-lobe",
            "cook-torrance-2", "cook-torrance-3"}


def comparison_sweep(noise: float = 0.02, repeats: int = 5,
                     optimizers: Iterable[str] | None = None) -> list[dict]:
    """Each comparison model on data made from itself: relative RMSE of each parameter
    against the truth (%), the data's relative RMSE (seed 004 eq. 14) and median time.
    Each model runs with each of ``optimizers`` it takes (default: all it takes)."""
    wl = parse_grid()
    ti, to = paper_geometry(5.0, theta_i_deg=(20.0, 30.0, 40.0, 50.0, 60.0, 70.0))
    rows = []
    for model, truth in _comparison_truths(wl).items():
        m = synthetic_measurement(model, truth, ti, to, noise=noise, seed=1)
        layered = model in _LAYERED
        own = OPTIMIZERS_BY_MODEL[model][:1] if layered else OPTIMIZERS_BY_MODEL[model]
        residuals = "compressive" if layered else "log"
        for optimizer in [o for o in own if optimizers is None or o in optimizers]:
            run = lambda: fit(prepare(m, residuals=residuals), model,  # noqa: E731
                              FitOptions(optimizer=optimizer))
            # a warm-up run, kept as the measure when a single repeat is asked for and
            # the fit is slow enough for first-call costs to vanish in it
            result, t = _timed(run, 1)
            if repeats > 1 or t < WARM_UP_ENOUGH_S:
                result, t = _timed(run, repeats)
            errs = {k: 100 * float(np.sqrt(np.mean((np.asarray(result.params[k]) / v - 1) ** 2)))
                    for k, v in truth.items() if k != "c"}
            if "c" in truth:   # c crosses 0: its error is absolute, in percent of its range
                errs["c"] = 100 * float(np.sqrt(np.mean((result.params["c"] - truth["c"]) ** 2))
                                        / np.ptp(truth["c"]))
            rows.append({"model": model, "optimizer": optimizer, "method": result.final,
                         "parameter_error_percent": errs,
                         "relative_rmse_percent": result.result.errors["relative_rmse_percent"],
                         "time_ms": 1e3 * t})
    return rows


def format_comparison(rows: list[dict]) -> str:
    lines = ["| model | optimizer | final method | parameter rel-RMSE % vs truth "
             "| data rel-RMSE % (eq. 14) | time ms |", "|---|---|---|---|---:|---:|"]
    for r in rows:
        errs = ", ".join(f"{k} {v:.2f}" for k, v in r["parameter_error_percent"].items())
        lines.append(f"| {r['model']} | {r['optimizer']} | {r['method']} | {errs} "
                     f"| {r['relative_rmse_percent']:.2f} | {r['time_ms']:.3g} |")
    return "\n".join(lines)
