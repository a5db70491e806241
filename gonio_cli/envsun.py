"""The sun of an HDR sky as a light of its own: split, measured, filled.

A prefiltered map cannot cast a shadow: a sun folded into P_E lights the shadow side of
an occluder as much as the lit side. :func:`split_sun` takes the sun out of a lat-long
map (docs/conventions.md, "Images, maps") as a small light — direction, irradiance at
normal incidence, size — that a renderer can shadow, and returns the rest of the map
(the *residual*) with the sun's texels filled by the surrounding sky, to be prefiltered.

The rule (docs/envsun.md):

1. **Sky level** S: the luminance Y (linear sRGB, :data:`SRGB_LUMINANCE`) that all but
   the brightest ``1 − SKY_QUANTILE`` of the sphere's *solid angle* stay under. A sun
   (even bloomed to a few degrees: ≤ 0.03 % of the sphere) cannot move it; it is the
   level of the brightest extended sky (sunlit clouds, the horizon's glow).
2. **Candidates**: texels with Y > ``SUN_CONTRAST`` × S, grouped into connected regions
   on the sphere (8-neighbours; column 0 and column W − 1 are neighbours; the texels of
   the first (last) row all meet at the zenith (nadir)). The region carrying the most
   luminous flux Σ Y Ω is the sun — if it is **compact**: every texel centre within
   ``MAX_SUN_RADIUS_DEG`` (or ``MIN_RADIUS_TEXELS`` texel pitches on a coarse map) of its
   flux-weighted centroid. No candidate, or a region wider than that (a window, a bright
   overcast patch), gives no sun.
3. **Removed texels**: the region plus a margin of ``MARGIN_TEXELS`` texel (the sun's
   partly covered edge texels, below the threshold, and its aureole's first ring).
4. **Fill**: the removed texels get the harmonic (Laplace–Beltrami) interpolation of the
   texels around them, per channel, capped at the texel's own value: residual =
   min(fill, L). The sun is what is left, L − residual ≥ 0, so residual + sun = map
   exactly and nothing is counted twice.

The sun's irradiance at normal incidence is E = Σ_j (L_j − residual_j) Ω_j over the removed
texels (E = ∫ L dω of a small source); its direction the net-luminance-weighted mean of
the texel directions, normalised (the right direction for a small source).

The core is pure numpy/scipy (STYLE 1): no printing, no files.
"""

from __future__ import annotations

import functools
import time
from dataclasses import dataclass

import numpy as np

from . import envmap
from .errors import InputError, num

#: Luminance of linear sRGB: the Y row of the IEC 61966-2-1 RGB → XYZ matrix (D65), to the
#: standard's four decimals; tests/test_envsun.py checks it against colour-science's matrix
#: (gonio_cli.spectra), which is not imported here (it costs ~1.5 s).
SRGB_LUMINANCE = np.array([0.2126, 0.7152, 0.0722])

#: The sky level is the luminance below which this share of the sphere's solid angle lies.
#: 1 % of the sphere (0.126 sr, a cap 23° across) is ~2000 × the solid angle of the sun
#: (6.8e-5 sr) and still ~30 × that of a sun bloomed to 4° across, so no sun moves it.
SKY_QUANTILE = 0.99

#: A sun's texels exceed the sky level by at least this factor. A clear-sky sun is 10⁴ to
#: 10⁵ × the sky on an unclipped map (quarry_01: 3·10⁴), a sunset sun behind haze ~25 ×
#: (venice_sunset: 43.8 against 1.7); on those skies nothing farther than 10° from the sun
#: exceeds 2.7 × the sky level (3.4 × beyond 5°, an aureole). 8 sits between.
SUN_CONTRAST = 8.0

#: Largest angular radius (about its centroid) of a region taken for a sun, degrees.
#: The sun's disc has a radius of 0.27°; photographed suns bloom, and the aureole above the
#: threshold reaches ~3° on the 1k skies measured (docs/envsun.md). A region wider than
#: 5° is not a small source (a window, a bright patch of overcast), and a directional light
#: would give it a shadow far too sharp.
MAX_SUN_RADIUS_DEG = 5.0

#: On a coarse map the allowed radius is at least this many texel pitches (π / H): a sun
#: straddling a texel corner covers a 2 × 2 block whatever its size.
MIN_RADIUS_TEXELS = 2.0

#: The sun (the brightest region above the threshold, with its fragments within the radius
#: above) holds at least this share of the luminous flux of all texels above the threshold.
#: Outdoors it holds all of it (1.0 on the three 1k skies measured) or most (a sun and its
#: reflection on water at a Fresnel reflectance of 0.5 give 0.67); an interior lit by
#: several lamps gives less (royal_esplanade, a ship's atrium: 0.49): no single direction
#: then stands for its light, and every lamp stays in the prefiltered map.
SUN_DOMINANCE = 0.6

#: The removed texels are the region grown by this many texels (8-neighbours): a disc's
#: partly covered edge texels (below the threshold, yet holding some of the sun) go with it.
MARGIN_TEXELS = 1


@dataclass(frozen=True)
class Sun:
    """The sun split off an environment map: a small light a renderer can shadow.

    Attributes
    ----------
    direction : (3,) float64
        Unit vector towards the sun, in the map's world frame (+y up).
    irradiance_rgb : (3,) float64
        Linear-sRGB irradiance at normal incidence, Σ (L_j − residual_j) Ω_j over the
        removed texels (radiance · sr).
    solid_angle_sr : float
        Solid angle of the removed texels (the region and its margin).
    angular_diameter_deg : float
        Diameter of the equivalent disc: the disc of uniform radiance equal to the sun's
        brightest net texel that holds the sun's luminous irradiance, 2 arccos(1 −
        E_Y / (2π L_peak)). The disc's size for a resolved sun; never much below a texel
        for a sun smaller than one (a 1k map's texels are 0.35° across, the sun 0.53°).
    texels : int
        Number of removed texels.
    flux_share : float
        The sun's share of the map's luminous flux ∫ Y dω over the sphere.
    fill_share : float
        Share of the map's luminous flux the fill kept in the residual at the removed
        texels (the sky behind the sun).
    peak_to_sky : float
        Brightest texel's luminance over the sky level (inf on a map with black sky).
    time_s : float
        Time the split took.
    """

    direction: np.ndarray
    irradiance_rgb: np.ndarray
    solid_angle_sr: float
    angular_diameter_deg: float
    texels: int
    flux_share: float
    fill_share: float
    peak_to_sky: float
    time_s: float

    @property
    def theta_deg(self) -> float:
        """Polar angle of :attr:`direction` from +y (the zenith), degrees."""
        return float(np.degrees(envmap.direction_to_spherical(self.direction)[0]))

    @property
    def phi_deg(self) -> float:
        """Azimuth of :attr:`direction` in the map's convention, degrees in [0, 360)."""
        return float(np.degrees(envmap.direction_to_spherical(self.direction)[1]))


@dataclass(frozen=True)
class SunRegion:
    """What :func:`find_sun_region` found: the texels to remove, or why there are none.

    ``mask`` (H, W) bool is the removed texels (region and margin), None without a sun;
    ``reason`` says why not ('' with one). ``sky_level`` and ``threshold`` are luminances.
    """

    mask: np.ndarray | None
    sky_level: float
    threshold: float
    peak_to_sky: float
    reason: str


# --------------------------------------------------------------------------- input --

def validate_env(env) -> np.ndarray:
    """The map as float64 (H, W, 3); anything else, NaN, ±inf or negative is an InputError.

    The message names the first bad texel (row, col, 0-based), its value and the count.
    """
    a = np.asarray(env, dtype=np.float64)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 1 or a.shape[1] < 2:
        raise InputError(f"an environment map of shape {a.shape} is not (H, W, 3) lat-long "
                         "RGB", fix="pass an equirectangular RGB map, H ≥ 1, W ≥ 2")
    bad_values = ~(np.isfinite(a) & (a >= 0.0))
    bad = bad_values.any(axis=2)
    if bad.any():
        row, col = (int(v) for v in np.argwhere(bad)[0])
        value = a[row, col][bad_values[row, col]][0]
        count = int(bad.sum())
        raise InputError(f"environment map texel (row {row}, col {col}) is {num(value)}; "
                         f"{count} texel{'s are' if count > 1 else ' is'} NaN, inf or "
                         "negative", fix="repair the map (gonio prefilter --fix-invalid)")
    return a


def luminance(env: np.ndarray) -> np.ndarray:
    """Luminance Y (H, W) of a linear-sRGB map (H, W, 3): env · :data:`SRGB_LUMINANCE`."""
    return np.asarray(env, dtype=float) @ SRGB_LUMINANCE


def sky_level(y: np.ndarray, omega: np.ndarray, quantile: float = SKY_QUANTILE) -> float:
    """The luminance below which ``quantile`` of the sphere's solid angle lies.

    y, omega : (H, W) luminance and texel solid angles (sr). Returns the smallest texel
    luminance whose cumulative solid angle (texels sorted by luminance) reaches
    ``quantile`` × 4π.
    """
    order = np.argsort(y, axis=None, kind="stable")
    cumulative = np.cumsum(omega.ravel()[order])
    k = int(np.searchsorted(cumulative, quantile * cumulative[-1]))
    return float(y.ravel()[order[min(k, order.size - 1)]])


# ---------------------------------------------------------- connectivity on the sphere --

def dilate(mask: np.ndarray, steps: int = 1) -> np.ndarray:
    """Grow a (H, W) bool mask by ``steps`` texels (8-neighbours) on the sphere.

    Columns wrap (φ is periodic); beyond the first (last) row lie the texels of the same
    row across the pole (φ + π), as a great circle through the pole runs.
    """
    out = np.asarray(mask, dtype=bool).copy()
    h, w = out.shape
    for _ in range(steps):
        grown = out | np.roll(out, 1, axis=1) | np.roll(out, -1, axis=1)
        rows = grown.copy()
        rows[1:] |= grown[:-1]
        rows[:-1] |= grown[1:]
        across = np.roll(grown[[0, -1]], w // 2, axis=1)   # over the poles
        rows[0] |= across[0]
        rows[-1] |= across[1]
        out = rows
    return out


def label_sphere(mask: np.ndarray) -> tuple[np.ndarray, int]:
    """Connected regions of a (H, W) bool mask on the sphere (8-neighbours).

    Like ``scipy.ndimage.label``, but column W − 1 touches column 0 (rows r − 1, r, r + 1),
    and all texels of the first row touch (they meet at the zenith), as do those of the
    last row (the nadir). Returns labels (H, W) int (0 outside the mask, 1..n) and n.
    """
    from scipy import ndimage
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    labels, n = ndimage.label(mask, structure=np.ones((3, 3), dtype=bool))
    if n <= 1:
        return labels, n
    h = labels.shape[0]
    pairs = []
    for dr in (-1, 0, 1):   # the seam: (r, W − 1) and (r + dr, 0)
        r = np.arange(max(0, -dr), min(h, h - dr))
        pairs.append(np.stack([labels[r, -1], labels[r + dr, 0]], axis=1))
    for row in (0, h - 1):   # a pole: every labelled texel of its row
        present = np.unique(labels[row][labels[row] > 0])
        pairs.append(np.stack([present[:-1], present[1:]], axis=1))
    pairs = np.concatenate(pairs)
    pairs = pairs[(pairs > 0).all(axis=1)] - 1
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    n_merged, component = connected_components(graph, directed=False)
    merged = np.zeros_like(labels)
    merged[labels > 0] = component[labels[labels > 0] - 1] + 1
    return merged, int(n_merged)


# ------------------------------------------------------------------------ detection --

def _texel_directions(rows: np.ndarray, cols: np.ndarray, shape) -> np.ndarray:
    """Directions (n, 3) of the centres of texels (rows, cols) of a map of ``shape``."""
    return envmap.spherical_to_direction(envmap.pixel_theta(shape[0])[rows],
                                         envmap.pixel_phi(shape[1])[cols])


def region_centre(mask: np.ndarray, weight: np.ndarray) -> tuple[np.ndarray, float]:
    """Weighted mean direction (3,), normalised, of the texel centres of ``mask`` (H, W)
    and the largest angle (rad) from it to one of them. ``weight`` (H, W) ≥ 0, e.g. Y Ω;
    all zero gives the unweighted mean."""
    rows, cols = np.nonzero(mask)
    dirs = _texel_directions(rows, cols, mask.shape)
    centre = (weight[rows, cols][:, None] * dirs).sum(axis=0)
    if not np.linalg.norm(centre) > 0.0:
        centre = dirs.sum(axis=0)
    centre = centre / np.linalg.norm(centre)
    return centre, float(np.arccos(np.clip(dirs @ centre, -1.0, 1.0)).max())


def _label_centres(labels: np.ndarray, n: int, weight: np.ndarray) -> np.ndarray:
    """Weighted mean direction (n, 3), normalised, of each labelled region 1..n."""
    rows, cols = np.nonzero(labels)
    sums = np.zeros((n + 1, 3))
    np.add.at(sums, labels[rows, cols],
              weight[rows, cols][:, None] * _texel_directions(rows, cols, labels.shape))
    sums = sums[1:]
    return sums / np.maximum(np.linalg.norm(sums, axis=1, keepdims=True), np.finfo(float).tiny)


def find_sun_region(env, *, contrast: float = SUN_CONTRAST,
                    max_radius_deg: float = MAX_SUN_RADIUS_DEG) -> SunRegion:
    """The texels :func:`split_sun` removes, or the reason there is no sun (module rule).

    ``env`` (H, W, 3) linear-sRGB lat-long map (validated); ``contrast`` the threshold
    over the sky level (:data:`SUN_CONTRAST`); ``max_radius_deg`` the largest radius of a
    sun (:data:`MAX_SUN_RADIUS_DEG`).
    """
    return _find(validate_env(env), contrast, max_radius_deg)


def _find(a: np.ndarray, contrast: float, max_radius_deg: float) -> SunRegion:
    """:func:`find_sun_region` of a validated map (the module's rule, steps 1–3)."""
    h, w = a.shape[:2]
    y = luminance(a)
    omega = envmap.solid_angles(h, w)
    flux = y * omega
    sky = sky_level(y, omega)
    peak = float(y.max())
    peak_to_sky = peak / sky if sky > 0.0 else (np.inf if peak > 0.0 else 0.0)
    threshold = contrast * sky
    found = functools.partial(SunRegion, sky_level=sky, threshold=threshold,
                              peak_to_sky=peak_to_sky)
    labels, n = label_sphere(y > threshold)
    if n == 0:
        return found(None, reason=f"no texel is brighter than {contrast:g} × the sky level "
                                  f"{sky:.4g} (the peak is {peak_to_sky:.3g} × it)")
    region_flux = np.bincount(labels.ravel(), weights=flux.ravel(), minlength=n + 1)[1:]
    centres = _label_centres(labels, n, flux)
    limit = max(np.radians(max_radius_deg), MIN_RADIUS_TEXELS * np.pi / h)
    near = centres @ centres[int(np.argmax(region_flux))] >= np.cos(limit)  # its fragments
    region = np.isin(labels, np.nonzero(near)[0] + 1)
    _, radius = region_centre(region, flux)
    if radius > limit:
        return found(None, reason=f"the brightest region above {contrast:g} × the sky level "
                                  f"reaches {np.degrees(radius):.3g}° from its centre, more "
                                  f"than {np.degrees(limit):.3g}°: not a small source")
    share = float(region_flux[near].sum() / region_flux.sum())
    if share < SUN_DOMINANCE:
        return found(None, reason=f"the brightest of {n} compact sources holds "
                                  f"{100 * share:.0f} % of their light (< "
                                  f"{100 * SUN_DOMINANCE:.0f} %): several lights, no one sun")
    mask = dilate(region, MARGIN_TEXELS)
    if mask.all():
        return found(None, reason=f"the sun would cover the whole {h} × {w} map")
    return found(mask, reason="")


# ----------------------------------------------------------------------------- fill --

def _edge_weights(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Finite-volume Laplace–Beltrami weights of a lat-long grid: shared edge length over
    the distance between the centres (both on the unit sphere).

    Returns ``ns`` (H − 1,), between rows r and r + 1 (sin θ_{r+1 edge} Δφ / Δθ), and ``ew``
    (H,), between neighbours in row r (Δθ / (sin θ_r Δφ)). Across a pole the shared edge
    is a point: weight 0.
    """
    d_theta, d_phi = np.pi / height, 2.0 * np.pi / width
    edges = np.pi * np.arange(1, height) / height
    ns = np.sin(edges) * d_phi / d_theta
    ew = d_theta / (np.sin(envmap.pixel_theta(height)) * d_phi)
    return ns, ew


def harmonic_fill(env: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Harmonic interpolation (H, W, 3) of ``env`` into the texels of ``mask``.

    Inside the mask the result solves the discrete Laplace–Beltrami equation on the
    sphere (:func:`_edge_weights`; columns wrap) with the texels around the mask as its
    boundary values; outside it equals ``env``. Every value inside is a weighted mean of
    the boundary's (the maximum principle): no overshoot, never negative. Every connected
    part of the mask must touch a texel outside it.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.linalg import spsolve

    h, w = mask.shape
    ns, ew = _edge_weights(h, w)
    index = np.full((h, w), -1)
    rows, cols = np.nonzero(mask)
    n = rows.size
    index[rows, cols] = np.arange(n)
    diag = np.zeros(n)
    rhs = np.zeros((n, 3))
    ii, jj, vv = [], [], []
    links = [(rows, (cols + 1) % w, ew[rows]), (rows, (cols - 1) % w, ew[rows])]
    up, down = rows > 0, rows < h - 1
    links += [(rows[up] - 1, cols[up], ns[rows[up] - 1]),
              (rows[down] + 1, cols[down], ns[rows[down]])]
    sources = [np.arange(n), np.arange(n), np.nonzero(up)[0], np.nonzero(down)[0]]
    for src, (r2, c2, weight) in zip(sources, links):
        np.add.at(diag, src, weight)
        j = index[r2, c2]
        inside = j >= 0
        ii.append(src[inside])
        jj.append(j[inside])
        vv.append(-weight[inside])
        np.add.at(rhs, src[~inside], weight[~inside, None] * env[r2[~inside], c2[~inside]])
    ii, jj, vv = (np.concatenate(x) for x in (ii, jj, vv))
    matrix = coo_matrix((np.concatenate([vv, diag]),
                         (np.concatenate([ii, np.arange(n)]),
                          np.concatenate([jj, np.arange(n)]))), shape=(n, n)).tocsc()
    values = spsolve(matrix, rhs).reshape(n, 3)
    out = np.array(env, dtype=float, copy=True)
    out[rows, cols] = np.maximum(values, 0.0)   # ≥ 0 already, up to round-off
    return out


# ---------------------------------------------------------------------------- split --

def split_sun(env, *, contrast: float = SUN_CONTRAST,
              max_radius_deg: float = MAX_SUN_RADIUS_DEG) -> tuple[np.ndarray, Sun | None]:
    """Split the sun off a lat-long map: the residual to prefilter and the sun as a light.

    Parameters
    ----------
    env : (H, W, 3) float
        Linear-sRGB radiance, lat-long (docs/conventions.md). NaN, ±inf or negative values
        are an :class:`~gonio_cli.errors.InputError`.
    contrast, max_radius_deg : float
        The detection rule's constants (:data:`SUN_CONTRAST`, :data:`MAX_SUN_RADIUS_DEG`).

    Returns
    -------
    residual : (H, W, 3) float64
        The map with the removed texels set to min(harmonic fill, L) per channel; the map
        itself (a copy) without a sun.
    sun : Sun or None
        None when the map has no compact bright source (:func:`find_sun_region` says why).
        residual + the sun's texels (L − residual) is the map exactly.
    """
    start = time.perf_counter()
    a = validate_env(env)
    found = _find(a, contrast, max_radius_deg)
    if found.mask is None:
        return a.copy(), None
    mask = found.mask
    residual = np.minimum(harmonic_fill(a, mask), a)
    h, w = mask.shape
    omega = envmap.solid_angles(h, w)
    net = a[mask] - residual[mask]                                   # (n, 3) ≥ 0
    irradiance = (net * omega[mask][:, None]).sum(axis=0)
    net_y = net @ SRGB_LUMINANCE
    total_y = float((luminance(a) * omega).sum())
    e_y = float(irradiance @ SRGB_LUMINANCE)
    if not e_y > 0.0:
        return a.copy(), None
    direction, _ = region_centre(mask, _scatter(mask, net_y * omega[mask]))
    disc = min(e_y / float(net_y.max()), 4.0 * np.pi)               # sr, ≤ the region's
    sun = Sun(direction=direction,
              irradiance_rgb=irradiance,
              solid_angle_sr=float(omega[mask].sum()),
              angular_diameter_deg=float(np.degrees(2.0 * np.arccos(1.0 - disc / (2 * np.pi)))),
              texels=int(mask.sum()),
              flux_share=e_y / total_y,
              fill_share=float((residual[mask] @ SRGB_LUMINANCE * omega[mask]).sum()) / total_y,
              peak_to_sky=float(found.peak_to_sky),
              time_s=time.perf_counter() - start)
    return residual, sun


def _scatter(mask: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(H, W) array, ``values`` at the texels of ``mask`` (row-major order), 0 elsewhere."""
    out = np.zeros(mask.shape)
    out[mask] = values
    return out
