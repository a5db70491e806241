"""``gonio render``: the thin shell over :mod:`gonio_cli.render.pipeline`."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

SPECTRAL = ("table", "exact")
TONEMAP_NAMES = ("clip", "reinhard", "filmic")  # gonio_cli.render.tonemap.TONEMAPS (lazy)


def render(
    scene: Path = typer.Argument(..., metavar="SCENE.toml", show_default=False,
                                help="The scene file (docs/render.md); paths in it are "
                                     "relative to it."),
    output: Path = typer.Option(..., "--output", "-o", metavar="OUT.png",
                                help="8-bit sRGB PNG (after exposure and tone map)."),
    exr: Optional[Path] = typer.Option(None, "--exr", metavar="OUT.exr",
                                       help="Also write scene-linear sRGB float32 EXR."),
    ssaa: Optional[int] = typer.Option(None, "--ssaa", metavar="N",
                                       help="Supersampling per axis (overrides [output])."),
    spectral: Optional[str] = typer.Option(
        None, "--spectral", metavar="table|exact",
        help="Tabulated spectral sum (fast) or all wavelengths per pixel (overrides [output])."),
    exposure: Optional[float] = typer.Option(None, "--exposure", metavar="STOPS",
                                             help="Exposure in stops (overrides [output])."),
    tonemap: Optional[str] = typer.Option(
        None, "--tonemap", metavar="NAME",
        help=f"One of: {', '.join(TONEMAP_NAMES)} (overrides [output])."),
    width: Optional[int] = typer.Option(None, "--width", metavar="PX",
                                        help="Image width (overrides [camera])."),
    height: Optional[int] = typer.Option(None, "--height", metavar="PX",
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
) -> None:
    """Render a scene to PNG (and EXR): spectral goniochromatic shading on the CPU.

    \b
    Example:
      gonio render sample_data/scenes/spheres.toml -o green.png --var material=green
      gonio render scene.toml -o a.png --exr a.exr --ssaa 3 --report run.json
      gonio render scene.toml -o a.png --grid-nm 400:700:10
    """
    import time

    start = time.perf_counter()  # the total: scene loading to images written
    from .. import log
    from ..errors import InputError
    from ..render import Stats
    from ..render.pipeline import frame_time, render_scene, write_outputs, write_report
    from ..render.scene import load_scene

    variables = {}
    for item in var:
        name, sep, value = item.partition("=")
        if not sep or not name:
            raise InputError(f"--var {item!r} is not NAME=VALUE", fix="e.g. --var ink=green")
        variables[name] = value
    for path, flag in ((output, "-o"), (exr, "--exr"), (report, "--report")):
        if path is not None and path.exists() and path.is_dir():
            raise InputError(f"{flag} {path} is a folder", fix="name a file")
    if spectral is not None and spectral not in SPECTRAL:
        raise InputError(f"--spectral {spectral!r} is unknown", fix=f"use one of {', '.join(SPECTRAL)}")
    if tonemap is not None and tonemap not in TONEMAP_NAMES:
        raise InputError(f"--tonemap {tonemap!r} is unknown",
                         fix=f"use one of {', '.join(TONEMAP_NAMES)}")
    if output.suffix.lower() != ".png":
        raise InputError(f"-o {output}: the image is written as PNG", fix="name it *.png")
    if exr is not None and exr.suffix.lower() != ".exr":
        raise InputError(f"--exr {exr}: not an .exr name", fix="name it *.exr")

    stats = Stats()
    with log.timer() as t:
        sc = load_scene(scene, variables=variables,
                        overrides={"width": width, "height": height, "ssaa": ssaa,
                                   "spectral": spectral, "exposure": exposure,
                                   "tonemap": tonemap, "grid_nm": grid_nm})
    stats.time_s["scene"] = t["time_s"]
    frame = render_scene(sc, stats)
    write_outputs(frame, sc, stats, png=output, exr=exr, start=start)
    total = time.perf_counter() - start
    if report is not None:
        write_report(report, sc, stats, total_s=total, png=output, exr=exr)
    frame_ms = 1e3 * frame_time(stats)
    log.info(f"{output}: {sc.camera.width}x{sc.camera.height}, ssaa {sc.output.ssaa}, "
             f"{sc.output.spectral} spectra, frame {frame_ms:.0f} ms, total {total:.2f} s")


EXAMPLE = "gonio render sample_data/scenes/spheres.toml -o red.png --exr red.exr --report run.json"


def register(app: typer.Typer) -> None:
    # a whole sentence in the command list of ``gonio --help`` (not cut at a width)
    app.command("render", short_help="Render a scene to PNG and EXR (spectral, on the CPU).")(
        render)
