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

The package: :mod:`.inputs` (validation, resolution), :mod:`.quadrature` (the lobe over
texels, hot texels), :mod:`.brute`, :mod:`.ring`, :mod:`.methods` (registry, costs, spot
check) and here :func:`prefilter` and its result. Reading and writing the files is
:mod:`gonio_cli.prefilter_files`.
"""

from __future__ import annotations

import dataclasses
import time
from typing import Iterable

import numpy as np

from .. import log
from .inputs import levels_for_height, output_levels, validate_exponents
from .methods import METHODS, check_method, choose_method, spot_check

#: ``brute`` on a map predicted to take longer than this (s) gets a warning.
BRUTE_WARN_S = 60.0


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
