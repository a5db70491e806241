"""From image pixels to ink coverage: decoding, gamut handling, resampling to print size.

The ink coverage of a channel is its *linear* level (seed 000, "Printing application": a
level of 0.3 of R is 3 of 9 pixels inked): encoded 8/16-bit images are decoded from sRGB
first, float images (EXR) are linear already. Inks are exclusive (at most one per
position, docs/conventions.md), so a coverage must lie in the simplex r, g, b ≥ 0, r + g + b ≤ 1;
:data:`GAMUT_MAPPERS` bring every pixel into it.
"""

from __future__ import annotations

import math
import re

import numpy as np

from ..errors import InputError
from ..names import pick
from ..schemas import MAX_MAGNITUDE
from ..spectra import srgb_decode

#: A pixel counts as out of gamut if r + g + b exceeds 1 by more than this: float32
#: rounding of in-gamut sums (an 8-bit (1, 0, 0) sums to exactly 1), not a colour.
GAMUT_TOLERANCE = 1e-6

#: The float32 sum r + g + b above which a pixel is out of gamut (:func:`out_of_gamut`).
SCALE_LIMIT = np.float32(1.0 + GAMUT_TOLERANCE)

#: Largest output in pixels (2²⁷ ≈ 11 585²): the float32 coverage alone is then 1.6 GB.
MAX_PIXELS = 1 << 27

#: Millimetres per inch, for --dpi with a print width in mm.
MM_PER_INCH = 25.4

INPUT_ENCODINGS = ("auto", "srgb", "linear")


#: Rows converted at a time by :func:`to_coverage`: the float temporaries of a band stay
#: in the CPU cache and never grow with the image (a 4096-wide band is 12 MB of float32).
BAND_ROWS = 256


def check_pixels(px: np.ndarray, path=None) -> None:
    """Refuse an image that is not R, G, B (+ opaque alpha) or has no pixels; an integer
    image's alpha is checked here whole (float images are checked as they are decoded)."""
    _check_channels(px, path)
    if px.shape[2] == 4 and px.dtype.kind in "ui" and not np.all(
            px[:, :, 3] == np.iinfo(px.dtype).max):
        raise _transparent(path)


def _check_channels(px: np.ndarray, path) -> None:
    channels = px.shape[2] if px.ndim == 3 else 1
    if px.ndim != 3 or channels not in (3, 4):
        raise InputError(f"has {channels} channel{'s' if channels != 1 else ''}, "
                         "halftoning needs R, G, B (3 channels, or 4 with an opaque alpha)",
                         path=path, fix="convert it to RGB")
    if px.shape[0] == 0 or px.shape[1] == 0:
        raise InputError("is empty (0 pixels)", path=path)


def check_encoding(encoding: str, is_float: bool) -> str:
    pick(INPUT_ENCODINGS, encoding, "--input-encoding")
    return ("linear" if is_float else "srgb") if encoding == "auto" else encoding


def _transparent(path) -> InputError:
    return InputError("has transparent pixels (alpha < 1); the print has no transparency",
                      path=path, fix="flatten it onto black (bare substrate) or white first")


def _non_finite(count: int, path) -> InputError:
    return InputError(f"has {count} pixels with NaN or infinite values (or beyond "
                      f"±{MAX_MAGNITUDE:g}, docs/conventions.md Numeric ranges)", path=path,
                      fix="fix or clamp them in the source image")


def decode_table(dtype, encoding: str) -> np.ndarray:
    """Linear level of every stored integer value, (2⁸,) or (2¹⁶,) float32.

    The stored value v is scaled to v · float32(1/vmax), as OpenImageIO converts integers to
    float (so a table lookup gives the same float32 numbers as decoding a float copy of
    the image), then decoded from sRGB by :func:`~gonio_cli.spectra.srgb_decode` if
    ``encoding`` is ``srgb``.
    """
    top = np.iinfo(dtype).max
    x = np.arange(top + 1, dtype=np.float32) * np.float32(1.0 / top)
    return srgb_decode(x) if encoding == "srgb" else x


def to_coverage(pixels: np.ndarray, encoding: str, is_float: bool, gamut: str, path=None
                ) -> tuple[np.ndarray, str, float, np.ndarray]:
    """Image pixels (H, W, 3|4) → coverage (H, W, 3) float32 in the simplex, in bands.

    ``pixels`` are float (values as stored, integers scaled to [0, 1]) or the stored
    uint8/uint16 integers themselves (:func:`gonio_cli.imageio.read_image` with
    ``keep_integers``), which are decoded through :func:`decode_table`; the result is the
    same float32 numbers either way. Each band of :data:`BAND_ROWS` rows is decoded
    (``encoding`` as in :func:`linear_rgb`) and mapped into gamut (:data:`GAMUT_MAPPERS`)
    before the next, so the only full-size float array is the result.

    Returns
    -------
    coverage : (H, W, 3) float32
    encoding_used : str
        ``srgb`` or ``linear``.
    out_of_gamut_fraction : float
        Fraction of the pixels outside the simplex before mapping (:func:`out_of_gamut`).
    mean_coverage : (3,) float64
        Mean coverage per ink (R, G, B) of the result.
    """
    used = check_encoding(encoding, is_float)
    pick(GAMUT_MAPPERS, gamut, "--gamut")
    px = np.asarray(pixels)
    _check_channels(px, path)
    integer = px.dtype.kind in "ui"
    if integer:
        table = decode_table(px.dtype, used)
        opaque = np.iinfo(px.dtype).max
    else:
        opaque = 1.0
    mapper = GAMUT_MAPPERS[gamut]
    h, w = px.shape[:2]
    out = np.empty((h, w, 3), dtype=np.float32)
    outside = 0
    bad = 0
    total = np.zeros(3)
    for y0 in range(0, h, BAND_ROWS):
        band = px[y0:y0 + BAND_ROWS]
        if band.shape[2] == 4:
            if not np.all(band[:, :, 3] == opaque):
                raise _transparent(path)
            band = band[:, :, :3]
        if integer:
            rgb = table[band]
        else:
            rgb = np.asarray(band, dtype=np.float32)
            finite = (np.abs(rgb) <= MAX_MAGNITUDE).all(axis=2)   # False for NaN too
            if not finite.all():
                bad += int(finite.size - np.count_nonzero(finite))
                continue
            if used == "srgb":
                rgb = srgb_decode(rgb)
        outside += int(np.count_nonzero(out_of_gamut(rgb)))
        c = out[y0:y0 + BAND_ROWS]
        c[...] = mapper(rgb)
        total += [c[:, :, k].sum(dtype=np.float64) for k in range(3)]
    if bad:
        raise _non_finite(bad, path)
    return out, used, outside / float(h * w), total / float(h * w)


def mean_coverage(coverage: np.ndarray) -> np.ndarray:
    """Mean coverage per ink (R, G, B) of (H, W, 3), (3,) float64 (one strided sum per
    channel: no float64 copy of the image)."""
    c = np.asarray(coverage)
    return np.array([c[:, :, k].sum(dtype=np.float64) for k in range(3)]) / float(
        c.shape[0] * c.shape[1])


def linear_rgb(pixels: np.ndarray, encoding: str, is_float: bool, path=None
               ) -> tuple[np.ndarray, str]:
    """Linear R, G, B (H, W, 3) float32 from image pixels (H, W, 3 or 4), whole.

    ``encoding`` ``auto`` means sRGB for integer files and linear for float files (EXR);
    returns the array and the encoding used. A fourth channel must be an opaque alpha;
    non-finite values are refused. (:func:`to_coverage` does this and the gamut mapping
    band by band.)
    """
    used = check_encoding(encoding, is_float)
    px = np.asarray(pixels, dtype=np.float32)
    _check_channels(px, path)
    if px.shape[2] == 4:
        if not np.all(px[:, :, 3] == 1.0):
            raise _transparent(path)
        px = px[:, :, :3]
    bad = ~(np.abs(px) <= MAX_MAGNITUDE)
    if bad.any():
        raise _non_finite(int(bad.any(axis=2).sum()), path)
    return (srgb_decode(px) if used == "srgb" else np.ascontiguousarray(px)), used


def _channels(rgb) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The three channel planes of (..., 3) as float32 (elementwise work on them is much
    faster than numpy reductions over a last axis of length 3)."""
    a = np.asarray(rgb, dtype=np.float32)
    return a[..., 0], a[..., 1], a[..., 2]


def out_of_gamut(rgb: np.ndarray) -> np.ndarray:
    """(H, W) bool: a channel below 0 or r + g + b above 1 (+ :data:`GAMUT_TOLERANCE`)."""
    r, g, b = _channels(rgb)
    return (r < 0) | (g < 0) | (b < 0) | (r + g + b > SCALE_LIMIT)


def gamut_scale(rgb: np.ndarray) -> np.ndarray:
    """Negative channels to 0, then divide by r + g + b where it exceeds 1: keeps the
    ratios of the inks (the hue of the mixture) and gives up lightness. (H, W, 3)."""
    c = np.maximum(np.asarray(rgb, dtype=np.float32), np.float32(0.0))
    r, g, b = _channels(c)
    c /= np.maximum(r + g + b, np.float32(1.0))[..., None]
    return c


def gamut_clip(rgb: np.ndarray) -> np.ndarray:
    """Euclidean projection onto the simplex {c ≥ 0, Σc ≤ 1}: the nearest in-gamut
    coverage. Where the clamped sum exceeds 1 it subtracts the same amount τ from every
    channel (clamping at 0) so that the sum is 1 — it removes the common grey and keeps
    saturated colours more saturated than :func:`gamut_scale`. (H, W, 3).

    τ follows the sort-based projection of Held, Wolfe & Crowder (1974) / Duchi et al.
    (2008): with u₁ ≥ u₂ ≥ u₃ the sorted channels and S_j their partial sums,
    ρ = max{j : u_j > (S_j − 1)/j} and τ = (S_ρ − 1)/ρ (ρ = 1 always qualifies). Only the
    pixels outside are projected, in float64.
    """
    out = np.maximum(np.asarray(rgb, dtype=np.float32), np.float32(0.0))
    r, g, b = _channels(out)
    outside = r + g + b > 1.0
    c = np.asarray(rgb, dtype=np.float64)[outside]                # (n, 3)
    x, y, z = c[:, 0], c[:, 1], c[:, 2]
    u1 = np.maximum(np.maximum(x, y), z)
    u3 = np.minimum(np.minimum(x, y), z)
    u2 = x + y + z - u1 - u3
    s1, s2, s3 = u1, u1 + u2, u1 + u2 + u3
    tau = np.where(u3 > (s3 - 1.0) / 3.0, (s3 - 1.0) / 3.0,
                   np.where(u2 > (s2 - 1.0) / 2.0, (s2 - 1.0) / 2.0, s1 - 1.0))
    out[outside] = np.maximum(c - tau[:, None], 0.0)
    return out


#: ``--gamut`` choices: name → function (H, W, 3) → (H, W, 3) in the simplex.
GAMUT_MAPPERS = {"scale": gamut_scale, "clip": gamut_clip}


def map_gamut(rgb: np.ndarray, mode: str) -> tuple[np.ndarray, float]:
    """Coverage in the simplex and the fraction of pixels that were out of gamut."""
    pick(GAMUT_MAPPERS, mode, "--gamut")
    fraction = float(out_of_gamut(rgb).mean())
    return GAMUT_MAPPERS[mode](rgb), fraction


def parse_size(text: str) -> tuple[int, int]:
    """``"WxH"`` → (width_px, height_px), both positive, within :data:`MAX_PIXELS`."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX×]\s*(\d+)\s*", text or "")
    if not m:
        raise InputError(f"--size-px {text!r} is not WIDTHxHEIGHT in pixels",
                         fix="write e.g. --size-px 2048x1536")
    return check_size(int(m.group(1)), int(m.group(2)), f"--size-px {text}")


def check_size(width: int, height: int, what: str) -> tuple[int, int]:
    """Refuse a zero or absurdly large output size."""
    if width <= 0 or height <= 0:
        raise InputError(f"{what}: the size {width}x{height} has no pixels",
                         fix="give a width and height of at least 1 pixel")
    if width * height > MAX_PIXELS:
        raise InputError(f"{what}: {width}x{height} is more than {MAX_PIXELS} pixels",
                         fix="halftone in tiles or at a lower resolution")
    return width, height


def size_from_dpi(dpi: float, print_width_mm: float, shape: tuple[int, int]
                  ) -> tuple[int, int]:
    """(width_px, height_px) of a print ``print_width_mm`` wide at ``dpi``, the height
    from the image's aspect ratio ``shape`` = (H, W)."""
    if not (math.isfinite(dpi) and dpi > 0):
        raise InputError(f"--dpi {dpi} must be a positive number")
    if not (math.isfinite(print_width_mm) and print_width_mm > 0):
        raise InputError(f"--print-width-mm {print_width_mm} must be a positive number")
    what = f"--dpi {dpi:g} --print-width-mm {print_width_mm:g}"
    width_px = print_width_mm / MM_PER_INCH * dpi
    if not width_px * max(1.0, shape[0] / shape[1]) <= MAX_PIXELS:  # also inf: no int()
        raise InputError(f"{what}: a print {width_px:.3g} pixels wide is more than "
                         f"{MAX_PIXELS} pixels", fix="halftone in tiles or at a lower "
                                                      "resolution")
    width = int(round(width_px))
    height = int(round(width * shape[0] / shape[1]))
    return check_size(width, height, what)


def resample(coverage: np.ndarray, width: int, height: int) -> np.ndarray:
    """Resample coverage (H, W, 3) to (height, width, 3) with scikit-image.

    Bilinear interpolation (``order=1``) with, when shrinking, skimage's Gaussian
    anti-aliasing prefilter: both are convex combinations of input pixels, so an in-gamut
    image stays in the simplex (no ringing as with Lanczos or bicubic), and it runs on
    linear coverage, as light mixes. A final clip/scale removes float rounding only.
    """
    from skimage.transform import resize

    c = np.asarray(coverage, dtype=np.float32)
    if c.shape[:2] == (height, width):
        return c
    shrink = height < c.shape[0] or width < c.shape[1]
    out = resize(c, (height, width, 3), order=1, mode="edge", anti_aliasing=shrink,
                 preserve_range=True).astype(np.float32)
    return gamut_scale(out)
