"""``gonio prefilter``: the thin shell over :mod:`gonio_cli.prefilter` (seed 001 §5.1).

Reads a lat-long HDR map and the exponents (a list, or the top-level ``exponents`` of a
``gonio.lobes`` artifact), computes every map in memory, then writes them: all files go
first into a temporary folder beside OUTDIR and are moved into OUTDIR one by one with
:func:`os.replace`, ``index.json`` last, when the command succeeds (the outputs'
transaction, :mod:`gonio_cli.outputs`). A failure before that point (bad input, a bad
option, an interrupted run) leaves OUTDIR untouched; ``index.json`` only ever lists maps
that are complete. The stage itself, reading the map and writing the maps:
:mod:`gonio_cli.prefilter_files`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from .. import log
from ..errors import InputError
from ..names import PREFILTER_AUTO, PREFILTER_METHOD_NAMES, metavar
from ..numbers import NumberList
from ..outputs import declare
from . import read_as, require_files


#: ``--exponents``: the maps' cosine-lobe exponents (their range is checked by the core).
EXPONENTS = NumberList("--exponents", "1,8,64")


def prefilter(
    envmap_path: Path = typer.Argument(..., metavar="ENV.exr", show_default=False,
                                       help="Lat-long HDR environment map (EXR or HDR)."),
    output: Path = typer.Option(..., "--output", "-o", metavar="OUTDIR",
                                help="Folder for the maps and index.json."),
    exponents: Optional[str] = typer.Option(None, "--exponents", "-e", metavar="E1,E2,…",
                                            help="Cosine-lobe exponents, 1 to 1e4."),
    lobes: Optional[Path] = typer.Option(None, "--lobes", metavar="LOBES.json",
                                         help="Take the exponents of a gonio.lobes file."),
    chain: bool = typer.Option(False, "--chain",
                               help="Exponents 1, 2, 4, … up to the map's own sharpness: "
                                    "what [environment] method = 'model' reads."),
    sun: bool = typer.Option(False, "--sun",
                             help="Split the sun off the map first: the renderer lights "
                                  "with it as a directional light that casts shadows."),
    method: str = typer.Option("auto", "--method", "-m",
                               metavar=metavar((PREFILTER_AUTO,) + PREFILTER_METHOD_NAMES),
                               help="auto (per exponent), ring, or brute (exact, slow)."),
    resolution: Optional[int] = typer.Option(
        None, "--height-px", "--resolution", metavar="PX",
        help="Force the output height (the input's divided by a power of two)."),
    fix_invalid: bool = typer.Option(False, "--fix-invalid",
                                     help="Replace NaN/inf/negative texels instead of failing."),
    check: bool = typer.Option(True, "--check/--no-check",
                               help="Spot-check each map against brute for error_estimate."),
) -> None:
    """Prefilter an environment map for cosine lobes (seed 001 §5.1, eqs. 7-9).

    --chain makes every level a material's own lobes need (gonio render's default
    environment method); --lobes the maps of seed 001's lobe weights. Writes
    OUTDIR/prefiltered_E<E>.exr, the normalised lobe average
    P_E(r) = ∫ L max(0, r·ω)^E dω / ∫ max(0, r·ω)^E dω, for every exponent and the
    diffuse map E = 1, and OUTDIR/index.json.

    \b
    Example:
      gonio prefilter sky.hdr --chain -o sky.chain
      gonio prefilter sky.exr --exponents 8,64,512 -o sky.prefiltered
      gonio prefilter sky.exr --lobes paint.lobes.json -o sky.prefiltered
    """
    # lazy: gonio --help and other commands do not load prefilter_files (benchmarks/bench_startup.py)
    from .. import prefilter_files as stage
    from ..schemas import read_lobe_exponents  # lazy: schemas loads numpy

    require_files([envmap_path], what="image file")
    require_files([lobes] if lobes is not None else [], schema="gonio.lobes")
    if (exponents is not None) + (lobes is not None) + chain != 1:
        raise InputError("give one of --chain, --exponents or --lobes",
                         fix="e.g. --chain (for any material) or --exponents 1,8,64")
    options = stage.PrefilterOptions(chain, sun, method, resolution, fix_invalid, check, lobes)
    stage.check_options(options)
    if output.exists() and not output.is_dir():
        raise InputError("exists and is not a folder", path=output,
                         fix="give a folder name for -o")
    declare({"-o": output}, [envmap_path, lobes], folders=["-o"])
    exps = (EXPONENTS.parse(exponents) if exponents is not None
            else read_as("--lobes", read_lobe_exponents, lobes) if lobes is not None else None)
    result = stage.run(envmap_path, exps, options)
    stage.write(result, output)
    log.info(result.summary(output))


EXAMPLE = "gonio prefilter sky.exr --exponents 8,64,512 -o sky.prefiltered"


SHORT_HELP = "Prefilter an HDR environment map for cosine lobes (seed 001)."


def register(app: typer.Typer) -> None:
    app.command("prefilter", short_help=SHORT_HELP)(prefilter)
