"""``gonio ingest``: the thin typer shell over :mod:`gonio_cli.ingest` (STYLE 1).

It parses options and calls the stage (:func:`gonio_cli.ingest.run`, imported on first use,
so ``gonio --help`` stays fast), writes the measurement artifact atomically with its
provenance (:func:`gonio_cli.ingest.write`) and, with ``--summary``, prints what was read
to stdout. Any error is raised before anything is written.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import List, Optional

import typer

from .. import log
from ..errors import InputError
from ..outputs import declare
from . import require_files
HELP = """Read goniometer spectra (CSV) and write one measurement artifact (JSON).

Layouts, detected from the header: long (theta_i_deg,theta_o_deg,wavelength_nm,value),
wide (theta_i_deg,theta_o_deg,<wavelength>,...) and multi-angle (geometry,<wavelength>,...
with ASTM E2194 labels such as 45as15). Comma, semicolon (decimal comma allowed) or tab
delimited; '#' starts a comment line. Several files merge into one artifact; repeated rows
of a configuration are averaged and their standard deviation kept. Values are converted to
BRDF (sr^-1) and resampled onto the working grid (with a warning if it differs).
Instrument exports saved from a spreadsheet are read as they are: preamble lines before
the header are skipped, label columns (Name, Date/Time, Sample, ID ...) set aside, and of
a file holding several samples --sample picks one. Values that look like percent (their
median at least 15 deg off the mirror above 1.5) are refused: --scale 0.01 reads them, an
explicit --scale 1 confirms values that are right as they are.

An RGL measured BSDF (a .bsdf file of the RGL material database, RGB or spectral) is read
through Mitsuba 3's measured plugin (the optional extra gonio[mitsuba]) and evaluated in
plane at --theta-i-deg x --theta-o-deg, as BRDF without the cosine; RGB files become
spectra through the Mallett-Yuksel basis (docs/rgl.md).

\b
Example:
  gonio ingest ink_blue_a.csv ink_blue_b.csv -o blue.measurement.json --summary
  gonio ingest ink_green.csv --quantity ratio-to-white --white-reflectance 0.99 \\
      -o green.measurement.json
  gonio ingest export.csv --sample PANEL_2 --quantity reflectance-factor --scale 0.01 \\
      --grid-nm 400:700:10 -o panel2.measurement.json
  gonio ingest cc_ibiza_sunset_rgb.bsdf --theta-i-deg 10:70:10 -o wrap.measurement.json
"""


#: The options without a default value (the core fills them in and says so in ``help``):
#: the parameter's name → flag, metavar, help.
OPTIONAL = {
    "quantity": (
        "--quantity", "NAME",
        "What the files hold: brdf (sr^-1), ratio-to-white (over a white standard), "
        "reflectance-factor (pi x BRDF) or flux-ratio (reflected over incident flux) "
        "[default: brdf, with a warning for a multi-angle file]."),
    "white_reflectance": (
        "--white-reflectance", "R|FILE.csv",
        "ratio-to-white only: the white standard's reflectance, a number in (0, 1] or a "
        "CSV wavelength_nm,value [default: 0.99]."),
    "aperture_mm": (
        "--aperture-mm", "MM", "flux-ratio only: diameter of the receptor aperture, in mm."),
    "distance_mm": (
        "--distance-mm", "MM",
        "flux-ratio only: distance from the sample to the receptor aperture, in mm."),
    "dark": (
        "--dark", "FILE.csv",
        "Dark/background spectrum (CSV wavelength_nm,value, in the units of the value "
        "columns) subtracted from every row before the conversion."),
    "grid_nm": (
        "--grid-nm", "START:STOP:STEP", "Working spectral grid in nm [default: 380:780:10]."),
    "scale": (
        "--scale", "FACTOR",
        "Multiply the values by FACTOR (after --dark, before the conversion): 0.01 reads "
        "percent; 1 given explicitly confirms the values' units (no percent check) "
        "[default: 1]."),
    "sample": (
        "--sample", "NAME",
        "Of a file holding several samples (a Name, Sample or ID column), the one to read, "
        "as the file writes it."),
    "theta_i_deg": (
        "--theta-i-deg", "LIST|START:STOP:STEP",
        ".bsdf only: angles of incidence to evaluate at, degrees, e.g. 10,30,50 or "
        "10:70:10 [default: 10:70:10]."),
    "theta_o_deg": (
        "--theta-o-deg", "LIST|START:STOP:STEP",
        ".bsdf only: signed detector angles for every angle of incidence, degrees "
        "[default: -80:85:5]."),
    "phi_o_deg": (
        "--phi-o-deg", "LIST|START:STOP:STEP",
        ".bsdf only: detector azimuths from the plane of incidence, each with every "
        "theta_o, degrees in [0, 180] [default: 0]."),
    "mirror_deg": (
        "--mirror-deg", "LIST|none",
        ".bsdf only: distances from the mirror direction of a fine ring of detectors "
        "(in and across the plane), degrees [default: 1,2,3 with the default "
        "--theta-o-deg, none with a list given]."),
}


def _optional(name: str):
    """The option :data:`OPTIONAL` names, without a default value."""
    flag, metavar, help = OPTIONAL[name]
    return typer.Option(None, flag, metavar=metavar, show_default=False, help=help)


def ingest(
    inputs: List[Path] = typer.Argument(
        ..., metavar="INPUT.csv", show_default=False,
        help="Goniometer CSV files; several merge into one artifact (same wavelengths). "
             "Or one RGL .bsdf file."),
    output: Path = typer.Option(
        ..., "--output", "-o", metavar="MEASUREMENT.json", show_default=False,
        help="The measurement artifact to write (gonio.measurement v1; v2 with "
             "configurations out of the plane of incidence)."),
    quantity: Optional[str] = _optional("quantity"),
    white_reflectance: Optional[str] = _optional("white_reflectance"),
    aperture_mm: Optional[float] = _optional("aperture_mm"),
    distance_mm: Optional[float] = _optional("distance_mm"),
    dark: Optional[Path] = _optional("dark"),
    grid_nm: Optional[str] = _optional("grid_nm"),
    scale: Optional[float] = _optional("scale"),
    sample: Optional[str] = _optional("sample"),
    theta_i_deg: Optional[str] = _optional("theta_i_deg"),
    theta_o_deg: Optional[str] = _optional("theta_o_deg"),
    phi_o_deg: Optional[str] = _optional("phi_o_deg"),
    mirror_deg: Optional[str] = _optional("mirror_deg"),
    summary: bool = typer.Option(
        False, "--summary", help="Print what was read (angles, grid, repeats, values, "
                                 "anything dropped or clipped) to stdout."),
) -> None:
    # lazy: gonio --help and the other commands do not load ingest (benchmarks/bench_startup.py)
    from .. import ingest as stage

    require_files(inputs)
    _refuse_overwriting_an_input(output, inputs, InputError)
    declare({"-o": output}, [*inputs, dark])
    result = stage.run(inputs, quantity=quantity, white_reflectance=white_reflectance,
                       aperture_mm=aperture_mm, distance_mm=distance_mm, dark=dark,
                       grid_nm=grid_nm, scale=scale, sample=sample, theta_i_deg=theta_i_deg,
                       theta_o_deg=theta_o_deg, phi_o_deg=phi_o_deg, mirror_deg=mirror_deg)
    stage.write(result, output)
    if summary:
        typer.echo(stage.format_summary(result.measurement.summary))
    log.info(result.summary_line(output))


def _refuse_overwriting_an_input(output: Path, inputs: List[Path], error) -> None:
    """``-o`` naming one of the inputs would destroy the measurement: refuse it."""
    out = os.path.realpath(output)
    if any(os.path.realpath(p) == out for p in inputs):
        raise error("is both an input and the output", path=output,
                    fix="write the artifact to another file, e.g. -o measurement.json")


EXAMPLE = "gonio ingest ink_red.csv -o red.measurement.json --summary"

SHORT_HELP = "Read goniometer spectra (CSV) into one measurement file."


def register(app: typer.Typer) -> None:
    """Attach ``gonio ingest`` to the app."""
    app.command("ingest", help=HELP, short_help=SHORT_HELP)(ingest)
