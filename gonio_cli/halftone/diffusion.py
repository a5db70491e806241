"""Vector error diffusion over the four exclusive ink states {none, R, G, B}.

Each pixel's *error-corrected coverage* v = c + e (c the target coverage, e the error
diffused into the pixel from pixels already decided) is replaced by the nearest of the
four corner points {0, e_R, e_G, e_B} of the coverage simplex (Euclidean distance). Since
|v − e_k|² = |v|² − 2 v_k + 1 and |v − 0|² = |v|², ink k wins over bare substrate exactly
when v_k > 1/2, and among the inks the largest v_k wins. So the rule is: take the ink with
the largest corrected coverage (the first of R, G, B on a tie) if it exceeds one half,
else leave the substrate bare (a tie at one half leaves it bare). The vector difference
v − corner is then spread to the unvisited neighbours with the weights of the chosen
diffusion matrix, all three channels with the same weights (vector error diffusion).

Rows are scanned serpentine (left to right on even rows, right to left on odd rows, the
matrix mirrored), which breaks up the directional "worms" of raster scanning (Ulichney
1987, *Digital Halftoning*, ch. 8).

Three builds of the same arithmetic exist: :func:`diffuse_reference`, plain Python, slow
and obviously right, and the kernel behind :func:`diffuse`, which keeps only ``rows`` lines
of error in a ring buffer, in two builds (:data:`BUILDS`): C (``_diffuse.c``, compiled when
gonio is installed; no start-up cost) and numba (:func:`_kernel_source`, used where the C
build is missing; ~0.7 s of numba start-up per process). All add the same float64 products
in the same order, so their outputs are identical bit for bit (tests check both builds).

References
----------
R. W. Floyd and L. Steinberg, "An adaptive algorithm for spatial greyscale", Proc. SID
17(2), 75-77, 1976.
J. F. Jarvis, C. N. Judice and W. H. Ninke, "A survey of techniques for the display of
continuous tone pictures on bilevel displays", Computer Graphics and Image Processing 5,
13-40, 1976.
P. Stucki, "MECCA — a multiple-error correction computation algorithm for bi-level image
hardcopy reproduction", IBM Research Report RZ1060, 1981.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

#: Number of ink channels and the label of each state in a label image (H, W) uint8:
#: 0 bare substrate, 1 R, 2 G, 3 B (label k selects channel k − 1).
N_INKS = 3

#: Corrected coverage an ink must exceed to beat bare substrate: the perpendicular bisector
#: between the corners 0 and e_k of the simplex (see the module docstring).
HALF = 0.5


@dataclass(frozen=True)
class DiffusionMatrix:
    """Error-diffusion weights as taps: the error goes to (row + dy, col + s·dx), s = ±1 the
    scan direction, with weight ``numerators / denominator``.

    Attributes
    ----------
    name : str
    taps : tuple of (dy, dx, numerator)
    denominator : int
    citation : str
    """

    name: str
    taps: tuple[tuple[int, int, int], ...]
    denominator: int
    citation: str

    def arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dy, dx, w): (n,) int64, (n,) int64, (n,) float64 weights summing to 1."""
        t = np.array(self.taps, dtype=np.int64)
        return t[:, 0].copy(), t[:, 1].copy(), t[:, 2] / float(self.denominator)


FLOYD_STEINBERG = DiffusionMatrix(
    "floyd-steinberg",
    ((0, 1, 7), (1, -1, 3), (1, 0, 5), (1, 1, 1)), 16,
    "Floyd & Steinberg 1976, Proc. SID 17(2) 75-77")

#: The twelve positions (dy, dx) shared by the Jarvis–Judice–Ninke and Stucki matrices:
#: two to the right on the current row, five on each of the next two rows.
TWELVE_TAPS = ((0, 1), (0, 2),
               (1, -2), (1, -1), (1, 0), (1, 1), (1, 2),
               (2, -2), (2, -1), (2, 0), (2, 1), (2, 2))

JARVIS = DiffusionMatrix(
    "jarvis", tuple((dy, dx, n) for (dy, dx), n in
                    zip(TWELVE_TAPS, (7, 5, 3, 5, 7, 5, 3, 1, 3, 5, 3, 1))), 48,
    "Jarvis, Judice & Ninke 1976, Comput. Graph. Image Process. 5, 13-40")

STUCKI = DiffusionMatrix(
    "stucki", tuple((dy, dx, n) for (dy, dx), n in
                    zip(TWELVE_TAPS, (8, 4, 2, 4, 8, 4, 2, 1, 2, 4, 2, 1))), 42,
    "Stucki 1981, IBM Research Report RZ1060")


def as_float32(coverage) -> np.ndarray:
    """Coverage as C-contiguous float32 (H, W, 3), the one dtype both implementations read
    (float32 holds a coverage to 6e-8, far below one pixel in 4096²)."""
    return np.ascontiguousarray(coverage, dtype=np.float32)


def diffuse_reference(coverage: np.ndarray, matrix: DiffusionMatrix,
                      serpentine: bool = True) -> np.ndarray:
    """Plain-Python vector error diffusion: the truth the numba kernel is tested against.

    Parameters
    ----------
    coverage : (H, W, 3) float array
        Target ink coverage in [0, 1] with r + g + b ≤ 1 (linear light); read as float32.
    matrix : DiffusionMatrix
    serpentine : bool
        Alternate the scan direction per row (default) or scan every row left to right.

    Returns
    -------
    labels : (H, W) uint8
        0 bare substrate, k = 1, 2, 3 ink k − 1 (R, G, B).
    """
    c = as_float32(coverage)
    h, w = c.shape[:2]
    dy, dx, wt = matrix.arrays()
    err = [[[0.0, 0.0, 0.0] for _ in range(w)] for _ in range(h)]
    labels = np.zeros((h, w), dtype=np.uint8)
    for y in range(h):
        step = -1 if (serpentine and y % 2 == 1) else 1
        cols = range(w - 1, -1, -1) if step < 0 else range(w)
        for x in cols:
            v = [float(c[y, x, k]) + err[y][x][k] for k in range(N_INKS)]
            best, label = v[0], 1
            for k in (1, 2):
                if v[k] > best:
                    best, label = v[k], k + 1
            if not best > HALF:
                label = 0
            labels[y, x] = label
            e = [v[k] - (1.0 if label == k + 1 else 0.0) for k in range(N_INKS)]
            for t in range(len(wt)):
                yy, xx = y + int(dy[t]), x + step * int(dx[t])
                if yy < h and 0 <= xx < w:
                    for k in range(N_INKS):
                        err[yy][xx][k] += e[k] * float(wt[t])
    return labels


def _kernel_source(coverage, pixels, table, scale_limit, dy, dx, wt, serpentine, labels,
                   stats):  # pragma: no cover - jitted
    """The numba kernel (see :func:`diffuse` and :func:`diffuse_pixels`); ``labels``
    (H, W) uint8 is filled in place.

    The coverage of a pixel comes from ``coverage`` (H, W, 3) float32, or, when
    ``pixels`` is not empty, from the stored 8-bit ``pixels`` (H, W, C): each channel
    through ``table`` (:func:`.coverage.decode_table`), then brought into gamut as
    :func:`.coverage.gamut_scale` does it, in the same float32 operations ((r + g) + b,
    divide by max(sum, 1)); ``stats`` (4,) float64 receives the number of pixels whose sum
    exceeds ``scale_limit`` (:func:`.coverage.out_of_gamut`) and the sum of the coverage of
    each ink.

    Error lives in a ring buffer of ``rows`` lines padded by ``pad`` columns on each side,
    so no bounds checks run in the inner loop; what lands in the padding or below the last
    row is dropped, exactly as the reference's bounds checks drop it.
    """
    h, w = labels.shape[0], labels.shape[1]
    from_pixels = pixels.shape[0] > 0
    one = np.float32(1.0)
    n = dy.shape[0]
    rows = 1
    pad = 0
    for t in range(n):
        rows = max(rows, dy[t] + 1)
        pad = max(pad, abs(dx[t]))
    err = np.zeros((rows, w + 2 * pad, 3), dtype=np.float64)
    ring = np.empty(n, dtype=np.int64)
    offset = np.empty(n, dtype=np.int64)
    outside = 0
    sum0 = 0.0
    sum1 = 0.0
    sum2 = 0.0
    for y in range(h):
        cur = y % rows
        step = 1
        if serpentine and (y % 2 == 1):
            step = -1
        for t in range(n):
            ring[t] = (cur + dy[t]) % rows
            offset[t] = step * dx[t]
        for i in range(w):
            x = i if step == 1 else w - 1 - i
            xe = x + pad
            if from_pixels:
                c0 = table[pixels[y, x, 0]]
                c1 = table[pixels[y, x, 1]]
                c2 = table[pixels[y, x, 2]]
                total = c0 + c1 + c2
                if total > scale_limit:
                    outside += 1
                if total > one:
                    c0 = c0 / total
                    c1 = c1 / total
                    c2 = c2 / total
                sum0 += c0
                sum1 += c1
                sum2 += c2
            else:
                c0 = coverage[y, x, 0]
                c1 = coverage[y, x, 1]
                c2 = coverage[y, x, 2]
            v0 = np.float64(c0) + err[cur, xe, 0]
            v1 = np.float64(c1) + err[cur, xe, 1]
            v2 = np.float64(c2) + err[cur, xe, 2]
            best = v0
            label = 1
            if v1 > best:
                best = v1
                label = 2
            if v2 > best:
                best = v2
                label = 3
            if not best > HALF:
                label = 0
            labels[y, x] = label
            e0 = v0 - (1.0 if label == 1 else 0.0)
            e1 = v1 - (1.0 if label == 2 else 0.0)
            e2 = v2 - (1.0 if label == 3 else 0.0)
            for t in range(n):
                r = ring[t]
                xx = xe + offset[t]
                wk = wt[t]
                err[r, xx, 0] += e0 * wk
                err[r, xx, 1] += e1 * wk
                err[r, xx, 2] += e2 * wk
        err[cur, :, :] = 0.0
    stats[0] = outside
    stats[1] = sum0
    stats[2] = sum1
    stats[3] = sum2


#: The kernel's one signature: float32 coverage or 8-bit pixels with their float32 decoding
#: table and the float32 out-of-gamut limit, taps as int64/float64, labels uint8, stats.
KERNEL_SIGNATURE = ("void(float32[:, :, ::1], uint8[:, :, ::1], float32[::1], float32, "
                    "int64[::1], int64[::1], float64[::1], boolean, uint8[:, ::1], float64[::1])")

_KERNEL: dict = {}

#: The builds of the kernel, in order of preference: the C extension module built by pip
#: (``_diffuse.c``; optional, skipped where no C compiler was found) and numba's JIT of
#: :func:`_kernel_source` (cached on disk).
BUILDS = ("c", "numba")


def c_build_available() -> bool:
    """Whether the C build of the kernel was compiled when gonio was installed."""
    try:
        # lazy: the C build is optional (absent where pip found no C compiler)
        from . import _diffuse  # noqa: F401
    except ImportError:
        return False
    return True


def compile_kernel(build: str | None = None) -> float:
    """Make the kernel ready in this process; return the seconds spent now (0 once ready).

    ``build`` is one of :data:`BUILDS`, or None for the first available one. The C build
    costs only its import. The numba build is compiled for :data:`KERNEL_SIGNATURE` with
    numba's on-disk cache (``cache=True``): the first process on a machine compiles it
    (seconds) and stores it, later processes load it (no compilation; what remains is
    numba's own start-up, ~0.5–1 s, which imports scipy.linalg). numba picks the folder:
    ``NUMBA_CACHE_DIR`` if set, else ``__pycache__`` beside this file if writable, else its
    user-wide cache (``~/.cache/numba``); if none is writable the kernel is compiled without
    a cache (:func:`kernel_status` says which happened).
    """
    if build is None:
        build = _KERNEL.get("active") or ("c" if c_build_available() else "numba")
    if build not in BUILDS:
        raise ValueError(f"unknown kernel build {build!r}; builds: {', '.join(BUILDS)}")
    _KERNEL["active"] = build
    if build in _KERNEL:
        return 0.0
    start = time.perf_counter()
    if build == "c":
        from ._diffuse import run
        _KERNEL["c"] = run
        return time.perf_counter() - start
    import numba  # importing numba is part of the price

    options = dict(nogil=True, error_model="numpy")
    try:
        fn = numba.njit([KERNEL_SIGNATURE], cache=True, **options)(_kernel_source)
        cached = True
    except RuntimeError:  # "cannot cache function ...: no locator available"
        fn = numba.njit([KERNEL_SIGNATURE], **options)(_kernel_source)
        cached = False
    _KERNEL.update(numba=fn, cached=cached)
    return time.perf_counter() - start


def kernel_status() -> str:
    """How this process got the kernel: ``c`` (the C build), or for the numba build
    ``cache`` (loaded from numba's on-disk cache), ``compiled`` (compiled and written to the
    cache), ``compiled-uncached`` (no writable cache folder); ``not-loaded`` before."""
    build = _KERNEL.get("active")
    if build is None or build not in _KERNEL:
        return "not-loaded"
    if build == "c":
        return "c"
    if not _KERNEL["cached"]:
        return "compiled-uncached"
    return "cache" if sum(_KERNEL["numba"].stats.cache_hits.values()) else "compiled"


def _run(coverage, pixels, table, scale_limit, dy, dx, wt, serpentine, labels, stats,
         build: str | None) -> None:
    """Call the chosen build with the kernel's arguments (see :func:`_kernel_source`)."""
    compile_kernel(build)
    build = _KERNEL["active"]
    if build == "numba":
        _KERNEL["numba"](coverage, pixels, table, scale_limit, dy, dx, wt, serpentine,
                         labels, stats)
        return
    h, w = labels.shape
    channels = pixels.shape[2] if pixels.size else 3
    _KERNEL["c"](coverage, pixels, h, w, channels, table, float(scale_limit), dy, dx, wt,
                 bool(serpentine), labels, stats)


def diffuse(coverage: np.ndarray, matrix: DiffusionMatrix,
            serpentine: bool = True, build: str | None = None) -> np.ndarray:
    """Vector error diffusion (the compiled kernel, ``build`` as in :func:`compile_kernel`);
    same arguments and result as :func:`diffuse_reference`, identical output, about 10⁴
    times faster."""
    c = as_float32(coverage)
    labels = np.zeros(c.shape[:2], dtype=np.uint8)
    dy, dx, wt = matrix.arrays()
    _run(c, _NO_PIXELS, _NO_TABLE, np.float32(0.0), dy, dx, wt, bool(serpentine),
         labels, np.zeros(4), build)
    return labels


_NO_COVERAGE = np.zeros((0, 0, 3), dtype=np.float32)
_NO_PIXELS = np.zeros((0, 0, 3), dtype=np.uint8)
_NO_TABLE = np.zeros(1, dtype=np.float32)


def diffuse_pixels(pixels: np.ndarray, table: np.ndarray, scale_limit: float,
                   matrix: DiffusionMatrix, serpentine: bool = True,
                   build: str | None = None) -> tuple[np.ndarray, int, np.ndarray]:
    """Vector error diffusion straight from stored 8-bit pixels, for ``--gamut scale``.

    Gives the labels of ``diffuse(gamut_scale(table[pixels[..., :3]]))`` (the result of
    :func:`.coverage.to_coverage` with ``gamut="scale"``), bit for bit, without ever holding
    the (H, W, 3) float32 coverage: each pixel is decoded and scaled into gamut as the
    kernel reaches it (a test checks the equality).

    Parameters
    ----------
    pixels : (H, W, C) uint8
        C ≥ 3; channels past the third are ignored (the caller checks alpha).
    table : (256,) float32
        Linear level of each stored value (:func:`.coverage.decode_table`).
    scale_limit : float
        A pixel counts as out of gamut where r + g + b > float32(scale_limit).
    build : str or None
        As in :func:`compile_kernel`.

    Returns
    -------
    labels : (H, W) uint8
    outside : int
        Pixels out of gamut before scaling.
    coverage_sum : (3,) float64
        Sum over the pixels of the in-gamut coverage of each ink.
    """
    px = np.ascontiguousarray(pixels, dtype=np.uint8)
    if px.ndim != 3 or px.shape[2] < 3:
        raise ValueError(f"pixels must be (H, W, C ≥ 3), not {px.shape}")
    table = np.ascontiguousarray(table, dtype=np.float32)
    if table.shape != (256,):
        raise ValueError(f"table must be (256,), not {table.shape}")
    labels = np.zeros(px.shape[:2], dtype=np.uint8)
    stats = np.zeros(4)
    dy, dx, wt = matrix.arrays()
    _run(_NO_COVERAGE, px, table, np.float32(scale_limit), dy, dx, wt, bool(serpentine),
         labels, stats, build)
    return labels, int(stats[0]), stats[1:].copy()
