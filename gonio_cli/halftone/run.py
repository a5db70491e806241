"""``gonio halftone`` as a library call: an image file in, the ink mask (and the per-ink
screens and the report) out.

:func:`check_options` refuses bad options before anything is read or written;
:func:`run` reads the image, checks the memory, halftones it (:func:`gonio_cli.halftone.
prepare_and_halftone`) and returns the labels with the report's payload; :func:`write`
writes the mask (:data:`MASK_WRITERS`), the screens and the report. The shell
:mod:`gonio_cli.commands.halftone` parses the options, declares the outputs and calls these.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import artifact, memory
from ..errors import InputError
from ..imageio import get_compression, read_image, write_png, write_png_1bit, write_png_indexed
from ..names import pick
from . import (INKS, MASK_SCHEMA, MASK_SCHEMA_VERSION, PALETTE, REPORT_SCHEMA,
               REPORT_SCHEMA_VERSION, TONE_SIGMA_PX, Halftone, Method, Prepared, evaluate,
               get_method, labels_to_mask, memory_estimate, prepare_and_halftone,
               resolve_parameters, summarize)
from .coverage import parse_size, size_from_dpi


def _write_palette(path: Path, labels, metadata: dict, compression: str) -> None:
    write_png_indexed(path, labels, PALETTE, metadata, compression=compression)


def _write_rgb(path: Path, labels, metadata: dict, compression: str) -> None:
    write_png(path, labels_to_mask(labels), metadata, compression=compression)


#: ``--mask-format``: how the mask PNG stores its RGB pixels (both decode to the same RGB
#: image, channels 0/255). ``palette``: a 2-bit paletted PNG (4 pixels a byte; a 4096² mask
#: encodes in ~0.15 s where 8-bit RGB takes ~1 s at the same --compress); ``rgb``: 8-bit
#: truecolour, for tools that read a paletted PNG's indices instead of its colours (Pillow's
#: Image.open without .convert("RGB")).
MASK_WRITERS = {"palette": _write_palette, "rgb": _write_rgb}

#: How the summary line names the kernel's start-up cost, by :func:`.diffusion.kernel_status`.
KERNEL_NOTES = {"c": "C kernel load",
                "cache": "numba start-up, kernel from cache",
                "compiled": "JIT compile, now cached",
                "compiled-uncached": "JIT compile, no writable numba cache"}

#: A kernel start-up shorter than this is not worth a word (the C build: ~0.1 ms).
STARTUP_SHOWN_S = 0.05


@dataclass(frozen=True)
class HalftoneOptions:
    """The options of ``gonio halftone`` (their help is the shell's). ``size`` is
    ``"WxH"``; ``report`` asks for the tone error (:func:`gonio_cli.halftone.evaluate`)."""

    method: str = "floyd-steinberg"
    input_encoding: str = "auto"
    gamut: str = "scale"
    size: str | None = None
    dpi: float | None = None
    print_width_mm: float | None = None
    bayer_size: int | None = None
    cell_size: int | None = None
    mask_size: int | None = None
    split: bool = False
    report: bool = False
    compress: str = "fast"
    mask_format: str = "palette"

    def given_parameters(self) -> dict[str, int | None]:
        """The method's options as given (None: not given)."""
        return {"bayer_size": self.bayer_size, "cell_size": self.cell_size,
                "mask_size": self.mask_size}


@dataclass
class HalftoneRun:
    """What :func:`run` made: the halftone, how its target was prepared (the coverage
    itself dropped), the report's payload, the artifact's parameters and the masks'
    metadata, the time (s) and what to say about the input (``notes``)."""

    result: Halftone
    prepared: Prepared
    payload: dict[str, Any]
    parameters: dict[str, Any]
    metadata: dict[str, Any]
    time_s: float
    notes: list[str] = field(default_factory=list)


def split_paths(output: Path) -> list[Path]:
    """``print.png`` → ``print.red.png``, ``print.green.png``, ``print.blue.png``."""
    return [output.with_name(f"{output.stem}.{ink}{output.suffix}") for ink in INKS]


def outputs(output: Path, report: Path | None, split: bool) -> dict[str, Path | None]:
    """Every file a run writes, by the option that names it (for the outputs' transaction,
    :func:`gonio_cli.outputs.declare`)."""
    return {"-o": output, "--report": report,
            **{f"--split ({ink})": p for ink, p in
               zip(INKS, split_paths(output) if split else [])}}


def check_options(options: HalftoneOptions, output: Path | None = None
                  ) -> tuple[Method, dict[str, int]]:
    """The method and its parameters, after refusing any bad option and an ``output`` that
    is not a PNG (a typo costs nothing and nothing is written)."""
    m = get_method(options.method)
    params = resolve_parameters(m, options.given_parameters())
    get_compression(options.compress)
    pick(MASK_WRITERS, options.mask_format, "--mask-format")
    if output is not None and output.suffix.lower() != ".png":
        raise InputError("the mask must be a PNG", path=output, fix="name it *.png")
    if options.size is not None and (options.dpi is not None
                                     or options.print_width_mm is not None):
        raise InputError("--size-px and --dpi/--print-width-mm both set the print size",
                         fix="give one of them")
    if (options.dpi is None) != (options.print_width_mm is None):
        raise InputError("--dpi and --print-width-mm go together",
                         fix="give both, or --size-px WxH")
    if options.size is not None:
        parse_size(options.size)
    return m, params


def run(image: str | os.PathLike, options: HalftoneOptions = HalftoneOptions()) -> HalftoneRun:
    """Halftone an image file into exclusive R/G/B ink labels (seed 000, Figure 6).

    Parameters
    ----------
    image : path of a PNG, JPEG, TIFF or EXR with R, G, B channels.
    options : :class:`HalftoneOptions`.

    Raises
    ------
    GonioError
        A bad option, an unreadable image, or a print too large for the memory.
    """
    m, params = check_options(options)
    target_size = parse_size(options.size) if options.size is not None else None
    img = read_image(image, keep_integers=True)     # 8/16-bit files as stored: no float copy
    if options.dpi is not None:
        target_size = size_from_dpi(options.dpi, options.print_width_mm, img.pixels.shape[:2])
    width, height = target_size or (img.pixels.shape[1], img.pixels.shape[0])
    memory.check(memory_estimate(width, height), f"a {width}x{height} halftone", path=image,
                 fix="lower --size-px (or --dpi)" if options.size or options.dpi
                 else "resample it first with --size-px")
    start = time.perf_counter()
    prepared, result = prepare_and_halftone(
        img.pixels, is_float=img.is_float, encoding=options.input_encoding,
        gamut=options.gamut, size=target_size, method=m.name,
        keep_coverage=options.report, path=image, **params)
    del img                                      # the decoded file is no longer needed
    time_s = time.perf_counter() - start
    payload = evaluate(result, prepared) if options.report else summarize(result, prepared)
    prepared.coverage = None                     # free it before the PNGs are encoded
    parameters = {"method": m.name, **params, "input_encoding": options.input_encoding,
                  "gamut": options.gamut, "size": options.size, "dpi": options.dpi,
                  "print_width_mm": options.print_width_mm, "split": options.split,
                  "compress": options.compress, "mask_format": options.mask_format}
    meta = artifact.image_metadata(MASK_SCHEMA, MASK_SCHEMA_VERSION, inputs=[image],
                          parameters=parameters, method=m.name, time_s=round(time_s, 6))
    notes = []
    if prepared.out_of_gamut_fraction > 0:
        notes.append(f"{image}: {100 * prepared.out_of_gamut_fraction:.1f} % of the pixels "
                     f"were out of gamut (r+g+b > 1), mapped by --gamut {options.gamut}")
    return HalftoneRun(result, prepared, payload, parameters, meta, time_s, notes)


def write(halftone: HalftoneRun, image: str | os.PathLike, output: Path,
          report: Path | None = None) -> None:
    """Write the mask of :func:`run` to ``output`` (and, with the run's ``split``, one
    screen per ink beside it; with ``report``, the ``gonio.halftone-report``)."""
    p = halftone.parameters
    screens = split_paths(output) if p["split"] else []
    halftone.payload.update(mask=str(output), split=[str(s) for s in screens])
    labels = halftone.result.labels
    MASK_WRITERS[p["mask_format"]](output, labels, halftone.metadata, p["compress"])
    for k, path in enumerate(screens):
        write_png_1bit(path, labels == k + 1, {**halftone.metadata, "ink": INKS[k]},
                       compression=p["compress"])
    if report is not None:
        # artifact.write_json looked up at the call: tests/test_outputs.py replaces it
        artifact.write_json(report, artifact.make_document(
            REPORT_SCHEMA, REPORT_SCHEMA_VERSION, halftone.payload, inputs=[image],
            parameters=p, time_s=halftone.time_s))


def summary_line(output: Path, halftone: HalftoneRun) -> str:
    """One line from numbers already computed: size, coverage per ink against target,
    the tone error if the report computed it, the core time and the kernel's start-up."""
    payload, result = halftone.payload, halftone.result
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
