"""``gonio export``: a fitted material out to another renderer.

:data:`TARGETS` is the registry the command's ``--to`` reads (STYLE 3); each target
writes a folder from a :class:`gonio_cli.schemas.Material`:

* ``mitsuba`` — a Mitsuba 3 BSDF plugin, its parameters and a ready scene
  (:mod:`gonio_cli.export.mitsuba`, docs/export.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..errors import InputError


@dataclass(frozen=True)
class Target:
    """An export target: ``write(material, material_path, out_dir, scene_path, variables)``
    returns the files it wrote; ``models()`` lists the models it takes."""

    name: str
    description: str
    write: Callable
    models: Callable[[], list[str]]


def _mitsuba_write(*args, **kwargs):
    from .mitsuba import export_mitsuba

    return export_mitsuba(*args, **kwargs)


def _mitsuba_models() -> list[str]:
    from .mitsuba import supported_models

    return supported_models()


TARGETS: dict[str, Target] = {
    "mitsuba": Target("mitsuba", "Mitsuba 3 BSDF plugin (Python) + scene XML",
                      _mitsuba_write, _mitsuba_models),
}


def get_target(name: str) -> Target:
    """The target by name; an unknown one is an error listing the targets."""
    if name not in TARGETS:
        raise InputError(f"--to {name}: unknown export target",
                         fix=f"use one of {', '.join(TARGETS)}")
    return TARGETS[name]
