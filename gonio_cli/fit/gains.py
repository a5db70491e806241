"""Light-source gains: one achromatic factor per angle of incidence, fitted with the model.

A multi-angle spectrophotometer (ASTM E2194; X-Rite MA-T12, MA-98, BYK-mac) lights the
sample with a separate lamp at each angle of incidence, each calibrated on its own
against a white tile, and each lighting its own spot (1/cos θi long). Where the lamps'
calibrations differ, or a translucent sample (wax, marble, paper, a tinted coat) loses a
different share of its light sideways out of each lamp's spot, the whole sweep of one lamp
reads a few percent brighter than the other's. No BRDF can follow: reciprocity ties the
two sweeps together (f(15°, 45°) = f(45°, 15°)), so a model fitted to such data splits
the difference and misses both (an MA-T12 green earth pigment: its reciprocal pair differs
by CIEDE2000 2.3, every model misses by a mean 0.75-1.1).

The model of such a measurement is therefore ``g(θi) f``: the reciprocal BRDF ``f`` (what
the material holds and a renderer uses) times one gain per angle of incidence (what the
instrument added). The gains' geometric mean is 1, so ``f`` lies between the sweeps.
They are fitted with the model by block coordinate descent on the fit's own loss, which
decreases at every round:

- the model on the data divided by the gains, each row's weights times g² (so the fit
  minimises Σ w (g f − y)², the same loss as the gain step);
- each gain in closed form: g_s = Σ w y f / Σ w f² over the rows of θi = s (log
  residuals: exp of the weighted mean of log y − log f), then all divided by their
  geometric mean.

Three to five rounds reach :data:`GAIN_TOL`. ``gonio fit --sweep-gain`` (:data:`CHOICES`):
``auto`` fits them when the measurement came from a multi-angle instrument's file (one
lamp per θi, :func:`light_sources`), ``on`` for any measurement with at least two θi,
``off`` never. ``gonio eval`` applies them at the measurement's θi, so its output
compares with the instrument's readings; ``gonio render`` and the exports use ``f``.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any, Callable

import numpy as np

from ..brdf import evaluate
from ..errors import GonioError, InputError
from ..names import SWEEP_GAIN_NAMES
from .common import FitData
from .results import FitOptions, ModelFit

#: ``--sweep-gain`` values, spelled in :mod:`gonio_cli.names`.
CHOICES = SWEEP_GAIN_NAMES

#: Rounds stop when no gain moves by more than this (relative): 0.1 % of Y, ~0.04 L*.
GAIN_TOL = 1e-3

#: Rounds at most (each is one fit of the model); measured: 3-5 on an MA-T12 pigment.
MAX_ROUNDS = 10

#: ``--model auto`` estimates the gains once with this model, judges every candidate on
#: the data divided by them, and then refits the gains with the chosen model (one or two
#: rounds). Cook-Torrance: 0.1-0.2 s a fit, and its gains on the MA-T12 pigment (15°:
#: 1.044, 45°: 0.958) are within 0.4 % of those of every layered model (1.039-1.050).
REFERENCE_MODEL = "cook-torrance"

#: Gains further apart than this (largest over smallest) are noted on the console: more
#: than a calibration, a sample that moved or changed between sweeps.
NOTE_RATIO = 1.25

#: File layouts whose angles of incidence are separate lamps (ingest's ``layout``).
LIGHT_SOURCE_LAYOUTS = ("multi-angle",)

#: Tolerance of a measurement's θi against a material's gains (degrees).
ANGLE_TOL_DEG = 1e-6


@dataclass
class SweepGains:
    """One gain per angle of incidence (ascending), geometric mean 1."""

    theta_i_deg: np.ndarray
    gain: np.ndarray
    rounds: int = 0
    converged: bool = True
    why: str = ""

    def per_configuration(self, theta_i_deg) -> np.ndarray:
        """The gain of each configuration (N,); KeyError naming a θi without one."""
        ti = np.asarray(theta_i_deg, dtype=float)
        out = np.empty(ti.shape)
        for k, t in enumerate(ti):
            hit = np.flatnonzero(np.abs(self.theta_i_deg - t) <= ANGLE_TOL_DEG)
            if not hit.size:
                raise KeyError(float(t))
            out[k] = self.gain[hit[0]]
        return out

    def covers(self, theta_i_deg) -> bool:
        """Whether every angle of ``theta_i_deg`` has a gain."""
        try:
            self.per_configuration(theta_i_deg)
        except KeyError:
            return False
        return True

    @property
    def ratio(self) -> float:
        return float(self.gain.max() / self.gain.min())

    def text(self) -> str:
        """``theta_i 15: x1.042, 45: x0.960``."""
        return "theta_i " + ", ".join(f"{t:g}: x{g:.3f}"
                                      for t, g in zip(self.theta_i_deg, self.gain))

    def to_dict(self) -> dict[str, Any]:
        return {"theta_i_deg": [float(t) for t in self.theta_i_deg],
                "gain": [float(g) for g in self.gain], "rounds": self.rounds,
                "converged": self.converged, "why": self.why,
                "applies_to": "the measurement (gonio eval), not the BRDF: the material's "
                              "parameters are the reciprocal BRDF, geometric mean of the "
                              "sweeps"}

    @classmethod
    def from_dict(cls, d: Any, path=None) -> "SweepGains":
        """Read ``fit.sweep_gain`` of a material; a malformed one is a one-line error."""
        try:
            ti = np.asarray(d["theta_i_deg"], dtype=float)
            g = np.asarray(d["gain"], dtype=float)
            ok = (ti.ndim == 1 and ti.shape == g.shape and ti.size >= 1
                  and np.all(np.isfinite(ti)) and np.all(np.isfinite(g)) and np.all(g > 0))
        except (KeyError, TypeError, ValueError):
            ok = False
        if not ok:
            raise InputError("'fit.sweep_gain' must hold theta_i_deg and gain, lists of "
                             "the same length with finite gains > 0", path=path,
                             fix="write the material again with gonio fit")
        return cls(ti, g, int(d.get("rounds", 0)), bool(d.get("converged", True)),
                   str(d.get("why", "")))


def light_sources(measurement) -> bool:
    """Whether a measurement's angles of incidence are separate lamps: every file ingest
    read was a multi-angle instrument's export (:data:`LIGHT_SOURCE_LAYOUTS`)."""
    files = (measurement.summary or {}).get("files") or []
    return bool(files) and all(isinstance(f, dict) and f.get("layout") in LIGHT_SOURCE_LAYOUTS
                               for f in files)


def wanted(choice: str, measurement, data: FitData, path=None) -> str | None:
    """Why the fit takes gains (a sentence for the material), or None: ``--sweep-gain``
    ``choice`` given the measurement and the data left after the exclusions."""
    n = len(data.theta_i_groups())
    if choice == "off":
        return None
    if choice == "on":
        if n < 2:
            raise InputError(f"--sweep-gain on needs at least two angles of incidence; the "
                             f"data have {n}", path=path,
                             fix="use --sweep-gain off (one sweep has nothing to compare to)")
        return "--sweep-gain on"
    if n >= 2 and light_sources(measurement):
        return ("--sweep-gain auto: a multi-angle instrument's file, one lamp per angle "
                "of incidence")
    return None


def scaled(data: FitData, g_rows: np.ndarray) -> FitData:
    """The data as the BRDF alone should reproduce them: y / g, and (linear residuals)
    weights × g², so that fitting them minimises Σ w (g f − y)²."""
    g = np.asarray(g_rows, dtype=float)[:, None]
    w = data.w if data.residuals == "log" else data.w * g * g
    return replace(data, y=data.y / g, w=w)


def best_gains(data: FitData, f: np.ndarray) -> np.ndarray:
    """The gains (one per θi group, ascending) that minimise the fit's loss for a fixed
    model ``f`` (N, L), geometric mean 1."""
    out = []
    for _, rows in data.theta_i_groups():
        w, y, m = data.w[rows], data.y[rows], f[rows]
        if data.residuals == "log":
            ok = (w > 0) & (y > 0) & (m > 0)
            g = (np.exp(np.sum(w[ok] * (np.log(y[ok]) - np.log(m[ok]))) / np.sum(w[ok]))
                 if ok.any() and np.sum(w[ok]) > 0 else 1.0)
        else:
            den = float(np.sum(w * m * m))
            g = float(np.sum(w * y * m)) / den if den > 0 else 1.0
        out.append(g if np.isfinite(g) and g > 0 else 1.0)
    out = np.asarray(out)
    return out / np.exp(np.mean(np.log(out)))


def fit_with_gains(data: FitData, model: str, options: FitOptions,
                   fit_one: Callable[[FitData, str, FitOptions], ModelFit], why: str,
                   start: np.ndarray | None = None, first: ModelFit | None = None
                   ) -> tuple[ModelFit, SweepGains]:
    """The model and the gains fitted together (module doc), from gains ``start`` (1) and,
    if given, ``first``: the model's fit already made with those gains (a round saved).

    Returns the fit made with the final gains (its figures are those of the data divided
    by them) and the gains."""
    angles = np.array([t for t, _ in data.theta_i_groups()])
    g = np.ones(angles.size) if start is None else np.asarray(start, dtype=float)

    def refit(gains):
        return fit_one(scaled(data, SweepGains(angles, gains).per_configuration(
            data.theta_i_deg)), model, options)

    rounds, converged, result = 0, False, first
    for _ in range(MAX_ROUNDS):
        if result is None:
            result, rounds = refit(g), rounds + 1
        new = best_gains(data, evaluate(model, data.cos, result.params))
        if np.max(np.abs(np.log(new / g))) <= GAIN_TOL:
            converged = True
            break
        g, result = new, None
    if result is None:                       # MAX_ROUNDS without converging: the last gains
        result, rounds = refit(g), rounds + 1
    return result, SweepGains(angles, g, rounds, converged, why)


def fit_auto_with_gains(data: FitData, options: FitOptions, run_auto, fit_one, why: str):
    """``--model auto`` with gains: (best fit, candidates, gains). The gains come from
    :data:`REFERENCE_MODEL` first, every candidate is judged on the data divided by them,
    then the chosen model refits them (starting from its fit in the comparison)."""
    angles = np.array([t for t, _ in data.theta_i_groups()])
    try:
        start = fit_with_gains(data, REFERENCE_MODEL, options, fit_one, why)[1].gain
    except GonioError:                         # the reference cannot fit: start from 1
        start = np.ones(angles.size)
    best, candidates = run_auto(scaled(data, SweepGains(angles, start).per_configuration(
        data.theta_i_deg)))
    result, gains = fit_with_gains(data, best.model, options, fit_one, why, start=start,
                                   first=best)
    return result, candidates, gains
