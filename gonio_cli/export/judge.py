"""What an export loses: the exported BRDF against the material, in CIEDE2000.

Every target that cannot carry a gonio material exactly (glTF: a fit of its own BRDF,
:mod:`gonio_cli.export.standard_fit`) is judged here the same way (docs/export.md):

* **Where**: at the configurations of the measurement the material was fitted to, when
  the material's ``inputs`` name a ``gonio.measurement`` that is still there (the path as
  recorded, else beside the material) and on its spectral grid; otherwise on
  :func:`in_plane_grid`.
* **Colour**: both as linear-sRGB reflectance factors R = π f under D65 (the CIE 1931 2°
  observer of docs/conventions.md; a spectrum through
  :func:`gonio_cli.export.mitsuba.rgb_weights`), to L*a*b* with each configuration scaled
  by 1 / max(1, Y) of the material there (:func:`gonio_cli.export.standard_fit.perceived`,
  as ``gonio fit``'s verdict scales a highlight), compared by CIEDE2000
  (:func:`gonio_cli.spectra.delta_e_2000`).
* **Beside it**: the material's own fit error, the same figure of the material against
  the measured data (with the fit's light-source gains, as ``gonio eval``), when the
  measurement is found; else the figures the fit recorded (D65, 10° observer).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any, Callable

import numpy as np

from ..artifact import atomic_path, read_artifact, sha256_file, write_artifact
from ..errors import GonioError, InputError, deg
from ..evaluate import evaluate_at, gains_for
from ..fit.verdict import COLOUR_RANGE_NM, covers_colour
from ..geometry import Cosines, measurement_cosines
from ..schemas import Material, read_measurement
from ..spectra import delta_e_2000, same_grid
from .mitsuba import rgb_weights
from .standard_fit import material_rgb, perceived

#: The in-plane grid used when the material's measurement is not at hand: θi 0–75° every
#: 15°, θo −75–85° every 5° (the light's side and the far side, the mirror included).
GRID_THETA_I_DEG = tuple(range(0, 76, 15))
GRID_THETA_O_DEG = tuple(range(-75, 86, 5))

#: The report's schema, beside every judged export's file (``NAME.glb.report.json``).
REPORT_SCHEMA = "gonio.export-report"
REPORT_VERSION = 1

#: Decimals of every parameter written (1e-6 of a colour factor is far below an 8-bit
#: step); the report judges the parameters as written.
DIGITS = 6

#: Percentile reported beside the mean and the worst.
PERCENTILE = 95.0

COLOUR = ("CIEDE2000 of R = pi f as linear sRGB under D65 (CIE 1931 2 degree observer), "
          "each configuration scaled by 1/max(1, Y) of the material")


def check_colour_grid(material, material_path) -> None:
    """Refuse a material whose grid misses the visible (its colour cannot be judged)."""
    if not covers_colour(material.wavelength_nm):
        wl = np.asarray(material.wavelength_nm, dtype=float)
        raise InputError(f"wavelength_nm {wl[0]:g}-{wl[-1]:g} nm does not cover "
                         f"{COLOUR_RANGE_NM[0]:g}-{COLOUR_RANGE_NM[1]:g} nm, so its colour "
                         "cannot be fitted or judged", path=material_path,
                         fix="fit the material on a grid covering the visible (gonio ingest "
                             "--grid-nm 380:780:10)")


def in_plane_grid() -> tuple[np.ndarray, np.ndarray]:
    """(θi, θo) in degrees, (N,) each: :data:`GRID_THETA_I_DEG` × :data:`GRID_THETA_O_DEG`."""
    ti, to = np.meshgrid(GRID_THETA_I_DEG, GRID_THETA_O_DEG, indexing="ij")
    return ti.ravel().astype(float), to.ravel().astype(float)


def find_measurement(material_path, material_doc: dict):
    """(path, Measurement) of the material's recorded input measurement, or (None, None)
    when none is recorded, found, readable or on the material's grid."""
    base = Path(material_path).resolve().parent
    for record in material_doc.get("inputs") or []:
        recorded = Path(str(record.get("path", "")))
        for path in (recorded, base / recorded.name):
            if not path.is_file():
                continue
            try:
                meas = read_measurement(path)
            except GonioError:
                continue
            if same_grid(meas.wavelength_nm, material_doc.get("wavelength_nm", [])):
                return path, meas
    return None, None


@dataclass
class Judgement:
    """CIEDE2000 (N,) of an export against its material at (θi, θo[, φo]) (N,) degrees
    (``phi_o_deg`` None: in the plane of incidence)."""

    delta_e: np.ndarray
    theta_i_deg: np.ndarray
    theta_o_deg: np.ndarray
    phi_o_deg: np.ndarray | None = None

    @property
    def worst_index(self) -> int:
        return int(np.argmax(self.delta_e))

    def summary(self) -> dict[str, Any]:
        k = self.worst_index
        return {"delta_e2000_mean": float(np.mean(self.delta_e)),
                "delta_e2000_p95": float(np.percentile(self.delta_e, PERCENTILE)),
                "delta_e2000_worst": float(self.delta_e[k]),
                "worst_configuration": self.configuration(k)}

    def configuration(self, k: int) -> dict[str, float]:
        """Configuration ``k`` by its angles (φo only out of the plane, as ``gonio eval``
        names one)."""
        out = {"theta_i_deg": float(self.theta_i_deg[k]),
               "theta_o_deg": float(self.theta_o_deg[k])}
        if self.phi_o_deg is not None and self.phi_o_deg[k] != 0.0:
            out["phi_o_deg"] = float(self.phi_o_deg[k])
        return out

    def angles(self) -> dict[str, np.ndarray]:
        """The per-configuration angles of a report (``phi_o_deg`` only when given)."""
        out = {"theta_i_deg": self.theta_i_deg, "theta_o_deg": self.theta_o_deg}
        if self.phi_o_deg is not None:
            out["phi_o_deg"] = self.phi_o_deg
        return out


def delta_e_rgb(rgb_ref, rgb_test) -> np.ndarray:
    """CIEDE2000 (N,) of linear-sRGB reflectance factors (N, 3) against ``rgb_ref``."""
    lab = perceived(rgb_ref)
    return delta_e_2000(lab(rgb_ref), lab(rgb_test))


def judge(material, exported_rgb: Callable[[Cosines], np.ndarray], theta_i_deg,
          theta_o_deg, phi_o_deg=None) -> Judgement:
    """The exported BRDF (f (..., 3) linear sRGB) against ``material`` at goniometer
    configurations (degrees; ``phi_o_deg`` None: in plane)."""
    cos = measurement_cosines(theta_i_deg, theta_o_deg, phi_o_deg)
    de = delta_e_rgb(np.pi * material_rgb(material)(cos), np.pi * exported_rgb(cos))
    return Judgement(de, np.asarray(theta_i_deg, float), np.asarray(theta_o_deg, float),
                     None if phi_o_deg is None else np.asarray(phi_o_deg, float))


def own_fit(material, material_path, material_doc: dict, meas_path, meas) -> dict[str, Any]:
    """The material's own fit error, as :func:`judge` measures (material against the
    data) when the measurement is at hand, else the verdict recorded by ``gonio fit``."""
    if meas is not None:
        gains = gains_for(material, meas, "auto", material_path=material_path,
                          measurement_path=meas_path)
        model = evaluate_at(material, meas, gains=gains).brdf
        w = rgb_weights(meas.wavelength_nm).T
        j = Judgement(delta_e_rgb(np.pi * meas.brdf @ w, np.pi * model @ w),
                      meas.theta_i_deg, meas.theta_o_deg, meas.phi_o_deg)
        return {"source": f"the material against {os.fspath(meas_path)}, as above",
                **j.summary()}
    verdict = (material_doc.get("fit") or {}).get("verdict") or {}
    if "delta_e2000_mean" not in verdict:
        return {"source": "not recorded"}
    return {"source": "recorded by gonio fit: " + str(verdict.get("colour", "")),
            "delta_e2000_mean": float(verdict["delta_e2000_mean"]),
            "delta_e2000_worst": float(verdict.get("delta_e2000_worst", np.nan))}


def report(target: str, material, material_path, exported_rgb) -> dict[str, Any]:
    """The payload of an export's report: where it was judged, per configuration
    CIEDE2000, mean, p95, worst, and the material's own fit error beside it."""
    doc = read_artifact(material_path, Material.SCHEMA, Material.READ_VERSIONS)
    meas_path, meas = find_measurement(material_path, doc)
    if meas is not None:
        ti, to, po = meas.theta_i_deg, meas.theta_o_deg, meas.phi_o_deg
        where = f"the configurations of {os.fspath(meas_path)}"
    else:
        (ti, to), po = in_plane_grid(), None
        where = "an in-plane grid (the material's measurement was not found)"
    j = judge(material, exported_rgb, ti, to, po)
    return {"target": target, "model": material.model, "configurations": where,
            "colour": COLOUR, **j.summary(),
            "material_fit": own_fit(material, material_path, doc, meas_path, meas),
            **j.angles(), "delta_e2000": j.delta_e}


def sentence(name: str, target_label: str, rep: dict[str, Any]) -> str:
    """The one stderr line: ``gonio export: red.glb: glTF keeps mean CIEDE2000 2.1 (worst
    5.3 at θi 45° θo 10°) against the material (its own fit: 1.2)`` (``φo 30°`` after θo
    when the worst configuration is out of the plane)."""
    w = rep["worst_configuration"]
    phi = f" φo {deg(w['phi_o_deg'])}°" if "phi_o_deg" in w else ""
    own = rep["material_fit"].get("delta_e2000_mean")
    own_text = f"{own:.1f}" if own is not None else "not recorded"
    return (f"gonio export: {name}: {target_label} keeps mean CIEDE2000 "
            f"{rep['delta_e2000_mean']:.1f} (worst {rep['delta_e2000_worst']:.1f} at "
            f"θi {deg(w['theta_i_deg'])}° θo {deg(w['theta_o_deg'])}°{phi}) against the "
            f"material (its own fit: {own_text})")


def report_path(path) -> Path:
    """Where the report of ``NAME.glb`` (``NAME.mtlx`` …) goes: ``NAME.glb.report.json``."""
    p = Path(path)
    return p.with_name(p.name + ".report.json")


def rounded(m):
    """The dataclass ``m`` as written: every number (and every number of a tuple) rounded
    to :data:`DIGITS` decimals."""
    changes = {}
    for f in fields(m):
        v = getattr(m, f.name)
        if isinstance(v, tuple):
            changes[f.name] = tuple(round(float(x), DIGITS) for x in v)
        elif isinstance(v, (int, float)):
            changes[f.name] = round(float(v), DIGITS)
    return replace(m, **changes)


@dataclass(frozen=True)
class Fitted:
    """A standard target that is fitted and judged: its name in reports (``gltf``),
    the fit (:func:`gonio_cli.export.standard_fit.fit_standard` in a space),
    ``brdf(cos, m)`` (..., 3), ``encode(m, extras)`` the file's bytes, and ``written(m)``
    the parameters as the file holds them (a format may print fewer digits)."""

    target: str
    fit: Callable
    brdf: Callable
    encode: Callable[[Any, dict], bytes]
    written: Callable[[Any], Any] = lambda m: m


def export_judged(kind: Fitted, material, material_path, out) -> tuple[list[Path], dict]:
    """Fit, write and judge: ``out`` and its report (:func:`report_path`), both atomically;
    returns both paths and the report's payload (``kind.target`` holds the parameters)."""
    check_colour_grid(material, material_path)
    fit = kind.fit(material_rgb(material))
    best = None
    for found in [fit.material, *fit.alternatives]:      # the closer one, as judged
        m = kind.written(rounded(replace(found, name=Path(material_path).name.split(".")[0])))
        rep = report(kind.target, material, material_path,
                     lambda cos, m=m: kind.brdf(cos, m))
        if best is None or rep["delta_e2000_mean"] < best[1]["delta_e2000_mean"]:
            best = (m, rep)
    m, rep = best
    out, rpath = Path(out), report_path(out)
    extras = {"gonio": {"material": str(material_path),
                        "material_sha256": sha256_file(material_path),
                        "report": rpath.name}}
    data = kind.encode(m, extras)
    with atomic_path(out) as tmp:
        tmp.write_bytes(data)
    payload = {**rep, "file": out.name, kind.target: m.to_dict(), "fit": fit.to_dict()}
    write_artifact(rpath, REPORT_SCHEMA, REPORT_VERSION, payload, inputs=[material_path],
                   parameters={"target": kind.target}, time_s=fit.time_s)
    return [out, rpath], payload
