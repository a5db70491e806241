"""The lobe integrated over input texels (both methods' quadrature): the lobe's weights, the
Gauss–Legendre texel integrals, the band of input rows a lobe reaches, and the hot texels
(a sun) that get more nodes and their own pass. :mod:`gonio_cli.prefilter`'s docstring
has the sums."""

from __future__ import annotations

import functools

import numpy as np

from .. import envmap
from .inputs import lobe_sigma

#: Kernel values below this fraction of a texel's peak weight are left out (input rows
#: outside the band). Even a sun 10⁵ × the sky then changes a texel by < 1e-5 of the sky.
KERNEL_CUTOFF = 1e-10
#: Texels brighter than this × the median texel (brightest channel) are "hot" (a sun):
#: ``ring`` convolves their rows at the input resolution instead of the working map.
HOT_RATIO = 100.0
#: At most this many input rows are treated as hot (those with the brightest texels);
#: hot texels of further rows stay in the working map (a map that bright everywhere has
#: no single sun to protect). Bounds the full-resolution work.
MAX_HOT_ROWS = 64
#: Elements (output × input texels) of one block of ``brute``: 32 MiB of float64.
BRUTE_BLOCK = 1 << 22


# ---------------------------------------------------------------------------- kernels --

#: Largest log-weight allowed: full-resolution hot rows can lie a little nearer an output
#: texel than the working map's nearest texel that sets the peak (E·Δ log c ≪ 1); this
#: bound only guards exp against overflow.
LOG_WEIGHT_MAX = 600.0


def lobe_weights(one_minus_cos: np.ndarray, exponent: float, log_peak) -> np.ndarray:
    """k(c) / k(c_peak) = exp(E (log c − log c_peak)) for c = r·ω > 0, else 0.

    Parameters
    ----------
    one_minus_cos : (...) float
        u = 1 − r·ω; passed as u so that log c = log1p(−u) keeps its precision for narrow
        lobes (float32 included).
    exponent : float
        E ≥ 1.
    log_peak : float or (...) float, broadcast
        log of the largest cosine for this output texel; dividing by it keeps the weights
        ≤ ~1 so nothing under- or overflows for E up to MAX_EXPONENT (it cancels in P_E).

    Returns
    -------
    (...) float, the dtype of ``one_minus_cos``.
    """
    positive = one_minus_cos < 1.0
    arg = np.log1p(-np.where(positive, one_minus_cos, 0.0))
    arg -= np.asarray(log_peak, dtype=arg.dtype)
    arg *= arg.dtype.type(exponent)
    np.minimum(arg, LOG_WEIGHT_MAX, out=arg)
    np.exp(arg, out=arg)
    arg[~positive] = 0.0
    return arg


# -------------------------------------------------------------------- texel integrals --

#: Each input texel is constant over its area, so its weight is the lobe integrated over
#: the texel, by Gauss–Legendre quadrature with n × n nodes (n = 1: the centre, the
#: midpoint rule). Hot texels (a sun 10⁵ × the sky) need it most: their weight is the
#: whole answer near them, and across one texel the lobe can change by e^10 (E = 512 on a
#: 64 × 32 map) or have its kink at the terminator (E = 1). Hot texels get
#: HOT_NODES_PER_SIGMA nodes per axis for every lobe σ of texel size, at least
#: HOT_MIN_NODES: on a 64 × 32 sky with a sun 10⁵ × the sky the maps of E = 1…512 are
#: then within 0.25 % (p99) of the area-true average (tests/test_prefilter.py).
HOT_NODES_PER_SIGMA = 2.0
HOT_MIN_NODES = 3
#: For E < 2 the lobe has a kink at the terminator (max(0, c)^E with c crossing 0), where
#: Gauss–Legendre converges only as 1/n²: hot texels the terminator crosses get this many
#: nodes per axis instead (a few texels per output row, so the price is small).
KINK_NODES = 15
#: Other texels (contrast ≤ HOT_RATIO) keep the midpoint rule while a texel spans at most
#: MIDPOINT_MAX_TEXEL_SIGMA lobe σ (Δ/σ ≤ 0.5: the midpoint weights of a textured sky
#: are then within 0.3 % of the area average), and get NODES_PER_SIGMA nodes per σ beyond.
MIDPOINT_MAX_TEXEL_SIGMA = 0.5
NODES_PER_SIGMA = 1.5
#: Texels across which log k changes by less than this keep the midpoint rule whatever
#: their node count (its relative error is then ≲ 0.15²/24 ≈ 1e-3): on large maps only
#: the texels near a narrow lobe's peak or far down its flanks need nodes.
NODE_SLOPE_MAX = 0.15
#: At most this many nodes per axis: for a lobe narrower than 1/4 of a hot texel (E over
#: 2.6·10⁴ on a 256 × 128 map, over 10⁶ on 2048 × 1024) the quadrature no longer resolves
#: the lobe; numerator and denominator still use the same nodes, so a constant map stays
#: constant and a lobe centred on a texel still returns it.
MAX_NODES = 9


def texel_angle(height: int, width: int) -> float:
    """The larger side of a texel of an H × W map, in radians: max(π/H, 2π/W)."""
    return max(np.pi / height, 2.0 * np.pi / width)


def texel_nodes(exponent: float, texel: float, hot: bool) -> int:
    """Gauss–Legendre nodes per axis for texels ``texel`` rad wide under lobe E
    (:data:`HOT_NODES_PER_SIGMA`, :data:`MIDPOINT_MAX_TEXEL_SIGMA`)."""
    x = texel / lobe_sigma(exponent)
    if hot:
        n = max(HOT_MIN_NODES, np.ceil(HOT_NODES_PER_SIGMA * x))
    else:
        n = 1 if x <= MIDPOINT_MAX_TEXEL_SIGMA else np.ceil(NODES_PER_SIGMA * x)
    n = int(min(MAX_NODES, n))
    return n + 1 - n % 2  # odd: the texel's centre is a node, so the weight of the
    # nearest texel (the peak) never underflows, however narrow the lobe


@functools.lru_cache(maxsize=None)
def _gauss_legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss–Legendre nodes on [−½, ½] and weights summing to 1."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * x, 0.5 * w


def one_minus_cos(theta_a, theta_b, hav_dphi, dtype=np.float64) -> np.ndarray:
    """1 − cos γ between directions (θ_a, φ_a) and (θ_b, φ_b), broadcast, in ``dtype``:
    2 sin²((θ_a − θ_b)/2) + 2 sin θ_a sin θ_b sin²((φ_a − φ_b)/2), exact with no
    cancellation for small γ (``hav_dphi`` is sin²((φ_a − φ_b)/2))."""
    a = (2.0 * np.sin(0.5 * (np.subtract(theta_a, theta_b))) ** 2).astype(dtype)
    b = (2.0 * np.sin(theta_a) * np.sin(theta_b)).astype(dtype)
    return a + b * np.asarray(hav_dphi).astype(dtype)


def texel_weights(theta_a, theta_b, dphi, height: int, width: int, exponent: float,
                  log_peak, nodes: int, dtype=np.float64, kink_nodes: int = 0) -> np.ndarray:
    """The lobe weight integrated over whole input texels: Σ_nodes Ω_node k(r·ω_node).

    Parameters
    ----------
    theta_a : float or (...) float
        Polar angle of the output direction r (rad); broadcast with the next two.
    theta_b : (...) float
        Polar angle of the centres of the input texels' rows.
    dphi : (...) float
        φ_a − φ_b from the texel centres (rad).
    height, width : int
        The input grid: texels are π/H × 2π/W.
    exponent, log_peak
        As :func:`lobe_weights` (the weights are k / k_peak).
    nodes : int
        Gauss–Legendre nodes per axis (:func:`texel_nodes`); 1 gives k at the texel
        centre times its solid angle, the midpoint rule.
    kink_nodes : int
        For E < 2, texels the terminator (r·ω = 0) crosses get this many nodes instead,
        if more (:data:`KINK_NODES`).

    Returns
    -------
    (...) ``dtype`` — ∫_texel k dω / k_peak (sr); the node weights of a texel sum exactly
    to its solid angle (:func:`gonio_cli.envmap.band_solid_angles`), so a constant map
    stays constant for any ``nodes``.
    """
    dtheta, dphi_w = np.pi / height, 2.0 * np.pi / width
    args = (theta_a, theta_b, dphi, log_peak)
    if nodes == 1 and not (exponent < 2.0 and kink_nodes > 1):
        return _node_sum(*args, dtheta, dphi_w, exponent, 1, dtype)
    shape = np.broadcast_shapes(*(np.shape(v) for v in args))
    gamma = 2.0 * np.arcsin(np.sqrt(0.5 * np.minimum(
        one_minus_cos(theta_a, theta_b, np.sin(0.5 * np.asarray(dphi)) ** 2), 2.0)))
    # |∇γ| ≤ 1 per radian: no point of the texel is nearer r than γ − its half diagonal
    half_diag = 0.5 * np.hypot(dtheta, dphi_w)
    total = np.array(np.broadcast_to(_node_sum(*args, dtheta, dphi_w, exponent, 1, dtype),
                                     shape))
    if nodes > 1:
        # Nodes only where the midpoint rule is not already within ~0.1 %: where log k
        # changes by more than NODE_SLOPE_MAX across the texel (its slope E tan γ, its
        # curvature ~E near the peak), and the texel can reach KERNEL_CUTOFF of the peak.
        near = np.maximum(gamma - half_diag, 0.0)
        with np.errstate(divide="ignore"):
            reach = exponent * (np.log(np.maximum(np.cos(near), 0.0)) - log_peak) \
                >= np.log(KERNEL_CUTOFF)
            slope = exponent * np.tan(np.minimum(gamma, 0.5 * np.pi)) + np.sqrt(exponent)
        steep = reach & ((gamma >= 0.5 * np.pi) | (slope * 2.0 * half_diag > NODE_SLOPE_MAX))
        _integrate(total, np.broadcast_to(steep, shape), args, dtheta, dphi_w, exponent,
                   nodes, dtype)
    if exponent < 2.0 and kink_nodes > nodes:
        # the terminator crosses texels within a half diagonal of γ = π/2
        cross = np.broadcast_to(np.abs(gamma - 0.5 * np.pi) <= half_diag, shape)
        _integrate(total, cross, args, dtheta, dphi_w, exponent, kink_nodes, dtype)
    return total


def _integrate(total: np.ndarray, where: np.ndarray, args, dtheta: float, dphi_w: float,
               exponent: float, nodes: int, dtype) -> None:
    """Set ``total[where]`` to :func:`_node_sum` of the selected texels only."""
    if not where.any():
        return
    picked = [np.broadcast_to(np.asarray(v, np.float64), total.shape)[where] for v in args]
    # all nodes of a chunk of texels at once: (texels, n, n) arrays, ≤ BRUTE_BLOCK elements
    x = _gauss_legendre(nodes)[0]
    step = max(1, BRUTE_BLOCK // nodes ** 2)
    sums = np.empty(picked[0].size, dtype)
    for i in range(0, sums.size, step):
        ta, tb, dphi, peak = (v[i:i + step, None, None] for v in picked)
        sums[i:i + step] = _node_sum(ta, tb, dphi, peak, dtheta, dphi_w, exponent, nodes,
                                     dtype, x[:, None], x[None, :]).sum(axis=(1, 2))
    total[where] = sums


def _node_sum(theta_a, theta_b, dphi, log_peak, dtheta: float, dphi_w: float,
              exponent: float, nodes: int, dtype, x_theta=None, x_phi=None) -> np.ndarray:
    """Σ over n × n Gauss–Legendre nodes of texels Δθ × Δφ_w of Ω_node k(r·ω_node), the
    node weights of each texel scaled to sum exactly to its solid angle.

    By default a loop over the nodes; given ``x_theta`` and ``x_phi`` (the nodes as arrays
    broadcasting along new axes), one pass over all of them, returning every node's term
    (the caller sums those axes)."""
    x, wq = _gauss_legendre(nodes)
    theta_b = np.asarray(theta_b, dtype=np.float64)
    if x_theta is not None:
        w_theta, w_phi = wq.reshape(np.shape(x_theta)), wq.reshape(np.shape(x_phi))
        t = theta_b + x_theta * dtheta
        wt = w_theta * np.sin(t)
        scale = envmap.band_solid_angles(theta_b - 0.5 * dtheta, theta_b + 0.5 * dtheta,
                                         dphi_w) / wt.sum(axis=-2, keepdims=True)
        hav = np.sin(0.5 * (np.asarray(dphi) + x_phi * dphi_w)) ** 2
        k = lobe_weights(one_minus_cos(theta_a, t, hav, dtype), exponent, log_peak)
        k *= (wt * scale * w_phi).astype(dtype)
        return k
    sub_theta = [theta_b + xi * dtheta for xi in x]
    sub_w = [wi * np.sin(t) for wi, t in zip(wq, sub_theta)]
    scale = envmap.band_solid_angles(theta_b - 0.5 * dtheta, theta_b + 0.5 * dtheta,
                                     dphi_w) / sum(sub_w)
    havs = [np.sin(0.5 * (np.asarray(dphi) + xj * dphi_w)) ** 2 for xj in x]
    total = None
    for t, wt in zip(sub_theta, sub_w):
        for hav, wj in zip(havs, wq):
            k = lobe_weights(one_minus_cos(theta_a, t, hav, dtype), exponent, log_peak)
            k *= (wt * scale * wj).astype(dtype)
            if total is None:
                total = k
            else:
                total += k
    return total


def band_halfwidth(exponent: float) -> float:
    """Angle (rad) beyond which the lobe weight falls below KERNEL_CUTOFF of its peak:
    arccos(KERNEL_CUTOFF^(1/E)), at most π/2 (the lobe is a hemisphere at most)."""
    return float(np.arccos(np.exp(np.log(KERNEL_CUTOFF) / exponent)))


def hot_rows(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Rows holding hot texels (brighter than HOT_RATIO × median) and the hot-texel mask.

    Returns
    -------
    rows : (n,) int — at most MAX_HOT_ROWS rows, those with the brightest hot texels.
    mask : (H, W) bool — hot texels in those rows.
    """
    lum = np.maximum.reduce([pixels[:, :, k] for k in range(pixels.shape[2])])
    mask = lum > HOT_RATIO * np.median(lum)
    row_peak = np.where(mask, lum, 0.0).max(axis=1)
    rows = np.nonzero(row_peak > 0.0)[0]
    if rows.size > MAX_HOT_ROWS:
        rows = np.sort(rows[np.argsort(row_peak[rows])[-MAX_HOT_ROWS:]])
    keep = np.zeros(lum.shape[0], bool)
    keep[rows] = True
    return rows, mask & keep[:, None]


def split_hot(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """The map without its hot texels, the hot rows and the hot-texel mask.

    Returns
    -------
    residual : (H, W, C) float64
    rows : (n,) int or None
    mask : (H, W) bool — :func:`hot_rows`.
    """
    rows, mask = hot_rows(pixels)
    if rows.size == 0:
        return pixels, None, mask
    residual = pixels.copy()
    residual[rows] = np.where(mask[rows][:, :, None], 0.0, pixels[rows])
    return residual, rows, mask
