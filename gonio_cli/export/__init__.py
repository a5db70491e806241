"""``gonio export``: a fitted material out to another renderer.

:data:`TARGETS` is the registry the command's ``--to`` reads (STYLE 3); each target
writes a folder from a :class:`gonio_cli.schemas.Material`:

* ``mitsuba`` — a Mitsuba 3 BSDF plugin, its parameters and a ready scene
  (:mod:`gonio_cli.export.mitsuba`, docs/export.md), judged in Mitsuba itself
  (:mod:`gonio_cli.export.mitsuba_judge`);
* ``gltf`` — a binary glTF 2.0 file (``NAME.glb``): a preview sphere with a PBR material
  fitted to the material's BRDF, and a report of what the fit loses
  (:mod:`gonio_cli.export.gltf`);
* ``openpbr`` — a MaterialX document (``NAME.mtlx``) with an ``open_pbr_surface`` fitted
  to the material's BRDF, and its report (:mod:`gonio_cli.export.openpbr`);
* ``cxf`` — an X-Rite CxF3 file (``NAME.cxf``): the material's spectra predicted at a
  measurement's multi-angle geometries (``--at``), for a QC tool
  (:mod:`gonio_cli.export.cxf`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..errors import InputError


@dataclass(frozen=True)
class Target:
    """An export target: ``write(material, material_path, output, scene_path, variables)``
    (and ``at=`` a measurement's path where ``at``) returns :class:`Written`; ``models()``
    lists the models it takes; ``output`` is ``folder`` (``-o DIR``) or a file suffix
    (``.glb``: ``-o NAME.glb``)."""

    name: str
    description: str
    write: Callable
    models: Callable[[], list[str]]
    output: str = "folder"
    label: str = ""          # its name in a sentence (glTF)
    at: bool = False         # takes --at MEASUREMENT (the configurations to write)
    judged: bool = False     # writes NAME.report.json beside its file (judge.py)


@dataclass
class Written:
    """What a target wrote, and its report (:func:`gonio_cli.export.judge.report`) if any."""

    files: list[Path]
    report: dict[str, Any] | None = None


# Every ``gonio`` run imports this registry (``commands/export.py`` lists its targets in
# ``--help``), so each target's module (numpy, its format's library, the renderer's scene
# reader) is imported when the target is used, not here.
def _mitsuba_write(material, material_path, out_dir, *args, **kwargs) -> Written:
    from .mitsuba import export_mitsuba  # lazy: the registry stays light
    from .mitsuba_judge import judge_mitsuba  # lazy: (the same)

    files = export_mitsuba(material, material_path, out_dir, *args, **kwargs)
    path, rep = judge_mitsuba(material, material_path, out_dir)
    return Written(files + ([path] if path is not None else []), rep)


def _mitsuba_models() -> list[str]:
    from .mitsuba import supported_models  # lazy: the registry stays light

    return supported_models()


def _gltf_write(*args, **kwargs) -> Written:
    from .gltf import export_gltf  # lazy: the registry stays light

    return Written(*export_gltf(*args, **kwargs))


def _openpbr_write(*args, **kwargs) -> Written:
    from .openpbr import export_openpbr  # lazy: the registry stays light

    return Written(*export_openpbr(*args, **kwargs))


def _cxf_write(*args, **kwargs) -> Written:
    from .cxf import export_cxf  # lazy: the registry stays light

    return Written(export_cxf(*args, **kwargs))


def _all_models() -> list[str]:
    from ..brdf import MODELS  # lazy: the registry stays light

    return list(MODELS)


TARGETS: dict[str, Target] = {
    "mitsuba": Target("mitsuba", "Mitsuba 3 BSDF plugin (Python) + scene XML, and its "
                      "colour-error report", _mitsuba_write, _mitsuba_models,
                      label="Mitsuba"),
    "gltf": Target("gltf", "glTF 2.0 binary (.glb): a preview sphere with a fitted PBR "
                   "material, and its colour-error report", _gltf_write, _all_models,
                   output=".glb", label="glTF", judged=True),
    "openpbr": Target("openpbr", "MaterialX document (.mtlx) with a fitted OpenPBR Surface, "
                      "and its colour-error report", _openpbr_write, _all_models,
                      output=".mtlx", label="OpenPBR", judged=True),
    "cxf": Target("cxf", "X-Rite CxF3 (.cxf): the material's spectra at a measurement's "
                  "multi-angle geometries (--at)", _cxf_write, _all_models, output=".cxf",
                  at=True),
}


def get_target(name: str) -> Target:
    """The target by name; an unknown one is an error listing the targets."""
    if name not in TARGETS:
        raise InputError(f"--to {name}: unknown export target",
                         fix=f"use one of {', '.join(TARGETS)}")
    return TARGETS[name]


def check_file_output(path, target: Target) -> None:
    """Refuse an output whose name does not end with the target's suffix (one line, with
    the fix)."""
    if Path(path).suffix.lower() != target.output:
        raise InputError(f"--output {path}: --to {target.name} writes one {target.output} "
                         "file", fix=f"name it with {target.output}, e.g. -o "
                                     f"{Path(path).stem or 'material'}{target.output}")
