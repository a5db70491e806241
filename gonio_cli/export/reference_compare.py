"""gonio's picture against a reference picture of the same scene (issue 26,
docs/reference.md): CIEDE2000 per pixel over what both cover, with one white for both;
the mean luminance ratio; and where a sharp feature lies in each — the row of the
largest step of log luminance down the object's centre column (on a sphere under a sky,
the horizon's reflection).

gonio's picture is an EXR (read in the space its header names) or an XYZ array, so any
``[environment]`` method can be compared; the reference is an XYZ array or a
:class:`~gonio_cli.export.mitsuba_reference.MitsubaRender` (anything with ``xyz`` and
``noise``), whose noise gives the CIEDE2000 that Monte Carlo noise alone makes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..imageio import read_image, write_png
from ..render.tonemap import get_exr_space
from ..spectra import delta_e_2000, srgb_encode, srgb_white_xyz, xyz_to_lab, xyz_to_linear_srgb

#: A white whose luminance is this percentile of the reference over the object (the
#: brightest 1 % at or above display white, as an auto exposure would set it).
WHITE_PERCENTILE = 99.0

#: Pixels of the object's edge left out of the comparison: a pixel there mixes object and
#: background, and gonio's polygon departs from Mitsuba's analytic sphere by up to ~1 px.
ERODE_PX = 1

#: Half-width (px) of the band of columns averaged down the centre column for the
#: sharp-feature row: 5 columns cut the Monte Carlo noise of one column by √5.
FEATURE_HALF_WIDTH = 2

#: Share of the band's rows left out at each end for the sharp-feature row: towards the
#: silhouette luminance falls steeply on every material (grazing view), which would
#: otherwise be the largest step; 10 % of a sphere's height leaves normals within ~53° of
#: the view's plane.
FEATURE_MARGIN = 0.1

#: Rows averaged on each side of an edge by the sharp-feature detector (a box step
#: filter): a reflected horizon is blurred over a few rows by the lobe, and averaging 4
#: rows a side cuts a pixel's Monte Carlo noise by 2.
FEATURE_WINDOW = 4

#: The step of log luminance across an edge (means of FEATURE_WINDOW rows a side) that
#: counts as a sharp feature: a 16 % change. On the benchmark's sky at 512² the glossy
#: sphere's horizon is ~0.25; the rough car paint's smooth sun highlight, ≤ 0.1, has no
#: feature whose row means anything (``feature_sharp`` False).
FEATURE_MIN_STEP = 0.15

#: Floor of luminance before its logarithm (the feature profile): far below any lit
#: pixel (Y ~ 1e-3 … 1e5 here), it only keeps log finite on a black pixel.
LOG_FLOOR = 1e-12


def read_xyz(path) -> np.ndarray:
    """CIE XYZ (H, W, 3) float64 of a gonio EXR, from the space its header names
    (``gonio:exr_space``; linear sRGB without one). Render with ``adapt = "none"``
    (:func:`write_gonio_scene` does) for the scene's own colorimetry."""
    img = read_image(path)
    space = str(img.metadata.get("exr_space", "srgb"))
    m = get_exr_space(space).matrix()
    return img.pixels[..., :3].astype(np.float64) @ np.linalg.inv(m).T


@dataclass
class Comparison:
    """gonio against Mitsuba on the pixels both cover.

    ``delta_e`` (H, W): CIEDE2000 per pixel, NaN outside ``mask``; ``mean_delta_e``,
    ``p95_delta_e``; ``noise_delta_e``: the mean CIEDE2000 that Mitsuba's own Monte Carlo
    noise makes (None without a noise image) — the floor of ``mean_delta_e``;
    ``luminance_ratio``: mean Y of gonio / of Mitsuba over the mask; ``white_y``: the
    luminance of the Lab white of both; ``feature_row_gonio``, ``feature_row_mitsuba``
    (px from the top edge, subpixel), ``feature_offset_px`` (gonio − Mitsuba) of the
    sharpest step of log luminance down ``feature_column``, ``feature_step_*`` its size
    and ``feature_sharp`` whether the reference has one (:func:`sharp_feature_row`)."""

    delta_e: np.ndarray
    mask: np.ndarray
    mean_delta_e: float
    p95_delta_e: float
    noise_delta_e: float | None
    luminance_ratio: float
    white_y: float
    feature_column: int
    feature_row_gonio: float
    feature_row_mitsuba: float
    feature_step_gonio: float
    feature_step_mitsuba: float

    @property
    def feature_offset_px(self) -> float:
        return self.feature_row_gonio - self.feature_row_mitsuba

    @property
    def feature_sharp(self) -> bool:
        """Does the reference show a sharp feature (step ≥ :data:`FEATURE_MIN_STEP`)?"""
        return bool(self.feature_step_mitsuba >= FEATURE_MIN_STEP)

    def summary(self) -> dict:
        """The figures as a JSON-ready dict."""
        return {"pixels": int(self.mask.sum()), "mean_delta_e": self.mean_delta_e,
                "p95_delta_e": self.p95_delta_e, "noise_delta_e": self.noise_delta_e,
                "luminance_ratio": self.luminance_ratio, "white_y": self.white_y,
                "feature_column": self.feature_column,
                "feature_row_gonio": self.feature_row_gonio,
                "feature_row_mitsuba": self.feature_row_mitsuba,
                "feature_offset_px": self.feature_offset_px,
                "feature_step_gonio": self.feature_step_gonio,
                "feature_step_mitsuba": self.feature_step_mitsuba,
                "feature_sharp": self.feature_sharp}


def _erode(mask: np.ndarray, px: int) -> np.ndarray:
    """``mask`` without the pixels within ``px`` (chessboard distance) of its outside."""
    out = mask.copy()
    for _ in range(px):
        m = np.pad(out, 1, constant_values=False)
        out = (m[1:-1, 1:-1] & m[:-2, 1:-1] & m[2:, 1:-1] & m[1:-1, :-2] & m[1:-1, 2:]
               & m[:-2, :-2] & m[:-2, 2:] & m[2:, :-2] & m[2:, 2:])
    return out


def covered(gonio_xyz: np.ndarray, mitsuba_xyz: np.ndarray, erode_px: int = ERODE_PX
            ) -> np.ndarray:
    """(H, W) bool: pixels both images cover (Y > 0; both backgrounds are black), the
    object's edge eroded by ``erode_px``."""
    return _erode((gonio_xyz[..., 1] > 0) & (mitsuba_xyz[..., 1] > 0), erode_px)


def feature_column(mask: np.ndarray) -> int:
    """The column through the centroid of ``mask`` (the object's centre column)."""
    return int(round(float(np.mean(np.nonzero(mask)[1])))) if mask.any() else 0


def sharp_feature_row(y: np.ndarray, mask: np.ndarray, column: int,
                      half_width: int = FEATURE_HALF_WIDTH) -> tuple[float, float]:
    """(row, step) of the sharpest edge of log luminance down the band ``column`` ±
    ``half_width`` (its mean; rows where the band lies inside ``mask``, less
    :data:`FEATURE_MARGIN` at each end): the step at the edge above row k is the mean of
    log Y over rows k … k + w − 1 minus that over k − w … k − 1 (w =
    :data:`FEATURE_WINDOW`); the row is k (px from the top edge), refined by a parabola
    through |step| at k − 1, k, k + 1. (NaN, 0) if the band has fewer than 2w + 1 rows."""
    w = FEATURE_WINDOW
    band = slice(max(column - half_width, 0), column + half_width + 1)
    rows = np.flatnonzero(mask[:, band].all(axis=1))
    cut = int(FEATURE_MARGIN * rows.size)
    rows = rows[cut:rows.size - cut]
    if rows.size < 2 * w + 1 or np.any(np.diff(rows) != 1):
        return float("nan"), 0.0
    profile = np.log(np.maximum(y[rows, band], LOG_FLOOR)).mean(axis=1)
    sums = np.concatenate([[0.0], np.cumsum(profile)])
    edges = np.arange(w, rows.size - w + 1)                 # edge above profile[k]
    step = (sums[edges + w] - 2 * sums[edges] + sums[edges - w]) / w
    k = int(np.argmax(np.abs(step)))
    shift = 0.0
    if 0 < k < step.size - 1:
        a, b, c = np.abs(step[k - 1:k + 2])
        shift = 0.5 * (a - c) / (a - 2 * b + c) if (a - 2 * b + c) < 0 else 0.0
    return float(rows[edges[k]] + shift), float(abs(step[k]))


def _as_xyz(image) -> np.ndarray:
    if isinstance(image, (str, os.PathLike)):
        return read_xyz(image)
    return np.asarray(image, dtype=np.float64)[..., :3]


def compare(gonio, mitsuba, *, noise: np.ndarray | None = None, mask=None,
            white_y: float | None = None, column: int | None = None) -> Comparison:
    """Compare gonio's picture (EXR path, or XYZ (H, W, 3)) with Mitsuba's (XYZ array or
    a ``MitsubaRender``, whose ``noise`` is then used).

    ``mask``: the pixels to compare (default :func:`covered`); ``white_y``: luminance of
    the Lab white (D65) of both images, their one exposure (default the
    :data:`WHITE_PERCENTILE` th percentile of Mitsuba's Y over the mask); ``column``: where
    to look for the sharp feature (default :func:`feature_column`).
    """
    if hasattr(mitsuba, "xyz"):                       # a MitsubaRender
        noise = mitsuba.noise if noise is None else noise
        mitsuba = mitsuba.xyz
    g, m = _as_xyz(gonio), _as_xyz(mitsuba)
    if g.shape != m.shape:
        raise InputError(f"gonio's image is {g.shape[1]} × {g.shape[0]}, Mitsuba's "
                         f"{m.shape[1]} × {m.shape[0]}", fix="render both at one size")
    mask = covered(g, m) if mask is None else np.asarray(mask, bool)
    if not mask.any():
        raise InputError("the two images share no covered pixel",
                         fix="check the camera and the object of both scenes")
    if white_y is None:
        white_y = float(np.percentile(m[..., 1][mask], WHITE_PERCENTILE))
    white = srgb_white_xyz() * white_y
    lab_m = xyz_to_lab(m[mask], white)
    de = np.full(mask.shape, np.nan)
    de[mask] = delta_e_2000(xyz_to_lab(g[mask], white), lab_m)
    noise_de = None
    if noise is not None:
        noise_de = float(np.mean(delta_e_2000(xyz_to_lab(m[mask] + noise[mask], white),
                                              lab_m)))
    col = feature_column(mask) if column is None else int(column)
    (row_g, step_g), (row_m, step_m) = (sharp_feature_row(image[..., 1], mask, col)
                                        for image in (g, m))
    return Comparison(de, mask, float(np.mean(de[mask])), float(np.percentile(de[mask], 95)),
                      noise_de, float(g[..., 1][mask].mean() / m[..., 1][mask].mean()),
                      white_y, col, row_g, row_m, step_g, step_m)


def side_by_side(comparison: Comparison, gonio, mitsuba, path, *, de_max: float = 10.0
                 ) -> Path:
    """PNG: gonio | Mitsuba (linear sRGB / white_y, clipped, sRGB-encoded; feature rows
    marked red at the centre column) | CIEDE2000 (black 0 … white ``de_max``)."""
    mitsuba = getattr(mitsuba, "xyz", mitsuba)
    tiles, c = [], comparison.feature_column
    for image, row in ((gonio, comparison.feature_row_gonio),
                       (mitsuba, comparison.feature_row_mitsuba)):
        rgb = srgb_encode(xyz_to_linear_srgb(_as_xyz(image)) / comparison.white_y)
        if np.isfinite(row):
            rgb[max(int(row) - 1, 0):int(row) + 1, max(c - 6, 0):c + 7] = (1.0, 0.0, 0.0)
        tiles += [rgb, np.ones((rgb.shape[0], 4, 3))]
    de = np.clip(np.nan_to_num(comparison.delta_e, nan=0.0) / de_max, 0.0, 1.0)
    tiles.append(np.repeat(de[..., None], 3, axis=2))
    write_png(path, np.concatenate(tiles, axis=1).astype(np.float32))
    return Path(path)


__all__ = ["read_xyz", "Comparison", "covered", "feature_column", "sharp_feature_row",
           "compare", "side_by_side"]
