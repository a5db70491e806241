"""``gonio halftone``: the thin shell over :mod:`gonio_cli.halftone`."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

#: Methods and gamut modes shown in --help; the core's registries are the truth and
#: refuse anything else (kept here only so that --help needs no core import).
METHOD_NAMES = ("floyd-steinberg", "jarvis", "stucki", "bayer", "clustered", "blue-noise")
GAMUT_NAMES = ("scale", "clip")


def split_paths(output: Path) -> list[Path]:
    """``print.png`` → ``print.red.png``, ``print.green.png``, ``print.blue.png``."""
    from ..halftone import INKS

    return [output.with_name(f"{output.stem}.{ink}{output.suffix}") for ink in INKS]


def halftone(
    image: Path = typer.Argument(..., metavar="IMAGE", show_default=False,
                                 help="PNG, JPEG, TIFF or EXR with R, G, B channels."),
    output: Path = typer.Option(..., "--output", "-o", metavar="MASK.png",
                                help="The RGB ink mask to write (channels 0/255, one ink "
                                     "per pixel at most)."),
    method: str = typer.Option("floyd-steinberg", "--method", "-m", metavar="NAME",
                               help=f"One of: {', '.join(METHOD_NAMES)}."),
    input_encoding: str = typer.Option(
        "auto", "--input-encoding", metavar="auto|srgb|linear",
        help="How pixel values are encoded; auto: sRGB for 8/16-bit files, linear for "
             "float files (EXR)."),
    gamut: str = typer.Option("scale", "--gamut", metavar="scale|clip",
                              help="Where r+g+b > 1: scale (divide by the sum) or clip "
                                   "(nearest in-gamut coverage)."),
    size: Optional[str] = typer.Option(None, "--size", metavar="WxH",
                                       help="Resample to this many pixels first."),
    dpi: Optional[float] = typer.Option(None, "--dpi", metavar="DPI",
                                        help="Resample to this resolution (needs "
                                             "--print-width-mm)."),
    print_width_mm: Optional[float] = typer.Option(None, "--print-width-mm", metavar="MM",
                                                   help="Width of the print for --dpi."),
    bayer_size: Optional[int] = typer.Option(None, "--bayer-size", metavar="N",
                                             help="bayer: matrix size, a power of two "
                                                  "(default 8)."),
    cell_size: Optional[int] = typer.Option(None, "--cell-size", metavar="N",
                                            help="clustered: cell size in pixels "
                                                 "(default 3, seed 000's example)."),
    mask_size: Optional[int] = typer.Option(None, "--mask-size", metavar="N",
                                            help="blue-noise: void-and-cluster mask size "
                                                 "(default 64)."),
    split: bool = typer.Option(False, "--split",
                               help="Also write one screen per ink: MASK.red.png, "
                                    "MASK.green.png, MASK.blue.png (0/255, 255 = ink)."),
    report: Optional[Path] = typer.Option(None, "--report", metavar="REPORT.json",
                                          help="Write coverage per ink, tone error, "
                                               "out-of-gamut fraction and times."),
) -> None:
    """Halftone an image into exclusive R/G/B ink masks (seed 000, Figure 6).

    \b
    Example:
      gonio halftone photo.png -o print.png --method floyd-steinberg --report print.json
      gonio halftone photo.exr -o print.png --dpi 300 --print-width-mm 120 --split
    """
    from .. import log
    from .. import halftone as core
    from ..artifact import make_document, write_json
    from ..errors import InputError
    from ..halftone import coverage as cov
    from ..imageio import read_image, write_png, write_png_1bit

    # options first, so a typo costs nothing and nothing is written
    m = core.get_method(method)
    params = core.resolve_parameters(m, {"bayer_size": bayer_size, "cell_size": cell_size,
                                         "mask_size": mask_size})
    if output.suffix.lower() != ".png":
        raise InputError("the mask must be a PNG", path=output, fix="name it *.png")
    if size is not None and (dpi is not None or print_width_mm is not None):
        raise InputError("--size and --dpi/--print-width-mm both set the print size",
                         fix="give one of them")
    if (dpi is None) != (print_width_mm is None):
        raise InputError("--dpi and --print-width-mm go together",
                         fix="give both, or --size WxH")
    target_size = cov.parse_size(size) if size is not None else None
    img = read_image(image)
    if dpi is not None:
        target_size = cov.size_from_dpi(dpi, print_width_mm, img.pixels.shape[:2])
    with log.timer() as t:
        prepared = core.prepare(img.pixels, is_float=img.is_float, encoding=input_encoding,
                                gamut=gamut, size=target_size, path=image)
        result = core.halftone(prepared.coverage, m.name, **params)
    payload = core.evaluate(result, prepared)
    parameters = {"method": m.name, **params, "input_encoding": input_encoding,
                  "gamut": gamut, "size": size, "dpi": dpi, "print_width_mm": print_width_mm,
                  "split": split}
    screens = split_paths(output) if split else []
    payload.update(mask=str(output), split=[str(p) for p in screens])
    meta = {"schema": "gonio.halftone-mask", "method": m.name, "parameters": parameters,
            "input": str(image), "time_s": round(t["time_s"], 6)}
    write_png(output, result.mask(), metadata=meta)
    for k, path in enumerate(screens):
        write_png_1bit(path, result.labels == k + 1, metadata={**meta, "ink": core.INKS[k]})
    if report is not None:
        write_json(report, make_document(core.REPORT_SCHEMA, core.REPORT_SCHEMA_VERSION,
                                         payload, inputs=[image], parameters=parameters,
                                         time_s=t["time_s"]))
    if prepared.out_of_gamut_fraction > 0:
        log.info(f"{image}: {100 * prepared.out_of_gamut_fraction:.1f} % of the pixels were "
                 f"out of gamut (r+g+b > 1), mapped by --gamut {gamut}")
    cover = " ".join(f"{ink[0].upper()}={100 * a:.2f}%(target {100 * c:.2f}%)"
                     for ink, a, c in zip(core.INKS, payload["coverage_mask"],
                                          payload["coverage_target"]))
    log.info(f"{output}: {m.name} {payload['width_px']}x{payload['height_px']} {cover} "
             f"tone RMSE {payload['tone_rmse']:.4f} (σ={core.TONE_SIGMA_PX:g} px) "
             f"{1e3 * result.time_s:.0f} ms"
             + (f" (+{result.compile_time_s:.1f} s JIT compile)" if result.compile_time_s else ""))


EXAMPLE = ("gonio halftone photo.png -o print.png --method floyd-steinberg --report "
           "print.json")


def register(app: typer.Typer) -> None:
    app.command("halftone")(halftone)
