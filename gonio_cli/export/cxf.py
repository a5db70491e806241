"""A material's predicted spectra as X-Rite CxF3 (``gonio export --to cxf --at M``).

CxF3 (ISO 17972-1) is the colour exchange format multi-angle instruments export; a QC
tool compares a file of this kind with the next measurement. :func:`export_cxf` writes,
with the ``colour-cxf`` package (``colour_cxf.cxf3``, the CxF3-core schema as dataclasses):

* one ``Object`` (``ObjectType`` ``Standard``, the material's name) whose ``ColorValues``
  hold one ``ReflectanceSpectrum`` per configuration of the measurement ``--at``: the
  material's reflectance factor R = π f there (gonio's f has no cosine; R is relative to
  the perfect diffuser, CxF3's reflectance), from ``StartWL`` every ``Increment`` nm of
  the material's grid;
* one ``ColorSpecification`` per configuration (``Id`` ``CS_45as15``): reflectance
  spectrum, a ``MultiAngle`` geometry with one ``BRDFAngle`` (``IlluminationAngle`` θi,
  ``Aspecular`` a = θi − θo, docs/conventions.md), the ``WavelengthRange``, and D65 / 10°
  for the colorimetry a reader derives.

``gonio ingest FILE.cxf`` (:mod:`gonio_cli.ingest.cxf`) reads it back to the same
spectra. The spectra are the material's own (no light-source gains of a multi-angle fit).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .. import __version__
from ..artifact import atomic_path
from ..csvlayouts import aspecular_of_theta_o
from ..errors import InputError
from ..geometry import measurement_cosines
from ..schemas import read_measurement
from . import check_file_output, get_target

#: CxF3 limits of a ``ReflectanceSpectrum`` (the schema's ``StartWL`` range, its values'
#: exclusive maximum; gonio's grid steps are whole nanometres to be written).
START_WL_RANGE = (360, 400)
REFLECTANCE_MAX = 3.0


def spec_id(theta_i_deg: float, aspecular_deg: float) -> str:
    """The ``ColorSpecification`` id of a geometry: ``CS_45as15``."""
    return f"CS_{theta_i_deg:g}as{aspecular_deg:g}"


def check_grid(wavelength_nm, path) -> tuple[int, int]:
    """(StartWL, Increment) of a grid CxF3 can hold: whole nanometres, evenly spaced,
    starting in [360, 400]; else one line naming the file and the fix."""
    wl = np.asarray(wavelength_nm, dtype=float)
    steps = np.diff(wl)
    start, step = float(wl[0]), float(steps[0]) if steps.size else 0.0
    even = steps.size > 0 and np.allclose(steps, step, atol=1e-6)
    whole = np.allclose(wl, np.round(wl), atol=1e-6)
    if not (even and whole and START_WL_RANGE[0] <= start <= START_WL_RANGE[1]):
        raise InputError(f"wavelength_nm {wl[0]:g}-{wl[-1]:g} nm is not a CxF3 range (whole "
                         "nanometres, evenly spaced, starting at 360-400 nm)", path=path,
                         fix="fit the material on such a grid (gonio ingest --grid-nm "
                             "380:780:10)")
    return int(round(start)), int(round(step))


def cxf_bytes(name: str, theta_i_deg, theta_o_deg, reflectance, start_wl: int,
              increment: int, description: str) -> bytes:
    """The CxF3 document (module docstring) of ``reflectance`` (n, n_λ) at the in-plane
    configurations (θi, θo) (n,) degrees."""
    from datetime import datetime, timezone

    import colour_cxf
    from colour_cxf import cxf3
    from xsdata.models.datatype import XmlDateTime

    now = XmlDateTime.from_datetime(datetime.now(timezone.utc).replace(microsecond=0))
    aspec = aspecular_of_theta_o(theta_i_deg, theta_o_deg)
    specs, values = [], []
    for ti, a, r in zip(np.asarray(theta_i_deg, float), aspec, reflectance):
        sid = spec_id(float(ti), float(a))
        geometry = cxf3.GeometryChoice(choice=cxf3.MultiAngleType(
            brdfangle=[cxf3.Brdfangle(illumination_angle=float(ti), aspecular=float(a))]))
        measured = cxf3.MeasurementSpec(
            measurement_type=cxf3.MeasurementType(cxf3.EspectrumType.SPECTRUM_REFLECTANCE),
            geometry_choice=geometry,
            wavelength_range=cxf3.WavelengthRange(start_wl=start_wl, increment=increment))
        tristimulus = cxf3.TristimulusSpec(
            illuminant_or_custom_illuminant=cxf3.Illuminant(cxf3.EilluminantType.D65),
            observer=cxf3.Observer(cxf3.EobserverType.VALUE_10_DEGREE),
            method=cxf3.Method(cxf3.EastmTableType.E308_TABLE5))
        specs.append(cxf3.ColorSpecification(tristimulus_spec=tristimulus,
                                             measurement_spec=measured, id=sid))
        values.append(cxf3.ReflectanceSpectrum(value=[float(v) for v in r],
                                               name=sid[3:], start_wl=start_wl,
                                               color_specification=sid))
    obj = cxf3.Object(creation_date=cxf3.CreationDate(now), object_type="Standard",
                      name=name, id="1", color_values=cxf3.ColorValues(choice=values))
    doc = cxf3.CxF(
        file_information=cxf3.FileInformation(creator=f"gonio {__version__}",
                                              creation_date=cxf3.CreationDate(now),
                                              description=description),
        resources=cxf3.Resources(
            object_collection=cxf3.ObjectCollection(object_value=[obj]),
            color_specification_collection=cxf3.ColorSpecificationCollection(specs)))
    return colour_cxf.write_cxf(doc)


def export_cxf(material, material_path, out, scene_path=None, variables=None, *, at
               ) -> list[Path]:
    """Write ``out`` (``NAME.cxf``): ``material``'s spectra at the configurations of the
    measurement ``at`` (module docstring); returns its path."""
    if scene_path is not None or variables:
        raise InputError("--scene: --to cxf writes spectra, not a scene",
                         fix="leave out --scene and --var")
    check_file_output(out, get_target("cxf"))
    meas = read_measurement(at)
    start_wl, increment = check_grid(material.wavelength_nm, material_path)
    if meas.phi_o_deg is not None:
        raise InputError("--at: the measurement has configurations out of the plane of "
                         "incidence (phi_o_deg), which the CxF3 multi-angle file written "
                         "here cannot name", path=at,
                         fix="give --at a measurement in the plane of incidence")
    cos = measurement_cosines(meas.theta_i_deg, meas.theta_o_deg, meas.phi_o_deg)
    r = np.pi * material.evaluate(cos)
    k = int(np.argmax(r.max(axis=-1)))
    if not np.all(np.isfinite(r)) or r[k].max() >= REFLECTANCE_MAX:
        raise InputError(f"the material's reflectance factor at θi {meas.theta_i_deg[k]:g}° "
                         f"θo {meas.theta_o_deg[k]:g}° is {r[k].max():.3g}, beyond CxF3's "
                         f"limit {REFLECTANCE_MAX:g}", path=at,
                         fix="leave the configurations near the mirror out of --at")
    name = Path(material_path).name.split(".")[0]
    data = cxf_bytes(name, meas.theta_i_deg, meas.theta_o_deg, r, start_wl, increment,
                     f"gonio export --to cxf: {os.fspath(material_path)} ({material.model}) "
                     f"at the configurations of {os.fspath(at)}")
    with atomic_path(out) as tmp:
        Path(tmp).write_bytes(data)
    return [Path(out)]
