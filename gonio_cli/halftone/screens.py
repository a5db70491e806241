"""Threshold screens for ordered halftoning of exclusive inks: Bayer, clustered dot, blue
noise (void and cluster).

A screen is a tile T (n, m) of thresholds in (0, 1), one per rank: t = (rank + ½) / (n m).
It is repeated over the image. With three exclusive inks the unit interval of each pixel
is stacked: ink R owns [0, r), G owns [r, r + g), B owns [r + g, r + g + b) and the rest
is bare substrate, so a pixel gets the ink whose interval holds its threshold
(:func:`threshold_stack`). Exactly one state per pixel by construction; over a whole tile
of a flat patch ink k covers the fraction of ranks in its interval, within 1/(n m) of its
coverage, and an ink of zero coverage owns an empty interval, so it never appears. R takes
the lowest thresholds, G the next, B the next: with a dispersed screen (Bayer, blue noise)
each band of ranks is itself dispersed; with a clustered dot the inks grow as concentric
rings (R core, G ring, B ring) in every dot.

The clustered-dot screen (:func:`clustered_dot_ranks`) is a production one: round
("Euclidean") dots on a 45° lattice, tiled into a supercell of at least
:data:`CLUSTERED_SUPERCELL_MIN_PX` ² pixels whose dots take their next pixel in turn, in a
dispersed order, so it holds over a thousand levels whatever the dot size.
:func:`clustered_ranks` is seed 000's illustration, a single square cell whose ranks grow
from its centre (3 × 3: ten levels).

References
----------
B. E. Bayer, "An optimum method for two-level rendition of continuous-tone pictures",
IEEE International Conference on Communications, 26-11 to 26-15, 1973.
R. Ulichney, "The void-and-cluster method for dither array generation", Proc. SPIE 1913,
Human Vision, Visual Processing, and Digital Display IV, 332-343, 1993.
R. Ulichney, *Digital Halftoning*, MIT Press, 1987 (clustered-dot ordered dither, 45°
screens).
ISO 32000-1:2008 (PDF 1.7), Table 130, predefined spot function ``Round`` (the
"Euclidean" dot).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from ..artifact import atomic_path
from ..cache import cache_dir
from ..errors import InputError


#: Ulichney 1993's Gaussian width (pixels) of the void-and-cluster energy filter.
VOID_AND_CLUSTER_SIGMA = 1.5

#: Fraction of pixels set in the random initial pattern (Ulichney 1993: "no more than
#: half", ~10 % is customary); the seed makes the mask reproducible.
VOID_AND_CLUSTER_INITIAL_FRACTION = 0.1
VOID_AND_CLUSTER_SEED = 0

#: Bumped whenever the generator changes, so a cached mask of an older generator is
#: never read (it is part of the cache file name).
VOID_AND_CLUSTER_VERSION = 1

#: Seed 000's illustrative clustered cell ("a square of 3×3 pixels"): ten levels per ink.
SEED_000_CELL_PX = 3

#: The clustered-dot screen is tiled into a supercell at least this many pixels wide:
#: 32² = 1024 ranks, so a flat patch over whole tiles is within 1/1024 ≈ 0.1 % of its
#: coverage per ink whatever the dot size (a single 8 × 8 cell would give 1/64 ≈ 1.6 %,
#: a 3 × 3 cell 1/9 ≈ 11 %), while the tile stays small (at most 60² for cells to 32).
CLUSTERED_SUPERCELL_MIN_PX = 32

#: Decimals to which the dot-order energies (sums of at most a few hundred Gaussians,
#: float64 rounding ~1e-13) are rounded before comparing, so that dots placed alike by the
#: lattice's symmetry tie exactly and the lower index wins on every machine; distinct
#: energies closer than 1e-9 also tie, which only decides which of two equally far dots
#: goes first.
ENERGY_DECIMALS = 9


def ranks_to_thresholds(ranks: np.ndarray) -> np.ndarray:
    """Ranks 0 … N−1 of an (n, m) tile → thresholds (rank + ½)/N, (n, m) float32."""
    ranks = np.asarray(ranks)
    return ((ranks + 0.5) / ranks.size).astype(np.float32)


def bayer_ranks(size: int) -> np.ndarray:
    """Bayer's (1973) recursive index matrix, (size, size) int, size a power of two ≥ 2.

    M₂ = [[0, 2], [3, 1]], M₂ₙ = [[4Mₙ, 4Mₙ + 2], [4Mₙ + 3, 4Mₙ + 1]].

    >>> bayer_ranks(2).tolist()
    [[0, 2], [3, 1]]
    """
    m = np.zeros((1, 1), dtype=np.int64)
    while m.shape[0] < size:
        m = np.block([[4 * m, 4 * m + 2], [4 * m + 3, 4 * m + 1]])
    return m


def clustered_ranks(cell: int) -> np.ndarray:
    """A square clustered-dot cell (cell, cell) int: ranks grow outwards from the cell
    centre (distance, then angle, then index on ties), so a level of k/cell² fills the k
    pixels nearest the centre — seed 000's example: 0.3 of R in a 3 × 3 cell fills 3
    pixels. It has only cell² + 1 levels (:data:`SEED_000_CELL_PX`: ten, steps of 1/9);
    :func:`clustered_dot_ranks` is the screen that keeps tone.
    """
    yy, xx = np.mgrid[0:cell, 0:cell].astype(float)
    centre = (cell - 1) / 2.0
    d2 = (yy - centre) ** 2 + (xx - centre) ** 2
    angle = np.arctan2(yy - centre, xx - centre)
    order = np.lexsort((np.arange(cell * cell), angle.ravel(), d2.ravel()))
    ranks = np.empty(cell * cell, dtype=np.int64)
    ranks[order] = np.arange(cell * cell)
    return ranks.reshape(cell, cell)


def _euclidean_dot_key(su: np.ndarray, sv: np.ndarray, half: int) -> np.ndarray:
    """Growth order of a round ("Euclidean") dot, integer, smallest first.

    ``su``, ``sv``: a pixel's offset from its dot centre along the lattice axes
    (dx + dy, dx − dy), in [−half, half); the dot's cell is the square |su|, |sv| ≤ half
    (a diamond in pixels), its corners the centres of the holes. Inside |su| + |sv| ≤ half
    (half the cell) the key is the squared distance from the dot centre (su² + sv² =
    2 (dx² + dy²)) minus half², ≤ 0; outside it is half² minus the squared distance from
    the nearest hole centre, > 0. So a dot grows round from its centre, the dots meet at
    50 % (a checkerboard of squares) and the holes then shrink round: the negated spot
    function ``Round`` of ISO 32000-1, Table 130, in integers (no ties broken by rounding).
    """
    u, v = np.abs(su), np.abs(sv)
    inside = u + v <= half
    return np.where(inside, u * u + v * v - half * half,
                    half * half - (half - u) ** 2 - (half - v) ** 2)


def _dispersed_order(points: np.ndarray, size: int, sigma: float) -> np.ndarray:
    """An order of ``points`` (D, 2) on a (size, size) torus in which every prefix is
    spread out: starting with point 0, repeatedly the point farthest (toroidal distance)
    from those already taken; among equally far points, the one of least Gaussian energy
    (σ = ``sigma`` px) from them — the "largest void" of Ulichney's (1993) void and
    cluster — then the lowest index. Returns the position of each point in the order,
    (D,) int. Distances are exact (integer squares); energies are rounded to
    :data:`ENERGY_DECIMALS` before comparing, so that points placed alike by the lattice's
    symmetry tie exactly and the order is the same on every machine."""
    delta = np.abs(points[:, None, :] - points[None, :, :])
    delta = np.minimum(delta, size - delta)
    d2 = (delta ** 2).sum(axis=2)
    gaussian = np.exp(-d2 / (2.0 * sigma ** 2))
    n = len(points)
    position = np.full(n, -1, dtype=np.int64)
    energy = np.zeros(n)
    nearest = np.full(n, np.iinfo(np.int64).max)
    chosen = 0
    for step in range(n):
        position[chosen] = step
        energy += gaussian[chosen]
        nearest = np.minimum(nearest, d2[chosen])
        free = position < 0
        if not free.any():
            break
        farthest = free & (nearest == nearest[free].max())
        chosen = int(np.argmin(np.where(farthest, np.round(energy, ENERGY_DECIMALS),
                                        np.inf)))
    return position


@lru_cache(maxsize=8)
def clustered_dot_ranks(cell: int, supercell_min_px: int | None = None
                        ) -> np.ndarray:
    """A clustered-dot screen that keeps tone: round dots on a 45° lattice in a supercell.

    Parameters
    ----------
    cell : int
        Even, ≥ 2: the dot lattice repeats every ``cell`` pixels across and down, with a
        second dot at the centre of each ``cell`` × ``cell`` square — dots on a 45°
        lattice, ``cell``/√2 px apart, ``cell``²/2 pixels per dot.
    supercell_min_px : int, optional
        The tile is the smallest multiple of ``cell`` at least this wide
        (default :data:`CLUSTERED_SUPERCELL_MIN_PX`).

    Returns
    -------
    ranks : (T, T) int
        A permutation of 0 … T² − 1, T = ⌈supercell_min_px / cell⌉ · cell. The rank of a
        pixel is (its order within its dot) · D + (its dot's turn), D = 2 T²/cell² dots:
        every dot grows by the Euclidean-dot order (:func:`_euclidean_dot_key`, angle on
        ties: a spiral), and all dots take their k-th pixel before any takes its
        (k + 1)-th, in a dispersed order of the dots (:func:`_dispersed_order`). At any
        level the dots differ by at most one pixel, and a flat patch over whole tiles is
        within 1/T² of its coverage (T² + 1 levels, ≥ 1025 by default). Built in
        1–3 ms and kept (read-only) for the next call with the same arguments.
    """
    minimum = CLUSTERED_SUPERCELL_MIN_PX if supercell_min_px is None else supercell_min_px
    half = cell // 2
    size = -(-minimum // cell) * cell
    y, x = np.mgrid[0:size, 0:size]
    s, d = x + y, x - y
    su = (s + half) % cell - half          # offset from the dot centre, lattice axes
    sv = (d + half) % cell - half          # (s and d, hence su and sv, share parity)
    # the dot a pixel belongs to: its centre pixel (x0, y0), x0 ± y0 = (s − su), (d − sv)
    x0 = ((s - su + d - sv) // 2) % size
    y0 = ((s - su - d + sv) // 2) % size
    centres, dot = np.unique(np.stack([y0.ravel(), x0.ravel()], axis=1), axis=0,
                             return_inverse=True)
    dot = dot.ravel()
    # order within a dot: every dot has the same offsets, so rank the offsets once
    key = _euclidean_dot_key(su, sv, half).ravel()
    angle = np.arctan2(sv, su).ravel()
    offset = ((su + half) * cell + (sv + half)).ravel()
    first = dot == 0
    table = np.empty(cell * cell, dtype=np.int64)
    own = np.lexsort((offset[first], angle[first], key[first]))
    table[offset[first][own]] = np.arange(own.size)
    turn = _dispersed_order(centres, size, VOID_AND_CLUSTER_SIGMA * cell / np.sqrt(2.0))
    ranks = (table[offset] * len(centres) + turn[dot]).reshape(size, size)
    ranks.flags.writeable = False
    return ranks


def _toroidal_gaussian(size: int, sigma: float) -> np.ndarray:
    """exp(−d²/2σ²) over the toroidal offsets of a (size, size) tile, (size, size)."""
    d = np.minimum(np.arange(size), size - np.arange(size)).astype(float)
    g = np.exp(-d ** 2 / (2.0 * sigma ** 2))
    return np.outer(g, g)


def void_and_cluster_ranks(size: int, sigma: float = VOID_AND_CLUSTER_SIGMA,
                           seed: int = VOID_AND_CLUSTER_SEED) -> np.ndarray:
    """Ulichney's (1993) void-and-cluster dither array, (size, size) int ranks.

    Energy of a pattern is its toroidal convolution with a Gaussian (σ = ``sigma`` px);
    the *tightest cluster* is the set pixel of highest energy, the *largest void* the
    empty pixel of lowest energy. Steps: (0) a seeded random pattern with 10 % set pixels
    is relaxed by moving the tightest cluster into the largest void until they coincide;
    (1) removing tightest clusters one by one ranks the initial pixels downwards; (2) adding
    largest voids one by one ranks the rest upwards. Ulichney's phase 3 (tightest cluster
    of the empty pixels once more than half are set) picks the same pixel as a largest
    void under a linear energy filter, so phases 2 and 3 are one loop here. Energies are
    updated incrementally (add or subtract one shifted Gaussian).
    """
    n = size * size
    lut = _toroidal_gaussian(size, sigma)

    def splat(index: int) -> np.ndarray:
        return np.roll(lut, divmod(index, size), axis=(0, 1)).ravel()

    rng = np.random.default_rng(seed)
    ones = max(1, int(round(VOID_AND_CLUSTER_INITIAL_FRACTION * n)))
    pattern = np.zeros(n, dtype=bool)
    pattern[rng.choice(n, ones, replace=False)] = True
    energy = np.real(np.fft.ifft2(np.fft.fft2(pattern.reshape(size, size))
                                  * np.fft.fft2(lut))).ravel()
    for _ in range(n):  # relaxation converges in far fewer moves; n is a hard stop
        cluster = int(np.argmax(np.where(pattern, energy, -np.inf)))
        pattern[cluster] = False
        energy -= splat(cluster)
        void = int(np.argmin(np.where(pattern, np.inf, energy)))
        pattern[void] = True
        energy += splat(void)
        if void == cluster:
            break
    ranks = np.empty(n, dtype=np.int64)
    p, e = pattern.copy(), energy.copy()
    for rank in range(ones - 1, -1, -1):
        cluster = int(np.argmax(np.where(p, e, -np.inf)))
        p[cluster] = False
        e -= splat(cluster)
        ranks[cluster] = rank
    p, e = pattern, energy
    for rank in range(ones, n):
        void = int(np.argmin(np.where(p, np.inf, e)))
        p[void] = True
        e += splat(void)
        ranks[void] = rank
    return ranks.reshape(size, size)


def blue_noise_ranks(size: int) -> tuple[np.ndarray, str]:
    """The void-and-cluster ranks of a (size, size) tile, generated once and cached.

    Returns the ranks and where they came from (``"cache"``, ``"generated"``, or
    ``"generated (cache not writable: …)"``). A cache file that is unreadable or not a
    permutation of 0 … size²−1 is regenerated, never trusted.
    """
    path = cache_dir() / (f"void_and_cluster_v{VOID_AND_CLUSTER_VERSION}_{size}x{size}_"
                          f"sigma{VOID_AND_CLUSTER_SIGMA}_seed{VOID_AND_CLUSTER_SEED}.npy")
    try:
        ranks = np.load(path, allow_pickle=False)
        if ranks.shape == (size, size) and np.array_equal(
                np.sort(ranks.ravel()), np.arange(size * size)):
            return ranks, "cache"
    except (OSError, ValueError):
        pass
    ranks = void_and_cluster_ranks(size)
    try:
        with atomic_path(path, immediate=True) as tmp, open(tmp, "wb") as fh:
            np.save(fh, ranks.astype(np.int32))
    except OSError as exc:
        return ranks, f"generated (cache not writable: {exc.strerror or exc})"
    return ranks, "generated"


def threshold_stack(coverage: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """Ordered halftoning of exclusive inks with one tiled threshold screen.

    Parameters
    ----------
    coverage : (H, W, 3) float
        Target coverage, r + g + b ≤ 1.
    thresholds : (n, m) float
        The screen tile, values in (0, 1); tiled from the top-left pixel.

    Returns
    -------
    labels : (H, W) uint8
        0 bare, 1 R (t < r), 2 G (r ≤ t < r + g), 3 B (r + g ≤ t < r + g + b).
    """
    c = np.asarray(coverage, dtype=np.float32)
    h, w = c.shape[:2]
    n, m = thresholds.shape
    t = np.tile(thresholds, (-(-h // n), -(-w // m)))[:h, :w]
    labels = np.zeros((h, w), dtype=np.uint8)
    upper = np.zeros((h, w), dtype=np.float32)
    for k in range(3):
        lower = upper
        upper = lower + c[:, :, k]
        labels[(t >= lower) & (t < upper)] = k + 1
    return labels


def check_power_of_two(value: int, option: str, lo: int, hi: int) -> None:
    """Refuse a screen size that is not a power of two in [lo, hi]."""
    if not (lo <= value <= hi) or value & (value - 1):
        raise InputError(f"{option} {value} is not a power of two in [{lo}, {hi}]",
                         fix=f"use one of {', '.join(str(1 << k) for k in range(lo.bit_length() - 1, hi.bit_length()))}")


def check_range(value: int, option: str, lo: int, hi: int, multiple_of: int = 1) -> None:
    """Refuse an integer option outside [lo, hi] or not a multiple of ``multiple_of``."""
    if not lo <= value <= hi:
        raise InputError(f"{option} {value} is outside [{lo}, {hi}]",
                         fix=f"use {_integers(multiple_of)} from {lo} to {hi}")
    if value % multiple_of:
        raise InputError(f"{option} {value} is not a multiple of {multiple_of}",
                         fix=f"use {_integers(multiple_of)} from {lo} to {hi}")


def _integers(multiple_of: int) -> str:
    return {1: "an integer", 2: "an even integer"}.get(multiple_of,
                                                      f"a multiple of {multiple_of}")
