"""The registry of prefilter methods (:data:`METHODS`), the cost models ``auto`` chooses by,
and the spot check of every map against ``brute``."""

from __future__ import annotations

import dataclasses
from typing import Callable

import numpy as np

from .. import envmap
from ..names import pick
from .brute import _texel_sums, prefilter_brute
from .quadrature import KERNEL_CUTOFF, band_halfwidth, hot_rows, texel_angle, texel_nodes
from .ring import RING_ERROR_BOUND, WORKING_LEVELS, RingInputs, prefilter_ring

#: The accuracy ``auto`` aims for: relative error at the 99th percentile of texels.
ACCURACY_TARGET = 0.01
#: Spot check of each result against ``brute``: at most this many output texels ...
CHECK_TEXELS = 12
#: ... and at most this many kernel evaluations (input texels × checked texels).
CHECK_BUDGET = 1_000_000
#: Relative error of a texel is |Δ| / its brightest channel, floored here so an all-black
#: texel (both 0) does not divide by zero.
RELATIVE_FLOOR = 1e-30
#: Cost model for ``auto``: seconds per kernel evaluation of ``brute`` and per
#: (output row × band row × working texel × log2 FFT length) of ``ring``, measured on 2
#: cores (benchmarks/bench_prefilter.py); only their ratio matters for the choice.
BRUTE_S_PER_EVAL = 1.6e-8
RING_S_PER_EVAL = 1.0e-9
#: ... plus the fixed price of one output row of ``ring`` (a dozen numpy calls).
RING_S_PER_ROW = 2.0e-4


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
