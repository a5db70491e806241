"""What every fit returns: its error figures (:func:`error_figures`), options
(:class:`FitOptions`), report (:class:`FitReport`) and result (:class:`ModelFit`), and
the :class:`Stopwatch` that times it."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .common import FitData

def error_figures(data: FitData, f_model: np.ndarray) -> dict[str, Any]:
    """Goodness of fit over the configurations and wavelengths used (unweighted).

    - ``rmse_per_sr``: √mean (y − f)²
    - ``relative_rmse_percent``: seed 004 eq. (14), √mean (100 (y − f)/y)² over y > 0
    - ``log_rmse``: √mean (log y − log f)² over y > 0 (≈ relative error for small errors)
    - ``worst_configuration``: the configuration with the largest RMS log residual
    """
    y = data.y
    f = np.asarray(f_model, dtype=float)
    pos = data.positive & (f > 0)
    rmse = float(np.sqrt(np.mean((y - f) ** 2)))
    rel = 100.0 * (y - f) / np.where(data.positive, y, 1.0)
    rel_rmse = float(np.sqrt(np.mean(rel[data.positive] ** 2))) if data.positive.any() else 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        logr = np.where(pos, np.log(np.where(pos, y, 1.0)) - np.log(np.where(pos, f, 1.0)), 0.0)
    log_rmse = float(np.sqrt(np.sum(logr ** 2) / max(int(pos.sum()), 1)))
    per_cfg = np.sqrt(np.sum(logr ** 2, axis=1) / np.maximum(pos.sum(axis=1), 1))
    k = int(np.argmax(per_cfg))
    return {
        "rmse_per_sr": rmse,
        "relative_rmse_percent": rel_rmse,
        "log_rmse": log_rmse,
        "worst_configuration": {"theta_i_deg": float(data.theta_i_deg[k]),
                                "theta_o_deg": float(data.theta_o_deg[k]),
                                "log_rmse": float(per_cfg[k])},
    }


def nm_list(nm: list[float]) -> str:
    """"380, 390 nm": wavelengths for a message, the first six and a count."""
    shown = ", ".join(f"{w:g}" for w in nm[:6])
    return shown + (f", … ({len(nm)} in all)" if len(nm) > 6 else "") + " nm"


# ------------------------------------------------------------------------ the results --

@dataclass
class FitOptions:
    """Options shared by the model fits (the flags of ``gonio fit``).

    refine : fit α and the spectra jointly after the paper's two steps (goniochromatic)
    step2 : "mirror" (seed 000 eq. 7) or "all" configurations in the paper's step 2
    optimizer : a key of the fitter's ``OPTIMIZERS`` (None: its default, the first key)
    alpha : fix the roughness instead of fitting it (models with an α)
    stages : a memo that fits of the same data within one run share (``--model auto``
        sets it: ``goniochromatic-backscatter`` starts where ``goniochromatic-coat`` ended,
        :mod:`.layered`); None (one fit) keeps nothing, so a fit's time is its own
    warm : the parameters of this model fitted to most of the same data (``--model auto``
        sets them for each fold: its fit to all the data); a fitter may search near them
        instead of from its coarse starts (:mod:`.warm`)
    """

    refine: bool = True
    step2: str = "mirror"
    optimizer: str | None = None
    alpha: float | None = None
    stages: dict | None = None
    warm: dict | None = None


@dataclass
class FitReport:
    """One fit of one model by one method: parameters, status and what it cost.

    ``params`` holds the model's parameters by the names of :data:`gonio_cli.brdf.MODELS`
    (scalars as floats, spectra as (L,) arrays). ``status`` is "success" or "failed";
    a failed wavelength is named in ``failed_wavelength_nm``, never hidden as NaN.
    """

    method: str
    status: str
    message: str
    params: dict[str, Any]
    errors: dict[str, Any]
    optimizer: str
    evaluations: int
    time_s: float
    failed_wavelength_nm: list[float] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status == "success"

    def to_dict(self) -> dict[str, Any]:
        out = {"method": self.method, "status": self.status, "message": self.message,
               "optimizer": self.optimizer, "evaluations": int(self.evaluations),
               "time_s": float(self.time_s),
               "failed_wavelength_nm": [float(x) for x in self.failed_wavelength_nm]}
        out.update({k: v for k, v in self.params.items()})
        out.update(self.errors)
        out.update(self.extra)
        return out


@dataclass
class ModelFit:
    """Everything ``gonio fit`` learnt: the final parameters and every fit that led there.

    ``reports`` maps a method name (``paper_two_step``, ``refined`` …) to its
    :class:`FitReport`; ``final`` names the one whose parameters the material carries.
    """

    model: str
    wavelength_nm: np.ndarray
    reports: dict[str, FitReport]
    final: str
    excluded: dict[str, Any] = field(default_factory=dict)

    @property
    def result(self) -> FitReport:
        return self.reports[self.final]

    @property
    def params(self) -> dict[str, Any]:
        return self.result.params


class Stopwatch:
    """``sw = Stopwatch(); ...; sw.lap()`` → seconds since the last lap (perf_counter)."""

    def __init__(self):
        self._t = time.perf_counter()

    def lap(self) -> float:
        now = time.perf_counter()
        dt, self._t = now - self._t, now
        return dt

