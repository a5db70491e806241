"""Image files through OpenImageIO: read any format it knows, write PNG/EXR atomically.

Arrays are (row, column, channel), row 0 the top (docs/conventions.md). Reading returns float32
values as stored (8/16-bit integers scaled to [0, 1]; no colour decoding: the caller
decides what the numbers mean, e.g. sRGB-encoded PNG vs linear EXR). EXR outputs carry
gonio metadata (schema, version, parameters, time) as string attributes, as pbrt writes
its render time into its EXRs (STYLE 13).
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from . import __version__
from .artifact import atomic_path
from .errors import InputError

#: Prefix of gonio's metadata attributes in image headers.
META_PREFIX = "gonio:"


@dataclass
class Image:
    """Pixels (H, W, C) float32 plus what the file said about them."""

    pixels: np.ndarray
    path: str
    format: str                       # OIIO type of the stored channels: uint8, half, float…
    channel_names: list[str] = field(default_factory=list)
    metadata: dict[str, Any] = field(default_factory=dict)

    @property
    def is_float(self) -> bool:
        """True if the file stores floating-point values (EXR, HDR): linear by convention."""
        return self.format in ("half", "float", "double")


def read_image(path: str | os.PathLike) -> Image:
    """Read an image (PNG, JPEG, TIFF, EXR, HDR/RGBE, …) as float32 (H, W, C).

    Raises :class:`InputError` naming the file for a missing or unreadable image.
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
        pixels = inp.read_image(0, 0, 0, spec.nchannels, "float")
        if pixels is None:
            raise InputError(f"cannot decode its pixels ({inp.geterror().strip()})", path=path)
        meta = {}
        for attr in spec.extra_attribs:
            if attr.name.startswith(META_PREFIX):
                meta[attr.name[len(META_PREFIX):]] = attr.value
        return Image(np.asarray(pixels, dtype=np.float32).reshape(
                         spec.height, spec.width, spec.nchannels),
                     path, str(spec.format), list(spec.channelnames), meta)
    finally:
        inp.close()


def _write(path: str | os.PathLike, pixels: np.ndarray, fmt: str,
           metadata: Mapping[str, Any] | None) -> None:
    import OpenImageIO as oiio

    a = np.asarray(pixels)
    if a.ndim == 2:
        a = a[:, :, None]
    h, w, c = a.shape
    spec = oiio.ImageSpec(w, h, c, fmt)
    spec.attribute(META_PREFIX + "gonio_version", __version__)
    for key, value in (metadata or {}).items():
        text = value if isinstance(value, str) else json.dumps(value, allow_nan=False)
        spec.attribute(META_PREFIX + key, text)
    with atomic_path(path) as tmp:
        out = oiio.ImageOutput.create(str(tmp))
        if out is None or not out.open(str(tmp), spec):
            raise InputError(f"cannot write ({oiio.geterror().strip()})", path=path)
        ok = out.write_image(np.ascontiguousarray(a))
        out.close()
        if not ok:
            raise InputError(f"cannot write ({out.geterror().strip()})", path=path)


def write_png(path: str | os.PathLike, pixels: np.ndarray,
              metadata: Mapping[str, Any] | None = None) -> None:
    """Write 8-bit PNG atomically. ``pixels``: uint8 (H, W[, C]), or float in [0, 1]
    (rounded; the caller has already encoded it, e.g. sRGB)."""
    a = np.asarray(pixels)
    if a.dtype != np.uint8:
        a = np.round(np.clip(a, 0.0, 1.0) * 255.0).astype(np.uint8)
    _write(path, a, "uint8", metadata)


def write_png_1bit(path: str | os.PathLike, mask: np.ndarray,
                   metadata: Mapping[str, Any] | None = None) -> None:
    """Write a boolean (H, W) mask as a true 1-bit greyscale PNG (white = True), atomically.

    OpenImageIO's PNG writer has no 1-bit output, so this uses Pillow (a well-kept
    library matplotlib already depends on). Metadata go into tEXt chunks with the same
    ``gonio:`` keys, which :func:`read_image` returns.
    """
    from PIL import Image as PILImage
    from PIL.PngImagePlugin import PngInfo

    info = PngInfo()
    info.add_text(META_PREFIX + "gonio_version", __version__)
    for key, value in (metadata or {}).items():
        info.add_text(META_PREFIX + key,
                      value if isinstance(value, str) else json.dumps(value, allow_nan=False))
    with atomic_path(path) as tmp:
        PILImage.fromarray(np.asarray(mask, dtype=bool)).save(tmp, format="PNG", pnginfo=info)


def write_exr(path: str | os.PathLike, pixels: np.ndarray,
              metadata: Mapping[str, Any] | None = None) -> None:
    """Write float32 EXR atomically (scene-referred linear values, docs/conventions.md)."""
    _write(path, np.asarray(pixels, dtype=np.float32), "float", metadata)
