"""X-Rite CxF3 multi-angle spectra in (``gonio ingest FILE.cxf``).

Multi-angle instruments (car-paint spectrophotometers) export CxF3: per sample an
``Object`` with one ``ReflectanceSpectrum`` per geometry, each naming a
``ColorSpecification`` whose ``MeasurementSpec`` gives the geometry as ``MultiAngle`` /
``BRDFAngle`` (``IlluminationAngle`` θi, ``Aspecular`` a) and the ``WavelengthRange``.
Read with the ``colour-cxf`` package; the angles become gonio's by the conventions'
rule θo = θi − a (:func:`gonio_cli.csvlayouts.theta_o_of_aspecular`, as for ``45as15``
labels in CSV); the values are reflectance factors R (CxF3's reflectance, relative to
the perfect diffuser), so f = R / π (quantity ``reflectance-factor``); the spectra are
resampled onto the working grid (``--grid-nm``) when their grid differs, with a warning.

One file at a time; a file of several objects needs ``--sample NAME``. Geometries that
are not multi-angle, or out of the plane (``Azimuth`` not 0), are errors naming the
specification.
"""

from __future__ import annotations

import os
from typing import Any, Sequence

import numpy as np

from .. import log
from ..csvlayouts import _check_angles  # the CSV layer's angle checks, one rule
from ..csvlayouts import theta_o_of_aspecular
from ..errors import InputError
from ..schemas import Measurement
from ..spectra import DEFAULT_GRID_NM, covers, parse_grid, resample, same_grid
from .quantities import QUANTITIES
from .rgl import single_file_summary

FORMAT = "cxf3"

#: The CSV options a CxF3 file cannot use (its values are reflectance factors, its
#: angles in the file).
_REFUSED = ("quantity", "white_reflectance", "aperture_mm", "distance_mm", "dark", "scale",
            "theta_i_deg", "theta_o_deg", "phi_o_deg", "mirror_deg")


def resolve_parameters(paths: Sequence[str | os.PathLike], *, grid_nm: str | None = None,
                       sample: str | None = None, **options) -> dict[str, Any]:
    """Check the options for a CxF3 input and fill in defaults (recorded in the artifact)."""
    where = os.fspath(paths[0])
    if len(paths) != 1:
        raise InputError(f"{len(paths)} inputs given with a CxF3 file: one is read at a "
                         "time", path=where, fix="ingest each .cxf into its own measurement")
    for name in _REFUSED:
        if options.get(name) is not None:
            flag = "--" + name.replace("_", "-")
            raise InputError(f"{flag} is for CSV input; a CxF3 file holds reflectance "
                             "factors at its own geometries", path=where, fix=f"drop {flag}")
    grid = grid_nm if grid_nm is not None else DEFAULT_GRID_NM
    parse_grid(grid)
    return {"format": FORMAT, "quantity": "reflectance-factor", "grid_nm": grid,
            "sample": sample}


def _geometries(doc, path: str) -> dict[str, tuple[float, float, np.ndarray | None]]:
    """Per ``ColorSpecification`` id: (θi, a, its wavelengths or None)."""
    from colour_cxf import cxf3

    out = {}
    coll = doc.resources.color_specification_collection if doc.resources else None
    for spec in (coll.color_specification if coll else []):
        ms = spec.measurement_spec
        choice = ms.geometry_choice.choice if ms and ms.geometry_choice else None
        if not isinstance(choice, cxf3.MultiAngleType) or len(choice.brdfangle) != 1:
            continue
        angle = choice.brdfangle[0]
        if angle.illumination_angle is None or angle.aspecular is None or (angle.azimuth or 0):
            raise InputError(f"ColorSpecification {spec.id}: BRDFAngle needs "
                             "IlluminationAngle and Aspecular in the plane (Azimuth 0)",
                             path=path, fix="export the in-plane multi-angle geometries")
        wr = ms.wavelength_range
        wl = None if wr is None else float(wr.start_wl) + float(wr.increment) * np.arange(
            10000)
        out[spec.id] = (float(angle.illumination_angle), float(angle.aspecular), wl)
    return out


def _object(doc, path: str, sample: str | None):
    objects = (doc.resources.object_collection.object_value
               if doc.resources and doc.resources.object_collection else [])
    names = [o.name for o in objects]
    if sample is not None:
        if sample not in names:
            raise InputError(f"--sample {sample}: no such object", path=path,
                             fix=f"use one of {', '.join(map(str, names))}")
        return objects[names.index(sample)]
    if len(objects) != 1:
        raise InputError(f"{len(objects)} objects in the file", path=path,
                         fix=f"name one with --sample, one of {', '.join(map(str, names))}"
                         if objects else "export the samples' spectra from the instrument")
    return objects[0]


def read_cxf(path: str, sample: str | None):
    """(object name, θi, θo (n,), wavelengths (n_λ,), R (n, n_λ)) of the multi-angle
    reflectance spectra of one object of a CxF3 file."""
    import colour_cxf
    from colour_cxf import cxf3

    try:
        doc = colour_cxf.read_cxf_from_file(path)
    except Exception as exc:                    # xsdata's parser errors, any kind
        raise InputError(f"not a CxF3 file ({type(exc).__name__}: {exc})", path=path,
                         fix="export CxF3 from the instrument's software") from None
    geometries = _geometries(doc, path)
    obj = _object(doc, path, sample)
    rows = []
    for v in (obj.color_values.choice if obj.color_values else []):
        if isinstance(v, cxf3.ReflectanceSpectrum) and v.color_specification in geometries:
            ti, a, wl = geometries[v.color_specification]
            start = float(v.start_wl) if v.start_wl is not None else wl[0]
            step = float(wl[1] - wl[0]) if wl is not None else None
            if step is None:
                raise InputError(f"ColorSpecification {v.color_specification} has no "
                                 "WavelengthRange", path=path,
                                 fix="export the spectra with their wavelength range")
            rows.append((ti, a, start + step * np.arange(len(v.value)), v.value))
    if not rows:
        raise InputError(f"object {obj.name}: no reflectance spectrum with a multi-angle "
                         "geometry", path=path,
                         fix="export the multi-angle spectra (MultiAngle/BRDFAngle)")
    wl = rows[0][2]
    if any(r[2].shape != wl.shape or not np.allclose(r[2], wl) for r in rows):
        raise InputError(f"object {obj.name}: the spectra have different wavelengths",
                         path=path, fix="export every geometry on one wavelength range")
    ti = np.array([r[0] for r in rows])
    return (str(obj.name), ti, theta_o_of_aspecular(ti, [r[1] for r in rows]), wl,
            np.array([r[3] for r in rows], dtype=float))


def ingest(paths: Sequence[str | os.PathLike], *, grid_nm: str | None = None,
           sample: str | None = None, **options) -> Measurement:
    """Read one CxF3 file into a measurement: f = R / π on the working grid, one repeat
    per geometry (module docstring)."""
    params = resolve_parameters(paths, grid_nm=grid_nm, sample=sample, **options)
    path = os.fspath(paths[0])
    name, ti, to, wl, r = read_cxf(path, params["sample"])
    grid = parse_grid(params["grid_nm"])
    if not covers(wl, grid):
        raise InputError(f"its wavelengths {wl[0]:g}-{wl[-1]:g} nm do not cover the working "
                         f"grid {grid[0]:g}-{grid[-1]:g} nm", path=path,
                         fix=f"choose a grid inside the file's, e.g. --grid-nm "
                             f"{wl[0]:g}:{wl[-1]:g}:{wl[1] - wl[0]:g}")
    _check_angles(ti, to, np.arange(ti.size) + 1, path)
    notes = []
    resampled = not same_grid(wl, grid)
    quantity = QUANTITIES["reflectance-factor"]
    brdf = quantity.convert(resample(wl, r, grid) if resampled else r)
    if resampled:
        notes.append(f"{path}: resampled from the file's {wl.size} wavelengths "
                     f"({wl[0]:g}-{wl[-1]:g} nm) onto the working grid {params['grid_nm']} nm")
    m = Measurement(grid, ti, to, brdf, None, np.ones(ti.size, dtype=int),
                    "reflectance-factor")
    info = {"format": FORMAT, "path": path, "object": name, "geometries": int(ti.size),
            "wavelength_nm": f"{wl[0]:g}-{wl[-1]:g} nm ({wl.size} wavelengths)"}
    m.summary = {**single_file_summary(m, info, params, resampled, 0, notes),
                 "quantity": quantity.name, "conversion": quantity.formula}
    for note in notes:
        log.warn(note)
    return m


def file_lines(info: dict[str, Any]) -> list[str]:
    """``--summary`` lines for one CxF3 input (:func:`gonio_cli.ingest.format_summary`)."""
    return [f"read {info['path']}: CxF3 object {info['object']!r}, {info['geometries']} "
            f"multi-angle geometries, {info['wavelength_nm']}"]
