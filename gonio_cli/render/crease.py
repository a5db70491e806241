"""Creases in a rendered surface: spikes of the second difference of L* along image rows.

A shading that is smooth in its directions (a fitted model) gives a lightness L*(col)
along an image row whose second difference Δ²L*(j) = L*(j−1) − 2 L*(j) + L*(j+1)
changes slowly from pixel to pixel. An interpolant with a kink (a crease: continuous value,
jumping slope, as at the rows of a piecewise-linear table) puts an isolated spike into
|Δ²L*| where a row of pixels crosses the kink. The crease ratio of a row is

    ratio = max_j |Δ²L*(j)| / (median_j |Δ²L*(j)| + floor),

over the pixels of the row inside the object (its silhouette eroded by :data:`EDGE_PX`),
and the image's crease ratio is the largest over rows with at least :data:`MIN_RUN_PX`
such pixels (issue 27: "along any image row across the sphere, the second difference of
L* has no spike above 3× its median"). The floor :data:`FLOOR_L` keeps a row of nearly
constant L* (median ≈ 0) from dividing by zero: a spike below it is invisible.

Used by ``tests/test_render_measured_smooth.py`` and ``benchmarks/bench_render_measured.py``.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage
from ..spectra import xyz_to_lab

#: Pixels dropped at each end of a row inside the mask: the silhouette's antialiased
#: pixels (ssaa blends sphere and background over ~1 px) and the grazing rim, where L*
#: falls to 0 within a few pixels on any material.
EDGE_PX = 4

#: Shortest run of interior pixels (after the erosion) a row needs to count: a median of
#: fewer second differences is noise.
MIN_RUN_PX = 24

#: Width (pixels) of the running median each |Δ²L*| is compared with. A crease spikes on
#: one or two pixels; a smooth highlight of half-width h px keeps |Δ²L*| within a factor
#: ~2 over ±h/2. WINDOW_PX = 9 ≥ 4× a spike's width, so the spike never sets its own
#: median, and no wider than the narrowest fitted highlight of Figure 5 at 480² (the rim
#: light's, ~10 px across), so a smooth peak is judged against its own flanks.
WINDOW_PX = 9

#: Floor (L* units) added to the median: 0.05 L* is ~1/20 of a just-noticeable
#: difference, below what an 8-bit display shows as a change of slope.
FLOOR_L = 0.05

#: |cos θi| below which a pixel is on a light's terminator band (±5.7°: ~5 px of a 65 px
#: sphere radius near the limb, where the band is widest in pixels, a few px elsewhere).
TERMINATOR_COS = 0.1


def lightness(xyz: np.ndarray, white_y: float) -> np.ndarray:
    """CIE L* (...,) of XYZ (..., 3) relative to a white of luminance ``white_y``
    (CIE 15:2004: L* = 116 f(Y/Yn) − 16, f the cube root with its linear toe)."""
    y = np.asarray(xyz, dtype=float)[..., 1:2]
    return xyz_to_lab(np.repeat(y, 3, axis=-1), np.full(3, float(white_y)))[..., 0]


def away_from_terminators(normal: np.ndarray, light_dirs: np.ndarray,
                          cos_band: float = TERMINATOR_COS) -> np.ndarray:
    """(H, W) bool: pixels where no light is within ``cos_band`` of grazing.

    ``normal`` (H, W, 3) unit normals; ``light_dirs`` (k, 3) unit directions towards the
    directional lights. Every material's shading has a real kink where a light's cos θi
    crosses 0 (L = f E cos θi for cos θi > 0, else 0): not the interpolant's crease."""
    cos_i = np.einsum("hwc,kc->hwk", np.asarray(normal, float), np.asarray(light_dirs, float))
    return np.all(np.abs(cos_i) > cos_band, axis=-1)


def row_crease_ratios(lstar: np.ndarray, mask: np.ndarray,
                      judged: np.ndarray | None = None) -> np.ndarray:
    """The crease ratio (module docstring) of each image row, NaN for rows that do not
    cross the object far enough.

    Parameters
    ----------
    lstar : (H, W) float — L* of the image.
    mask : (H, W) bool — the object's pixels (one convex object, e.g. a sphere).
    judged : (H, W) bool, optional — where a spike counts (default: everywhere in the
        mask); :func:`away_from_terminators` leaves out the lights' terminators. The
        second differences and their running median are taken over the whole run.

    Returns
    -------
    (H,) float — max |Δ²L*| / (median |Δ²L*| + :data:`FLOOR_L`) per row.
    """
    inner = ndimage.binary_erosion(mask, structure=np.ones((1, 2 * EDGE_PX + 1), bool))
    out = np.full(lstar.shape[0], np.nan)
    for r in range(lstar.shape[0]):
        cols = np.flatnonzero(inner[r])
        if cols.size < MIN_RUN_PX:
            continue
        line = lstar[r, cols[0]:cols[-1] + 1]
        d2 = np.abs(line[:-2] - 2.0 * line[1:-1] + line[2:])
        local = ndimage.median_filter(d2, size=WINDOW_PX, mode="nearest")
        keep = judged[r, cols[0] + 1:cols[-1]] if judged is not None else slice(None)
        ratio = (d2 / (local + FLOOR_L))[keep]
        if ratio.size:
            out[r] = ratio.max()
    return out


def crease_ratio(lstar: np.ndarray, mask: np.ndarray,
                 judged: np.ndarray | None = None) -> float:
    """The largest row crease ratio of an object (:func:`row_crease_ratios`); NaN if no
    row crosses it far enough. Below 3: no crease (issue 27)."""
    ratios = row_crease_ratios(lstar, mask, judged)
    return float(np.nanmax(ratios)) if np.any(np.isfinite(ratios)) else float("nan")
