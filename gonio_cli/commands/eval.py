"""``gonio eval``: the thin shell over :mod:`gonio_cli.evaluate`."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from .. import log
from ..errors import InputError
from ..names import SWEEP_GAIN_NAMES, metavar, pick
from ..outputs import declare, same_file
from . import read_as, require_files


def evaluate(
    material: Path = typer.Argument(..., metavar="MATERIAL.json", show_default=False,
                                   help="A gonio.material file (gonio fit)."),
    at: Path = typer.Option(..., "--at", metavar="MEASUREMENT.json",
                            help="A gonio.measurement file (gonio ingest) whose "
                                 "configurations and spectral grid the model is evaluated at."),
    output: Path = typer.Option(..., "--output", "-o", metavar="OUT.json",
                                help="The gonio.measurement file to write (quantity brdf)."),
    sweep_gain: str = typer.Option(
        "auto", "--sweep-gain", metavar=metavar(SWEEP_GAIN_NAMES),
        help="A material fitted with light-source gains (gonio fit --sweep-gain): auto "
             "applies them where the measurement's angles of incidence have one, so the "
             "output compares with the instrument; off: the BRDF alone."),
    plot: Optional[Path] = typer.Option(None, "--plot", metavar="FILE.png",
                                        help="Also draw data against model (seed 000 "
                                             "Figure 4 layout, PNG)."),
) -> None:
    """Evaluate a fitted material at a measurement's configurations, as a measurement.

    The output has the measurement's angles and wavelengths and the model's BRDF
    (sr⁻¹, no cosine factor), so data and model compare row for row in any tool.

    \b
    Example:
      gonio eval red.material.json --at red.measurement.json -o red.model.json --plot red.png
    """
    # lazy: gonio --help and the other commands skip the eval core (bench_startup.py)
    from .. import evaluate as stage, schemas
    pick(SWEEP_GAIN_NAMES, sweep_gain, "--sweep-gain")
    require_files([material], schema="gonio.material")
    require_files([at], schema="gonio.measurement")
    for flag, path in (("-o", output), ("--plot", plot)):
        if path is None:
            continue
        for name, given in (("the material", material), ("--at", at)):
            if same_file(path, given):
                raise InputError(f"{flag} {path} is {name} ({given}): it would be overwritten",
                                 fix=f"choose another {flag}")
    if plot is not None and same_file(plot, output):
        raise InputError(f"--plot {plot} is also -o", fix="choose another --plot")
    if plot is not None and plot.suffix.lower() != ".png":
        raise InputError(f"--plot {plot}: the plot is written as PNG", fix="name it *.png")
    declare({"-o": output, "--plot": plot}, [material, at])
    mat = schemas.read_material(material)
    data = read_as("--at", schemas.read_measurement, at)
    if mat.status == "failed":  # a poor fit is what eval is for: comparing it with data
        log.warn(f"{material}: a fit with status {mat.status!r} is evaluated")
    result = stage.run(mat, data, sweep_gain, material_path=material, measurement_path=at)
    stage.write(result, output, plot=plot)
    log.info(f"{output}: {mat.model} at {data.n_configurations} configurations x "
             f"{data.wavelength_nm.size} wavelengths of {at}{result.gains_text()}"
             f"{stage.band_text(result.model.summary['colour_band'])}")


EXAMPLE = ("gonio eval red.material.json --at red.measurement.json -o red.model.json "
           "--plot red.model.png")

SHORT_HELP = "Evaluate a fitted material at a measurement's configurations, as a measurement."


def register(app: typer.Typer) -> None:
    app.command("eval", short_help=SHORT_HELP)(evaluate)
