"""``gonio render``: the thin shell over :mod:`gonio_cli.render.pipeline`."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from ..names import ADAPTATION_NAMES as ADAPT_NAMES
from ..names import EXR_SPACE_NAMES, TONEMAP_NAMES, metavar, pick
from ..names import SPECTRAL_PATHS as SPECTRAL


def render(
    scene: Path = typer.Argument(..., metavar="SCENE.toml", show_default=False,
                                help="The scene file (docs/render.md); paths in it are "
                                     "relative to it."),
    output: Path = typer.Option(..., "--output", "-o", metavar="OUT.png",
                                help="8-bit sRGB PNG (after exposure and tone map)."),
    exr: Optional[Path] = typer.Option(None, "--exr", metavar="OUT.exr",
                                       help="Also write scene-linear float32 EXR "
                                            "(in --exr-space)."),
    exr_space: str = typer.Option("srgb", "--exr-space", metavar=metavar(EXR_SPACE_NAMES),
                                  help="Colour space of the --exr image (named in its "
                                       "header)."),
    spectral_exr: Optional[Path] = typer.Option(
        None, "--spectral-exr", metavar="OUT.exr",
        help="Also write the spectral radiance per wavelength (spectral OpenEXR layout)."),
    ssaa: Optional[int] = typer.Option(None, "--ssaa", metavar="N",
                                       help="Supersampling per axis (overrides [output])."),
    spectral: Optional[str] = typer.Option(
        None, "--spectral", metavar=metavar(SPECTRAL),
        help="Tabulated spectral sum (fast) or all wavelengths per pixel (overrides [output])."),
    exposure: Optional[float] = typer.Option(None, "--exposure-stops", "--exposure",
                                             metavar="STOPS",
                                             help="Exposure in stops (overrides [output])."),
    tonemap: Optional[str] = typer.Option(
        None, "--tonemap", metavar=metavar(TONEMAP_NAMES),
        help=f"One of: {', '.join(TONEMAP_NAMES)} (overrides [output]; default neutral, "
             "which keeps hue)."),
    adapt: Optional[str] = typer.Option(
        None, "--adapt", metavar=metavar(ADAPT_NAMES),
        help=f"Chromatic adaptation of the lights' white to D65, one of: "
             f"{', '.join(ADAPT_NAMES)} (overrides [output]; default bradford)."),
    exr_adapt: Optional[str] = typer.Option(
        None, "--exr-adapt", metavar=metavar(ADAPT_NAMES),
        help="Chromatic adaptation of the --exr image (and the --spectral-exr preview): "
             "none keeps it scene-referred, the lights' colour in it [default: none]; "
             "bradford or cat16 adapt it as the PNG is (--adapt)."),
    gamut_warning: Optional[Path] = typer.Option(
        None, "--gamut-warning", metavar="FILE.png",
        help="Also write the PNG with pixels outside sRGB painted grey."),
    width: Optional[int] = typer.Option(None, "--width-px", "--width", metavar="PX",
                                        help="Image width (overrides [camera])."),
    height: Optional[int] = typer.Option(None, "--height-px", "--height", metavar="PX",
                                         help="Image height (overrides [camera])."),
    grid_nm: Optional[str] = typer.Option(
        None, "--grid-nm", metavar="START:STOP:STEP",
        help="Working spectral grid in nm (overrides [output]; without it the scene's grid, "
             "or the materials' common range if they do not cover it)."),
    var: List[str] = typer.Option([], "--var", metavar="NAME=VALUE",
                                  help="Set a ${NAME} of the scene (overrides [vars]); "
                                       "repeatable."),
    report: Optional[Path] = typer.Option(None, "--report", metavar="run.json",
                                          help="Write the run report: each stage's time_s "
                                               "and the total."),
    turntable: Optional[int] = typer.Option(
        None, "--turntable", metavar="N",
        help="Orbit about the scene's up axis in N frames: writes OUT.frame000.png ... "
             "and OUT.png as an animated PNG of them (with --frame: that frame only, at -o)."),
    frame: Optional[int] = typer.Option(None, "--frame", metavar="K",
                                        help="With --turntable: render frame K (0 to N-1) "
                                             "only, to -o."),
    orbit: str = typer.Option("camera", "--orbit", metavar="camera|object",
                              help="With --turntable: move the camera, or turn the objects "
                                   "under a fixed camera and lights."),
) -> None:
    """Render a scene to PNG (and EXR): spectral goniochromatic shading on the CPU.

    \b
    Example:
      gonio render sample_data/scenes/spheres.toml -o green.png --var material=green
      gonio render scene.toml -o a.png --exr a.exr --ssaa 3 --report run.json
      gonio render scene.toml -o a.png --grid-nm 400:700:10
      gonio render scene.toml -o a.png --exr a.exr --exr-space acescg --spectral-exr s.exr
    """
    import time

    start = time.perf_counter()  # the total: scene loading to images written
    from ..machine import one_blas_thread

    one_blas_thread()                                # before numpy loads (its docstring)
    from .. import log
    from ..errors import InputError
    from ..render import Stats
    from ..render.pipeline import frame_time, render_scene, write_outputs, write_report
    from ..render.scene import load_scene
    from . import parse_vars

    variables = parse_vars(var)
    for path, flag in ((output, "-o"), (exr, "--exr"), (report, "--report"),
                       (gamut_warning, "--gamut-warning"), (spectral_exr, "--spectral-exr")):
        if path is not None and path.exists() and path.is_dir():
            raise InputError(f"{flag} {path} is a folder", fix="name a file")
    for value, names, flag in ((spectral, SPECTRAL, "--spectral"),
                               (tonemap, TONEMAP_NAMES, "--tonemap"),
                               (adapt, ADAPT_NAMES, "--adapt"),
                               (exr_adapt, ADAPT_NAMES, "--exr-adapt")):
        if value is not None:
            pick(names, value, flag)
    if gamut_warning is not None and gamut_warning.suffix.lower() != ".png":
        raise InputError(f"--gamut-warning {gamut_warning}: the image is written as PNG",
                         fix="name it *.png")
    if output.suffix.lower() != ".png":
        raise InputError(f"-o {output}: the image is written as PNG", fix="name it *.png")
    for path, flag in ((exr, "--exr"), (spectral_exr, "--spectral-exr")):
        if path is not None and path.suffix.lower() != ".exr":
            raise InputError(f"{flag} {path}: not an .exr name", fix="name it *.exr")
    pick(EXR_SPACE_NAMES, exr_space, "--exr-space")
    if exr_adapt is not None and exr is None and spectral_exr is None:
        raise InputError("--exr-adapt is for the --exr image (or the --spectral-exr "
                         "preview), and neither is written", fix="add --exr OUT.exr, or "
                         "drop --exr-adapt (the PNG's adaptation is --adapt)")
    check_turntable(turntable, frame, orbit)

    from ..outputs import declare

    given = {"-o": output, "--exr": exr, "--report": report, "--gamut-warning": gamut_warning,
             "--spectral-exr": spectral_exr}
    whole = turntable is not None and frame is None  # every frame, then the preview
    frames = list(range(turntable)) if whole else [frame]
    # each frame's files: the given names, or OUT.frameK.png … for a whole turntable
    named = [{flag: (frame_name(path, k) if whole and path is not None else path)
              for flag, path in given.items()} for k in frames]
    outs = {f"{flag} (frame {k})" if whole else flag: path
            for k, names in zip(frames, named) for flag, path in names.items()}
    if whole:
        outs["-o"] = output  # the animated preview
    declare(outs, [scene])
    stats = Stats()
    with log.timer() as t:  # once, however many frames
        loaded = load_scene(scene, variables=variables,
                            overrides={"width": width, "height": height, "ssaa": ssaa,
                                       "spectral": spectral, "exposure": exposure,
                                       "tonemap": tonemap, "adapt": adapt, "grid_nm": grid_nm},
                            flags={"width": "--width-px", "height": "--height-px",
                                   "exposure": "--exposure-stops"})
    stats.time_s["scene"] = t["time_s"]
    declare(outs, loaded.inputs)  # the files the scene reads
    for k, names in zip(frames, named):
        if k is not None:
            from ..render.turntable import orbit as turn

            sc = turn(loaded, k, turntable, orbit)
        else:
            sc = loaded
        image = render_scene(sc, stats, spectra=names["--spectral-exr"] is not None)
        write_outputs(image, sc, stats, png=names["-o"], exr=names["--exr"], start=start,
                      gamut_warning=names["--gamut-warning"], exr_space=exr_space,
                      spectral_exr=names["--spectral-exr"], exr_adapt=exr_adapt)
        total = time.perf_counter() - start
        if names["--report"] is not None:
            write_report(names["--report"], sc, stats, total_s=total, png=names["-o"],
                         exr=names["--exr"], gamut_warning=names["--gamut-warning"],
                         spectral_exr=names["--spectral-exr"])
        frame_ms = 1e3 * frame_time(stats)
        n_out = stats.counts.get("out_of_gamut_pixels", 0)
        n_clip = stats.counts.get("clipped_pixels", 0)
        n_meas = stats.counts.get("measured_outside_samples", 0)
        shown = "".join([f", {n_out} pixel(s) outside the sRGB gamut" if n_out else "",
                         f", {n_clip} pixel(s) clipped at white" if n_clip else "",
                         f", {n_meas} measured-reference sample(s) outside the measured "
                         "range" if n_meas else ""])
        log.info(f"{names['-o']}: {sc.camera.width}x{sc.camera.height}, ssaa "
                 f"{sc.output.ssaa}, {sc.output.spectral} spectra, frame {frame_ms:.0f} ms, "
                 f"total {total:.2f} s{shown}")
        start = time.perf_counter()  # the next frame's total: its render and files
        stats = Stats()
    if whole:
        from ..imageio import write_apng
        from ..render.pipeline import turntable_metadata

        pngs = [names["-o"] for names in named]
        write_apng(output, pngs, metadata=turntable_metadata(pngs, orbit=orbit))
        log.info(f"{output}: turntable preview of {len(pngs)} frames ({orbit} orbit)")


def check_turntable(turntable: int | None, frame: int | None, orbit: str) -> None:
    """Refuse turntable options that do not fit together."""
    from ..errors import InputError
    from ..render.turntable import ORBITS

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


EXAMPLE = "gonio render sample_data/scenes/spheres.toml -o red.png --exr red.exr --report run.json"


def register(app: typer.Typer) -> None:
    # a whole sentence in the command list of ``gonio --help`` (not cut at a width)
    app.command("render", short_help="Render a scene to PNG and EXR (spectral, on the CPU).")(
        render)
