"""``gonio prefilter``: the thin shell over :mod:`gonio_cli.prefilter` (seed 001 §5.1).

Reads a lat-long HDR map and the exponents (a list, or the top-level ``exponents`` of a
``gonio.lobes`` artifact), computes every map in memory, then writes them: all files go
first into a temporary folder beside OUTDIR and are moved into OUTDIR one by one with
:func:`os.replace`, ``index.json`` last, when the command succeeds (the outputs'
transaction, :mod:`gonio_cli.outputs`). A failure before that point (bad input, a bad
option, an interrupted run) leaves OUTDIR untouched; ``index.json`` only ever lists maps
that are complete.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..names import PREFILTER_AUTO, PREFILTER_METHOD_NAMES, metavar

#: Digits of a non-integer exponent in its file name (``prefiltered_E12p5.exr``).
NAME_DIGITS = 6


def map_name(exponent: float) -> str:
    """File name of the map of exponent E: ``prefiltered_E64.exr``, ``prefiltered_E12p5.exr``."""
    import numpy as np

    if float(exponent).is_integer():
        tag = str(int(exponent))
    else:
        tag = np.format_float_positional(exponent, precision=NAME_DIGITS, unique=True,
                                         trim="-").replace(".", "p")
    return f"prefiltered_E{tag}.exr"


def parse_exponents(text: str) -> list[float]:
    """``"1,8,64"`` → [1.0, 8.0, 64.0]; a bad item is an error naming it."""
    from ..errors import InputError

    values = []
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        try:
            values.append(float(item))
        except ValueError:
            raise InputError(f"--exponents item {item!r} is not a number",
                             fix="give a comma-separated list such as 1,8,64") from None
    if not values:
        raise InputError("--exponents is empty", fix="give a list such as 1,8,64")
    return values


def prefilter(
    envmap_path: Path = typer.Argument(..., metavar="ENV.exr", show_default=False,
                                       help="Lat-long HDR environment map (EXR or HDR)."),
    output: Path = typer.Option(..., "--output", "-o", metavar="OUTDIR",
                                help="Folder for the maps and index.json."),
    exponents: Optional[str] = typer.Option(None, "--exponents", "-e", metavar="E1,E2,…",
                                            help="Cosine-lobe exponents, 1 to 1e4."),
    lobes: Optional[Path] = typer.Option(None, "--lobes", metavar="LOBES.json",
                                         help="Take the exponents of a gonio.lobes file."),
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

    Writes OUTDIR/prefiltered_E<E>.exr, the normalised lobe average
    P_E(r) = ∫ L max(0, r·ω)^E dω / ∫ max(0, r·ω)^E dω, for every exponent and the
    diffuse map E = 1, and OUTDIR/index.json.

    \b
    Example:
      gonio prefilter sky.exr --exponents 8,64,512 -o sky.prefiltered
      gonio prefilter sky.exr --lobes paint.lobes.json -o sky.prefiltered
    """
    from .. import log
    from .. import prefilter as core
    from ..errors import InputError
    from ..imageio import read_image
    from ..schemas import read_lobe_exponents
    from . import require_files

    require_files([envmap_path], what="image file")
    require_files([lobes] if lobes is not None else [])
    if (exponents is None) == (lobes is None):
        raise InputError("give either --exponents or --lobes (one of them)",
                         fix="e.g. --exponents 1,8,64")
    core.check_method(method)
    if output.exists() and not output.is_dir():
        raise InputError("exists and is not a folder", path=output,
                         fix="give a folder name for -o")
    from ..outputs import declare
    declare({"-o": output}, [envmap_path, lobes], folders=["-o"])
    exps = parse_exponents(exponents) if exponents is not None else read_lobe_exponents(lobes)
    exps = core.validate_exponents(exps, path=lobes)
    image = read_image(envmap_path)
    if not image.is_float:
        raise InputError(f"is a {image.format} image, not HDR", path=envmap_path,
                         fix="pass a linear EXR or HDR (RGBE) map")
    pixels = image.pixels
    if pixels.shape[2] == 4:  # RGBA: the alpha of an environment map is not light
        pixels = pixels[:, :, :3]
    pixels, replaced = core.validate_map(pixels, fix_invalid=fix_invalid, path=envmap_path)
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
    parameters = {"exponents": exps, "lobes": str(lobes) if lobes else None,
                  "method": method, "resolution": resolution, "fix_invalid": fix_invalid,
                  "check": check}
    _write(output, envmap_path, lobes, pixels.shape, results, names, parameters,
           replaced, t["time_s"])
    log.info(summary_line(output, results, t["time_s"]))


def summary_line(output: Path, results, time_s: float) -> str:
    """The one line a run ends with; each map's size, method, error and time are in
    OUTDIR/index.json."""
    methods = "/".join(sorted({r.method for r in results}))
    exps = ", ".join(f"{r.exponent:g}" for r in results)
    worst = max(r.error_estimate for r in results)
    return (f"{output}: {len(results)} maps, E = {exps} ({methods}), spot-checked error "
            f"<= {worst:.2g}, {time_s:.2f} s (each map in {output / 'index.json'})")


def _write(output: Path, envmap_path: Path, lobes, shape, results, names, parameters,
           replaced: int, time_s: float) -> None:
    """Write the maps and index.json through a temporary folder beside OUTDIR."""
    from ..artifact import image_metadata
    from ..imageio import write_exr
    from ..outputs import folder_output
    from ..schemas import PrefilterIndex, write_prefilter_index

    # staged as a whole, moved into OUTDIR when the command succeeds, index.json last
    with folder_output(output, merge=True) as tmp:
        inputs = [envmap_path] + ([lobes] if lobes else [])
        base = image_metadata(PrefilterIndex.SCHEMA, PrefilterIndex.VERSION, inputs=inputs,
                              parameters=parameters)
        entries = []
        for r, name in zip(results, names):
            meta = {**base, "exponent": r.exponent, "method": r.method,
                    "error_estimate": r.error_estimate, "time_s": r.time_s,
                    "layout": "lat-long, Mitsuba 3 envmap (docs/conventions.md)"}
            write_exr(tmp / name, r.pixels, meta)
            entries.append({"exponent": r.exponent, "path": name, "width": r.width,
                            "height": r.height, "method": r.method,
                            "error_estimate": r.error_estimate,
                            "checked_texels": r.checked_texels,
                            "working_width": r.working_shape[1],
                            "working_height": r.working_shape[0],
                            "time_s": r.time_s})
        index = PrefilterIndex(
            source={"width": int(shape[1]), "height": int(shape[0]),
                    "channels": int(shape[2]), "invalid_texels_replaced": int(replaced)},
            diffuse=names[0], maps=entries)
        # checked against the reader's definition before writing (gonio_cli.schemas)
        write_prefilter_index(tmp / "index.json", index, inputs=inputs,
                              parameters=parameters, time_s=time_s)


EXAMPLE = "gonio prefilter sky.exr --exponents 8,64,512 -o sky.prefiltered"


SHORT_HELP = "Prefilter an HDR environment map for cosine lobes (seed 001)."


def register(app: typer.Typer) -> None:
    app.command("prefilter", short_help=SHORT_HELP)(prefilter)
