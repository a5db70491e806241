"""``gonio export``: a fitted material out to another renderer.

:data:`TARGETS` is the registry the command's ``--to`` reads (STYLE 3); each target
writes a folder from a :class:`gonio_cli.schemas.Material`:

* ``mitsuba`` — a Mitsuba 3 BSDF plugin, its parameters and a ready scene
  (:mod:`gonio_cli.export.mitsuba`, docs/export.md);
* ``gltf`` — a binary glTF 2.0 file (``NAME.glb``): a preview sphere with a PBR material
  fitted to the material's BRDF, and a report of what the fit loses
  (:mod:`gonio_cli.export.gltf`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..errors import InputError


@dataclass(frozen=True)
class Target:
    """An export target: ``write(material, material_path, output, scene_path, variables)``
    returns :class:`Written`; ``models()`` lists the models it takes; ``output`` is
    ``folder`` (``-o DIR``) or a file suffix (``.glb``: ``-o NAME.glb``)."""

    name: str
    description: str
    write: Callable
    models: Callable[[], list[str]]
    output: str = "folder"
    label: str = ""          # its name in a sentence (glTF)


@dataclass
class Written:
    """What a target wrote, and its report (:func:`gonio_cli.export.judge.report`) if any."""

    files: list[Path]
    report: dict[str, Any] | None = None


def _mitsuba_write(*args, **kwargs) -> Written:
    from .mitsuba import export_mitsuba

    return Written(export_mitsuba(*args, **kwargs))


def _mitsuba_models() -> list[str]:
    from .mitsuba import supported_models

    return supported_models()


def _gltf_write(*args, **kwargs) -> Written:
    from .gltf import export_gltf

    return Written(*export_gltf(*args, **kwargs))


def _all_models() -> list[str]:
    from ..brdf import MODELS

    return list(MODELS)


TARGETS: dict[str, Target] = {
    "mitsuba": Target("mitsuba", "Mitsuba 3 BSDF plugin (Python) + scene XML",
                      _mitsuba_write, _mitsuba_models),
    "gltf": Target("gltf", "glTF 2.0 binary (.glb): a preview sphere with a fitted PBR "
                   "material, and its colour-error report", _gltf_write, _all_models,
                   output=".glb", label="glTF"),
}


def get_target(name: str) -> Target:
    """The target by name; an unknown one is an error listing the targets."""
    if name not in TARGETS:
        raise InputError(f"--to {name}: unknown export target",
                         fix=f"use one of {', '.join(TARGETS)}")
    return TARGETS[name]
