"""An environment's light as K directions of equal flux: the median cut of Debevec 2005.

The occlusion of environment light (:mod:`.occlusion`) asks, per sample, what share of
its diffuse irradiance E(N) = ∫ L(ω) max(0, N·ω) dω the scene lets through. It samples
the sky where its light is: the lat-long map is cut into K regions of (nearly) equal
luminous flux Φ_k = Σ_texels Y Ω (P. Debevec 2005, "A median cut algorithm for light
probe sampling", SIGGRAPH poster: cut a region across its longer side, its width
measured × sin θ, where the flux on either side is equal), each region standing for a
small area light — its flux Φ_k, its flux-weighted mean direction ω_k, its solid angle
Ω_k. Regions are stratified by construction: every part of the sphere belongs to one,
dark parts (the ground) to few large ones, bright parts (the sky near the sun) to many
small ones. K need not be a power of two: the brightest region is cut next.

Which map: the environment's residual (``gonio prefilter --sun`` has taken the sun out
as a light of its own, which casts its own shadow), read at the level of the chain with
the fewest texels and, among those, the sharpest exponent (quarry_01's chain: E = 64 on
128 × 64: lobes ~10° wide, finer than the regions of K ≤ 64, ~0.2 sr and ~30° across
or more). Without ``--sun`` the map keeps its sun, and the cut puts regions round it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..envmap import pixel_directions, solid_angles
from ..envsun import luminance

#: Widest angular diameter (degrees) of a region's equivalent disc as a light: a dark
#: region (the ground under a bright sky) can span 90°; its penumbra is modelled as a
#: disc seen through a cone (:mod:`.shadow`), and a cone wider than this would make the
#: shadow maps' margins (tan of half the angle × the blockers' distance) wider than the
#: scene. Regions holding a 1/K share of the flux are narrower than this for skies whose
#: ground is at least ~1/10 as bright as the sky at K = 16.
MAX_SPREAD_DEG = 60.0


@dataclass(frozen=True)
class SkyDirections:
    """K regions of an environment map as lights.

    direction : (K, 3) unit vectors towards each region's flux-weighted centre (world, +y up)
    flux : (K,) Σ Y Ω over the region (luminance × sr: the luminous irradiance it gives
        a surface facing it, before the cosine)
    solid_angle_sr : (K,) the region's solid angle
    angular_diameter_deg : (K,) the disc of that solid angle on a plane across the
        axis, 2 arctan √(Ω / π), at most :data:`MAX_SPREAD_DEG`
    """

    direction: np.ndarray
    flux: np.ndarray
    solid_angle_sr: np.ndarray
    angular_diameter_deg: np.ndarray


def _cut(sums: np.ndarray, lo: int, hi: int) -> int:
    """The index in (lo, hi) where the running flux ``sums`` (cumulative, with a leading
    0: sums[i] = flux of [lo', i)) reaches half of [lo, hi)."""
    half = 0.5 * (sums[lo] + sums[hi])
    i = int(np.searchsorted(sums[lo:hi + 1], half)) + lo
    # the nearer of the two indices around the half, kept inside (lo, hi)
    if i > lo and abs(sums[i - 1] - half) <= abs(sums[min(i, hi)] - half):
        i -= 1
    return min(max(i, lo + 1), hi - 1)


def median_cut(energy: np.ndarray, k: int) -> list[tuple[int, int, int, int]]:
    """``k`` regions (r0, r1, c0, c1), half-open texel ranges, of a lat-long map whose
    texels hold ``energy`` (H, W) ≥ 0 (luminance × solid angle), of nearly equal energy:
    the region with the most energy is cut next, across its longer side (rows span π / H
    each, columns 2π / W × sin θ at the region's middle), where the energy on either
    side is equal. Fewer than ``k`` when every region is one texel."""
    h, w = energy.shape
    sat = np.zeros((h + 1, w + 1))
    sat[1:, 1:] = np.cumsum(np.cumsum(energy, axis=0), axis=1)

    def total(r):
        r0, r1, c0, c1 = r
        return sat[r1, c1] - sat[r0, c1] - sat[r1, c0] + sat[r0, c0]

    regions = [(0, h, 0, w)]
    while len(regions) < k:
        splittable = [i for i, r in enumerate(regions) if r[1] - r[0] > 1 or r[3] - r[2] > 1]
        if not splittable:
            break
        i = max(splittable, key=lambda j: total(regions[j]))
        r0, r1, c0, c1 = regions.pop(i)
        mid = np.pi * (r0 + r1) / (2.0 * h)
        across = (c1 - c0) * 2.0 * np.pi / w * np.sin(mid)
        if c1 - c0 > 1 and (across > (r1 - r0) * np.pi / h or r1 - r0 == 1):
            sums = sat[r1, :] - sat[r0, :]                      # columns' running flux
            c = _cut(sums, c0, c1)
            regions += [(r0, r1, c0, c), (r0, r1, c, c1)]
        else:
            sums = sat[:, c1] - sat[:, c0]                      # rows' running flux
            r = _cut(sums, r0, r1)
            regions += [(r0, r, c0, c1), (r, r1, c0, c1)]
    return regions


def sky_directions(rgb: np.ndarray, k: int) -> SkyDirections:
    """The :func:`median_cut` of a lat-long linear-sRGB map ``rgb`` (H, W, 3) into ``k``
    regions by luminance (:data:`gonio_cli.envsun.SRGB_LUMINANCE`) × texel solid angle,
    as :class:`SkyDirections`. A region of zero flux keeps its geometric centre."""
    h, w = rgb.shape[:2]
    omega = solid_angles(h, w)
    energy = np.maximum(luminance(rgb), 0.0) * omega
    dirs = pixel_directions(h, w)
    out_d, out_f, out_o = [], [], []
    for r0, r1, c0, c1 in median_cut(energy, k):
        e = energy[r0:r1, c0:c1]
        o = omega[r0:r1, c0:c1]
        d = dirs[r0:r1, c0:c1]
        weight = e if e.sum() > 0 else o
        mean = (d * weight[..., None]).sum(axis=(0, 1))
        out_d.append(mean / np.linalg.norm(mean))
        out_f.append(float(e.sum()))
        out_o.append(float(o.sum()))
    omega_k = np.asarray(out_o)
    # the disc on a plane across the axis whose area, seen from a unit distance, is Ω
    # (tan(α/2) = √(Ω/π)): the shadow maps take a light's disc on such planes
    diameter = np.degrees(2.0 * np.arctan(np.sqrt(omega_k / np.pi)))
    return SkyDirections(np.asarray(out_d), np.asarray(out_f), omega_k,
                         np.minimum(diameter, MAX_SPREAD_DEG))


def environment_directions(environment, k: int) -> SkyDirections:
    """:func:`sky_directions` of a :class:`gonio_cli.render.environment.Environment`
    at the level with the fewest texels, the sharpest among those (module docstring);
    kept on the environment per ``k``."""
    key = ("skycut", int(k))
    if key not in environment.maps:
        sizes = [int(s[0]) * int(s[1]) for s in environment.shapes]
        smallest = min(sizes)
        level = max((i for i, s in enumerate(sizes) if s == smallest),
                    key=lambda i: environment.exponents[i])
        environment.maps[key] = sky_directions(environment.level(level), k)
    return environment.maps[key]
