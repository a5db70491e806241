"""The resolve of a supersampled frame: shaded rows → the output's XYZ, coverage and
linear image (a box filter over ssaa × ssaa samples, a scatter at ssaa 1)."""

from __future__ import annotations

import numpy as np

from .. import log
from . import Stats
from .raster import downsample
from .tonemap import xyz_to_linear


def resolve(rows: np.ndarray, pixels: np.ndarray, object_id: np.ndarray, ssaa: int,
            where: str = "", stats: Stats | None = None, *, matrix: np.ndarray | None = None
            ) -> tuple[np.ndarray, ...]:
    """The box filter of the supersampled frame: shaded rows → output XYZ and coverage
    (and, with ``matrix``, the linear image ``tonemap.xyz_to_linear(xyz, matrix)``).

    Parameters
    ----------
    rows : (n, C) XYZ (or any C channels, e.g. wavelengths) of the covered samples ;
    pixels : (n,) their flat indices in the (ssaa H, ssaa W) image ; object_id : (ssaa H,
    ssaa W), −1 on the background.

    Returns
    -------
    xyz : (H, W, 3) float64, the mean over each ssaa × ssaa block (background 0), summed
    in float32 (≤ 256 values: relative error ~1e-7);
    coverage : (H, W) float64, the fraction of covered samples. Non-finite shaded
    samples are set to black with one warning that counts them.
    linear : (H, W, C) float32, only with ``matrix`` (C, C).

    At ssaa 1 there is nothing to filter: the rows' product with the matrix (in the rows'
    float32, ~1e-7 relative, as the G-buffer; on covered pixels only, zero elsewhere as
    0 · M is) is scattered whole into a zeroed image, and with ``matrix`` the XYZ image
    is returned as a function that makes it (:attr:`.pipeline.Frame.xyz` calls it when a report or
    an XYZ EXR asks): the frame's time goes to what the PNG and EXR need.
    """
    n_bad = 0
    if not np.isfinite(rows.sum()):          # the per-row mask only when needed (a sum of
        bad = ~np.isfinite(rows).all(axis=-1)    # finite rows may still overflow: then 0)
        n_bad = int(bad.sum())
        if n_bad:
            log.warn(f"{where}: {n_bad} sample(s) shaded to NaN or inf were set to black")
            rows = np.where(bad[:, None], 0.0, rows)
    if stats is not None:
        stats.counts["nonfinite_samples"] = n_bad
    hh, ww = object_id.shape
    channels = rows.shape[1]
    if ssaa == 1:
        pixels = np.asarray(pixels, dtype=np.intp)
        coverage = (object_id >= 0).astype(np.float64)

        def xyz_image():
            return _scatter_rows(rows.astype(np.float64), pixels,
                                 hh * ww).reshape(hh, ww, channels)

        if matrix is None:
            return xyz_image(), coverage
        linear = _scatter_rows(rows @ matrix.T.astype(rows.dtype), pixels, hh * ww)
        return xyz_image, coverage, linear.reshape(hh, ww, channels)
    xyz = np.empty((hh // ssaa * (ww // ssaa), channels))
    # one channel at a time through one reused float32 image (the rows' columns are
    # contiguous: shade_rows stores them so), box-filtered by downsample's strided sums
    image = np.empty(object_id.size, np.float32)
    pixels = np.asarray(pixels, dtype=np.intp)                # converted once, not per channel
    for c in range(channels):
        image.fill(0.0)
        image[pixels] = rows[:, c]
        xyz[:, c] = downsample(image.reshape(hh, ww), ssaa, np.float32).reshape(-1)
    coverage = downsample(object_id >= 0, ssaa, np.float32)
    xyz = xyz.reshape(hh // ssaa, ww // ssaa, channels)
    if matrix is None:
        return xyz, coverage.astype(np.float64)
    return xyz, coverage.astype(np.float64), xyz_to_linear(xyz, matrix)


def _scatter_rows(rows: np.ndarray, pixels: np.ndarray, size: int) -> np.ndarray:
    """(size, C) zeros of ``rows``' dtype with ``rows`` (n, C) at ``pixels`` (n,): each
    row moved as one C-value item (a void view), 2.5× faster than numpy's row-of-floats
    fancy assignment."""
    rows = np.ascontiguousarray(rows)
    item = np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))
    out = np.zeros((size, rows.shape[1]), rows.dtype)
    out.view(item).reshape(-1)[pixels] = rows.view(item).reshape(-1)
    return out
