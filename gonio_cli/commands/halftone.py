"""``gonio halftone``: the thin shell over :mod:`gonio_cli.halftone`."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from .. import log
from ..names import COMPRESSION_NAMES, GAMUT_NAMES, INPUT_ENCODING_NAMES, MASK_FORMAT_NAMES
from ..names import HALFTONE_METHOD_NAMES as METHOD_NAMES
from ..names import metavar
from ..outputs import declare


def _method_option(flag: str, help: str):
    """An integer option of some methods (:data:`gonio_cli.halftone.METHODS`'s parameters)."""
    return typer.Option(None, flag, metavar="N", help=help)


def halftone(
    image: Path = typer.Argument(..., metavar="IMAGE", show_default=False,
                                 help="PNG, JPEG, TIFF or EXR with R, G, B channels."),
    output: Path = typer.Option(..., "--output", "-o", metavar="MASK.png",
                                help="The RGB ink mask to write (channels 0/255, one ink "
                                     "per pixel at most)."),
    method: str = typer.Option("floyd-steinberg", "--method", "-m", metavar=metavar(METHOD_NAMES),
                               help="How to halftone (docs/halftone.md)."),
    input_encoding: str = typer.Option(
        "auto", "--input-encoding", metavar=metavar(INPUT_ENCODING_NAMES),
        help="How pixel values are encoded; auto: sRGB for 8/16-bit files, linear for "
             "float files (EXR)."),
    gamut: str = typer.Option("scale", "--gamut", metavar=metavar(GAMUT_NAMES),
                              help="Where r+g+b > 1: scale (divide by the sum) or clip "
                                   "(nearest in-gamut coverage)."),
    size: Optional[str] = typer.Option(None, "--size-px", "--size", metavar="WxH",
                                       help="Resample to this many pixels first."),
    dpi: Optional[float] = typer.Option(None, "--dpi", metavar="DPI",
                                        help="Resample to this resolution (needs "
                                             "--print-width-mm)."),
    print_width_mm: Optional[float] = typer.Option(None, "--print-width-mm", metavar="MM",
                                                   help="Width of the print for --dpi."),
    bayer_size: Optional[int] = _method_option(
        "--bayer-size", "bayer: matrix size, a power of two (default 8)."),
    cell_size: Optional[int] = _method_option(
        "--cell-size", "clustered: cell in pixels, even (default 8; dots N/sqrt(2) px apart "
                       "at 45 degrees)."),
    mask_size: Optional[int] = _method_option(
        "--mask-size", "blue-noise: void-and-cluster mask size (default 64)."),
    split: bool = typer.Option(False, "--split",
                               help="Also write one screen per ink: MASK.red.png, "
                                    "MASK.green.png, MASK.blue.png (0/255, 255 = ink)."),
    report: Optional[Path] = typer.Option(None, "--report", metavar="REPORT.json",
                                          help="Write coverage per ink, tone error, "
                                               "out-of-gamut fraction and times (the tone "
                                               "error is computed only for the report)."),
    compress: str = typer.Option("fast", "--compress", metavar=metavar(COMPRESSION_NAMES),
                                 help="PNG deflate level, lossless: "
                                      f"{', '.join(COMPRESSION_NAMES)} (zlib 0, 1, 6, 9)."),
    mask_format: str = typer.Option("palette", "--mask-format", metavar=metavar(MASK_FORMAT_NAMES),
                                    help="How the mask PNG stores its RGB pixels: palette "
                                         "(2 bits per pixel, fast) or rgb (8-bit "
                                         "truecolour); both decode to the same RGB image."),
) -> None:
    """Halftone an image into exclusive R/G/B ink masks (seed 000, Figure 6).

    \b
    Example:
      gonio halftone photo.png -o print.png --method floyd-steinberg --report print.json
      gonio halftone photo.exr -o print.png --dpi 300 --print-width-mm 120 --split
    """
    # lazy: gonio --help and other commands do not load halftone.run (benchmarks/bench_startup.py)
    from ..halftone import run as stage

    options = stage.HalftoneOptions(method, input_encoding, gamut, size, dpi, print_width_mm,
                                    bayer_size, cell_size, mask_size, split, report is not None,
                                    compress, mask_format)
    stage.check_options(options, output)        # options first: a typo costs nothing
    declare(stage.outputs(output, report, split), [image])
    result = stage.run(image, options)
    stage.write(result, image, output, report)
    for note in result.notes:
        log.info(note)
    log.info(stage.summary_line(output, result))


EXAMPLE = ("gonio halftone photo.png -o print.png --method floyd-steinberg --report "
           "print.json")


def register(app: typer.Typer) -> None:
    app.command("halftone")(halftone)
