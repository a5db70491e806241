"""``brute``: every input texel within the lobe's band for every output texel, in blocks —
the exact reference the other methods are checked against."""

from __future__ import annotations

import numpy as np

from .. import envmap
from ..errors import InputError
from .quadrature import (BRUTE_BLOCK, KINK_NODES, band_halfwidth, hot_rows, one_minus_cos,
                         texel_angle, texel_nodes, texel_weights)

# ------------------------------------------------------------------------------ brute --

def _texel_sums(pixels: np.ndarray, rows: np.ndarray, hot_mask: np.ndarray,
                theta_a: np.ndarray, phi_a: np.ndarray, exponent: float
                ) -> tuple[np.ndarray, np.ndarray]:
    """Σ_j L_j ∫_j k and Σ_j ∫_j k over the texels of input ``rows`` for output directions
    (θ_a, φ_a) (B,): (B, C) and (B,), k divided by the nearest texel centre's value.
    Hot texels (``hot_mask``, (H, W)) are integrated with their own node count."""
    h, w, _ = pixels.shape
    tb = envmap.pixel_theta(h)[rows][None, :, None]
    ta = np.asarray(theta_a, float)[:, None, None]
    dphi = np.asarray(phi_a, float)[:, None, None] - envmap.pixel_phi(w)[None, None, :]
    nearest = one_minus_cos(ta, tb, np.sin(0.5 * dphi) ** 2).min(axis=(1, 2), keepdims=True)
    if np.any(nearest >= 1.0):
        raise InputError("the map is too small: an output direction sees no texel",
                         fix="use a map with more texels")
    log_peak = np.log1p(-nearest)
    size = texel_angle(h, w)
    nodes, hot_nodes = texel_nodes(exponent, size, False), texel_nodes(exponent, size, True)
    wgt = texel_weights(ta, tb, dphi, h, w, exponent, log_peak, nodes)
    hot = hot_mask[rows]
    hot_r = np.nonzero(hot.any(axis=1))[0]
    if hot_r.size:
        got = texel_weights(ta, tb[:, hot_r], dphi, h, w, exponent, log_peak, hot_nodes,
                            kink_nodes=KINK_NODES)
        wgt[:, hot_r] = np.where(hot[hot_r], got, wgt[:, hot_r])
    b = wgt.shape[0]
    num = wgt.reshape(b, -1) @ pixels[rows].reshape(-1, pixels.shape[2])
    return num, wgt.reshape(b, -1).sum(axis=1)


def brute_at(pixels: np.ndarray, exponent: float, directions: np.ndarray) -> np.ndarray:
    """P_E at given directions from every input texel, each integrated over its area
    (:func:`texel_weights`; hot texels, :func:`hot_rows`, with more nodes). Rows beyond
    :func:`band_halfwidth` (weight < KERNEL_CUTOFF of the peak) are left out.

    Parameters
    ----------
    pixels : (H, W, C) float
        Input map.
    exponent : float
        E.
    directions : (N, 3) float
        Unit output directions.

    Returns
    -------
    (N, C) float64.
    """
    h, w, c = pixels.shape
    values = pixels.astype(np.float64)
    theta_a, phi_a = envmap.direction_to_spherical(directions)
    _, hot = hot_rows(values)
    theta_b = envmap.pixel_theta(h)
    reach = band_halfwidth(exponent) + np.pi / h
    out = np.empty((len(theta_a), c))
    block = max(1, BRUTE_BLOCK // (h * w))
    for start in range(0, len(theta_a), block):
        sl = slice(start, start + block)
        rows = np.nonzero((theta_b >= theta_a[sl].min() - reach)
                          & (theta_b <= theta_a[sl].max() + reach))[0]
        num, den = _texel_sums(values, rows, hot, theta_a[sl], phi_a[sl], exponent)
        out[sl] = num / den[:, None]
    return out


def prefilter_brute(pixels: np.ndarray, exponent: float, levels: int,
                    inputs=None) -> tuple[np.ndarray, tuple]:
    """``brute``: every input texel, integrated over its area, for every output texel
    (H/2^k × W/2^k output)."""
    h, w, _ = pixels.shape
    ho, wo = h // 2 ** levels, w // 2 ** levels
    dirs = envmap.pixel_directions(ho, wo).reshape(-1, 3)
    return brute_at(pixels, exponent, dirs).reshape(ho, wo, -1), (h, w)
