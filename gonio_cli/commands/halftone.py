"""``gonio halftone``: the thin shell over :mod:`gonio_cli.halftone`."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from ..names import COMPRESSION_NAMES, GAMUT_NAMES, INPUT_ENCODING_NAMES, MASK_FORMAT_NAMES
from ..names import HALFTONE_METHOD_NAMES as METHOD_NAMES
from ..names import metavar, pick


def _write_palette(path: Path, labels, metadata: dict, compression: str) -> None:
    from ..halftone import PALETTE
    from ..imageio import write_png_indexed

    write_png_indexed(path, labels, PALETTE, metadata, compression=compression)


def _write_rgb(path: Path, labels, metadata: dict, compression: str) -> None:
    from ..halftone import labels_to_mask
    from ..imageio import write_png

    write_png(path, labels_to_mask(labels), metadata, compression=compression)


#: ``--mask-format``: how the mask PNG stores its RGB pixels (both decode to the same RGB
#: image, channels 0/255). ``palette``: a 2-bit paletted PNG (4 pixels a byte; a 4096² mask
#: encodes in ~0.15 s where 8-bit RGB takes ~1 s at the same --compress); ``rgb``: 8-bit
#: truecolour, for tools that read a paletted PNG's indices instead of its colours (Pillow's
#: Image.open without .convert("RGB")).
MASK_WRITERS = {"palette": _write_palette, "rgb": _write_rgb}


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
    bayer_size: Optional[int] = typer.Option(None, "--bayer-size", metavar="N",
                                             help="bayer: matrix size, a power of two "
                                                  "(default 8)."),
    cell_size: Optional[int] = typer.Option(None, "--cell-size", metavar="N",
                                            help="clustered: cell in pixels, even "
                                                 "(default 8; dots N/sqrt(2) px apart at "
                                                 "45 degrees)."),
    mask_size: Optional[int] = typer.Option(None, "--mask-size", metavar="N",
                                            help="blue-noise: void-and-cluster mask size "
                                                 "(default 64)."),
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
    from .. import log
    from .. import halftone as core
    from ..artifact import image_metadata, make_document, write_json
    from ..errors import InputError
    from ..halftone import coverage as cov
    from ..imageio import get_compression, read_image, write_png_1bit

    # options first, so a typo costs nothing and nothing is written
    m = core.get_method(method)
    params = core.resolve_parameters(m, {"bayer_size": bayer_size, "cell_size": cell_size,
                                         "mask_size": mask_size})
    get_compression(compress)
    pick(MASK_WRITERS, mask_format, "--mask-format")
    if output.suffix.lower() != ".png":
        raise InputError("the mask must be a PNG", path=output, fix="name it *.png")
    if size is not None and (dpi is not None or print_width_mm is not None):
        raise InputError("--size-px and --dpi/--print-width-mm both set the print size",
                         fix="give one of them")
    if (dpi is None) != (print_width_mm is None):
        raise InputError("--dpi and --print-width-mm go together",
                         fix="give both, or --size-px WxH")
    target_size = cov.parse_size(size) if size is not None else None
    from ..outputs import declare
    declare({"-o": output, "--report": report,
             **{f"--split ({ink})": p for ink, p in
                zip(core.INKS, split_paths(output) if split else [])}},
            [image])
    img = read_image(image, keep_integers=True)     # 8/16-bit files as stored: no float copy
    if dpi is not None:
        target_size = cov.size_from_dpi(dpi, print_width_mm, img.pixels.shape[:2])
    from .. import memory

    width, height = target_size or (img.pixels.shape[1], img.pixels.shape[0])
    memory.check(core.memory_estimate(width, height), f"a {width}x{height} halftone", path=image,
          fix="lower --size-px (or --dpi)" if size or dpi else "resample it first with --size-px")
    with log.timer() as t:
        prepared, result = core.prepare_and_halftone(
            img.pixels, is_float=img.is_float, encoding=input_encoding, gamut=gamut,
            size=target_size, method=m.name, keep_coverage=report is not None, path=image,
            **params)
        del img                                  # the decoded file is no longer needed
    if report is not None:
        payload = core.evaluate(result, prepared)
    else:
        payload = core.summarize(result, prepared)
    prepared.coverage = None                     # free it before the PNGs are encoded
    parameters = {"method": m.name, **params, "input_encoding": input_encoding,
                  "gamut": gamut, "size": size, "dpi": dpi, "print_width_mm": print_width_mm,
                  "split": split, "compress": compress, "mask_format": mask_format}
    screens = split_paths(output) if split else []
    payload.update(mask=str(output), split=[str(p) for p in screens])
    meta = image_metadata(core.MASK_SCHEMA, core.MASK_SCHEMA_VERSION, inputs=[image],
                          parameters=parameters, method=m.name, time_s=round(t["time_s"], 6))
    MASK_WRITERS[mask_format](output, result.labels, meta, compress)
    for k, path in enumerate(screens):
        write_png_1bit(path, result.labels == k + 1, {**meta, "ink": core.INKS[k]},
                       compression=compress)
    if report is not None:
        write_json(report, make_document(core.REPORT_SCHEMA, core.REPORT_SCHEMA_VERSION,
                                         payload, inputs=[image], parameters=parameters,
                                         time_s=t["time_s"]))
    if prepared.out_of_gamut_fraction > 0:
        log.info(f"{image}: {100 * prepared.out_of_gamut_fraction:.1f} % of the pixels were "
                 f"out of gamut (r+g+b > 1), mapped by --gamut {gamut}")
    log.info(summary_line(output, payload, result))


#: How the summary line names the kernel's start-up cost, by :func:`kernel_status`.
KERNEL_NOTES = {"c": "C kernel load",
                "cache": "numba start-up, kernel from cache",
                "compiled": "JIT compile, now cached",
                "compiled-uncached": "JIT compile, no writable numba cache"}


#: A kernel start-up shorter than this is not worth a word (the C build: ~0.1 ms).
STARTUP_SHOWN_S = 0.05


def summary_line(output: Path, payload: dict, result) -> str:
    """One line from numbers already computed: size, coverage per ink against target,
    the tone error if the report computed it, the core time and the kernel's start-up."""
    from ..halftone import INKS, TONE_SIGMA_PX

    cover = " ".join(f"{ink[0].upper()}={100 * a:.2f}%(target {100 * c:.2f}%)"
                     for ink, a, c in zip(INKS, payload["coverage_mask"],
                                          payload["coverage_target"]))
    tone = (f" tone RMSE {payload['tone_rmse']:.4f} (σ={TONE_SIGMA_PX:g} px)"
            if "tone_rmse" in payload else "")
    startup = ""
    if result.compile_time_s >= STARTUP_SHOWN_S:
        note = KERNEL_NOTES.get(result.info.get("kernel", ""), "numba start-up")
        startup = f" (+{result.compile_time_s:.1f} s {note})"
    return (f"{output}: {payload['method']} {payload['width_px']}x{payload['height_px']} "
            f"{cover}{tone} {1e3 * result.time_s:.0f} ms{startup}")

EXAMPLE = ("gonio halftone photo.png -o print.png --method floyd-steinberg --report "
           "print.json")


def register(app: typer.Typer) -> None:
    app.command("halftone")(halftone)
