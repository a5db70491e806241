"""``gonio render`` as a library call: :func:`run` checks the options, loads the scene,
renders each frame (one, or a turntable's), writes its images and run report, and
returns what it wrote (:class:`Frames`). The command's typer shell
(:mod:`gonio_cli.commands.render`) parses the options into a
:class:`~gonio_cli.render.options.RenderOptions` and calls it; so can ``gonio batch`` or
any Python program. Errors are :class:`~gonio_cli.errors.GonioError` (one line naming the
option, the scene file or its key)."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from .. import log
from ..imageio import write_apng
from ..outputs import declare
from . import Stats
from .frame import frame_time
from .options import OVERRIDE_FLAGS, RenderOptions, check_options, declared_outputs, frame_files
from .output import turntable_metadata, write_outputs, write_report
from .pipeline import render_scene
from .scene import load_scene
from .scene_types import Scene
from .turntable import orbit


@dataclass
class RenderedFrame:
    """One frame written: its turntable index (None without a turntable), its files by
    flag (``-o``, ``--exr``, …; None for those not asked for), its stages' times and
    counters (``stats``) and its total time (s: its render and files; the first frame's
    also the scene's loading), and the size of its image."""

    index: int | None
    files: dict[str, Path | None]
    stats: Stats
    total_s: float
    width: int
    height: int


@dataclass
class Frames:
    """What :func:`run` rendered and wrote: the frames in order, and the animated PNG of
    a whole turntable (``preview``; None otherwise)."""

    frames: list[RenderedFrame] = field(default_factory=list)
    preview: Path | None = None


def run(scene: str | os.PathLike | Scene, options: RenderOptions, *,
        start: float | None = None) -> Frames:
    """Render ``scene`` as ``gonio render SCENE`` with ``options`` does.

    Parameters
    ----------
    scene : the scene file (``options.variables`` and the overrides applied as it is
        read), or a :class:`~gonio_cli.render.scene.Scene` already loaded (rendered as it
        is: then ``variables`` and the overrides must be unset).
    options : the files to write and the overrides (:class:`RenderOptions`).
    start : :func:`time.perf_counter` when the command started (its first frame's total
        counts from there); default now.

    Returns
    -------
    :class:`Frames`: each frame's files, stats and times, and the turntable's preview.

    Raises
    ------
    GonioError : a bad option, scene, input file or output path, one line; nothing of the
        frame that failed is written.
    """
    start = time.perf_counter() if start is None else start
    check_options(options)
    outs = declared_outputs(options)
    stats = Stats()
    if isinstance(scene, Scene):
        if options.variables or any(v is not None for v in options.overrides().values()):
            raise ValueError("a loaded Scene is rendered as it is: give variables and "
                             "overrides to load_scene, or pass the scene's path")
        declare(outs, [scene.path])
        loaded = scene
    else:
        declare(outs, [scene])
        with log.timer() as t:  # once, however many frames
            loaded = load_scene(scene, variables=options.variables,
                                overrides=options.overrides(), flags=OVERRIDE_FLAGS)
        stats.time_s["scene"] = t["time_s"]
    declare(outs, loaded.inputs)  # the files the scene reads
    done = Frames()
    for k, files in frame_files(options):
        sc = loaded if k is None else orbit(loaded, k, options.turntable, options.orbit)
        done.frames.append(_frame(sc, k, files, options, stats, start))
        start = time.perf_counter()  # the next frame's total: its render and files
        stats = Stats()
    if options.whole_turntable:
        pngs = [f.files["-o"] for f in done.frames]
        write_apng(options.output, pngs,
                   metadata=turntable_metadata(pngs, orbit=options.orbit))
        log.info(f"{options.output}: turntable preview of {len(pngs)} frames "
                 f"({options.orbit} orbit)")
        done.preview = options.output
    return done


def _frame(sc: Scene, k: int | None, files: dict, options: RenderOptions, stats: Stats,
           start: float) -> RenderedFrame:
    """Render one frame and write its files (and report); log its one-line summary."""
    image = render_scene(sc, stats, spectra=files["--spectral-exr"] is not None)
    write_outputs(image, sc, stats, png=files["-o"], exr=files["--exr"], start=start,
                  gamut_warning=files["--gamut-warning"], exr_space=options.exr_space,
                  spectral_exr=files["--spectral-exr"], exr_adapt=options.exr_adapt)
    total = time.perf_counter() - start
    if files["--report"] is not None:
        write_report(files["--report"], sc, stats, total_s=total, png=files["-o"],
                     exr=files["--exr"], gamut_warning=files["--gamut-warning"],
                     spectral_exr=files["--spectral-exr"])
    log.info(f"{files['-o']}: {sc.camera.width}x{sc.camera.height}, ssaa "
             f"{sc.output.ssaa}, {sc.output.spectral} spectra, frame "
             f"{1e3 * frame_time(stats):.0f} ms, total {total:.2f} s{_shown(stats)}")
    return RenderedFrame(k, files, stats, total, sc.camera.width, sc.camera.height)


def _shown(stats: Stats) -> str:
    """What the summary line adds about pixels the display or the measurement could not
    show: out of gamut, clipped at white, measured-reference samples outside the range."""
    n_out = stats.counts.get("out_of_gamut_pixels", 0)
    n_clip = stats.counts.get("clipped_pixels", 0)
    n_meas = stats.counts.get("measured_outside_samples", 0)
    return "".join([f", {n_out} pixel(s) outside the sRGB gamut" if n_out else "",
                    f", {n_clip} pixel(s) clipped at white" if n_clip else "",
                    f", {n_meas} measured-reference sample(s) outside the measured "
                    "range" if n_meas else ""])
