"""``gonio export`` as a library call: a material file in, the target's files out.

:func:`outputs` names the files a target writes (for the outputs' transaction),
:func:`run` reads the material and has the target of :data:`gonio_cli.export.TARGETS`
write it, returning what was written with its report, and :meth:`ExportRun.lines` says
it. The shell :mod:`gonio_cli.commands.export` parses the options, checks the inputs,
declares the outputs and calls these.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass
from pathlib import Path

from .. import log
from ..schemas import Material, read_material
from . import Target, Written, check_file_output
from .judge import report_path, sentence


@dataclass
class ExportRun:
    """What :func:`run` wrote: the target, the material, the files (and the report of a
    judged target) and the time (s)."""

    target: Target
    material: Material
    written: Written
    time_s: float

    def lines(self, output: Path) -> list[str]:
        """The lines a run ends with: what was written, then a judged target's colour
        error (:func:`gonio_cli.export.judge.sentence`)."""
        out = [f"{output}: {self.material.model} for {self.target.name} "
               f"({len(self.written.files)} files, {self.time_s:.2f} s)"]
        if self.written.report is not None:
            out.append(sentence(output.name, self.target.label, self.written.report))
        return out


def outputs(target: Target, output: Path) -> dict[str, Path] | None:
    """The files a file target writes, by the option that names them (None for a folder
    target, which the target stages itself); a wrong suffix is refused."""
    if target.output == "folder":
        return None
    check_file_output(output, target)
    outs = {"-o": output}
    if target.judged:
        outs["-o (its report)"] = report_path(output)
    return outs


def run(target: Target, material: str | os.PathLike, output: Path,
        scene: str | os.PathLike | None = None, variables: dict | None = None,
        at: str | os.PathLike | None = None) -> ExportRun:
    """Export the ``gonio.material`` file ``material`` with ``target`` to ``output``.

    Parameters
    ----------
    target : an entry of :data:`gonio_cli.export.TARGETS` (:func:`~gonio_cli.export.get_target`).
    material : path of a ``gonio.material`` file.
    output : the folder (``mitsuba``) or the file (``NAME.glb``, ``NAME.mtlx``, ``NAME.cxf``)
        to write.
    scene, variables : a gonio scene whose camera and lights the exported scene uses, and
        its ``${NAME}`` values (None: the sample sphere scene).
    at : for a target that takes it (``cxf``), the ``gonio.measurement`` whose
        configurations are written.
    """
    mat = read_material(material)
    if mat.status == "failed":
        log.warn(f"{material}: a fit with status {mat.status!r} is exported")
    start = time.perf_counter()
    extra = {"at": at} if target.at else {}
    written = target.write(mat, material, output, scene, variables or None, **extra)
    return ExportRun(target, mat, written, time.perf_counter() - start)
