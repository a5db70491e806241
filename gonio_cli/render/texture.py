"""Area-filtered halftone masks: ink coverage per pixel without moiré.

A halftone mask (docs/conventions.md) is an RGB image whose channels are 0 or 1, at most one set
per pixel: channel k selects ink k, (0, 0, 0) is bare substrate. Its dots are far smaller
than a rendered pixel, so point sampling would alias into moiré. :class:`MaskPyramid`
keeps a mip pyramid of ink *coverage* (level 0 the mask itself, each further level the
box-filter average of the previous over exactly 2 × 2 of its texels' area) and looks
coverage up trilinearly: bilinear within the two levels around
λ = log2(footprint · max(W, H)) (the pixel's size in level-0 texels), blended linearly.
At any level a texel holds the exact fraction of its area covered by each ink, so a
pixel far larger than the dots sees the coverage-weighted mix of inks and substrate.

Texel centres sit at ((i + ½) / W, (j + ½) / H) and v = 0 is the bottom row of the image
(row H − 1), so row = (1 − v) H − ½ (OpenGL / Mitsuba 3). Addressing (:data:`WRAP_MODES`):
``clamp`` (the default, OpenGL ``CLAMP_TO_EDGE``) clamps uv to [0, 1] and texel indices to
the image, so a filter near an edge repeats the edge texels and never reads the opposite
edge: a print is a sheet, not a tile. ``repeat`` (OpenGL ``REPEAT``, Mitsuba 3's default)
wraps uv into [0, 1) and indices modulo the size, for masks made to tile.
"""

from __future__ import annotations

import os

import numpy as np

from ..errors import InputError
from ..imageio import read_image
from ..names import pick

#: A mask value counts as 0 or 1 when within this of it: 8- and 16-bit PNGs decode to
#: exact k / 255 or k / 65535, so anything further off is a grey level, not a halftone.
MASK_TOLERANCE = 1e-3
#: Footprints below this (uv units) are treated as this: log2 needs a positive argument,
#: and 1e-12 is far finer than any texel of a mask that fits in memory.
MIN_FOOTPRINT = 1e-12
#: Footprints above this are this: a pixel wider than the whole texture already reads the
#: 1 × 1 top level; clamping keeps log2 finite for inf.
MAX_FOOTPRINT = 1e6
#: Relative margin below 1 to which coverages summing above 1 (float32 round-off) are
#: rescaled: a few float64 ulps, so the rescaled sum is ≤ 1 exactly.
SUM_MARGIN = 4 * np.finfo(np.float64).eps
#: Number of inks (mask channels).
N_INKS = 3


def _clamp_uv(t: np.ndarray) -> np.ndarray:
    """uv into [0, 1] (NaN → 0, ±inf → the nearer edge)."""
    return np.clip(np.nan_to_num(t, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)


def _repeat_uv(t: np.ndarray) -> np.ndarray:
    """uv into [0, 1) by wrapping (non-finite → 0; also keeps huge values castable)."""
    return np.mod(np.nan_to_num(t, nan=0.0, posinf=0.0, neginf=0.0), 1.0)


def _clamp_index(i: np.ndarray, n: int) -> np.ndarray:
    return np.clip(i, 0, n - 1)


def _repeat_index(i: np.ndarray, n: int) -> np.ndarray:
    return np.mod(i, n)


#: Texture addressing by name (STYLE 3): (uv into range, texel index into [0, n)).
WRAP_MODES = {
    "clamp": (_clamp_uv, _clamp_index),
    "repeat": (_repeat_uv, _repeat_index),
}
#: The addressing of a print unless its scene says otherwise: a printed sheet has edges.
DEFAULT_WRAP = "clamp"


def get_wrap(name: str):
    """The addressing pair called ``name``; an unknown name gets the valid ones."""
    return pick(WRAP_MODES, name, "wrap mode")


def validate_mask(mask: np.ndarray, path: str | os.PathLike | None = None) -> np.ndarray:
    """Check a halftone mask and return it as (H, W, 3) uint8 of 0/1.

    Parameters
    ----------
    mask : (H, W, 3) or (H, W, 4) array
        Values in [0, 1] (an alpha channel, if present, must be opaque and is dropped).
    path : path, optional
        Named in error messages.

    Raises
    ------
    InputError
        Wrong shape, values other than 0 and 1, or more than one ink in a pixel; the
        message names the file, how many pixels and the first one (row, col).
    """
    a = np.asarray(mask)
    where = os.fspath(path) if path is not None else None
    if a.ndim != 3 or a.shape[2] not in (3, 4) or a.shape[0] == 0 or a.shape[1] == 0:
        raise InputError(f"a halftone mask must be an RGB image, not shape {a.shape}",
                         path=where, fix="use the RGB mask written by gonio halftone")
    if a.shape[2] == 4:
        if not np.all(np.abs(a[..., 3] - 1.0) <= MASK_TOLERANCE):
            raise InputError("the mask has a transparent alpha channel", path=where,
                             fix="save the mask as opaque RGB")
        a = a[..., :3]
    bits = a > 0.5
    # whole-array checks first (fast); per-pixel details only to word an error
    off = ~(np.abs(a - bits) <= MASK_TOLERANCE)                  # also catches NaN
    if off.any():
        bad = off.any(-1)
        r, c = np.argwhere(bad)[0]
        raise InputError(f"{int(bad.sum())} pixels are not 0 or 1 in every channel, the first "
                         f"at row {r}, column {c}: {np.asarray(a[r, c]).tolist()}", path=where,
                         fix="a halftone mask holds 0/1 (0/255) channels only")
    bits = bits.view(np.uint8)
    multi = (bits[..., 0] + bits[..., 1] + bits[..., 2]) > 1
    if multi.any():
        r, c = np.argwhere(multi)[0]
        raise InputError(f"{int(multi.sum())} pixels select more than one ink, the first at "
                         f"row {r}, column {c}: {bits[r, c].tolist()}", path=where,
                         fix="at most one channel may be set per pixel (dot-off-dot)")
    return bits


def _halve_axis(a: np.ndarray, axis: int) -> np.ndarray:
    """Box-filter ``a`` to ⌊n / 2⌋ along ``axis`` by exact area (n = a.shape[axis]).

    Even n: the mean of each pair. Odd n ≥ 3: the m = (n − 1) / 2 coarse texels each
    cover n / m fine texels (fractionally at their ends), weighted by overlap, so every
    fine texel contributes its whole area once and the mean is kept exactly. n = 1 stays.
    """
    n = a.shape[axis]
    if n == 1:
        return a
    a = np.moveaxis(a, axis, 0)
    if n % 2 == 0:
        out = 0.5 * (a[0::2] + a[1::2])
    else:
        m = (n - 1) // 2
        ratio = n / m                                       # in (2, 3]
        lo = np.arange(m) * ratio                           # coarse texel j: [lo, lo + ratio)
        first = np.floor(lo).astype(int)
        out = np.zeros((m,) + a.shape[1:], dtype=np.float32)
        for tap in range(4):                                # ≤ 4 fine texels overlap one
            idx = first + tap
            overlap = np.clip(np.minimum(idx + 1, lo + ratio) - np.maximum(idx, lo), 0, None)
            wgt = (overlap / ratio).astype(np.float32).reshape((m,) + (1,) * (a.ndim - 1))
            out += wgt * a[np.minimum(idx, n - 1)]
    return np.moveaxis(out.astype(np.float32, copy=False), 0, axis)


class MaskPyramid:
    """Mip pyramid of ink coverage of a halftone mask, with trilinear coverage lookup.

    Parameters
    ----------
    mask : (H, W, 3) or (H, W, 4) array
        A halftone mask (validated by :func:`validate_mask`).
    path : path, optional
        The mask's file, named in errors.

    Attributes
    ----------
    levels : list of (H_l, W_l, 3) arrays
        Level 0 the mask (uint8 0/1), each next one the float32 area average of the
        previous (sizes halve, odd sizes by exact area, down to 1 × 1). Channels are ink
        coverages summing ≤ 1.
    """

    def __init__(self, mask: np.ndarray, path: str | os.PathLike | None = None):
        bits = validate_mask(mask, path)
        self.path = os.fspath(path) if path is not None else None
        levels = [bits]                    # uint8 0/1: a quarter of float32's memory
        while levels[-1].shape[0] > 1 or levels[-1].shape[1] > 1:
            levels.append(_halve_axis(_halve_axis(levels[-1], 0), 1))
        self.levels = levels

    @classmethod
    def from_file(cls, path: str | os.PathLike) -> "MaskPyramid":
        """Read a mask image (PNG …) with :func:`gonio_cli.imageio.read_image`."""
        return cls(read_image(path).pixels, path)

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W) of the mask."""
        return self.levels[0].shape[:2]

    def mean_coverage(self) -> np.ndarray:
        """(3,) float — the mask's mean coverage of each ink (the top level)."""
        return self.levels[-1][0, 0].astype(np.float64)

    def level_of(self, footprint: np.ndarray) -> np.ndarray:
        """Continuous mip level λ = log2(footprint · max(W, H)), clamped to the pyramid.

        ``footprint`` (...) is the pixel's size in uv units (GBuffer ``uv_footprint``);
        the larger image side makes the choice conservative (blur before alias).
        """
        h, w = self.shape
        fp = np.clip(np.nan_to_num(np.asarray(footprint, np.float64), nan=0.0,
                                   posinf=MAX_FOOTPRINT), MIN_FOOTPRINT, MAX_FOOTPRINT)
        return np.clip(np.log2(fp * max(h, w)), 0.0, len(self.levels) - 1.0)

    def _bilinear(self, level: int, u: np.ndarray, v: np.ndarray, index=_repeat_index
                  ) -> np.ndarray:
        """Bilinear coverage (N, 3) float32 of one level at uv (N,); ``index`` addresses
        texel indices outside the image (a :data:`WRAP_MODES` index function)."""
        img = self.levels[level]
        h, w = img.shape[:2]
        flat = img.reshape(-1, N_INKS)
        x = u * w - 0.5
        y = (1.0 - v) * h - 0.5                           # OpenGL: v = 0 is the bottom row
        x0 = np.floor(x)
        y0 = np.floor(y)
        fx = (x - x0).astype(np.float32)[:, None]
        fy = (y - y0).astype(np.float32)[:, None]
        ix = x0.astype(np.int64)
        iy = y0.astype(np.int64)
        c0 = index(ix, w)
        c1 = index(ix + 1, w)
        r0 = index(iy, h) * w
        r1 = index(iy + 1, h) * w
        top = np.take(flat, r0 + c0, axis=0) * (1 - fx)
        top += np.take(flat, r0 + c1, axis=0) * fx
        bottom = np.take(flat, r1 + c0, axis=0) * (1 - fx)
        bottom += np.take(flat, r1 + c1, axis=0) * fx
        top *= 1 - fy
        bottom *= fy
        top += bottom
        return top

    def coverage(self, uv: np.ndarray, footprint: np.ndarray, wrap: str = DEFAULT_WRAP
                 ) -> np.ndarray:
        """Area-filtered ink coverage at texture coordinates.

        Parameters
        ----------
        uv : (..., 2) float
            Texture coordinates (OpenGL: v = 0 bottom).
        footprint : (...) float
            Pixel size in uv units (GBuffer ``uv_footprint``); 0 gives the finest level.
        wrap : str
            Addressing, a key of :data:`WRAP_MODES`: ``clamp`` (uv clamped to [0, 1],
            edge texels repeated) or ``repeat`` (uv wrapped, the mask tiles).

        Returns
        -------
        (..., 3) float64 in [0, 1], summing to ≤ 1: the fractions of the pixel covered by
        inks R, G, B (1 − sum is bare substrate).
        """
        uv = np.asarray(uv, np.float64)
        lead = uv.shape[:-1]
        to_range, index = get_wrap(wrap)
        u = to_range(uv[..., 0].reshape(-1))
        v = to_range(uv[..., 1].reshape(-1))
        lam = self.level_of(np.broadcast_to(footprint, lead)).reshape(-1)
        lo = np.minimum(np.floor(lam).astype(np.int64), len(self.levels) - 1)
        frac = (lam - lo).astype(np.float32)[:, None]
        top = len(self.levels) - 1
        out = np.empty((len(u), N_INKS), np.float32)
        # a loop over the (few) levels in use, each level's pixels in one vectorised lookup
        present = np.flatnonzero(np.bincount(lo, minlength=len(self.levels)))
        for level in present:
            sel = slice(None) if len(present) == 1 else np.flatnonzero(lo == level)
            val = self._bilinear(int(level), u[sel], v[sel], index)
            if level < top:                                # trilinear: blend the next level
                upper = self._bilinear(int(level) + 1, u[sel], v[sel], index)
                upper -= val
                upper *= frac[sel]
                val += upper
            out[sel] = val
        cov = np.clip(out.astype(np.float64), 0.0, 1.0)
        total = cov.sum(-1, keepdims=True)
        # float32 round-off can lift a full-coverage sum just above 1: rescale those to
        # just below 1 (the margin absorbs float64 round-off of the rescaled sum)
        over = total[:, 0] > 1.0
        if over.any():
            cov[over] *= (1.0 - SUM_MARGIN) / total[over]
        return cov.reshape(lead + (N_INKS,))
