"""A fitted material as an OpenPBR Surface in MaterialX (``gonio export --to openpbr``).

:func:`export_openpbr` writes

* ``NAME.mtlx`` — a MaterialX document (colour space ``lin_rec709``) with one
  ``open_pbr_surface`` and the ``surfacematerial`` that uses it, written and validated
  (``Document.validate()`` against MaterialX's own standard libraries) with the
  ``materialx`` package. The inputs are a fit of OpenPBR's own BRDF
  (:mod:`gonio_cli.export.openpbr_brdf`) to the material, in the space of :data:`SPACE`
  (fitted with the loop every standard target shares,
  :func:`gonio_cli.export.standard_fit.fit_standard`), rounded as written;
* ``NAME.mtlx.report.json`` (``gonio.export-report`` v1) — the written inputs judged
  against the material (:mod:`gonio_cli.export.judge`).

Fitted: ``base_color``, ``base_metalness``, ``specular_color``, ``specular_roughness``,
``specular_ior``, ``coat_weight``, ``coat_color``, ``coat_roughness``, ``coat_ior``.
Written at fixed values: ``base_weight`` 1 and ``specular_weight`` 1 (their effect is
``base_color``'s and ``specular_ior``'s), ``coat_darkening`` 0 (what the BRDF computes,
:data:`gonio_cli.export.openpbr_brdf.COAT_DARKENING`); every other input keeps its
default (off).
"""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import GonioError, InputError
from ..geometry import Cosines
from . import check_file_output, get_target
from .judge import Fitted, export_judged
from .openpbr_brdf import COAT_DARKENING, OpenPbrMaterial, openpbr_brdf
from . import gltf_fit
from .standard_fit import ExportFit, FilmStage, Space, fit_standard

#: Smallest roughness searched (the tables' first; α = 1e-4, narrower than any sample).
ROUGHNESS_MIN = 0.01
#: IORs searched: the spec's soft range of ``specular_ior`` and ``coat_ior``.
IOR_RANGE = (1.0, 3.0)

NAMES = ("base_r", "base_g", "base_b", "base_metalness", "specular_r", "specular_g",
         "specular_b", "specular_roughness", "specular_ior", "coat_weight", "coat_r",
         "coat_g", "coat_b", "coat_roughness", "coat_ior")
LOWER = np.array([0, 0, 0, 0, 0, 0, 0, ROUGHNESS_MIN, IOR_RANGE[0], 0, 0, 0, 0,
                  ROUGHNESS_MIN, IOR_RANGE[0]], dtype=float)
UPPER = np.array([1, 1, 1, 1, 1, 1, 1, 1, IOR_RANGE[1], 1, 1, 1, 1, 1, IOR_RANGE[1]],
                 dtype=float)

#: Fixed starts (base colour from the material): a plastic, a rough and a smooth metal,
#: and a plastic under a smooth and a hazy clear coat (glTF's, :mod:`.gltf_fit`).
STARTS = ((0.0, 0.5, 0.0, 0.3), (1.0, 0.5, 0.0, 0.3), (1.0, 0.2, 0.0, 0.3),
          (0.0, 0.5, 1.0, 0.1), (0.0, 0.5, 1.0, 0.35))   # metalness, roughness, coat, r_c


#: Films of the grid that start the film's stage, and the steps the best then takes
#: (fewer than glTF's: an OpenPBR evaluation costs twice a glTF one).
FILM_STARTS = 3
FILM_NFEV = 60

#: The thin film's inputs, appended to :data:`NAMES` in the second stage
#: (:class:`~.standard_fit.FilmStage`: glTF's grid, the thickness in µm).
FILM_NAMES = ("thin_film_weight", "thin_film_ior", "thin_film_thickness")


def to_material(x) -> OpenPbrMaterial:
    """The :class:`OpenPbrMaterial` of a parameter vector (:data:`NAMES`, and
    :data:`FILM_NAMES` after them when the vector is that long)."""
    x = [float(v) for v in x]
    film = dict(zip(FILM_NAMES, x[15:18]))
    return OpenPbrMaterial(base_color=tuple(x[0:3]), base_metalness=x[3],
                           specular_color=tuple(x[4:7]), specular_roughness=x[7],
                           specular_ior=x[8], coat_weight=x[9], coat_color=tuple(x[10:13]),
                           coat_roughness=x[13], coat_ior=x[14], **film)


def starts(base) -> list[np.ndarray]:
    """The vectors of :data:`STARTS` with the base colour ``base`` (3,), and a smooth
    white metal under a rough, index-matched coat of ``base``'s hue (the coat's
    view-dependent absorption is what shifts a goniochromatic ink's colour)."""
    out = [np.array([*base, metal, 1, 1, 1, r, 1.5, coat, 1, 1, 1, r_c, 1.6], float)
           for metal, r, coat, r_c in STARTS]
    hue = np.clip(np.asarray(base, float) / max(float(np.max(base)), 1e-6), 0.02, 1.0)
    out.append(np.array([0.8, 0.8, 0.8, 1.0, 1, 1, 1, 0.05, 1.5, 1.0, *hue, 0.35, 1.0]))
    return out


#: Starts continued after the screening (:meth:`~.standard_fit.Problem.solve`; the
#: others run :data:`~.standard_fit.SCREEN_NFEV` steps), and the steps each then takes.
KEEP_STARTS = 2
START_NFEV = 100

#: Colour inputs that change their own channel of f only (base, specular and coat colour).
CHANNELS = ((0, 1, 2), (4, 5, 6), (10, 11, 12))

SPACE = Space(NAMES, LOWER, UPPER, starts,
              lambda cos, x: openpbr_brdf(cos, to_material(x)), to_material, CHANNELS)
_UM = np.array(gltf_fit.FILM_THICKNESS_NM) / 1e3          # the thickness range in µm
FILM = FilmStage(
    Space(NAMES + FILM_NAMES, np.concatenate([LOWER, [0.0, gltf_fit.FILM_IOR[0], _UM[0]]]),
          np.concatenate([UPPER, [1.0, gltf_fit.FILM_IOR[1], _UM[1]]]),
          starts, SPACE.brdf, to_material, CHANNELS),
    gltf_fit.FILM_GRID_IOR, tuple(d / 1e3 for d in gltf_fit.FILM_GRID_NM),
    lambda x: [np.asarray(x)], FILM_STARTS, 1, FILM_NFEV, gltf_fit.FILM_GAIN)


def fit_openpbr(target_rgb: Callable[[Cosines], np.ndarray], directions=None) -> ExportFit:
    """The OpenPBR Surface closest to ``target_rgb`` (f (..., 3) linear sRGB, sr⁻¹)."""
    return fit_standard(target_rgb, SPACE, directions, keep=KEEP_STARTS,
                        max_nfev=START_NFEV, film=FILM)


def _document(m: OpenPbrMaterial, extras: dict):
    """The MaterialX document of ``m`` (without the libraries)."""
    import MaterialX as mx

    doc = mx.createDocument()
    doc.setColorSpace("lin_rec709")
    name = mx.createValidName(m.name or "material")
    shader = doc.addNode("open_pbr_surface", f"{name}_surface", "surfaceshader")
    for key, value in m.to_dict().items():
        if isinstance(value, list):
            shader.setInputValue(key, mx.Color3(*value))
        else:
            shader.setInputValue(key, float(value))
    shader.setInputValue("coat_darkening", float(COAT_DARKENING))
    material = doc.addMaterialNode(name, shader)
    g = extras.get("gonio", {})
    material.setDocString(f"gonio export --to openpbr of {g.get('material', '')} "
                          f"(sha256 {g.get('material_sha256', '')}); fitted and judged: "
                          f"{g.get('report', '')}")
    return doc


def validate(text: str, where: str = "the written document") -> None:
    """Read a MaterialX document's text with MaterialX's standard libraries and
    ``validate()`` it; an invalid one is an error (a bug of the export, named)."""
    import MaterialX as mx

    doc = mx.createDocument()
    mx.readFromXmlString(doc, text)
    lib = mx.createDocument()
    mx.loadLibraries(mx.getDefaultDataLibraryFolders(), mx.getDefaultDataSearchPath(), lib)
    doc.setDataLibrary(lib)
    ok, message = doc.validate()
    if not ok:
        raise GonioError(f"{where}: MaterialX finds the document invalid: "
                         f"{' '.join(message.split())}")


def read_surface(text: str) -> OpenPbrMaterial:
    """The :class:`OpenPbrMaterial` of a document's ``open_pbr_surface``, its inputs as
    written (MaterialX prints six significant digits and reads float32)."""
    import MaterialX as mx

    doc = mx.createDocument()
    mx.readFromXmlString(doc, text)
    node = doc.getNodes("open_pbr_surface")[0]
    known = set(OpenPbrMaterial().to_dict())
    values = {}
    for i in node.getInputs():
        if i.getName() in known:
            v = tuple(float(x) for x in i.getValueString().split(","))
            values[i.getName()] = v if i.getType() == "color3" else v[0]
    return OpenPbrMaterial(**values)


def as_written(m: OpenPbrMaterial) -> OpenPbrMaterial:
    """``m`` as the ``.mtlx`` holds it (:func:`read_surface` of :func:`mtlx_bytes`)."""
    from dataclasses import replace

    return replace(read_surface(mtlx_bytes(m).decode("utf-8")), name=m.name)


def mtlx_bytes(m: OpenPbrMaterial, extras: dict | None = None) -> bytes:
    """The ``.mtlx`` of ``m``, validated (:func:`validate`)."""
    import MaterialX as mx

    text = mx.writeToXmlString(_document(m, extras or {}))
    validate(text)
    return text.encode("utf-8")


def export_openpbr(material, material_path, out, scene_path=None, variables=None
                   ) -> tuple[list[Path], dict]:
    """Fit, write and judge: ``out`` (``NAME.mtlx``) and its report; returns both paths and
    the report's payload. ``scene_path``/``variables`` are refused (a material only)."""
    if scene_path is not None or variables:
        raise InputError("--scene: --to openpbr writes a material, not a scene",
                         fix="leave out --scene and --var")
    check_file_output(out, get_target("openpbr"))
    return export_judged(Fitted("openpbr", fit_openpbr, openpbr_brdf, mtlx_bytes, as_written),
                         material, material_path, out)
