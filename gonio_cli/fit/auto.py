"""``--model auto``: every applicable model, judged on angles it did not see.

Each candidate (:data:`CANDIDATES`) is fitted to all the data, then once per angle of
incidence with that angle left out; the left-out configurations are predicted and their
colour error measured (CIEDE2000 as in :mod:`.verdict`). The candidate with the lowest
mean held-out colour error is kept. Judging on held-out angles, not on the data each
model was fitted to, keeps a model with more parameters from winning only because it can
bend to the noise. With a single angle of incidence there is nothing to hold out and the
in-sample error decides (said in the material).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..errors import GonioError
from .common import FitData, FitOptions, ModelFit, Stopwatch, compressive_floor
from .verdict import colour_errors, covers_colour

#: Models ``auto`` tries, cheapest first (a tie keeps the earlier, simpler one).
CANDIDATES = ("goniochromatic", "goniochromatic-diffuse", "torrance-sparrow",
              "cook-torrance", "cook-torrance-2", "cook-torrance-3", "goniochromatic-coat")


@dataclass
class Candidate:
    model: str
    fit: ModelFit | None
    held_out_delta_e: float = float("inf")
    in_sample_delta_e: float = float("inf")
    time_s: float = 0.0
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        def num(v):
            return float(v) if np.isfinite(v) else None
        return {"model": self.model, "held_out_delta_e2000_mean": num(self.held_out_delta_e),
                "delta_e2000_mean": num(self.in_sample_delta_e), "time_s": self.time_s,
                "status": (self.fit.result.status if self.fit else "failed"),
                "notes": self.notes}


def _score(data: FitData, rows: np.ndarray, f: np.ndarray) -> np.ndarray:
    """Per-configuration error of predictions ``f`` on ``rows``: CIEDE2000 where colour
    can be judged, else the RMS relative error with the compressive residual's floor."""
    if covers_colour(data.wavelength_nm):
        return colour_errors(data.wavelength_nm, data.theta_i_deg[rows],
                             data.theta_o_deg[rows], data.y[rows], f).delta_e
    y = data.y[rows]
    return np.sqrt(np.mean(((f - y) / (np.abs(y) + compressive_floor(data.y))) ** 2, axis=1))


def fit_auto(data: FitData, options: FitOptions,
             fit_one: Callable[[FitData, str, FitOptions], ModelFit],
             candidates=CANDIDATES) -> tuple[ModelFit, list[Candidate]]:
    """The best candidate's fit by held-out error, and every candidate's figures."""
    from ..brdf import evaluate

    groups = data.theta_i_groups()
    results: list[Candidate] = []
    for model in candidates:
        sw = Stopwatch()
        try:
            full = fit_one(data, model, options)
        except GonioError as exc:
            results.append(Candidate(model, None, notes=[exc.message]))
            continue
        cand = Candidate(model, full)
        all_rows = np.ones(data.n_configurations, dtype=bool)
        cand.in_sample_delta_e = float(np.mean(_score(data, all_rows,
                                                      evaluate(model, data.cos, full.params))))
        if not full.result.success:
            cand.notes.append(f"fit failed: {full.result.message}")
        if len(groups) < 2:
            cand.held_out_delta_e = cand.in_sample_delta_e
            cand.notes.append("one angle of incidence: judged in sample")
        else:
            errors = []
            for theta_i, rows in groups:
                try:
                    part = fit_one(data.subset(~rows), model, options)
                except GonioError as exc:
                    cand.notes.append(f"without theta_i {theta_i:g}: {exc.message}")
                    errors = []
                    break
                sub = data.subset(rows)
                errors.append(_score(data, rows, evaluate(model, sub.cos, part.params)))
            if errors:
                cand.held_out_delta_e = float(np.mean(np.concatenate(errors)))
        cand.time_s = sw.lap()
        results.append(cand)
    usable = [c for c in results if c.fit is not None and c.fit.result.success
              and np.isfinite(c.held_out_delta_e)]
    if not usable:
        usable = [c for c in results if c.fit is not None]
    if not usable:
        raise GonioError("no model could be fitted: " + "; ".join(
            f"{c.model}: {' '.join(c.notes)}" for c in results))
    best = min(usable, key=lambda c: c.held_out_delta_e)
    return best.fit, results
