"""``gonio export``: the thin shell over :mod:`gonio_cli.export`."""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer

from .. import log
from ..errors import InputError
from ..export import TARGETS, get_target  # the registry (light: no renderer is imported here)
from ..outputs import declare
from . import parse_vars, require_files


def export(
    material: Path = typer.Argument(..., metavar="MATERIAL.json", show_default=False,
                                   help="A gonio.material file (gonio fit)."),
    output: Path = typer.Option(..., "--output", "-o", metavar="OUT",
                                help="The folder to write (made if missing); for --to "
                                     "gltf, openpbr or cxf the .glb, .mtlx or .cxf file "
                                     "(a fit's report beside it)."),
    to: str = typer.Option("mitsuba", "--to", metavar="TARGET",
                           help=f"The renderer to export to: {', '.join(TARGETS)}."),
    scene: Optional[Path] = typer.Option(None, "--scene", metavar="SCENE.toml",
                                         help="A gonio scene whose camera and lights the "
                                              "exported scene uses (default: the sample "
                                              "sphere scene of seed 000 Figure 5)."),
    var: List[str] = typer.Option([], "--var", metavar="NAME=VALUE",
                                  help="A ${NAME} of --scene (as in gonio render)."),
    at: Optional[Path] = typer.Option(None, "--at", metavar="MEASUREMENT.json",
                                      help="For --to cxf: the gonio.measurement whose "
                                           "configurations the spectra are predicted at."),
) -> None:
    """Export a fitted material to another renderer, with a scene that shows it.

    For Mitsuba 3: a BSDF plugin (gonio_bsdf.py, Python, mi.register_bsdf) that evaluates
    and importance-samples the model, its parameters, scene.xml (the material on a sphere
    under the scene's lights) and render.py; gonio_scene.toml renders the same scene with
    gonio render. For glTF 2.0: NAME.glb, a sphere with a PBR material (clearcoat,
    specular, ior extensions) fitted to the material's BRDF, and NAME.glb.report.json, its
    CIEDE2000 against the material. For OpenPBR: NAME.mtlx, a MaterialX document with a
    fitted open_pbr_surface, and its report. For CxF3: NAME.cxf, the material's spectra at
    the multi-angle geometries of --at MEASUREMENT.json. See docs/export.md.

    \b
    Example:
      gonio export red.material.json -o red.mitsuba --to mitsuba
      python red.mitsuba/render.py -o red-mitsuba.exr
      gonio export red.material.json -o red.glb --to gltf
      gonio export red.material.json -o red.mtlx --to openpbr
      gonio export red.material.json -o red.cxf --to cxf --at red.measurement.json
    """
    # lazy: gonio --help and the other commands do not load export.run (benchmarks/bench_startup.py)
    from ..export import run as stage

    target = get_target(to)
    variables = _checked_inputs(target, material, scene, var, at)
    outs = stage.outputs(target, output)
    if outs is not None:
        declare(outs, [material] + ([at] if at is not None else []))
    result = stage.run(target, material, output, scene, variables, at)
    for line in result.lines(output):
        log.info(line)


def _checked_inputs(target, material: Path, scene: Optional[Path], var: List[str],
                    at: Optional[Path]) -> dict:
    """The input files checked and the --var values parsed; an option the target does not
    take (or lacks) is one line."""
    require_files([material], schema="gonio.material")
    if scene is not None:
        require_files([scene], missing_fix="check the path of the scene file")
    variables = parse_vars(var)
    if variables and scene is None:
        raise InputError("--var needs --scene", fix="name the scene the variables are for")
    if at is not None and not target.at:
        raise InputError(f"--at: --to {target.name} does not take a measurement",
                         fix="leave out --at (it is for --to cxf)")
    if target.at and at is None:
        raise InputError(f"--to {target.name} needs --at MEASUREMENT.json",
                         fix="name the measurement whose configurations to predict, "
                             "e.g. --at red.measurement.json")
    if at is not None:
        require_files([at], schema="gonio.measurement")
    return variables


EXAMPLE = "gonio export red.material.json -o red.mitsuba --to mitsuba"

SHORT_HELP = ("Export a fitted material to another renderer (Mitsuba 3, glTF 2.0, OpenPBR "
              "MaterialX) or a QC tool (CxF3), with a scene, a preview or spectra.")


def register(app: typer.Typer) -> None:
    app.command("export", short_help=SHORT_HELP)(export)
