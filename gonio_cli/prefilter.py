"""Prefiltered environment maps, one per cosine-lobe exponent (seed 001 §5.1, eqs. 7–9).

For every exponent E the output is the normalised lobe average (docs/conventions.md)

    P_E(r) = ∫ L(ω) max(0, r·ω)^E dω / ∫ max(0, r·ω)^E dω,

a lat-long map indexed by the reflected direction R (glossy and directionally diffuse
terms, seed 001 eqs. 7–8) or by the normal N for E = 1 (the diffuse map, eq. 9). A
constant map stays the same constant for every E.

Each input texel is taken as constant over its area (the "area-true" average), so both
integrals are sums over the texels j of the input map of the lobe integrated over the texel:

    P_E(r) = Σ_j L_j ∫_j k(r·ω) dω / Σ_j ∫_j k(r·ω) dω,   k(c) = exp(E log c) for c > 0, else 0,

with k divided by its value at the nearest texel centre for each output texel (it
cancels), so that nothing underflows to 0/0 for E up to 10⁴ and beyond, and nothing
overflows. The texel integrals (:func:`texel_weights`) are Gauss–Legendre sums whose node
weights add up to the texel's exact solid angle (a constant map stays constant): the
texel centre alone (the midpoint rule) where that is within ~0.1 %, more nodes where the
lobe changes steeply across a texel, always for hot texels (a sun 10⁵ × the sky, whose
weight is the whole answer near it; :data:`HOT_NODES_PER_SIGMA`) and for lobes narrower
than two texels (:data:`MIDPOINT_MAX_TEXEL_SIGMA`).

Methods (registry :data:`METHODS`, chosen per exponent by ``auto``):

``brute``
    The sums above, every input texel (within the lobe's band) for every output texel,
    in blocks. The exact reference (cost H_o W_o H W).
``ring``
    The same quadrature, computed ring by ring. For an output row θ_a and an input row θ_b
    the weight depends on φ only through φ_out − φ_in, so the sum over a ring is a
    circular convolution, done with an FFT in φ; only input rows inside the lobe's band
    (k above :data:`KERNEL_CUTOFF`) are visited. The input is reduced by area
    (:func:`gonio_cli.envmap.downsample`) to a *working* map :data:`WORKING_LEVELS`
    octaves finer than the output; texels brighter than :data:`HOT_RATIO` × the median
    (a sun) are taken out first and convolved at full input resolution, so a sun 10⁵ × the
    sky is not moved by the reduction; in the denominator their share is their area
    integral, as in ``brute``. Output samples at the coarser φ grid are read off
    the fine convolution exactly (the output width divides the working width). All
    weights are non-negative, so the output is non-negative: nothing rings.

Each exponent gets the output resolution its lobe width calls for
(:func:`output_levels`: :data:`OUTPUT_TEXELS_PER_SIGMA` texels per lobe standard deviation
1/√E, reduced from the input by powers of two), unless one is forced.

Why one module: the two methods of :data:`METHODS` (brute force, the exact reference;
the ring convolution) share the texel integrals, the lobe weights, the resolution rule,
the cost models that choose between them and the spot checks of every map against brute
force. Reading and writing the files is :mod:`gonio_cli.prefilter_files`.
"""

from __future__ import annotations

import dataclasses
import functools
import time
from typing import Callable, Iterable

import numpy as np

from . import envmap, log
from .errors import InputError, num
from .names import pick

#: Kernel values below this fraction of a texel's peak weight are left out (input rows
#: outside the band). Even a sun 10⁵ × the sky then changes a texel by < 1e-5 of the sky.
KERNEL_CUTOFF = 1e-10

#: Output texels per lobe standard deviation σ = 1/√E rad (cos^E θ ≈ exp(−Eθ²/2)), at
#: least. The levels are powers of two, so maps get 2.5–5 texels per σ: bilinear lookup
#: between texel centres is then within ~1 % (99th percentile; a few % at the edge of a
#: sun's lobe) of the exact map (measured, docs/prefilter.md); force ``resolution`` for more.
OUTPUT_TEXELS_PER_SIGMA = 2.5

#: Smallest output height chosen automatically (a 128 × 64 diffuse map): the clamped cosine
#: of E = 1 has a kink at the terminator that a sun makes steep, so its lookup error falls
#: only linearly with the texel size (p99 26 % at 16 rows, 3 % at 64, on quarry_01).
MIN_OUTPUT_HEIGHT = 64

#: The working map of ``ring`` is this many octaves (powers of two) finer than the output,
#: at most the input: its box filter then moves the result by ≤ 0.2 % (measured on real
#: skies, docs/prefilter.md) against the full-resolution quadrature.
WORKING_LEVELS = 2

#: Largest relative error of ``ring`` against ``brute`` with WORKING_LEVELS (measured
#: maximum 1.6e-3 on quarry_01 and venice_sunset; 5e-7, float32 round-off, without
#: reduction): what ``auto`` counts on.
RING_ERROR_BOUND = 2e-3

#: Texels brighter than this × the median texel (brightest channel) are "hot" (a sun):
#: ``ring`` convolves their rows at the input resolution instead of the working map.
HOT_RATIO = 100.0

#: At most this many input rows are treated as hot (those with the brightest texels);
#: hot texels of further rows stay in the working map (a map that bright everywhere has
#: no single sun to protect). Bounds the full-resolution work.
MAX_HOT_ROWS = 64

#: The accuracy ``auto`` aims for: relative error at the 99th percentile of texels.
ACCURACY_TARGET = 0.01

#: Spot check of each result against ``brute``: at most this many output texels ...
CHECK_TEXELS = 12
#: ... and at most this many kernel evaluations (input texels × checked texels).
CHECK_BUDGET = 1_000_000

#: Elements (output × input texels) of one block of ``brute``: 32 MiB of float64.
BRUTE_BLOCK = 1 << 22

#: Relative error of a texel is |Δ| / its brightest channel, floored here so an all-black
#: texel (both 0) does not divide by zero.
RELATIVE_FLOOR = 1e-30

#: Largest exponent accepted: the lobe is then ~0.06° wide, far below any map's texel.
MAX_EXPONENT = 1e6

#: ``brute`` on a map predicted to take longer than this (s) gets a warning.
BRUTE_WARN_S = 60.0

#: Cost model for ``auto``: seconds per kernel evaluation of ``brute`` and per
#: (output row × band row × working texel × log2 FFT length) of ``ring``, measured on 2
#: cores (benchmarks/bench_prefilter.py); only their ratio matters for the choice.
BRUTE_S_PER_EVAL = 1.6e-8
RING_S_PER_EVAL = 1.0e-9
#: ... plus the fixed price of one output row of ``ring`` (a dozen numpy calls).
RING_S_PER_ROW = 2.0e-4


@dataclasses.dataclass
class PrefilterResult:
    """One prefiltered map and how it was made.

    Attributes
    ----------
    exponent : float
        Lobe exponent E.
    pixels : (H_o, W_o, C) float32
        P_E at the output pixel centres, non-negative.
    method : str
        Registry name of the method used.
    error_estimate : float
        Largest relative error (|Δ| over the texel's brightest channel) found by checking
        ``checked_texels`` output texels against ``brute`` (0 for ``brute`` itself).
    checked_texels : int
        How many texels the error estimate rests on.
    time_s : float
        Wall time of the prefilter itself (without the check).
    working_shape : tuple of int
        (H, W) of the map the method integrated (``ring``'s reduced map; the input for
        ``brute``).
    """

    exponent: float
    pixels: np.ndarray
    method: str
    error_estimate: float
    checked_texels: int
    time_s: float
    working_shape: tuple[int, int]

    @property
    def height(self) -> int:
        return int(self.pixels.shape[0])

    @property
    def width(self) -> int:
        return int(self.pixels.shape[1])


# ------------------------------------------------------------------------- validation --

def validate_map(pixels: np.ndarray, *, fix_invalid: bool = False,
                 path=None) -> tuple[np.ndarray, int]:
    """Check an environment map; return it as float64 (H, W, C) and the texels replaced.

    NaN, ±inf or negative values are an error naming the first such texel (row, col, 0-based
    as in the image) and how many there are; with ``fix_invalid`` negative values become 0
    and NaN/inf the mean of the valid texels of their row (0 if none), and the count is
    returned (the caller says so). A map needs at least 1 row and 2 columns (one column
    is a single direction, not a sphere).
    """
    a = np.asarray(pixels, dtype=np.float64)
    if a.ndim == 2:
        a = a[:, :, None]
    if a.ndim != 3 or a.shape[0] < 1 or a.shape[1] < 2 or a.shape[2] < 1:
        raise InputError(f"a {' × '.join(map(str, a.shape[:2]))} image is not a lat-long "
                         "map (needs at least 1 row and 2 columns)", path=path,
                         fix="pass an equirectangular map, 2:1 (width = 2 × height)")
    from .schemas import MAX_MAGNITUDE

    finite = np.isfinite(a) & (np.abs(a) <= MAX_MAGNITUDE)   # huge: as inf (Numeric ranges)
    bad_values = ~finite | (np.where(finite, a, 0.0) < 0.0)
    bad = bad_values.any(axis=2)
    count = int(bad.sum())
    if count == 0:
        return a, 0
    if not fix_invalid:
        row, col = (int(v) for v in np.argwhere(bad)[0])
        value = a[row, col][bad_values[row, col]][0]
        raise InputError(f"texel (row {row}, col {col}) is {num(value)}; {count} texel"
                         f"{'s are' if count > 1 else ' is'} NaN, inf or negative (or above "
                         f"{MAX_MAGNITUDE:g})", path=path,
                         fix="repair the map or pass --fix-invalid to replace them")
    a = a.copy()
    a[finite & (a < 0.0)] = 0.0
    good = np.isfinite(a) & (a <= MAX_MAGNITUDE)
    row_mean = np.where(good, a, 0.0).sum(axis=1) / np.maximum(good.sum(axis=1), 1)
    a = np.where(good, a, row_mean[:, None, :])
    return a, count


def validate_exponents(exponents: Iterable[float], *, path=None) -> list[float]:
    """Sorted unique exponents in [1, MAX_EXPONENT], always including the diffuse E = 1."""
    out = set()
    for e in exponents:
        try:
            v = float(e)
        except (TypeError, ValueError):
            raise InputError(f"exponent {e!r} is not a number", path=path,
                             fix="give numbers such as 1,8,64") from None
        if not (np.isfinite(v) and 1.0 <= v <= MAX_EXPONENT):
            raise InputError(f"exponent {num(e)} is outside [1, {MAX_EXPONENT:g}]", path=path,
                             fix="cosine-lobe exponents are at least 1 (the diffuse map)")
        out.add(v)
    out.add(1.0)
    return sorted(out)


# ------------------------------------------------------------------------- resolution --

def lobe_sigma(exponent: float) -> float:
    """Angular standard deviation of max(0, cos θ)^E: 1/√E rad (cos^E θ ≈ exp(−Eθ²/2))."""
    return 1.0 / np.sqrt(exponent)


def output_levels(height: int, width: int, exponent: float) -> int:
    """Octaves k by which the output is smaller than the input (H/2^k × W/2^k).

    The coarsest level whose texel spacing π/H_o is at most σ/OUTPUT_TEXELS_PER_SIGMA and
    whose height is at least MIN_OUTPUT_HEIGHT (or the input's, if smaller); only levels
    that divide both sides exactly are used.
    """
    needed = max(np.pi * OUTPUT_TEXELS_PER_SIGMA / lobe_sigma(exponent),
                 min(MIN_OUTPUT_HEIGHT, height))
    k = 0
    while (height % 2 ** (k + 1) == 0 and width % 2 ** (k + 1) == 0
           and height // 2 ** (k + 1) >= needed):
        k += 1
    return k


def levels_for_height(height: int, width: int, out_height: int, *, path=None) -> int:
    """Octaves k for a forced output height (must be the input's height / 2^k)."""
    valid = []
    k = 0
    while True:
        h = height // 2 ** k
        valid.append(h)
        if h == out_height:
            return k
        if height % 2 ** (k + 1) or width % 2 ** (k + 1):
            break
        k += 1
    raise InputError(f"resolution {out_height} is not one of this map's: "
                     f"{', '.join(map(str, valid))}", path=path,
                     fix="outputs are the input reduced by powers of two")


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


# ------------------------------------------------------------------------------- ring --

#: Floating-point type of ``ring``'s kernels and FFTs. float32 is enough because hot
#: texels (contrast > HOT_RATIO) are always convolved separately in float64: round-off is
#: then ~1e-7 × HOT_RATIO = 1e-5 of a texel, far below ACCURACY_TARGET.
RING_DTYPE = np.float32


@dataclasses.dataclass
class _Rings:
    """Input rows for :func:`_ring_convolve`, all of one width W (a multiple of W_o)."""

    theta: np.ndarray       # (n,) polar angle of each row
    height: int             # rows of the whole grid (texels are π/height × 2π/width)
    spectra: np.ndarray     # (W//2+1, C, n) rfft of the row values along φ (rows last:
    width: int              # a band of rows is a contiguous slice for batched matmul)

    @classmethod
    def of(cls, theta, height, values, dtype):
        import scipy.fft

        spec = scipy.fft.rfft(values.astype(dtype), axis=1, workers=-1)
        return cls(theta, height, np.ascontiguousarray(spec.transpose(1, 2, 0)),
                   values.shape[1])

    def phase(self, wo: int) -> tuple[int, np.ndarray]:
        """s = W / W_o and Δφ_n = 2πn/W + π(s − 1)/W (n = 0…W−1): the azimuth from input
        centre j + ½ to output centre s·c + s/2 for n = s·c − j."""
        s = self.width // wo
        return s, 2.0 * np.pi * np.arange(self.width) / self.width + np.pi * (s - 1) / self.width

    def nodes(self, exponent: float, hot: bool) -> int:
        """Quadrature nodes per axis of these rows' texels (:func:`texel_nodes`)."""
        return texel_nodes(exponent, texel_angle(self.height, self.width), hot)

    def row(self, theta_a: float, rows: np.ndarray, dphi: np.ndarray, exponent: float,
            log_peak: float, dtype, nodes: int, kink_nodes: int = 0
            ) -> tuple[np.ndarray, float] | None:
        """Weights of ``rows`` for output row θ_a: (kernel (n, W), each texel's lobe
        integral :func:`texel_weights`, and its sum)."""
        if rows.size == 0:
            return None
        kern = texel_weights(theta_a, self.theta[rows][:, None], dphi[None, :], self.height,
                             self.width, exponent, log_peak, nodes, dtype, kink_nodes)
        return kern, float(kern.sum(dtype=np.float64))


def _convolve_row(kern_spec: np.ndarray, spectra: np.ndarray, width: int, s: int
                  ) -> np.ndarray:
    """Σ_b (g_b ⊛ L_b) read at every s-th sample: (W_o, C) from (M, n) and (M, C, n)."""
    import scipy.fft

    spec = np.matmul(spectra, kern_spec[:, :, None])[:, :, 0]
    return scipy.fft.irfft(spec, n=width, axis=0)[::s]


def _nearest_hav(rings: _Rings, dphi: np.ndarray, nodes: int) -> float:
    """sin²(δ/2) of the smallest azimuth δ between an output centre and a quadrature node
    of ``rings`` (nodes > 1 reach to within the texel's half width of its centre)."""
    d = np.minimum(np.mod(dphi, 2.0 * np.pi), 2.0 * np.pi - np.mod(dphi, 2.0 * np.pi)).min()
    if nodes > 1:
        d = max(0.0, d - np.pi / rings.width)
    return float(np.sin(0.5 * d) ** 2)


def _band(theta_a: float, rings: _Rings, exponent: float, log_peak: float,
          min_hav_dphi: float, nodes: int = 1) -> np.ndarray:
    """Rows of ``rings`` whose nearest texel (its nearest node) has weight ≥ KERNEL_CUTOFF
    for row θ_a."""
    gap = np.abs(theta_a - rings.theta)
    if nodes > 1:
        gap = np.maximum(0.0, gap - 0.5 * np.pi / rings.height)
    u = one_minus_cos(gap, 0.0, 0.0) + 2.0 * np.sin(theta_a) * np.sin(rings.theta) \
        * min_hav_dphi
    ok = u < 1.0
    logc = np.log1p(-np.where(ok, u, 0.0))
    return np.nonzero(ok & (exponent * (logc - log_peak) >= np.log(KERNEL_CUTOFF)))[0]


def _span(rows: np.ndarray) -> slice:
    """The contiguous rows from the first to the last of ``rows`` (a band is one span)."""
    return slice(int(rows[0]), int(rows[-1]) + 1) if rows.size else slice(0, 0)


def _ring_convolve(work: _Rings, hot: _Rings | None, ho: int, wo: int, exponent: float,
                   dtype=RING_DTYPE) -> np.ndarray:
    """P_E on an H_o × W_o grid from a full working grid and optional hot rows.

    For output row a and input row b the weights along φ are g(n) = k(θ_a, θ_b, Δφ_n)
    (:meth:`_Rings.phase`), so the numerator over a ring is the circular convolution
    Σ_j L_j g(i − j), read exactly at i = s·c. The working grid is symmetric about the
    equator, so the kernel of output row a serves row H_o − 1 − a with the rows mirrored.
    The denominator is the working grid's (the whole sphere's) weight sum, in which the
    hot texels' share (their weights with the working grid's nodes) is replaced by their
    area integrals (hot nodes), the same weights as in the numerator, as ``brute`` has.
    """
    import scipy.fft

    theta_o = envmap.pixel_theta(ho)
    n_work = work.theta.size
    out = np.zeros((ho, wo, work.spectra.shape[1]))
    s_w, dphi_w = work.phase(wo)
    nodes_w = work.nodes(exponent, hot=False)
    centre_hav_w = _nearest_hav(work, dphi_w, 1)
    near_hav_w = _nearest_hav(work, dphi_w, nodes_w)
    if hot is not None:
        s_h, dphi_h = hot.phase(wo)
        nodes_h = hot.nodes(exponent, hot=True)
        near_hav_h = _nearest_hav(hot, dphi_h, nodes_h)
    for a in range((ho + 1) // 2):
        ta = theta_o[a]
        u_near = one_minus_cos(ta, work.theta, centre_hav_w)
        if u_near.min() >= 1.0:
            raise InputError("the map is too small: an output direction sees no texel",
                             fix="use a map with more texels")
        log_peak = float(np.log1p(-u_near.min()))
        band = _span(_band(ta, work, exponent, log_peak, near_hav_w, nodes_w))
        kern, den = work.row(ta, np.arange(n_work)[band], dphi_w, exponent, log_peak, dtype,
                             nodes_w)
        kern_spec = np.ascontiguousarray(scipy.fft.rfft(kern, axis=1).T)
        mirror = slice(n_work - band.stop, n_work - band.start)
        for t, spectra, ks in ((a, work.spectra[:, :, band], kern_spec),
                               (ho - 1 - a, work.spectra[:, :, mirror],
                                np.ascontiguousarray(kern_spec[:, ::-1]))):
            num = _convolve_row(ks, spectra, work.width, s_w)
            den_t = den
            if hot is not None:
                hot_band = _band(theta_o[t], hot, exponent, log_peak, near_hav_h, nodes_h)
                got = hot.row(theta_o[t], hot_band, dphi_h, exponent, log_peak, np.float64,
                              nodes_h, KINK_NODES)
                if got is not None:
                    add = _convolve_row(scipy.fft.rfft(got[0], axis=1).T,
                                        hot.spectra[:, :, hot_band], hot.width, s_h)
                    mid = hot.row(theta_o[t], hot_band, dphi_h, exponent, log_peak,
                                  np.float64, nodes_w)[0]
                    mid = _convolve_row(scipy.fft.rfft(mid, axis=1).T,
                                        hot.spectra[:, -1:, hot_band], hot.width, s_h)[:, 0]
                    num = num + add[:, :-1]
                    # the other texels' weight is ≥ 0; max() only removes round-off
                    den_t = np.maximum(den - mid, 0.0) + add[:, -1]
                    den_t = np.where(den_t > 0.0, den_t, den)[:, None]
            out[t] = num / den_t
            if t == ho - 1 - t:
                break
    return out


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


class RingInputs:
    """What ``ring`` prepares once per map and reuses for every exponent: the hot rows
    (float64 spectra at input resolution, with the hot mask as a last channel) and the
    working maps by reduction factor."""

    def __init__(self, pixels: np.ndarray):
        self.pixels = pixels
        h, w, _ = pixels.shape
        self.residual, rows, mask = split_hot(pixels)
        self.hot = None
        if rows is not None:
            # the hot values and, as one more channel, the mask (for the denominator)
            self.hot = _Rings.of(envmap.pixel_theta(h)[rows], h,
                                 np.concatenate([pixels[rows] - self.residual[rows],
                                                 mask[rows][:, :, None]], axis=2),
                                 np.float64)
        self._work: dict[int, _Rings] = {}
        self._maps: dict[int, np.ndarray] = {1: self.residual}

    def reduced(self, factor: int) -> np.ndarray:
        """The residual map reduced by ``factor`` (a power of two) by area, octave by octave
        from the cached finer one (nested box filters in solid angle compose exactly)."""
        if factor not in self._maps:
            self._maps[factor] = envmap.downsample(self.reduced(factor // 2), 2)
        return self._maps[factor]

    def working(self, factor: int) -> _Rings:
        """The residual map reduced by ``factor`` (area), as float32 ring spectra."""
        if factor not in self._work:
            m = self.reduced(factor)
            hw, ww = m.shape[:2]
            self._work[factor] = _Rings.of(envmap.pixel_theta(hw), hw, m, RING_DTYPE)
        return self._work[factor]


def prefilter_ring(pixels: np.ndarray, exponent: float, levels: int,
                   inputs: RingInputs | None = None,
                   working_levels: int = WORKING_LEVELS) -> tuple[np.ndarray, tuple]:
    """``ring``: FFT-in-φ convolution per latitude ring on an area-reduced working map.

    The working map is the input reduced by 2^max(0, levels − working_levels) after the
    hot texels (a sun) are taken out; their rows are convolved at input resolution in
    float64. ``inputs`` (from :class:`RingInputs`) saves preparing the map again.
    """
    h, w, _ = pixels.shape
    inputs = inputs if inputs is not None else RingInputs(pixels)
    work = inputs.working(2 ** max(0, levels - working_levels))
    out = _ring_convolve(work, inputs.hot, h // 2 ** levels, w // 2 ** levels, exponent)
    return out, (work.theta.size, work.width)


# --------------------------------------------------------------------------- registry --

@dataclasses.dataclass(frozen=True)
class Method:
    """A prefilter method: ``run(pixels, E, levels, prepared)`` → (map, working shape),
    ``prepare(pixels)`` done once per map, the predicted cost (s) and the error bound
    (relative, against the exact quadrature) for ``auto``."""

    run: Callable[..., tuple[np.ndarray, tuple]]
    prepare: Callable[[np.ndarray], object]
    predict_s: Callable[[tuple, float, int], float]
    error_bound: float
    description: str


def _brute_cost(shape, exponent, levels) -> float:
    h, w = shape[:2]
    return BRUTE_S_PER_EVAL * (h * w) ** 2 / 4 ** levels


def _ring_cost(shape, exponent, levels) -> float:
    h, w = shape[:2]
    reduce = 2 ** max(0, levels - WORKING_LEVELS)
    hw, ww = h // reduce, w // reduce
    ho = h // 2 ** levels
    band = min(hw, hw * 2 * np.sqrt(-2 * np.log(KERNEL_CUTOFF) / exponent) / np.pi + 1)
    return RING_S_PER_ROW * ho + RING_S_PER_EVAL * ho * band * ww * (1 + np.log2(ww))


METHODS: dict[str, Method] = {
    "brute": Method(prefilter_brute, lambda pixels: None, _brute_cost, 0.0,
                    "every input texel for every output texel (exact reference)"),
    "ring": Method(prefilter_ring, RingInputs, _ring_cost, RING_ERROR_BOUND,
                   "FFT in φ per latitude ring on an area-reduced map, suns at full "
                   "resolution"),
}


def check_method(name: str) -> str:
    """Refuse an unknown method name, listing the valid ones (STYLE 3)."""
    pick(METHODS, name, "method", extra=("auto",))
    return name


def choose_method(shape, exponent: float, levels: int) -> str:
    """``auto``: of the methods whose error bound is within ACCURACY_TARGET, the one
    predicted fastest for this map, exponent and output level."""
    good = [m for m in METHODS if METHODS[m].error_bound <= ACCURACY_TARGET]
    return min(good, key=lambda m: METHODS[m].predict_s(shape, exponent, levels))


# ------------------------------------------------------------------------------ check --

def relative_errors(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Per texel max_c |Δ_c| / max_c truth_c: (...) from (..., C)."""
    scale = np.maximum(np.abs(truth).max(axis=-1), RELATIVE_FLOOR)
    return np.abs(estimate - truth).max(axis=-1) / scale


def band_halfwidth(exponent: float) -> float:
    """Angle (rad) beyond which the lobe weight falls below KERNEL_CUTOFF of its peak:
    arccos(KERNEL_CUTOFF^(1/E)), at most π/2 (the lobe is a hemisphere at most)."""
    return float(np.arccos(np.exp(np.log(KERNEL_CUTOFF) / exponent)))


def spot_check(pixels: np.ndarray, result: np.ndarray, exponent: float,
               seed: int = 0) -> tuple[float, int]:
    """Largest relative error of ``result`` against ``brute`` on a few output texels.

    The texels are the darkest and the brightest output texel (where the relative error
    of a sun is largest and where its light is) and random others, as many as CHECK_TEXELS
    and CHECK_BUDGET (kernel evaluations) allow. Each is integrated over the input rows
    within :func:`band_halfwidth` of it, the same cut ``ring`` makes. Returns
    (max relative error, texels checked).
    """
    h, w, c = pixels.shape
    ho, wo = result.shape[:2]
    theta = envmap.pixel_theta(h)
    half = band_halfwidth(exponent)
    lum = result.max(axis=2).reshape(-1)
    rng = np.random.default_rng(seed)
    picks = [int(lum.argmin()), int(lum.argmax())]
    picks += [int(i) for i in rng.permutation(lum.size)[:CHECK_TEXELS] if i not in picks]
    theta_o, phi_o = envmap.pixel_theta(ho), envmap.pixel_phi(wo)
    _, hot = hot_rows(pixels)
    size = texel_angle(h, w)
    cost = np.where(hot.any(axis=1), texel_nodes(exponent, size, True) ** 2, 0) \
        + texel_nodes(exponent, size, False) ** 2
    worst, spent, done = 0.0, 0, 0
    for i in picks[:CHECK_TEXELS]:
        r, col = divmod(i, wo)
        rows = np.nonzero(np.abs(theta - theta_o[r]) <= half + np.pi / h)[0]
        evals = int(cost[rows].sum()) * w
        if done >= 2 and spent + evals > CHECK_BUDGET:
            break
        num, den = _texel_sums(pixels, rows, hot, theta_o[r:r + 1], phi_o[col:col + 1],
                               exponent)
        worst = max(worst, float(relative_errors(result[r, col], num[0] / den[0])))
        spent += evals
        done += 1
    return worst, done


# ------------------------------------------------------------------------------- main --

#: Peak bytes per input texel of :func:`prefilter` besides the maps it returns: measured
#: with ru_maxrss on random 1024×512 … 4096×2048 maps, exponents 8,64 (three maps): 70–95
#: bytes a texel above the baseline, of which the three maps at full size are 36.
BYTES_PER_TEXEL = 44
#: Bytes per texel of each returned map (float32 RGB at most the input's size).
MAP_BYTES_PER_TEXEL = 12


def memory_estimate(height: int, width: int, n_maps: int) -> int:
    """Peak bytes of prefiltering an ``height`` × ``width`` map into ``n_maps`` maps
    (the diffuse map included)."""
    return int(height) * int(width) * (BYTES_PER_TEXEL + MAP_BYTES_PER_TEXEL * int(n_maps))


def prefilter(pixels: np.ndarray, exponents: Iterable[float], *, method: str = "auto",
              resolution: int | None = None, check: bool = True,
              path=None) -> list[PrefilterResult]:
    """Prefilter a lat-long map for each exponent (seed 001 §5.1; eqs. 7–9 read them).

    Parameters
    ----------
    pixels : (H, W, C) float
        Validated map (:func:`validate_map`), linear radiance.
    exponents : iterable of float
        Lobe exponents (validated; E = 1, the diffuse map, is added).
    method : str
        ``auto`` or a key of :data:`METHODS`.
    resolution : int, optional
        Force the output height (the input's divided by a power of two) for every E.
    check : bool
        Spot-check each result against ``brute`` (:func:`spot_check`).

    Returns
    -------
    list of :class:`PrefilterResult`, in increasing E.
    """
    check_method(method)
    pixels = np.asarray(pixels, dtype=np.float64)
    h, w = pixels.shape[:2]
    if w != 2 * h:
        log.warn(f"{path + ': ' if path else ''}the map is {w} × {h}, not 2:1; read as "
                 "lat-long all the same (θ over the rows, φ over the columns)")
    exps = validate_exponents(exponents, path=path)
    forced = None if resolution is None else levels_for_height(h, w, resolution, path=path)
    results = []
    prepared: dict[str, object] = {}
    for e in log.progress(exps, "prefilter", total=len(exps)):
        levels = output_levels(h, w, e) if forced is None else forced
        name = choose_method(pixels.shape, e, levels) if method == "auto" else method
        predicted = METHODS[name].predict_s(pixels.shape, e, levels)
        if predicted > BRUTE_WARN_S and name == "brute":
            log.warn(f"brute for E={e:g} will take about {predicted:.0f} s; "
                     "--method auto is as accurate to 0.2 % and far faster")
        start = time.perf_counter()
        if name not in prepared:
            prepared[name] = METHODS[name].prepare(pixels)
        out, working = METHODS[name].run(pixels, e, levels, prepared[name])
        out = np.maximum(out, 0.0)  # removes FFT round-off only: all weights are ≥ 0
        elapsed = time.perf_counter() - start
        err, n = (0.0, 0) if (name == "brute" or not check) else spot_check(pixels, out, e)
        results.append(PrefilterResult(e, out.astype(np.float32), name, err, n, elapsed,
                                       tuple(int(v) for v in working)))
    return results
