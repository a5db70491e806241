"""A material's model evaluated at a measurement's configurations (``gonio eval``).

The result is a :class:`~gonio_cli.schemas.Measurement` on the measurement's own grid
and geometry, quantity ``brdf`` (sr⁻¹, no cosine factor, docs/conventions.md), so that
data and model can be compared row for row in any tool that reads ``gonio.measurement``.
The model is evaluated once per configuration through :meth:`Material.evaluate` (the
one code path of :mod:`gonio_cli.brdf`); nothing is resampled: a material on another
spectral grid is refused.

A material fitted with light-source gains (:mod:`gonio_cli.fit.gains`: one per angle of
incidence of a multi-angle instrument) models its measurement as g(θi) f: ``sweep_gain``
``auto`` applies them where the measurement's angles of incidence all have one (the
output then compares with the instrument's readings), ``on`` requires that, ``off`` gives
the BRDF f alone.

:func:`run` is the stage as one call (``gonio eval``'s): the gains chosen, the model
evaluated, its record made; :func:`write` writes the measurement and the plot.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from . import log
from .brdf import MODELS
from .errors import InputError, deg
from .fit import uncertainty, uncertainty_draws
from .fit.gains import SweepGains
from .fit.plot import plot_fit
from .fit.verdict import COLOUR_RANGE_NM, colour_errors, covers_colour
from .geometry import measurement_cosines
from .names import SWEEP_GAIN_NAMES, pick
from .schemas import Material, Measurement, write_measurement
from .spectra import grid_spec, same_grid


def _grid_text(wavelength_nm) -> str:
    w = np.asarray(wavelength_nm, dtype=float)
    return f"{w[0]:g}-{w[-1]:g} nm ({w.size} wavelengths)"


def check_same_grid(material: Material, measurement: Measurement, *,
                    material_path=None, measurement_path=None) -> None:
    """Refuse a material whose spectral grid is not the measurement's (one line, with the
    ``--grid-nm`` that re-ingesting the measurement needs)."""
    if same_grid(material.wavelength_nm, measurement.wavelength_nm):
        return
    spec = grid_spec(material.wavelength_nm)
    fix = (f"re-ingest the measurement with --grid-nm {spec} (the material's grid)"
           if spec else "re-ingest the measurement with --grid-nm on the material's grid")
    whose = (f"the material's ({os.fspath(material_path)})" if material_path is not None
             else "the material's")
    raise InputError(f"spectral grid {_grid_text(measurement.wavelength_nm)} is not "
                     f"{whose} {_grid_text(material.wavelength_nm)}",
                     path=measurement_path, fix=fix)


def gains_for(material: Material, measurement: Measurement, sweep_gain: str = "auto", *,
              material_path=None, measurement_path=None):
    """The material's light-source gains to apply at ``measurement`` (a
    :class:`~gonio_cli.fit.gains.SweepGains`), or None (``sweep_gain`` as the module doc)."""
    stored = (material.fit or {}).get("sweep_gain")
    if sweep_gain == "off" or (stored is None and sweep_gain == "auto"):
        return None
    if stored is None:
        raise InputError("--sweep-gain on: the material has no light-source gains (it was "
                         "fitted without them)", path=material_path,
                         fix="use --sweep-gain auto or off")
    gains = SweepGains.from_dict(stored, path=material_path)
    if gains.covers(measurement.theta_i_deg):
        return gains
    if sweep_gain == "on":
        missing = sorted({float(t) for t in measurement.theta_i_deg
                          if not gains.covers([t])})
        raise InputError(f"--sweep-gain on: the material has gains at theta_i "
                         f"{', '.join(f'{t:g}' for t in gains.theta_i_deg)} only, not at "
                         f"{', '.join(f'{t:g}' for t in missing)}", path=measurement_path,
                         fix="use --sweep-gain auto or off for the BRDF alone")
    return None


def evaluate_at(material: Material, measurement: Measurement, *, material_path=None,
                measurement_path=None, gains=None) -> Measurement:
    """The model of ``material`` at every configuration of ``measurement``.

    Returns
    -------
    Measurement
        Same ``wavelength_nm`` (n_λ,), ``theta_i_deg``, ``theta_o_deg``, ``phi_o_deg`` as
        ``measurement``; ``brdf`` (n_cfg, n_λ) the model in sr⁻¹ (no cosine factor),
        times ``gains`` (:func:`gains_for`) per angle of incidence when given;
        no ``brdf_std``; ``n_repeats`` 1; quantity ``brdf``; ``summary`` naming the model.

    Raises
    ------
    InputError
        The two spectral grids differ (:func:`check_same_grid`).
    """
    check_same_grid(material, measurement, material_path=material_path,
                    measurement_path=measurement_path)
    f = material.evaluate(cosines_of(measurement))
    if gains is not None:
        f = f * gains.per_configuration(measurement.theta_i_deg)[:, None]
    n = measurement.n_configurations
    return Measurement(measurement.wavelength_nm.copy(), measurement.theta_i_deg.copy(),
                       measurement.theta_o_deg.copy(), np.asarray(f, dtype=float), None,
                       np.ones(n, dtype=int), "brdf",
                       {"model": material.model, "material_status": material.status,
                        "configurations": n,
                        "sweep_gain": gains.to_dict() if gains is not None else None,
                        "brdf_min_per_sr": float(np.min(f)) if f.size else 0.0,
                        "brdf_max_per_sr": float(np.max(f)) if f.size else 0.0},
                       None if measurement.phi_o_deg is None else measurement.phi_o_deg.copy())


def cosines_of(measurement: Measurement):
    """The :class:`~gonio_cli.geometry.Cosines` of the measurement's configurations (the
    one place eval turns its geometry into a model's arguments)."""
    return measurement_cosines(measurement.theta_i_deg, measurement.theta_o_deg,
                               measurement.phi_o_deg)


#: The colour band: parameter sets drawn from the fit's covariance (seeded, so a band is
#: the same at every run), and the percentile of CIEDE2000 per configuration it reports.
#: 200 draws put the 95th percentile within ~±15 % of its value (binomial: ±√(0.95·0.05·200)
#: ≈ 3 draws around the 10th largest).
BAND_DRAWS = 200
BAND_SEED = 0
BAND_PERCENTILE = 95.0


def colour_band(material: Material, measurement: Measurement, f_model: np.ndarray,
                gains=None) -> dict[str, Any]:
    """How far the model can move within the fit's intervals, in colour: per configuration
    the :data:`BAND_PERCENTILE` th percentile of CIEDE2000 between the model drawn from the
    fit's Gaussian (:func:`gonio_cli.fit.uncertainty_draws.draw`, :data:`BAND_DRAWS` draws) and
    the fitted one ``f_model`` (N, L), with the light-source ``gains`` (and their own
    uncertainty) where eval applies them. A material without intervals (older files, a
    failed fit) has ``available`` false and why."""
    record = (material.fit or {}).get("intervals")
    if not record:
        return {"available": False, "why": "the material has no intervals (written before "
                                           "gonio fit recorded them: fit it again)"}
    if not record.get("available") or "covariance" not in record:
        return {"available": False, "why": f"the fit has no intervals: "
                                           f"{record.get('why', 'not recorded')}"}
    wl = measurement.wavelength_nm
    if not covers_colour(wl):
        return {"available": False, "why": f"the grid does not cover "
                f"{COLOUR_RANGE_NM[0]:g}-{COLOUR_RANGE_NM[1]:g} nm (no colour)"}
    f, log_g = uncertainty_draws.propagate(record, material.model, cosines_of(measurement),
                                     material.params, BAND_DRAWS, BAND_SEED)
    if gains is not None:
        g = gains.per_configuration(measurement.theta_i_deg)
        f = f * g[None, :, None]
        if log_g is not None:
            idx = np.array([np.flatnonzero(np.abs(gains.theta_i_deg - t) <= 1e-6)[0]
                            for t in measurement.theta_i_deg])
            f = f * np.exp(log_g[:, idx])[:, :, None]
    n, d = measurement.n_configurations, f.shape[0]
    po = measurement.phi_o_deg
    de = colour_errors(wl, np.tile(measurement.theta_i_deg, d),
                       np.tile(measurement.theta_o_deg, d), np.tile(f_model, (d, 1)),
                       f.reshape(d * n, -1),
                       None if po is None else np.tile(po, d)).delta_e.reshape(d, n)
    band = np.percentile(de, BAND_PERCENTILE, axis=0)
    k = int(np.argmax(band))
    return {"available": True, "delta_e2000_p95": [float(v) for v in band],
            "median_delta_e2000_p95": float(np.median(band)),
            "worst_delta_e2000_p95": float(band[k]),
            "worst_configuration": worst_configuration(measurement, k),
            "draws": d, "seed": BAND_SEED, "percentile": BAND_PERCENTILE,
            "level": float(record.get("level", uncertainty.LEVEL)),
            "method": "parameters drawn from the fit's Gaussian (fit.intervals.covariance), "
                      "the model moved by the delta method (f + J du); CIEDE2000 of each "
                      "drawn model against the fitted one, D65, 10 degree observer, pairs "
                      "with Y > 1 scaled to Y = 1"}


def worst_configuration(measurement: Measurement, k: int) -> dict[str, float]:
    """Configuration ``k`` by its angles (φo only out of the plane)."""
    out = {"theta_i_deg": float(measurement.theta_i_deg[k]),
           "theta_o_deg": float(measurement.theta_o_deg[k])}
    if measurement.phi_o_deg is not None and measurement.phi_o_deg[k] != 0.0:
        out["phi_o_deg"] = float(measurement.phi_o_deg[k])
    return out


def band_text(band: dict[str, Any]) -> str:
    """The band on eval's stderr line."""
    if not band.get("available"):
        return f"; colour band not available: {band.get('why', '')}"
    w = band["worst_configuration"]
    return (f"; colour band of the fit's {100 * band['level']:g} % intervals: CIEDE2000 "
            f"p{band['percentile']:g} median {band['median_delta_e2000_p95']:.2f}, worst "
            f"{band['worst_delta_e2000_p95']:.2f} at theta_i {deg(w['theta_i_deg'])}, theta_o "
            f"{deg(w['theta_o_deg'])}" + (f", phi_o {deg(w['phi_o_deg'])}" if "phi_o_deg" in w
                                          else ""))


def model_parameters(material: Material) -> dict[str, Any]:
    """The model as the ``parameters`` of an evaluated measurement: its name, its
    citation and every parameter (scalars as numbers, spectra as lists)."""
    return {"model": material.model, "citation": MODELS[material.model].citation,
            "status": material.status,
            "params": {k: (np.asarray(v, dtype=float) if np.ndim(v) else float(v))
                       for k, v in material.params.items()}}


@dataclass
class Evaluation:
    """What ``gonio eval`` computed: the ``model`` (a measurement, :func:`evaluate_at`) of
    ``material`` at ``measurement``, the light-source ``gains`` applied (or None), the
    output's ``parameters`` and the time it took; the two paths (or None) it came from."""

    material: Material
    measurement: Measurement
    model: Measurement
    gains: SweepGains | None
    sweep_gain: str
    parameters: dict[str, Any]
    material_path: Path | None = None
    measurement_path: Path | None = None
    time_s: float = 0.0

    def gains_text(self) -> str:
        """How the gains were applied, for the summary line ("" when there were none)."""
        if self.gains is not None:
            return (f", times the material's light-source gains ({self.gains.text()}; "
                    f"--sweep-gain off for the BRDF alone)")
        if self.sweep_gain == "auto" and (self.material.fit or {}).get("sweep_gain"):
            return (", the BRDF alone: the material's light-source gains are for other "
                    "angles of incidence")
        return ""


def run(material: Material, measurement: Measurement, sweep_gain: str = "auto", *,
        material_path=None, measurement_path=None) -> Evaluation:
    """``material`` evaluated at ``measurement`` (the paths name them in errors and in the
    output's ``parameters``), with its light-source gains as ``sweep_gain`` says.

    Raises
    ------
    InputError
        An unknown ``sweep_gain``, gains required but missing (:func:`gains_for`), or the
        two spectral grids differ (:func:`check_same_grid`).
    """
    pick(SWEEP_GAIN_NAMES, sweep_gain, "--sweep-gain")
    with log.timer() as t:
        gains = gains_for(material, measurement, sweep_gain, material_path=material_path,
                          measurement_path=measurement_path)
        model = evaluate_at(material, measurement, material_path=material_path,
                            measurement_path=measurement_path, gains=gains)
        model.summary["colour_band"] = colour_band(material, measurement, model.brdf, gains)
    parameters = {"material": str(material_path), "at": str(measurement_path),
                  "sweep_gain": sweep_gain, **model_parameters(material)}
    return Evaluation(material, measurement, model, gains, sweep_gain, parameters,
                      None if material_path is None else Path(material_path),
                      None if measurement_path is None else Path(measurement_path),
                      t["time_s"])


def write(evaluation: Evaluation, output, *, plot=None) -> None:
    """Write the evaluated measurement (``gonio.measurement``, its inputs the material and
    the measurement) and, with ``plot``, data against model (seed 000 Figure 4, PNG)."""
    e = evaluation
    inputs = [p for p in (e.material_path, e.measurement_path) if p is not None]
    write_measurement(output, e.model, inputs=inputs, parameters=e.parameters,
                      time_s=e.time_s)
    if plot is not None:
        at = e.measurement_path.name if e.measurement_path is not None else "measurement"
        name = e.material_path.name if e.material_path is not None else "material"
        plot_fit(plot, e.measurement, e.material,
                 title=f"{at} against {name} ({e.material.model})", gains=e.gains)
