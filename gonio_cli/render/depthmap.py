"""Depth maps for shadows: triangles → the nearest depth per texel, and its local bounds.

A compact vectorised z-buffer that keeps depth only (:func:`rasterize_depth`). The camera
rasterizer (:mod:`.raster`) casts exact rays from a pinhole and interpolates attributes;
a shadow map needs neither the attributes nor a pinhole (a directional light's map is
orthographic), and it is dominated by a few large triangles (a floor covers the whole
map), where :mod:`.raster`'s per-hit set-up costs ~50 ns a texel: here a hit costs a few
array elements (~5 ns), so a 512² floor takes ~2 ms instead of ~13 ms.

Coordinates: texel (col, row) has its centre at (col + ½, row + ½); row 0 is the top of the
map. Each triangle gives its corners' texel coordinates (x, y) and a *nearness* d that is
affine in (x, y) over the triangle (a directional light: distance along the light
direction, measured towards the light; a point light: 1 / z along its face's axis, which
is affine on its image plane). The map keeps the largest d at each texel centre, −inf
where no triangle covers it.

Coverage rule (watertight): a texel centre (xc, yc) is covered by a triangle if
y_top ≤ yc < y_bottom and x_left ≤ xc < x_right on that row. Every edge's x at a row is
computed by one expression from its upper and its lower corner, xa + (yc − ya) · ((xb −
xa) / (yb − ya)), so the two triangles that share an edge compute the same float64 number
for it, and a centre on the edge belongs to exactly one of them (no crack, no overlap).

Near plane (point lights): corners behind the light's image plane have no projection;
:func:`clip_near` cuts triangles at z = near first (one or two triangles each).

Local bounds: :func:`dilate` gives, per texel, the smallest and largest depth within r
texels (a separable running min / max, van Herk 1992), so a shadow lookup learns with one
read whether any texel its filter could touch might block it.
"""

from __future__ import annotations

import numpy as np

#: Most hits (texels written) per vectorised chunk of :func:`rasterize_depth`: ~6 arrays of
#: them (≤ ~50 MB).
CHUNK_HITS = 1 << 20
#: A triangle whose doubled screen area (texels²) is at most this is skipped: it covers no
#: texel centre that its neighbours do not (its depth plane would be ill-conditioned).
MIN_AREA2 = 1e-12


def clip_near(P: np.ndarray, near: float) -> np.ndarray:
    """Triangles (3 corners, 3, T) in a camera frame whose third axis is the depth, cut at
    depth = ``near``: the parts with depth ≥ near, as (3, 3, T′) triangles (a triangle
    with one corner in front becomes one triangle, with two corners in front two)."""
    inside = P[:, 2, :] >= near                                   # (3, T)
    n_in = inside.sum(axis=0)
    parts = [P[:, :, n_in == 3]]
    for count in (1, 2):
        sel = np.flatnonzero(n_in == count)
        if sel.size == 0:
            continue
        # roll the corners so that corner 0 is the lone one (inside for 1, outside for 2)
        lone = np.argmax(inside[:, sel] if count == 1 else ~inside[:, sel], axis=0)
        order = (lone[None, :] + np.arange(3)[:, None]) % 3         # (3, n)
        Q = P[order, :, sel[None, :]]                               # (3, n, 3)
        Q = np.moveaxis(Q, 1, 2)                                    # (3 corners, 3, n)
        a, b, c = Q[0], Q[1], Q[2]

        def cut(p, q):                                              # point at depth near
            t = (p[2] - near) / (p[2] - q[2])
            return p + t * (q - p)

        ab, ac = cut(a, b), cut(a, c)
        if count == 1:
            parts.append(np.stack([a, ab, ac]))
        else:
            parts.append(np.stack([ab, b, c]))
            parts.append(np.stack([ab, c, ac]))
    return np.concatenate(parts, axis=2)


def _edge_x(xa, ya, k, yc):
    """x at row centre yc of the edge from its upper corner (xa, ya) with slope k =
    (xb − xa) / (yb − ya): the one expression both triangles of a shared edge evaluate,
    on the same numbers."""
    return xa + (yc - ya) * k


def empty_map(width: int, height: int) -> np.ndarray:
    """A (height, width) float32 depth map with nothing in it (−inf)."""
    if height * width >= 2 ** 31:
        raise ValueError(f"a {width} x {height} depth map is beyond int32 texel indices")
    return np.full((height, width), -np.inf, np.float32)


def rasterize_depth(X: np.ndarray, Y: np.ndarray, D: np.ndarray, depth: np.ndarray
                    ) -> np.ndarray:
    """Add triangles to a nearest-depth map: each texel keeps the largest nearness.

    Parameters
    ----------
    X, Y : (3, T) float64 texel coordinates of the corners (module docstring).
    D : (3, T) float64 nearness of the corners (larger = nearer the light), affine in
        (x, y) over each triangle.
    depth : (height, width) float32 map (:func:`empty_map`), updated in place and returned.
    """
    height, width = depth.shape
    out = depth.reshape(-1)
    if X.shape[1] == 0:
        return depth
    order = np.argsort(Y, axis=0, kind="stable")                    # corners top → bottom
    x0, x1, x2 = np.take_along_axis(X, order, axis=0)
    y0, y1, y2 = np.take_along_axis(Y, order, axis=0)
    d0, d1, d2 = np.take_along_axis(D, order, axis=0)
    area2 = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0)
    r_lo = np.clip(np.ceil(y0 - 0.5), 0, height)                    # rows: y0 ≤ yc < y2
    r_hi = np.clip(np.ceil(y2 - 0.5), 0, height)
    keep = ((np.abs(area2) > MIN_AREA2) & (r_hi > r_lo)
            & (np.maximum(np.maximum(x0, x1), x2) > 0.5)
            & (np.minimum(np.minimum(x0, x1), x2) < width - 0.5))
    tri = np.flatnonzero(keep)
    if tri.size == 0:
        return depth
    x0, x1, x2, y0, y1, y2, d0, d1, d2, area2 = (
        v[tri] for v in (x0, x1, x2, y0, y1, y2, d0, d1, d2, area2))
    # the depth plane d = a + bx · x + by · y of each triangle
    bx = ((d1 - d0) * (y2 - y0) - (d2 - d0) * (y1 - y0)) / area2
    by = ((x1 - x0) * (d2 - d0) - (x2 - x0) * (d1 - d0)) / area2
    a = d0 - bx * x0 - by * y0
    n_rows = (r_hi[tri] - r_lo[tri]).astype(np.int64)
    r_lo = r_lo[tri].astype(np.int64)
    # triangles in chunks of at most CHUNK_HITS texels, bounded by rows × columns spanned
    cols = np.minimum(np.ceil(np.maximum(np.maximum(x0, x1), x2)
                              - np.minimum(np.minimum(x0, x1), x2)) + 1, width)
    ends = np.cumsum(n_rows * cols.astype(np.int64))
    # each edge as (x, y of its upper corner, dx/dy), the numbers both triangles that
    # share it hold; rows only where y_a ≤ yc < y_b, so a flat edge's slope is never read
    with np.errstate(divide="ignore", invalid="ignore"):
        edges = (x0, y0, (x2 - x0) / (y2 - y0), (x1 - x0) / (y1 - y0), x1, y1,
                 (x2 - x1) / (y2 - y1))
    start = 0
    while start < len(tri):
        base = ends[start - 1] if start else 0
        stop = max(int(np.searchsorted(ends, base + CHUNK_HITS, side="right")), start + 1)
        t = np.arange(start, stop)
        _spans(out, t, n_rows[t], r_lo[t], edges, (a, bx, by), width)
        start = stop
    return depth


def _spans(out, t, n_rows, r_lo, edges, plane, width) -> None:
    """Write the row spans of triangles ``t`` (indices into the kept arrays) into ``out``:
    per row the long edge (corner 0 → 2) and the short one above or below corner 1."""
    pair_tri = np.repeat(t, n_rows)
    row = np.arange(len(pair_tri)) - np.repeat(np.cumsum(n_rows) - n_rows - r_lo, n_rows)
    yc = row + 0.5
    x0, y0, k02, k01, x1, y1, k12 = (e[pair_tri] for e in edges)
    long_x = _edge_x(x0, y0, k02, yc)
    upper = yc < y1
    short_x = _edge_x(np.where(upper, x0, x1), np.where(upper, y0, y1),
                      np.where(upper, k01, k12), yc)
    left, right = np.minimum(long_x, short_x), np.maximum(long_x, short_x)
    c_lo = np.clip(np.ceil(left - 0.5), 0, width).astype(np.int64)    # left ≤ xc < right
    c_hi = np.clip(np.ceil(right - 0.5), 0, width).astype(np.int64)
    n = np.maximum(c_hi - c_lo, 0)
    total = int(n.sum())
    if total == 0:
        return
    a, bx, by = (c[pair_tri] for c in plane)
    # depth at the first texel of each span, then + bx per texel: float32 (the map's
    # type; k · bx is exact to its rounding, k < 2^24) and int32 texel indices
    d_start = (a + bx * (c_lo + 0.5) + by * yc).astype(np.float32)
    run = np.repeat(np.arange(len(n), dtype=np.int32), n)
    k = np.arange(total, dtype=np.int32)
    k -= np.repeat((np.cumsum(n) - n).astype(np.int32), n)
    pix = np.take((row * width + c_lo).astype(np.int32), run)
    pix += k
    d = k.astype(np.float32)
    d *= np.take(bx.astype(np.float32), run)
    d += np.take(d_start, run)
    np.maximum.at(out, pix, d)


def dilate(depth: np.ndarray, radius: int, op=np.maximum) -> np.ndarray:
    """The largest (``op`` np.maximum) or smallest (np.minimum) value of a map over the
    (2 r + 1)² texels around each texel (beyond the map: ignored), (h, w) float32: what
    any filter of radius ≤ r − ½ around a point of that texel can read. Separable, each
    axis in ⌈log2(2 r + 1)⌉ + 1 passes (windows doubled, then two overlapping halves)."""
    pad = -np.inf if op is np.maximum else np.inf
    out = depth
    for axis in (0, 1):
        out = _running(out, radius, axis, op, pad)
    return np.ascontiguousarray(out)


def _running(a: np.ndarray, r: int, axis: int, op, pad: float) -> np.ndarray:
    """``op`` over the window [i − r, i + r] along ``axis`` (van Herk's doubling)."""
    if r <= 0:
        return a
    a = np.moveaxis(a, axis, 0)
    n = a.shape[0]
    size = 2 * r + 1
    padded = np.concatenate([np.full((r,) + a.shape[1:], pad, a.dtype), a,
                             np.full((r,) + a.shape[1:], pad, a.dtype)])
    span, m = 1, padded                        # m[i] = op over [i, i + span)
    while 2 * span <= size:
        m = op(m[:-span], m[span:])
        span *= 2
    # the window [i, i + size) of the padded array = two spans that overlap
    out = op(m[:n], m[size - span:size - span + n])
    return np.moveaxis(out, 0, axis)
