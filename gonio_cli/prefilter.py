"""Prefiltered environment maps, one per cosine-lobe exponent (seed 001 §5.1, eqs. 7–9).

For every exponent E the output is the normalised lobe average (docs/conventions.md)

    P_E(r) = ∫ L(ω) max(0, r·ω)^E dω / ∫ max(0, r·ω)^E dω,

a lat-long map indexed by the reflected direction R (glossy and directionally diffuse
terms, seed 001 eqs. 7–8) or by the normal N for E = 1 (the diffuse map, eq. 9). A
constant map stays the same constant for every E.

Both integrals are the same quadrature over the texels of the input map (texel centre
ω_j, exact solid angle Ω_j, :mod:`gonio_cli.envmap`):

    P_E(r) = Σ_j L_j Ω_j k(r·ω_j) / Σ_j Ω_j k(r·ω_j),   k(c) = exp(E log c) for c > 0, else 0,

with k divided by its largest value for each output texel (it cancels), so that nothing
underflows to 0/0 for E up to 10⁴ and beyond, and nothing overflows.

Methods (registry :data:`METHODS`, chosen per exponent by ``auto``):

``brute``
    The quadrature above, every input texel for every output texel, in blocks. The exact
    reference (cost H_o W_o H W).
``ring``
    The same quadrature, computed ring by ring. For an output row θ_a and an input row θ_b
    the weight depends on φ only through φ_out − φ_in, so the sum over a ring is a
    circular convolution, done with an FFT in φ; only input rows inside the lobe's band
    (k above :data:`KERNEL_CUTOFF`) are visited. The input is reduced by area
    (:func:`gonio_cli.envmap.downsample`) to a *working* map :data:`WORKING_LEVELS`
    octaves finer than the output; texels brighter than :data:`HOT_RATIO` × the median
    (a sun) are taken out first and convolved at full input resolution, so a sun 10⁵ × the
    sky is not moved by the reduction. Output samples at the coarser φ grid are read off
    the fine convolution exactly (the output width divides the working width). All
    weights are non-negative, so the output is non-negative: nothing rings.

Each exponent gets the output resolution its lobe width calls for
(:func:`output_levels`: :data:`OUTPUT_TEXELS_PER_SIGMA` texels per lobe standard deviation
1/√E, reduced from the input by powers of two), unless one is forced.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Callable, Iterable

import numpy as np

from . import envmap, log
from .errors import InputError, num

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
    finite = np.isfinite(a)
    bad_values = ~finite | (np.where(finite, a, 0.0) < 0.0)
    bad = bad_values.any(axis=2)
    count = int(bad.sum())
    if count == 0:
        return a, 0
    if not fix_invalid:
        row, col = (int(v) for v in np.argwhere(bad)[0])
        value = a[row, col][bad_values[row, col]][0]
        raise InputError(f"texel (row {row}, col {col}) is {num(value)}; {count} texel"
                         f"{'s are' if count > 1 else ' is'} NaN, inf or negative", path=path,
                         fix="repair the map or pass --fix-invalid to replace them")
    a = a.copy()
    a[finite & (a < 0.0)] = 0.0
    good = np.isfinite(a)
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


# ------------------------------------------------------------------------------ brute --

def brute_at(pixels: np.ndarray, exponent: float, directions: np.ndarray) -> np.ndarray:
    """P_E at given directions from every input texel (the exact quadrature).

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
    d_in = envmap.pixel_directions(h, w).reshape(-1, 3)
    omega = envmap.solid_angles(h, w).reshape(-1)
    values = pixels.reshape(-1, c).astype(np.float64)
    out = np.empty((len(directions), c))
    block = max(1, BRUTE_BLOCK // d_in.shape[0])
    for start in range(0, len(directions), block):
        u = 1.0 - directions[start:start + block] @ d_in.T
        nearest = u.min(axis=1, keepdims=True)
        if np.any(nearest >= 1.0):
            raise InputError("the map is too small: an output direction sees no texel",
                             fix="use a map with more texels")
        wgt = lobe_weights(u, exponent, np.log1p(-nearest))
        wgt *= omega
        out[start:start + block] = (wgt @ values) / wgt.sum(axis=1, keepdims=True)
    return out


def prefilter_brute(pixels: np.ndarray, exponent: float, levels: int,
                    inputs=None) -> tuple[np.ndarray, tuple]:
    """``brute``: every input texel for every output texel (H/2^k × W/2^k output)."""
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
    omega: np.ndarray       # (n,) solid angle of one texel of each row
    spectra: np.ndarray     # (W//2+1, C, n) rfft of the row values along φ (rows last:
    width: int              # a band of rows is a contiguous slice for batched matmul)

    @classmethod
    def of(cls, theta, omega, values, dtype):
        import scipy.fft

        spec = scipy.fft.rfft(values.astype(dtype), axis=1, workers=-1)
        return cls(theta, omega, np.ascontiguousarray(spec.transpose(1, 2, 0)),
                   values.shape[1])

    def phase(self, wo: int) -> tuple[int, np.ndarray]:
        """s = W / W_o and sin²(Δφ_n / 2), Δφ_n = 2πn/W + π(s − 1)/W (n = 0…W−1): the
        azimuth from input centre j + ½ to output centre s·c + s/2 for n = s·c − j."""
        s = self.width // wo
        dphi = 2.0 * np.pi * np.arange(self.width) / self.width + np.pi * (s - 1) / self.width
        return s, np.sin(0.5 * dphi) ** 2

    def row(self, theta_a: float, rows: np.ndarray, hav_dphi: np.ndarray, exponent: float,
            log_peak: float, dtype) -> tuple[np.ndarray, float] | None:
        """Weights of ``rows`` for output row θ_a: (kernel (n, W) including Ω, its sum)."""
        if rows.size == 0:
            return None
        # 1 − cos γ = 2 sin²(Δθ/2) + 2 sin θ_a sin θ_b sin²(Δφ/2): exact, no cancellation
        u = (2.0 * np.sin(0.5 * (theta_a - self.theta[rows])) ** 2).astype(dtype)[:, None] \
            + (2.0 * np.sin(theta_a) * np.sin(self.theta[rows])).astype(dtype)[:, None] \
            * hav_dphi.astype(dtype)[None, :]
        kern = lobe_weights(u, exponent, log_peak)
        kern *= self.omega[rows].astype(dtype)[:, None]
        return kern, float(kern.sum(dtype=np.float64))


def _convolve_row(kern_spec: np.ndarray, spectra: np.ndarray, width: int, s: int
                  ) -> np.ndarray:
    """Σ_b (g_b ⊛ L_b) read at every s-th sample: (W_o, C) from (M, n) and (M, C, n)."""
    import scipy.fft

    spec = np.matmul(spectra, kern_spec[:, :, None])[:, :, 0]
    return scipy.fft.irfft(spec, n=width, axis=0)[::s]


def _band(theta_a: float, rings: _Rings, exponent: float, log_peak: float,
          min_hav_dphi: float) -> np.ndarray:
    """Rows of ``rings`` whose nearest texel has weight ≥ KERNEL_CUTOFF for row θ_a."""
    u = 2.0 * np.sin(0.5 * (theta_a - rings.theta)) ** 2 \
        + 2.0 * np.sin(theta_a) * np.sin(rings.theta) * min_hav_dphi
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
    The denominator is the working grid's (the whole sphere's) weight sum.
    """
    import scipy.fft

    theta_o = envmap.pixel_theta(ho)
    n_work = work.theta.size
    out = np.zeros((ho, wo, work.spectra.shape[1]))
    s_w, hav_w = work.phase(wo)
    hot_phase = hot.phase(wo) if hot is not None else None
    for a in range((ho + 1) // 2):
        ta = theta_o[a]
        u_near = 2.0 * np.sin(0.5 * (ta - work.theta)) ** 2 \
            + 2.0 * np.sin(ta) * np.sin(work.theta) * hav_w.min()
        if u_near.min() >= 1.0:
            raise InputError("the map is too small: an output direction sees no texel",
                             fix="use a map with more texels")
        log_peak = float(np.log1p(-u_near.min()))
        band = _span(_band(ta, work, exponent, log_peak, hav_w.min()))
        kern, den = work.row(ta, np.arange(n_work)[band], hav_w, exponent, log_peak, dtype)
        kern_spec = np.ascontiguousarray(scipy.fft.rfft(kern, axis=1).T)
        mirror = slice(n_work - band.stop, n_work - band.start)
        for t, spectra, ks in ((a, work.spectra[:, :, band], kern_spec),
                               (ho - 1 - a, work.spectra[:, :, mirror],
                                np.ascontiguousarray(kern_spec[:, ::-1]))):
            num = _convolve_row(ks, spectra, work.width, s_w)
            if hot is not None:
                s_h, hav_h = hot_phase
                hot_band = _band(theta_o[t], hot, exponent, log_peak, hav_h.min())
                got = hot.row(theta_o[t], hot_band, hav_h, exponent, log_peak, np.float64)
                if got is not None:
                    num = num + _convolve_row(scipy.fft.rfft(got[0], axis=1).T,
                                              hot.spectra[:, :, hot_band], hot.width, s_h)
            out[t] = num / den
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


def split_hot(pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """The map without its hot texels, and the hot rows (values only at hot texels).

    Returns
    -------
    residual : (H, W, C) float64
    rows : (n,) int or None
    """
    rows, mask = hot_rows(pixels)
    if rows.size == 0:
        return pixels, None
    residual = pixels.copy()
    residual[rows] = np.where(mask[rows][:, :, None], 0.0, pixels[rows])
    return residual, rows


class RingInputs:
    """What ``ring`` prepares once per map and reuses for every exponent: the hot rows
    (float64 spectra at input resolution) and the working maps by reduction factor."""

    def __init__(self, pixels: np.ndarray):
        self.pixels = pixels
        h, w, _ = pixels.shape
        self.residual, rows = split_hot(pixels)
        self.hot = None
        if rows is not None:
            self.hot = _Rings.of(envmap.pixel_theta(h)[rows],
                                 envmap.row_solid_angles(h, w)[rows],
                                 (pixels[rows] - self.residual[rows]), np.float64)
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
            self._work[factor] = _Rings.of(envmap.pixel_theta(hw),
                                           envmap.row_solid_angles(hw, ww), m, RING_DTYPE)
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
    if name != "auto" and name not in METHODS:
        raise InputError(f"method {name!r} is unknown",
                         fix=f"use one of: auto, {', '.join(METHODS)}")
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
    theta, phi = envmap.pixel_theta(h), envmap.pixel_phi(w)
    half = band_halfwidth(exponent)
    lum = result.max(axis=2).reshape(-1)
    rng = np.random.default_rng(seed)
    picks = [int(lum.argmin()), int(lum.argmax())]
    picks += [int(i) for i in rng.permutation(lum.size)[:CHECK_TEXELS] if i not in picks]
    theta_o, phi_o = envmap.pixel_theta(ho), envmap.pixel_phi(wo)
    omega = envmap.row_solid_angles(h, w)
    worst, spent, done = 0.0, 0, 0
    for i in picks[:CHECK_TEXELS]:
        r, col = divmod(i, wo)
        rows = np.nonzero(np.abs(theta - theta_o[r]) <= half + np.pi / h)[0]
        if done >= 2 and spent + rows.size * w > CHECK_BUDGET:
            break
        # 1 − cos γ by the haversine form, as in ring (exact, no cancellation)
        u = (2.0 * np.sin(0.5 * (theta[rows] - theta_o[r])) ** 2)[:, None] \
            + (2.0 * np.sin(theta[rows]) * np.sin(theta_o[r]))[:, None] \
            * (np.sin(0.5 * (phi - phi_o[col])) ** 2)[None, :]
        wgt = lobe_weights(u, exponent, np.log1p(-u.min()))
        wgt *= omega[rows, None]
        truth = np.einsum("rw,rwc->c", wgt, pixels[rows]) / wgt.sum()
        worst = max(worst, float(relative_errors(result[r, col], truth)))
        spent += rows.size * w
        done += 1
    return worst, done


# ------------------------------------------------------------------------------- main --

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
