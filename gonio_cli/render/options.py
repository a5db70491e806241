"""What a render writes and how, besides the scene: :class:`RenderOptions` (``gonio
render``'s options as a dataclass, so :func:`gonio_cli.render.run.run` is callable from
Python), their checks (:func:`check_options`, one line naming the option, as the command
line spells it) and the files of each frame of a turntable (:func:`frame_files`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..errors import InputError
from ..names import (ADAPTATION_NAMES, EXR_SPACE_NAMES, SPECTRAL_PATHS, TONEMAP_NAMES,
                     pick)
from .turntable import ORBITS

#: The options that name a file, in the order they are checked, by their flag.
FILE_FLAGS = {"output": "-o", "exr": "--exr", "report": "--report",
              "gamut_warning": "--gamut-warning", "spectral_exr": "--spectral-exr"}

#: The options that override the scene file's values (:func:`.scene.load_scene`'s
#: ``overrides``), and the flags that name them in its messages where they differ.
OVERRIDES = ("width", "height", "ssaa", "spectral", "exposure", "tonemap", "adapt",
             "grid_nm")
OVERRIDE_FLAGS = {"width": "--width-px", "height": "--height-px",
                  "exposure": "--exposure-stops"}


@dataclass
class RenderOptions:
    """``gonio render``'s options (docs/render.md), None where not given.

    Files: ``output`` the PNG (required), ``exr`` (in ``exr_space``, adapted by
    ``exr_adapt``), ``spectral_exr``, ``gamut_warning`` (a PNG), ``report`` (the run
    report). Scene: ``variables`` (``--var``) and the overrides of its values
    (:data:`OVERRIDES`; ``grid_nm`` as "START:STOP:STEP"). Turntable: ``turntable``
    frames, only frame ``frame`` if given, ``orbit`` of :data:`.turntable.ORBITS`.
    """

    output: Path
    exr: Path | None = None
    exr_space: str = "srgb"
    spectral_exr: Path | None = None
    exr_adapt: str | None = None
    gamut_warning: Path | None = None
    report: Path | None = None
    variables: dict[str, str] = field(default_factory=dict)
    width: int | None = None
    height: int | None = None
    ssaa: int | None = None
    spectral: str | None = None
    exposure: float | None = None
    tonemap: str | None = None
    adapt: str | None = None
    grid_nm: str | None = None
    turntable: int | None = None
    frame: int | None = None
    orbit: str = "camera"

    def files(self) -> dict[str, Path | None]:
        """The files by their flag (``-o``, ``--exr``, …), None for those not asked for."""
        return {flag: getattr(self, name) for name, flag in FILE_FLAGS.items()}

    def overrides(self) -> dict[str, Any]:
        """The scene's values these options override (None: the scene's own)."""
        return {name: getattr(self, name) for name in OVERRIDES}

    @property
    def whole_turntable(self) -> bool:
        """Every frame of a turntable, then its animated preview at ``output``."""
        return self.turntable is not None and self.frame is None


def check_options(o: RenderOptions) -> None:
    """Refuse options that cannot work before anything is read: a file option naming a
    folder or the wrong kind of file, an unknown name, ``--exr-adapt`` without an EXR,
    turntable options that do not fit together (:func:`check_turntable`)."""
    for flag, path in o.files().items():
        if path is not None and path.exists() and path.is_dir():
            raise InputError(f"{flag} {path} is a folder", fix="name a file")
    for value, names, flag in ((o.spectral, SPECTRAL_PATHS, "--spectral"),
                               (o.tonemap, TONEMAP_NAMES, "--tonemap"),
                               (o.adapt, ADAPTATION_NAMES, "--adapt"),
                               (o.exr_adapt, ADAPTATION_NAMES, "--exr-adapt")):
        if value is not None:
            pick(names, value, flag)
    if o.gamut_warning is not None and o.gamut_warning.suffix.lower() != ".png":
        raise InputError(f"--gamut-warning {o.gamut_warning}: the image is written as PNG",
                         fix="name it *.png")
    if o.output.suffix.lower() != ".png":
        raise InputError(f"-o {o.output}: the image is written as PNG", fix="name it *.png")
    for path, flag in ((o.exr, "--exr"), (o.spectral_exr, "--spectral-exr")):
        if path is not None and path.suffix.lower() != ".exr":
            raise InputError(f"{flag} {path}: not an .exr name", fix="name it *.exr")
    pick(EXR_SPACE_NAMES, o.exr_space, "--exr-space")
    if o.exr_adapt is not None and o.exr is None and o.spectral_exr is None:
        raise InputError("--exr-adapt is for the --exr image (or the --spectral-exr "
                         "preview), and neither is written", fix="add --exr OUT.exr, or "
                         "drop --exr-adapt (the PNG's adaptation is --adapt)")
    check_turntable(o.turntable, o.frame, o.orbit)


def check_turntable(turntable: int | None, frame: int | None, orbit: str) -> None:
    """Refuse turntable options that do not fit together."""
    pick(ORBITS, orbit, "--orbit")
    if turntable is None:
        if frame is not None:
            raise InputError("--frame needs --turntable N", fix="add --turntable N")
        return
    if turntable < 1:
        raise InputError(f"--turntable {turntable} is not a number of frames",
                         fix="give N >= 1, e.g. --turntable 8")
    if frame is not None and not 0 <= frame < turntable:
        raise InputError(f"--frame {frame} is outside 0 to {turntable - 1}",
                         fix=f"give a frame from 0 to {turntable - 1}")


def frame_name(path: Path, k: int) -> Path:
    """Frame ``k`` of a turntable written to ``path``: ``OUT.frame007.png`` beside it."""
    return path.with_name(f"{path.stem}.frame{k:03d}{path.suffix}")


def frame_files(o: RenderOptions) -> list[tuple[int | None, dict[str, Path | None]]]:
    """Each frame to render (its turntable index, None without a turntable) with its
    files by flag: the given names, or ``OUT.frameK.png`` … for a whole turntable."""
    given = o.files()
    if not o.whole_turntable:
        return [(o.frame, given)]
    return [(k, {flag: None if path is None else frame_name(path, k)
                 for flag, path in given.items()}) for k in range(o.turntable)]


def declared_outputs(o: RenderOptions) -> dict[str, Path | None]:
    """Every file the render may write, by the name :func:`gonio_cli.outputs.declare`
    gives it in a message: the flag (``-o``), with the frame for a whole turntable
    (``-o (frame 3)``), whose animated preview is ``-o``."""
    if not o.whole_turntable:
        return o.files()
    outs = {f"{flag} (frame {k})": path for k, names in frame_files(o)
            for flag, path in names.items()}
    outs["-o"] = o.output
    return outs
