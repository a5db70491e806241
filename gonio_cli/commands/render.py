"""``gonio render``: the thin shell over :func:`gonio_cli.render.run.run` (options →
:class:`~gonio_cli.render.options.RenderOptions` → run)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import List, Optional

import typer

from ..machine import one_blas_thread
from ..names import ADAPTATION_NAMES as ADAPT_NAMES
from ..names import EXR_SPACE_NAMES, TONEMAP_NAMES, metavar
from ..names import SPECTRAL_PATHS as SPECTRAL
from . import parse_vars


def render(
    scene: Path = typer.Argument(..., metavar="SCENE.toml", show_default=False, help=(
        "The scene file (docs/render.md); paths in it are relative to it.")),
    output: Path = typer.Option(..., "--output", "-o", metavar="OUT.png",
                                help="8-bit sRGB PNG (after exposure and tone map)."),
    exr: Optional[Path] = typer.Option(None, "--exr", metavar="OUT.exr", help=(
        "Also write scene-linear float32 EXR (in --exr-space).")),
    exr_space: str = typer.Option("srgb", "--exr-space", metavar=metavar(EXR_SPACE_NAMES),
                                  help="Colour space of the --exr image (named in its header)."),
    spectral_exr: Optional[Path] = typer.Option(
        None, "--spectral-exr", metavar="OUT.exr",
        help="Also write the spectral radiance per wavelength (spectral OpenEXR layout)."),
    ssaa: Optional[int] = typer.Option(None, "--ssaa", metavar="N",
                                       help="Supersampling per axis (overrides [output])."),
    spectral: Optional[str] = typer.Option(
        None, "--spectral", metavar=metavar(SPECTRAL),
        help="Tabulated spectral sum (fast) or all wavelengths per pixel (overrides [output])."),
    exposure: Optional[float] = typer.Option(
        None, "--exposure-stops", "--exposure", metavar="STOPS",
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
    var: List[str] = typer.Option([], "--var", metavar="NAME=VALUE", help=(
        "Set a ${NAME} of the scene (overrides [vars]); repeatable.")),
    report: Optional[Path] = typer.Option(None, "--report", metavar="run.json", help=(
        "Write the run report: each stage's time_s and the total.")),
    turntable: Optional[int] = typer.Option(
        None, "--turntable", metavar="N",
        help="Orbit about the scene's up axis in N frames: writes OUT.frame000.png ... "
             "and OUT.png as an animated PNG of them (with --frame: that frame only, at -o)."),
    frame: Optional[int] = typer.Option(None, "--frame", metavar="K", help=(
        "With --turntable: render frame K (0 to N-1) only, to -o.")),
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
    start = time.perf_counter()  # the total: scene loading to images written
    one_blas_thread()                                # before numpy loads (its docstring)
    # lazy: gonio --help and the other commands do not load render.run (benchmarks/bench_startup.py)
    from ..render import options, run

    run.run(scene, options.RenderOptions(
        output=output, exr=exr, exr_space=exr_space, spectral_exr=spectral_exr,
        exr_adapt=exr_adapt, gamut_warning=gamut_warning, report=report,
        variables=parse_vars(var), width=width, height=height, ssaa=ssaa,
        spectral=spectral, exposure=exposure, tonemap=tonemap, adapt=adapt,
        grid_nm=grid_nm, turntable=turntable, frame=frame, orbit=orbit), start=start)


EXAMPLE = "gonio render sample_data/scenes/spheres.toml -o red.png --exr red.exr --report run.json"


def register(app: typer.Typer) -> None:
    # a whole sentence in the command list of ``gonio --help`` (not cut at a width)
    app.command("render", short_help="Render a scene to PNG and EXR (spectral, on the CPU).")(
        render)
