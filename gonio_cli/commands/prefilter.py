"""``gonio prefilter``: the thin shell over :mod:`gonio_cli.prefilter` (seed 001 §5.1).

Reads a lat-long HDR map and the exponents (a list, or the top-level ``exponents`` of a
``gonio.lobes`` artifact), computes every map in memory, then writes them: all files go
first into a temporary folder beside OUTDIR and are moved into OUTDIR one by one with
:func:`os.replace`, ``index.json`` last, when the command succeeds (the outputs'
transaction, :mod:`gonio_cli.outputs`). A failure before that point (bad input, a bad
option, an interrupted run) leaves OUTDIR untouched; ``index.json`` only ever lists maps
that are complete. Reading the map and writing the maps: :mod:`gonio_cli.prefilter_files`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..names import PREFILTER_AUTO, PREFILTER_METHOD_NAMES, metavar
from ..numbers import NumberList
from ..prefilter_files import map_name  # the maps' file names (pathlib only: a light import)


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
    from .. import log
    from .. import prefilter as core
    from ..errors import InputError
    from ..prefilter_files import read_envmap, write_maps
    from ..schemas import read_lobe_exponents
    from . import read_as, require_files

    require_files([envmap_path], what="image file")
    require_files([lobes] if lobes is not None else [], schema="gonio.lobes")
    if (exponents is not None) + (lobes is not None) + chain != 1:
        raise InputError("give one of --chain, --exponents or --lobes",
                         fix="e.g. --chain (for any material) or --exponents 1,8,64")
    core.methods.check_method(method)
    if output.exists() and not output.is_dir():
        raise InputError("exists and is not a folder", path=output,
                         fix="give a folder name for -o")
    from ..outputs import declare
    declare({"-o": output}, [envmap_path, lobes], folders=["-o"])
    pixels, replaced = read_envmap(envmap_path, fix_invalid)
    sun_found = split_sun(pixels, envmap_path) if sun else None
    if sun_found is not None:
        pixels = sun_found[0]
    if chain:
        from ..envmap import chain_exponents

        exps = chain_exponents(pixels.shape[0])
    else:
        exps = (EXPONENTS.parse(exponents) if exponents is not None
                else read_as("--lobes", read_lobe_exponents, lobes))
    exps = core.inputs.validate_exponents(exps, path=lobes)
    if replaced:
        log.warn(f"{envmap_path}: replaced {replaced} NaN, inf or negative texels "
                 "(negative → 0, NaN/inf → the mean of their row)")
    from .. import memory

    n_maps = len(set(exps) | {1.0})
    memory.check(core.memory_estimate(pixels.shape[0], pixels.shape[1], n_maps),
          f"prefiltering a {pixels.shape[1]}x{pixels.shape[0]} map into {n_maps} maps",
          path=envmap_path, fix="give a smaller map (or fewer --exponents)")
    with log.timer() as t:
        results = core.prefilter(pixels, exps, method=method, resolution=resolution,
                                 check=check, path=str(envmap_path))
    names = [map_name(r.exponent) for r in results]
    if len(set(names)) != len(names):
        raise InputError("two exponents round to the same file name",
                         fix="give exponents that differ in their first 6 digits")
    parameters = {"exponents": exps, "lobes": str(lobes) if lobes else None, "chain": chain,
                  "sun": sun,
                  "method": method, "resolution": resolution, "fix_invalid": fix_invalid,
                  "check": check}
    write_maps(output, envmap_path, lobes, pixels.shape, results, names, parameters,
               replaced, t["time_s"], sun_found[1] if sun_found is not None else None)
    log.info(summary_line(output, results, t["time_s"]))


def split_sun(pixels, envmap_path: Path):
    """(residual, index.json's sun entry) of :func:`gonio_cli.envsun.split_sun`, said on
    stderr; None, with a warning that says why, when the map has no sun."""
    import numpy as np

    from .. import log
    from ..envsun import find_sun_region, split_sun as split
    from ..prefilter_files import sun_entry

    residual, found = split(pixels)
    if found is None:
        log.warn(f"{envmap_path}: no sun split off ({find_sun_region(pixels).reason}); "
                 "the map is prefiltered whole and casts no shadow")
        return None
    log.info(f"{envmap_path}: sun at theta {found.theta_deg:.1f} deg, phi "
             f"{found.phi_deg:.1f} deg, {found.angular_diameter_deg:.2f} deg across, "
             f"{found.flux_share:.0%} of the map's light, split off as a light")
    return residual.astype(np.float32), sun_entry(found)


def summary_line(output: Path, results, time_s: float) -> str:
    """The one line a run ends with; each map's size, method, error and time are in
    OUTDIR/index.json."""
    methods = "/".join(sorted({r.method for r in results}))
    exps = ", ".join(f"{r.exponent:g}" for r in results)
    worst = max(r.error_estimate for r in results)
    return (f"{output}: {len(results)} maps, E = {exps} ({methods}), spot-checked error "
            f"<= {worst:.2g}, {time_s:.2f} s (each map in {output / 'index.json'})")


EXAMPLE = "gonio prefilter sky.exr --exponents 8,64,512 -o sky.prefiltered"


SHORT_HELP = "Prefilter an HDR environment map for cosine lobes (seed 001)."


def register(app: typer.Typer) -> None:
    app.command("prefilter", short_help=SHORT_HELP)(prefilter)
