"""What a prefilter takes: a valid map and exponents, and each exponent's output resolution
(:data:`OUTPUT_TEXELS_PER_SIGMA` texels per lobe standard deviation)."""

from __future__ import annotations

from typing import Iterable

import numpy as np

from ..errors import InputError, num
from ..schemas import MAX_MAGNITUDE

#: Output texels per lobe standard deviation σ = 1/√E rad (cos^E θ ≈ exp(−Eθ²/2)), at
#: least. The levels are powers of two, so maps get 2.5–5 texels per σ: bilinear lookup
#: between texel centres is then within ~1 % (99th percentile; a few % at the edge of a
#: sun's lobe) of the exact map (measured, docs/prefilter.md); force ``resolution`` for more.
OUTPUT_TEXELS_PER_SIGMA = 2.5
#: Smallest output height chosen automatically (a 128 × 64 diffuse map): the clamped cosine
#: of E = 1 has a kink at the terminator that a sun makes steep, so its lookup error falls
#: only linearly with the texel size (p99 26 % at 16 rows, 3 % at 64, on quarry_01).
MIN_OUTPUT_HEIGHT = 64
#: Largest exponent accepted: the lobe is then ~0.06° wide, far below any map's texel.
MAX_EXPONENT = 1e6


# ------------------------------------------------------------------------- validation --

def validate_map(pixels: np.ndarray, *, fix_invalid: bool = False,
                 path=None) -> tuple[np.ndarray, int]:
    """Check an environment map; return it as float64 (H, W, C) and the texels replaced.

    NaN, ±inf or negative values are an error naming the first such texel (row, col, 0-based
    as in the image) and how many there are; with ``fix_invalid`` negative values become 0
    and NaN/inf the mean of the valid texels of their row (0 if none), and the count is
    returned (the caller says so). A map needs at least 1 row and 2 columns (one column
    is a single direction, not a sphere).
    """
    a = np.asarray(pixels, dtype=np.float64)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 2 or a.shape[2] < 1:
        raise InputError(f"a {' × '.join(map(str, a.shape[:2]))} image is not a lat-long "
                         "map (needs at least 1 row and 2 columns)", path=path,
                         fix="pass an equirectangular map, 2:1 (width = 2 × height)")
    finite = np.isfinite(a) & (np.abs(a) <= MAX_MAGNITUDE)   # huge: as inf (Numeric ranges)
    bad_values = ~finite | (np.where(finite, a, 0.0) < 0.0)
    bad = bad_values.any(axis=2)
    count = int(bad.sum())
    if count == 0:
        return a, 0
    if not fix_invalid:
        row, col = (int(v) for v in np.argwhere(bad)[0])
        value = a[row, col][bad_values[row, col]][0]
        raise InputError(f"texel (row {row}, col {col}) is {num(value)}; {count} texel"
                         f"{'s are' if count > 1 else ' is'} NaN, inf or negative (or above "
                         f"{MAX_MAGNITUDE:g})", path=path,
                         fix="repair the map or pass --fix-invalid to replace them")
    a = a.copy()
    a[finite & (a < 0.0)] = 0.0
    good = np.isfinite(a) & (a <= MAX_MAGNITUDE)
    row_mean = np.where(good, a, 0.0).sum(axis=1) / np.maximum(good.sum(axis=1), 1)
    a = np.where(good, a, row_mean[:, None, :])
    return a, count


def validate_exponents(exponents: Iterable[float], *, path=None) -> list[float]:
    """Sorted unique exponents in [1, MAX_EXPONENT], always including the diffuse E = 1."""
    out = set()
    for e in exponents:
        try:
            v = float(e)
        except (TypeError, ValueError):
            raise InputError(f"exponent {e!r} is not a number", path=path,
                             fix="give numbers such as 1,8,64") from None
        if not (np.isfinite(v) and 1.0 <= v <= MAX_EXPONENT):
            raise InputError(f"exponent {num(e)} is outside [1, {MAX_EXPONENT:g}]", path=path,
                             fix="cosine-lobe exponents are at least 1 (the diffuse map)")
        out.add(v)
    out.add(1.0)
    return sorted(out)


# ------------------------------------------------------------------------- resolution --

def lobe_sigma(exponent: float) -> float:
    """Angular standard deviation of max(0, cos θ)^E: 1/√E rad (cos^E θ ≈ exp(−Eθ²/2))."""
    return 1.0 / np.sqrt(exponent)


def output_levels(height: int, width: int, exponent: float) -> int:
    """Octaves k by which the output is smaller than the input (H/2^k × W/2^k).

    The coarsest level whose texel spacing π/H_o is at most σ/OUTPUT_TEXELS_PER_SIGMA and
    whose height is at least MIN_OUTPUT_HEIGHT (or the input's, if smaller); only levels
    that divide both sides exactly are used.
    """
    needed = max(np.pi * OUTPUT_TEXELS_PER_SIGMA / lobe_sigma(exponent),
                 min(MIN_OUTPUT_HEIGHT, height))
    k = 0
    while (height % 2 ** (k + 1) == 0 and width % 2 ** (k + 1) == 0
           and height // 2 ** (k + 1) >= needed):
        k += 1
    return k


def levels_for_height(height: int, width: int, out_height: int, *, path=None) -> int:
    """Octaves k for a forced output height (must be the input's height / 2^k)."""
    valid = []
    k = 0
    while True:
        h = height // 2 ** k
        valid.append(h)
        if h == out_height:
            return k
        if height % 2 ** (k + 1) or width % 2 ** (k + 1):
            break
        k += 1
    raise InputError(f"resolution {out_height} is not one of this map's: "
                     f"{', '.join(map(str, valid))}", path=path,
                     fix="outputs are the input reduced by powers of two")
