"""Image files: read any format OpenImageIO knows, write PNG/EXR atomically.

Arrays are (row, column, channel), row 0 the top (docs/conventions.md). Reading returns float32
values as stored (8/16-bit integers scaled to [0, 1]; no colour decoding: the caller
decides what the numbers mean, e.g. sRGB-encoded PNG vs linear EXR), or, on request, the
stored 8/16-bit integers themselves. EXR outputs carry gonio metadata (schema, version,
parameters) as string attributes (STYLE 13); times go to the command's JSON and run
report, never into an image (docs/conventions.md, "Files and errors").

Writers take a ``compression`` level by name (:data:`COMPRESSION`); all of them are
lossless. The same pixels and metadata give the same bytes: PNG files carry no time at
all, and EXR headers a ``DateTime`` only where the ``SOURCE_DATE_EPOCH`` environment
variable is set (the reproducible-builds convention,
https://reproducible-builds.org/specs/source-date-epoch/): that moment in UTC.
"""

from __future__ import annotations

import datetime as _dt
import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from . import __version__
from .artifact import atomic_path, check_finite
from .errors import InputError
from .names import pick
from .outputs import readable
from .runrecord import drop_timings, portable
from .spectra import rgb_space_chromaticities

#: Prefix of gonio's metadata attributes in image headers.
META_PREFIX = "gonio:"

#: The environment variable of the reproducible-builds standard: seconds since
#: 1970-01-01T00:00:00Z, used instead of the current time in EXR headers.
SOURCE_DATE_EPOCH_ENV = "SOURCE_DATE_EPOCH"

#: Stored integer formats :func:`read_image` can return as such (``keep_integers``).
INTEGER_FORMATS = {"uint8": np.uint8, "uint16": np.uint16}


@dataclass(frozen=True)
class Compression:
    """A lossless compression level, for each format a writer supports.

    Attributes
    ----------
    png_zlib_level : int
        zlib level 0–9 of PNG's IDAT stream (libpng's and Pillow's default is 6).
    exr_codec : str
        OpenEXR codec as OpenImageIO names it (``zip`` is OpenImageIO's default; ``zip:N``
        sets the deflate level).
    help : str
    """

    png_zlib_level: int
    exr_codec: str
    help: str
    #: zlib strategy of the PNGs Pillow writes (masks, paletted and 1-bit images), or None
    #: for zlib's default; OpenImageIO's PNG writer has no such setting
    png_zlib_strategy: int | None = None


#: Named compression levels, lossless all. ``balanced`` is what the libraries do by default
#: (every file written before these levels existed is reproduced byte for byte);
#: ``fast`` deflates at level 1: a 4096² RGB mask encodes ~4× faster than ``balanced``
#: for a file ~1.6× larger.
COMPRESSION: dict[str, Compression] = {
    "none": Compression(0, "none", "stored uncompressed (largest files, least CPU)"),
    # Z_RLE (= 3, zlib.h) matches runs only: a 4096² Floyd–Steinberg mask (2-bit
    # paletted) deflates in 0.12 s instead of 0.17 s, for 3 % more bytes
    "fast": Compression(1, "zip:1", "deflate level 1 (PNG masks: run-length matching)",
                        png_zlib_strategy=3),
    "balanced": Compression(6, "zip", "deflate level 6, the libraries' default"),
    "small": Compression(9, "zip:9", "deflate level 9 (smallest, slowest)"),
}

#: The writers' default level (the libraries' own, see :data:`COMPRESSION`); stages that
#: write large images pass ``"fast"`` (``gonio halftone --compress``).
DEFAULT_COMPRESSION = "balanced"


def get_compression(name: str, flag: str = "--compress") -> Compression:
    """The level called ``name``; an unknown name gets the list of valid ones."""
    return pick(COMPRESSION, name, flag)


def header_date_time(source_date_epoch: int | str | None = None) -> str | None:
    """The ``DateTime`` for an image header, ``"YYYY:MM:DD HH:MM:SS"`` (TIFF/EXIF form,
    what OpenImageIO writes), UTC.

    ``source_date_epoch`` (seconds since 1970-01-01T00:00:00Z) or else the
    ``SOURCE_DATE_EPOCH`` environment variable; None when neither is set (the writer then
    writes no date).

    >>> header_date_time(0)
    '1970:01:01 00:00:00'
    """
    given = source_date_epoch
    if given is None:
        given = os.environ.get(SOURCE_DATE_EPOCH_ENV)
        if given is None or given == "":
            return None
    text = str(given).strip()
    if not text.isdigit():
        raise InputError(f"{SOURCE_DATE_EPOCH_ENV}={given!r} is not a number of seconds "
                         "since 1970-01-01 UTC",
                         fix="set it to a non-negative integer, e.g. "
                             "$(git log -1 --format=%ct), or unset it")
    try:
        moment = _dt.datetime.fromtimestamp(int(text), _dt.timezone.utc)
    except (OverflowError, OSError, ValueError):
        raise InputError(f"{SOURCE_DATE_EPOCH_ENV}={given!r} is out of range",
                         fix="give seconds since 1970-01-01 UTC before the year 10000"
                         ) from None
    return moment.strftime("%Y:%m:%d %H:%M:%S")


@dataclass
class Image:
    """Pixels (H, W, C) plus what the file said about them: float32, or the stored
    uint8/uint16 values when read with ``keep_integers``."""

    pixels: np.ndarray
    path: str
    format: str                       # OIIO type of the stored channels: uint8, half, float…
    channel_names: list[str] = field(default_factory=list)
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def is_float(self) -> bool:
        """True if the file stores floating-point values (EXR, HDR): linear by convention."""
        return self.format in ("half", "float", "double")


def read_image(path: str | os.PathLike, *, keep_integers: bool = False) -> Image:
    """Read an image (PNG, JPEG, TIFF, EXR, HDR/RGBE, …) as (H, W, C).

    Pixels are float32 (integers scaled to [0, 1]); with ``keep_integers`` an 8- or 16-bit
    file is returned as its stored uint8/uint16 values instead (a quarter or half of the
    memory, decoded once, no float copy). Raises :class:`InputError` naming the file for a
    missing or unreadable image.
    """
    import OpenImageIO as oiio

    path = os.fspath(path)
    if not Path(path).is_file():
        raise InputError("no such image file", path=path, fix="check the path")
    inp = oiio.ImageInput.open(path)
    if inp is None:
        msg = oiio.geterror().strip().splitlines()
        raise InputError(f"cannot read it as an image ({msg[-1] if msg else 'unknown format'})",
                         path=path, fix="use PNG, JPEG, TIFF, EXR or HDR")
    try:
        spec = inp.spec()
        stored = str(spec.format)
        as_type = stored if keep_integers and stored in INTEGER_FORMATS else "float"
        pixels = inp.read_image(0, 0, 0, spec.nchannels, as_type)
        if pixels is None:
            raise InputError(f"cannot decode its pixels ({inp.geterror().strip()})", path=path)
        meta = {}
        for attr in spec.extra_attribs:
            if attr.name.startswith(META_PREFIX):
                meta[attr.name[len(META_PREFIX):]] = attr.value
        dtype = INTEGER_FORMATS.get(as_type, np.float32)
        return Image(np.asarray(pixels, dtype=dtype).reshape(
                         spec.height, spec.width, spec.nchannels),
                     path, stored, list(spec.channelnames), meta)
    finally:
        inp.close()


def _with_version(metadata: Mapping[str, Any] | None, path: str | os.PathLike
                  ) -> dict[str, Any]:
    """The metadata to write at ``path``: ``gonio_version`` first (once, whether or not
    the caller's :func:`gonio_cli.artifact.image_metadata` has it), then the caller's keys,
    reproducibly (:mod:`gonio_cli.runrecord`): no times (``time_s``, ``…_time_s``: the
    command's JSON and run report have them), paths relative to the image's folder."""
    return portable(drop_timings({"gonio_version": __version__, **(metadata or {})}), path)


def _meta_text(value: Any) -> str:
    return value if isinstance(value, str) else json.dumps(value, allow_nan=False)


#: Header attributes that need an explicit OpenImageIO type (name → type).
TYPED_ATTRIBUTES = {"chromaticities": "float[8]"}


def _write(path: str | os.PathLike, pixels: np.ndarray, fmt: str,
           metadata: Mapping[str, Any] | None, attributes: Mapping[str, Any],
           channel_names: Sequence[str] | None = None) -> None:
    import OpenImageIO as oiio

    a = np.asarray(pixels)
    if a.ndim == 2:
        a = a[:, :, None]
    h, w, c = a.shape
    spec = oiio.ImageSpec(w, h, c, fmt)
    if channel_names is not None:
        spec.channelnames = tuple(channel_names)
    for key, value in attributes.items():
        if key in TYPED_ATTRIBUTES:
            spec.attribute(key, oiio.TypeDesc(TYPED_ATTRIBUTES[key]), tuple(value))
        else:
            spec.attribute(key, value)
    for key, value in _with_version(metadata, path).items():
        spec.attribute(META_PREFIX + key, _meta_text(value))
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise InputError(f"cannot write ({oiio.geterror().strip()})", path=path)
        ok = out.write_image(np.ascontiguousarray(a))
        out.close()
        if not ok:
            raise InputError(f"cannot write ({out.geterror().strip()})", path=path)


def write_png(path: str | os.PathLike, pixels: np.ndarray,
              metadata: Mapping[str, Any] | None = None, *,
              compression: str = DEFAULT_COMPRESSION) -> None:
    """Write 8-bit PNG atomically. ``pixels``: uint8 (H, W[, C]), or float in [0, 1]
    (rounded; the caller has already encoded it, e.g. sRGB). ``compression``: a key of
    :data:`COMPRESSION`."""
    level = get_compression(compression, "compression").png_zlib_level
    a = np.asarray(pixels)
    if a.dtype != np.uint8:
        check_finite(a, "the image", path)
        a = np.round(np.clip(a, 0.0, 1.0) * 255.0).astype(np.uint8)
    _write(path, a, "uint8", metadata, {"png:compressionLevel": level})


def _write_pillow_png(path: str | os.PathLike, image, metadata: Mapping[str, Any] | None,
                      compression: str) -> None:
    """Save a Pillow image as PNG atomically, metadata in tEXt chunks with the same
    ``gonio:`` keys as OpenImageIO writes (so :func:`read_image` returns them)."""
    from PIL.PngImagePlugin import PngInfo

    chosen = get_compression(compression, "compression")
    level = chosen.png_zlib_level
    strategy = {} if chosen.png_zlib_strategy is None else {
        "compress_type": chosen.png_zlib_strategy}
    info = PngInfo()
    for key, value in _with_version(metadata, path).items():
        info.add_text(META_PREFIX + key, _meta_text(value))
    with atomic_path(path) as tmp:
        image.save(tmp, format="PNG", pnginfo=info, compress_level=level, optimize=False,
                   **strategy)


#: The level of animated previews (:func:`write_apng`): a preview is looked at, not kept
#: as the record (the frames are), and deflate level 1 writes four 1024² frames in 0.19 s
#: instead of 0.47 s, for a file 1.5× larger.
PREVIEW_COMPRESSION = "fast"


def write_apng(path: str | os.PathLike, frames: Sequence[str | os.PathLike], *,
               frame_ms: int = 250, metadata: Mapping[str, Any] | None = None,
               compression: str = PREVIEW_COMPRESSION) -> None:
    """Write an animated PNG (APNG, looping) of the PNG files ``frames``, in order,
    atomically; browsers show it in an ``<img>``. ``frame_ms``: each frame's duration;
    ``compression``: a key of :data:`COMPRESSION`."""
    from PIL import Image as PILImage
    from PIL.PngImagePlugin import PngInfo

    images = []
    for f in frames:  # frames this command wrote may still be held back (outputs.py)
        with PILImage.open(readable(f)) as im:
            images.append(im.convert("RGBA" if "A" in im.getbands() else "RGB"))
    info = PngInfo()
    for key, value in _with_version(metadata, path).items():
        info.add_text(META_PREFIX + key, _meta_text(value))
    with atomic_path(path) as tmp:
        images[0].save(tmp, format="PNG", save_all=True, append_images=images[1:],
                       duration=frame_ms, loop=0, pnginfo=info,
                       compress_level=get_compression(compression).png_zlib_level)


def write_png_1bit(path: str | os.PathLike, mask: np.ndarray,
                   metadata: Mapping[str, Any] | None = None, *,
                   compression: str = DEFAULT_COMPRESSION) -> None:
    """Write a boolean (H, W) mask as a true 1-bit greyscale PNG (white = True), atomically.

    OpenImageIO's PNG writer has no 1-bit output, so this uses Pillow (a well-kept
    library matplotlib already depends on). Readers that expand low bit depths (libpng,
    OpenImageIO) see 0 and 255.
    """
    from PIL import Image as PILImage

    _write_pillow_png(path, PILImage.fromarray(np.asarray(mask, dtype=bool)), metadata,
                      compression)


def write_png_indexed(path: str | os.PathLike, indices: np.ndarray,
                      palette: Sequence[Sequence[int]],
                      metadata: Mapping[str, Any] | None = None, *,
                      compression: str = DEFAULT_COMPRESSION) -> None:
    """Write an index image (H, W) uint8 with an RGB ``palette`` (n, 3) as a paletted PNG
    (colour type 3), atomically.

    The bit depth is the smallest that holds the palette (1, 2, 4 or 8 bits: a 4-colour
    palette stores 4 pixels per byte, so a 4096² image is 4 MB before deflate, not the
    48 MB of RGB). Every PNG reader that returns RGB (libpng with expansion, OpenImageIO
    and so :func:`read_image`, browsers, ImageMagick, matplotlib) decodes it to the
    palette's colours; Pillow's ``Image.open`` keeps mode ``P`` until ``.convert("RGB")``.
    """
    from PIL import Image as PILImage

    idx = np.ascontiguousarray(indices, dtype=np.uint8)
    pal = np.asarray(palette, dtype=np.uint8)
    if idx.ndim != 2 or pal.ndim != 2 or pal.shape[1] != 3 or not 1 <= len(pal) <= 256:
        raise ValueError(f"indices {idx.shape} must be (H, W) and palette {pal.shape} (n, 3)")
    if idx.size and int(idx.max()) >= len(pal):
        raise ValueError(f"index {int(idx.max())} is outside the {len(pal)}-colour palette")
    h, w = idx.shape
    image = PILImage.frombuffer("P", (w, h), idx, "raw", "P", 0, 1)
    image.putpalette(pal.ravel().tolist())
    _write_pillow_png(path, image, metadata, compression)


def write_exr(path: str | os.PathLike, pixels: np.ndarray,
              metadata: Mapping[str, Any] | None = None, *,
              compression: str = DEFAULT_COMPRESSION,
              source_date_epoch: int | None = None,
              chromaticities: Sequence[float] | None = None,
              channel_names: Sequence[str] | None = None,
              allow_nonfinite: bool = False) -> None:
    """Write float32 EXR atomically (scene-referred linear values, docs/conventions.md).

    A NaN or inf texel (also a value beyond float32) is refused with
    :class:`~gonio_cli.errors.NumericError` naming the file, unless ``allow_nonfinite``
    (for a test that makes a broken map on purpose).

    ``compression``: a key of :data:`COMPRESSION` (all lossless). The header has a
    ``DateTime`` only when ``source_date_epoch`` or the ``SOURCE_DATE_EPOCH`` environment
    variable gives one (:func:`header_date_time`): no run's time is written. ``chromaticities``: CIE xy
    of R, G, B and white (8 floats), the standard attribute naming the colour space;
    ``channel_names``: e.g. ``("X", "Y", "Z")`` (default R, G, B, A).
    """
    attributes: dict[str, Any] = {
        "compression": get_compression(compression, "compression").exr_codec}
    # an empty DateTime: OpenImageIO then writes none (it would stamp the current time)
    attributes["DateTime"] = header_date_time(source_date_epoch) or ""
    if chromaticities is not None:
        attributes["chromaticities"] = [float(v) for v in chromaticities]
    with np.errstate(over="ignore"):  # a value beyond float32 becomes inf: refused next
        a = np.asarray(pixels, dtype=np.float32)
    if not allow_nonfinite:
        check_finite(a, "the image (float32)", path)
    _write(path, a, "float", metadata, attributes, channel_names)


#: OpenEXR codec of the spectral EXR: PIZ (lossless wavelet + Huffman, every OpenEXR
#: reader has it). Measured on seed 000 Figure 5's 480² × 41 spectra: 17.9 MB, the
#: compression adding ~0 s to the write, against 18.1 MB and ~3 s for zip (a loaded
#: 2-core machine); most of the rest of the write is colour-science's building of the
#: image one channel at a time.
SPECTRAL_EXR_CODEC = "piz"

#: The units of the spectral EXR's values as the spectral layout names them
#: (``emissiveUnits``, Fichet et al. 2021 §3; the only units the layout defines).
SPECTRAL_EXR_UNITS = "W.m^-2.sr^-1"


def write_spectral_exr(path: str | os.PathLike, spectra: np.ndarray, wavelength_nm,
                       preview_rgb: np.ndarray, metadata: Mapping[str, Any] | None = None
                       ) -> None:
    """Write spectral radiance (H, W, n_λ) as a spectral OpenEXR (Fichet et al. 2021,
    "An OpenEXR layout for spectral images", JCGT 10(3)), atomically.

    The layout (one ``S0.<λ>nm`` channel per wavelength, ``spectralLayoutVersion``,
    ``emissiveUnits``, ``polarisationHandedness``) is written by colour-science's
    ``colour.io.write_spectral_image_Fichet2021``, imported here only. Its R, G, B
    channels are ``preview_rgb`` (H, W, 3), linear sRGB (the header's ``chromaticities``
    says so) — gonio's own colour image instead of colour-science's preview, which is
    exposure-normalised and undefined for a black image. ``metadata`` goes into
    ``gonio:`` string attributes as :func:`write_exr` writes them; float32 values,
    :data:`SPECTRAL_EXR_CODEC` compression (lossless).
    """
    from colour.io import (Image_Specification_Attribute, Specification_Fichet2021,
                           write_spectral_image_Fichet2021)
    from OpenImageIO import TypeDesc

    with np.errstate(over="ignore"):  # a value beyond float32 becomes inf: refused next
        values = np.asarray(spectra, dtype=np.float32)
    check_finite(values, "the spectral image (float32)", path)
    ours = [Image_Specification_Attribute(META_PREFIX + k, _meta_text(v))
            for k, v in _with_version(metadata, path).items()]
    ours.append(Image_Specification_Attribute(
        "chromaticities", list(rgb_space_chromaticities("srgb")), TypeDesc("float[8]")))
    ours.append(Image_Specification_Attribute("compression", SPECTRAL_EXR_CODEC))
    ours.append(Image_Specification_Attribute("DateTime", header_date_time() or ""))

    def preview(components, specification):
        return np.asarray(preview_rgb, dtype=np.float32), ours

    # attributes=None: colour-science writes the layout's own attributes
    specification = Specification_Fichet2021(is_emissive=True, attributes=None)
    components = {"S0": (np.asarray(wavelength_nm, dtype=float), values)}
    with atomic_path(path) as tmp:
        if not write_spectral_image_Fichet2021(components, tmp, "float32", specification,
                                               preview):
            raise InputError("cannot write the spectral EXR", path=path)
