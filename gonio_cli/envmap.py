"""Lat-long (equirectangular) environment-map geometry, shared by prefilter and renderer.

The layout is Mitsuba 3's ``envmap`` (docs/conventions.md, "Images, maps"): the pixel centre
(row, col) of an H × W map has

    θ = π (row + ½) / H,   φ = 2π (col + ½) / W,
    ω = (sin θ sin φ, cos θ, −sin θ cos φ),

+y is up and row 0 is the zenith. A texel covers θ ∈ [π row / H, π (row + 1) / H] and
φ ∈ [2π col / W, 2π (col + 1) / W]; its solid angle is the exact band integral
∫∫ sin θ dθ dφ = (cos θ_top − cos θ_bottom) · 2π / W, so the texels of any map sum to 4π.

Every function here is the one place its formula lives (STYLE 2): directions of pixel
centres, solid angles, direction → continuous pixel coordinates, bilinear lookup (wrapping
in φ, clamped in θ) and downsampling by area (a box filter in solid angle, which keeps
∫ L dω of every coarse texel exactly).
"""

from __future__ import annotations

import numpy as np


def pixel_theta(height: int) -> np.ndarray:
    """Polar angle θ of the pixel centres of each row.

    Parameters
    ----------
    height : int
        Rows H of the map.

    Returns
    -------
    (H,) float64 — θ = π (row + ½) / H in radians (row 0 next to the zenith, +y).
    """
    return np.pi * (np.arange(height) + 0.5) / height


def pixel_phi(width: int) -> np.ndarray:
    """Azimuth φ of the pixel centres of each column: (W,) float64, 2π (col + ½) / W rad."""
    return 2.0 * np.pi * (np.arange(width) + 0.5) / width


def spherical_to_direction(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit direction of polar angle θ and azimuth φ (docs/conventions.md, Mitsuba ``envmap``).

    Parameters
    ----------
    theta, phi : (...) float
        Radians; broadcast together.

    Returns
    -------
    (..., 3) float64 — (sin θ sin φ, cos θ, −sin θ cos φ).
    """
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    s = np.sin(theta)
    return np.stack([s * np.sin(phi), np.cos(theta), -s * np.cos(phi)], axis=-1)


def pixel_directions(height: int, width: int) -> np.ndarray:
    """Directions of all pixel centres of an H × W map: (H, W, 3) float64, unit length."""
    return spherical_to_direction(pixel_theta(height)[:, None], pixel_phi(width)[None, :])


def row_solid_angles(height: int, width: int) -> np.ndarray:
    """Solid angle of one texel in each row (all texels of a row are equal).

    Exact band integral (cos θ_top − cos θ_bottom) · 2π / W, not the midpoint rule
    sin θ Δθ Δφ, so a map's texels sum to exactly 4π (up to round-off).

    Returns
    -------
    (H,) float64 — steradians.
    """
    edges = np.pi * np.arange(height + 1) / height
    return band_solid_angles(edges[:-1], edges[1:], 2.0 * np.pi / width)


def band_solid_angles(theta_top, theta_bottom, phi_width) -> np.ndarray:
    """Solid angle of the patches θ ∈ [θ_top, θ_bottom], φ over ``phi_width`` rad.

    The exact integral ∫∫ sin θ dθ dφ = (cos θ_top − cos θ_bottom) · Δφ (every texel and
    sub-texel solid angle in gonio comes from here). Arguments broadcast; (...) float64 sr.
    """
    return (np.cos(theta_top) - np.cos(theta_bottom)) * phi_width


def solid_angles(height: int, width: int) -> np.ndarray:
    """Solid angle of every texel: (H, W) float64, steradians, summing to 4π."""
    return np.broadcast_to(row_solid_angles(height, width)[:, None], (height, width)).copy()


def direction_to_spherical(directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Polar angle θ and azimuth φ of directions, the inverse of :func:`spherical_to_direction`.

    Parameters
    ----------
    directions : (..., 3) float
        Directions (need not be normalised; a zero vector gives the zenith).

    Returns
    -------
    theta, phi : (...) float64 — radians, θ in [0, π], φ in [0, 2π).
    """
    d = np.asarray(directions, dtype=float)
    norm = np.linalg.norm(d, axis=-1)
    safe = np.where(norm > 0.0, norm, 1.0)
    cos_theta = np.clip(np.where(norm > 0.0, d[..., 1] / safe, 1.0), -1.0, 1.0)
    return np.arccos(cos_theta), np.mod(np.arctan2(d[..., 0], -d[..., 2]), 2.0 * np.pi)


def direction_to_pixel(directions: np.ndarray, height: int, width: int) -> np.ndarray:
    """Continuous pixel coordinates (row, col) of directions; pixel centres are integers.

    The inverse of :func:`pixel_directions`: the centre of texel (r, c) maps to (r, c).

    Parameters
    ----------
    directions : (..., 3) float
        Directions (need not be normalised; a zero vector gives the zenith).
    height, width : int
        Map size.

    Returns
    -------
    (..., 2) float64 — row in [−½, H − ½], col in [−½, W − ½).
    """
    theta, phi = direction_to_spherical(directions)
    row = theta * height / np.pi - 0.5
    col = phi * width / (2.0 * np.pi) - 0.5
    return np.stack([row, col], axis=-1)


def lookup(image: np.ndarray, directions: np.ndarray) -> np.ndarray:
    """Bilinear lookup of a lat-long map in given directions (wraps in φ, clamps in θ).

    Parameters
    ----------
    image : (H, W, C) or (H, W) array
        The map.
    directions : (..., 3) float
        Where to look.

    Returns
    -------
    (..., C) or (...) float64 — bilinear interpolation between the four nearest texel
    centres; columns wrap around (φ is periodic), rows clamp at the poles.
    """
    theta, phi = direction_to_spherical(directions)
    return lookup_angles(np.asarray(image, dtype=float), theta, phi)


def lookup_angles(image: np.ndarray, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """:func:`lookup` at polar angles ``theta`` and azimuths ``phi`` (radians, (...)):
    the directions' angles computed once serve maps of every size (a chain of prefiltered
    maps). The arithmetic is in the image's own float dtype (a float32 map: float32, 1e-7
    relative, twice as fast as float64 at 512²)."""
    img = image
    h, w = img.shape[:2]
    row = np.clip(theta * (h / np.pi) - 0.5, 0.0, h - 1.0)
    col = phi * (w / (2.0 * np.pi)) - 0.5
    r0 = row.astype(np.intp)                              # row ≥ 0: floor
    c0 = np.floor(col).astype(np.intp)
    dtype = img.dtype if img.dtype.kind == "f" else np.float64
    fr, fc = (row - r0).astype(dtype), (col - c0).astype(dtype)
    r1 = np.minimum(r0 + 1, h - 1) * w
    r0 = r0 * w
    c0 %= w                                               # φ wraps
    c1 = c0 + 1
    c1 %= w
    flat = img.reshape(h * w, -1)                         # one gather per corner
    if img.ndim == 3:
        fr, fc = fr[..., None], fc[..., None]
    else:
        flat = flat[:, 0]
    top = np.take(flat, r0 + c0, axis=0).astype(dtype, copy=False)
    right = np.take(flat, r0 + c1, axis=0) - top
    right *= fc
    top += right                                          # the upper row, in place
    bottom = np.take(flat, r1 + c0, axis=0).astype(dtype, copy=False)
    right = np.take(flat, r1 + c1, axis=0) - bottom
    right *= fc
    bottom += right
    bottom -= top
    bottom *= fr
    top += bottom
    return top


def downsample(image: np.ndarray, factor: int) -> np.ndarray:
    """Reduce a map by an integer factor in both axes, averaging by solid angle.

    A coarse texel's value is ∫ L dω / ∫ dω over the factor × factor fine texels it covers
    (fine rows weighted by their exact solid angle), so ∫ L dω over every coarse texel, and
    over the sphere, is kept exactly: a box filter in solid angle.

    Parameters
    ----------
    image : (H, W, C) or (H, W) array
        The map; H and W must be divisible by ``factor``.
    factor : int
        ≥ 1.

    Returns
    -------
    (H / factor, W / factor[, C]) float64.
    """
    img = np.asarray(image, dtype=float)
    h, w = img.shape[:2]
    if factor == 1:
        return img.copy()
    if h % factor or w % factor:
        raise ValueError(f"a {h} × {w} map cannot be reduced by {factor}")
    omega = row_solid_angles(h, w)
    shape = (-1, 1) + (1,) * (img.ndim - 2)
    # strided sums over the factor × factor fine texels (faster than a reshape-sum)
    rows = sum(img[k::factor] * omega[k::factor].reshape(shape) for k in range(factor))
    summed = sum(rows[:, k::factor] for k in range(factor))
    coarse_omega = omega.reshape(h // factor, factor).sum(axis=1) * factor
    return summed / coarse_omega.reshape(shape)


#: Ratio of consecutive exponents of a prefiltered chain (``gonio prefilter --chain``):
#: a lobe between two levels is mixed from both (gonio_cli.render.env_model).
CHAIN_RATIO = 2.0


def chain_exponents(height: int, maximum: float = 1e6) -> list[float]:
    """Exponents 1, 2, 4, … of a prefiltered chain for a map ``height`` texels high, up to
    the first whose lobe (σ ≈ 1/√E rad) is no wider than a texel (π/H): that level is the
    map itself, so the chain reaches a mirror. A 1k map (H = 512): 1 … 32768 (16 maps).
    No exponent exceeds ``maximum`` (gonio prefilter's largest)."""
    texel = np.pi / float(height)
    out = [1.0]
    while 1.0 / np.sqrt(out[-1]) > texel and out[-1] * CHAIN_RATIO <= maximum:
        out.append(out[-1] * CHAIN_RATIO)
    return out
