"""``ring``: the same quadrature ring by ring, a circular convolution in φ per pair of
rows, on an area-reduced working map with the hot texels (a sun) at full resolution."""

from __future__ import annotations

import dataclasses

import numpy as np

from .. import envmap
from ..errors import InputError
from .quadrature import (KERNEL_CUTOFF, KINK_NODES, one_minus_cos, split_hot, texel_angle,
                         texel_nodes, texel_weights)

#: The working map of ``ring`` is this many octaves (powers of two) finer than the output,
#: at most the input: its box filter then moves the result by ≤ 0.2 % (measured on real
#: skies, docs/prefilter.md) against the full-resolution quadrature.
WORKING_LEVELS = 2
#: Largest relative error of ``ring`` against ``brute`` with WORKING_LEVELS (measured
#: maximum 1.6e-3 on quarry_01 and venice_sunset; 5e-7, float32 round-off, without
#: reduction): what ``auto`` counts on.
RING_ERROR_BOUND = 2e-3


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
