"""XYZ → display: linear sRGB, exposure, a tone map, the sRGB transfer function, 8 bits.

docs/conventions.md: linear sRGB from XYZ by the IEC 61966-2-1 matrix (no chromatic adaptation);
the EXR holds that linear sRGB before any exposure; the PNG is 8-bit, sRGB-encoded after
exposure and tone mapping. Tone maps act per channel on linear values ≥ 0 (negative
linear sRGB, i.e. colours outside the sRGB gamut, are clipped to 0 first) and return
display-linear values in [0, 1]:

- ``clip``: min(x, 1).
- ``reinhard``: x / (1 + x), the simple global operator of Reinhard et al. 2002,
  "Photographic tone reproduction for digital images", eq. 3 (applied per channel).
- ``filmic``: the ACES filmic curve as fitted by K. Narkowicz, "ACES Filmic Tone Mapping
  Curve" (2015): x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), clipped to [0, 1]. It is
  monotone for x ≥ 0 (the numerator of its derivative is 1.408 x² + 0.7028 x + 0.0042)
  and reaches 1 at x ≈ 7.24.
"""

from __future__ import annotations

import functools
from typing import Callable

import numpy as np

from ..errors import InputError


def clip(x: np.ndarray) -> np.ndarray:
    """Display value min(max(x, 0), 1)."""
    return np.clip(x, 0, 1)


def reinhard(x: np.ndarray) -> np.ndarray:
    """Reinhard et al. 2002 eq. 3 per channel: x / (1 + x), x ≥ 0."""
    x = np.maximum(x, 0)
    return x / (1 + x)


#: Narkowicz 2015 coefficients of the fitted ACES curve.
ACES_A, ACES_B, ACES_C, ACES_D, ACES_E = 2.51, 0.03, 2.43, 0.59, 0.14


def filmic(x: np.ndarray) -> np.ndarray:
    """Narkowicz 2015 ACES fit: x(a x + b) / (x(c x + d) + e), clipped to [0, 1]."""
    x = np.maximum(x, 0)
    t = x.dtype.type if isinstance(x, np.ndarray) and x.dtype.kind == "f" else float
    a, b, c, d, e = (t(k) for k in (ACES_A, ACES_B, ACES_C, ACES_D, ACES_E))
    return np.clip(x * (a * x + b) / (x * (c * x + d) + e), 0, 1)


#: Tone maps by name (STYLE 3): display-linear value in [0, 1] from scene-linear x ≥ 0.
TONEMAPS: dict[str, Callable[[np.ndarray], np.ndarray]] = {
    "clip": clip,
    "reinhard": reinhard,
    "filmic": filmic,
}


def get_tonemap(name: str) -> Callable[[np.ndarray], np.ndarray]:
    """The tone map called ``name``; an unknown name gets the list of valid ones."""
    if name not in TONEMAPS:
        raise InputError(f"tone map {name!r} is unknown", fix=f"use one of {', '.join(TONEMAPS)}")
    return TONEMAPS[name]


def xyz_to_linear(xyz: np.ndarray) -> np.ndarray:
    """XYZ (..., 3) → scene-referred linear sRGB (..., 3) float32 (what the EXR holds)."""
    from ..spectra import xyz_to_linear_srgb

    return xyz_to_linear_srgb(xyz).astype(np.float32)


#: Entries of the 8-bit sRGB encoding table over display-linear [0, 1]: with 2^16 steps
#: a value lands on the code :func:`gonio_cli.spectra.srgb_encode` gives, except within
#: half a step (1/131070) of a rounding threshold, where it may be one code off (measured:
#: 0.3 % of the values of a random HDR image, never more than one code), at a fraction
#: of the cost of the power function per pixel.
ENCODE_TABLE_SIZE = 1 << 16


@functools.lru_cache(maxsize=1)
def encode_table() -> np.ndarray:
    """round(255 · srgb_encode(k / (N − 1))), k = 0 … N − 1: (N,) uint8."""
    from ..spectra import srgb_encode

    y = np.arange(ENCODE_TABLE_SIZE) / (ENCODE_TABLE_SIZE - 1)
    return np.round(srgb_encode(y) * 255.0).astype(np.uint8)


def display(linear_srgb: np.ndarray, exposure: float = 0.0, tonemap: str = "filmic"
            ) -> np.ndarray:
    """Linear sRGB (..., 3) → 8-bit sRGB-encoded (..., 3) uint8.

    ``exposure``: stops; values are multiplied by 2^exposure before the tone map. The
    tone map runs in float32 (display values need ~1e-4, float32 gives 6e-8); the sRGB
    transfer function is read from :func:`encode_table`.
    """
    op = get_tonemap(tonemap)
    x = np.asarray(linear_srgb, dtype=np.float32) * np.float32(2.0 ** float(exposure))
    x[~np.isfinite(x)] = 0.0  # never reached by a valid frame; guards the cast
    y = np.clip(op(x), 0.0, 1.0)
    index = (y * np.float32(ENCODE_TABLE_SIZE - 1) + np.float32(0.5)).astype(np.intp)
    return encode_table()[index]


def xyz_to_display(xyz: np.ndarray, exposure: float = 0.0, tonemap: str = "filmic"
                   ) -> np.ndarray:
    """XYZ → linear sRGB → exposure → tone map → sRGB encode → uint8 (docs/conventions.md)."""
    return display(xyz_to_linear(xyz), exposure, tonemap)
