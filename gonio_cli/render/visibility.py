"""The rasterizer's depth test: which triangle each pixel shows (:mod:`.raster` has the
camera, the G-buffer and the interpolation; its docstring the ray casting this performs).

Set-up (:func:`setup`): per triangle the edge vectors C_k = σ P_{k+1} × P_{k+2} (camera
space, σ = sign(P0 · N) so that a pixel shows the triangle iff min_k e_k ≥ 0 with
e_k = d · C_k, whichever way it faces), its plane, and its screen box clipped to the image;
triangles wholly nearer than :data:`NEAR` are culled, those crossing it get the whole
screen as their box and keep only hits beyond it.

Depth test (:func:`visible_keys`): for every pixel of every kept triangle's box that the
triangle covers, a 64-bit key ((complemented float32 bits of 1/z) << 32 | back-face bit
<< 31 | triangle) min-ed into the image, which resolves depth and the winning triangle at
once and prefers a front face on an exact tie (a silhouette edge shared with a back
face). The edge tests and 1/z are evaluated in float32 (a 24-bit mantissa, like a hardware
depth buffer), the same numbers for a shared edge from both sides, so edges are
watertight. The back faces of a closed mesh seen from outside are not tested
(:func:`closed_back_faces`). Two builds give the same keys bit for bit:

* C (``_rasterscan.c``, built by pip where a compiler is found): per triangle and row,
  the columns within the float32 round-off of the edges' roots, each tested — ~1–2 ms
  for the 20 448-triangle sphere at 512²;
* numpy (:func:`_scan`): (triangle, row) pairs batched into spans found in float64,
  pixels farther from an edge than the test's round-off taken without testing, the rest
  tested; front faces first, then the back faces a min-pyramid of their 1/z does not
  hide (hierarchical z, :func:`hidden_back_faces`); the hits scattered with
  ``np.minimum.at``. 7–11 ms for that sphere at 512² (warm, median of 9).
"""

from __future__ import annotations

import numpy as np

from . import Mesh

#: Builds of :func:`visible_keys`, in order of preference (this module's docstring).
BUILDS = ("c", "numpy")

#: Near plane distance (world units along the view axis): hits nearer are discarded, and
#: triangles with all vertices nearer are culled. Small against any scene scale, large
#: enough that 1 / depth stays far from float overflow.
NEAR = 1e-4
#: Most candidate pixels per vectorised chunk of :func:`_scan`: ~10 arrays of them
#: (≤ ~80 MB), e.g. a whole 1024² frame in one chunk.
CHUNK_CANDIDATES = 1 << 20
#: Most (triangle, box row) pairs per chunk of :func:`_scan`: ~15 arrays of them (≤ ~30 MB).
CHUNK_ROWS = 1 << 18
#: A triangle whose plane passes this close to the eye (|P0 · N| / (|P0| |N|), the sine
#: of the angle between the view ray and the plane) is seen edge-on and covers no pixel.
EDGE_ON_SINE = 1e-9

KEY_EMPTY = np.iinfo(np.int64).max
TRI_INDEX_MASK = np.int64(0x7FFFFFFF)   # low 31 bits of a key; bit 31 = back face


def setup(pc: np.ndarray, faces: np.ndarray, handedness: float, w: int, h: int, F: float):
    """Per-triangle set-up: which triangles can show, their screen boxes and planes.

    Parameters
    ----------
    pc : (V, 3) camera-space vertex coordinates on (r, u, f) ; faces : (F, 3)
    handedness : ±1, det of the (r, u, f) basis (−1: cross products of camera
        coordinates are the world's negated) ; w, h : image size ; F : focal length (px)

    Returns
    -------
    dict of arrays over the kept triangles (n,): ``tri`` their indices into ``faces``;
    ``C`` (3 edges, 3, n) float64 edge vectors σ P_{k+1} × P_{k+2} oriented by
    σ = sign(P0 · N) so that a pixel shows the triangle iff every e_k = d · C_k ≥ 0;
    ``N`` (3, n) = Σ_k C_k ; ``q`` (n,) = |P0 · N| > 0 (depth = q / (d · N));
    ``back`` (n,) bool ; boxes ``x0, y0, bw, bh`` (n,) int64, clipped to the image.
    """
    ft = np.ascontiguousarray(faces.T)                         # (3 corners, F)
    X, Y, Z = (np.ascontiguousarray(pc[:, i])[ft] for i in range(3))
    # edge k (opposite corner k): C_k = P_{k+1} × P_{k+2}, written out so that the shared
    # edge of two triangles gives exactly negated numbers (watertight edge tests)
    def cross(a, b):                                           # corners a × b: 3 × (F,)
        return (Y[a] * Z[b] - Z[a] * Y[b], Z[a] * X[b] - X[a] * Z[b],
                X[a] * Y[b] - Y[a] * X[b])

    c0, c1, c2 = cross(1, 2), cross(2, 0), cross(0, 1)
    Cx, Cy, Cz = (np.stack([c0[i], c1[i], c2[i]]) for i in range(3))   # (3 edges, F)
    Nx, Ny, Nz = Cx[0] + Cx[1] + Cx[2], Cy[0] + Cy[1] + Cy[2], Cz[0] + Cz[1] + Cz[2]
    p0n = X[0] * Nx + Y[0] * Ny + Z[0] * Nz
    in_front = Z > NEAR
    any_front = in_front[0] | in_front[1] | in_front[2]
    all_front = in_front[0] & in_front[1] & in_front[2]
    scale = np.sqrt((X[0] ** 2 + Y[0] ** 2 + Z[0] ** 2) * (Nx**2 + Ny**2 + Nz**2))
    keep = any_front & (np.abs(p0n) > EDGE_ON_SINE * scale)
    # boxes of the projected corners for triangles wholly in front, else the whole screen;
    # pixel (col, row) is a candidate if its centre (col + ½, row + ½) is inside the box
    inv_z = F / np.where(in_front, Z, 1.0)
    sx = X * inv_z
    sy = Y * inv_z
    big = float(2 * (w + h))                                   # beyond any box edge
    whole = ~all_front
    x_lo = np.where(whole, -big, np.minimum(np.minimum(sx[0], sx[1]), sx[2]))
    x_hi = np.where(whole, big, np.maximum(np.maximum(sx[0], sx[1]), sx[2]))
    y_lo = np.where(whole, -big, np.minimum(np.minimum(sy[0], sy[1]), sy[2]))
    y_hi = np.where(whole, big, np.maximum(np.maximum(sy[0], sy[1]), sy[2]))
    x0 = np.clip(np.ceil(w / 2.0 - 0.5 + np.clip(x_lo, -big, big)), 0, w)
    x1 = np.clip(np.floor(w / 2.0 - 0.5 + np.clip(x_hi, -big, big)), -1, w - 1)
    y0 = np.clip(np.ceil(h / 2.0 - 0.5 - np.clip(y_hi, -big, big)), 0, h)
    y1 = np.clip(np.floor(h / 2.0 - 0.5 - np.clip(y_lo, -big, big)), -1, h - 1)
    keep &= (x1 >= x0) & (y1 >= y0)
    tri = np.flatnonzero(keep)
    sigma = np.sign(p0n[tri])
    C = np.stack([Cx[:, tri], Cy[:, tri], Cz[:, tri]], axis=1) * sigma   # (3 edges, 3, n)
    # back face ⟺ the world normal points away from the eye ⟺ handedness · P0 · N > 0
    return {"tri": tri, "C": C, "N": C[0] + C[1] + C[2], "q": np.abs(p0n[tri]),
            "back": handedness * p0n[tri] > 0, "whole": whole[tri],
            "x0": x0[tri].astype(np.int64), "y0": y0[tri].astype(np.int64),
            "bw": (x1 - x0 + 1)[tri].astype(np.int64), "bh": (y1 - y0 + 1)[tri].astype(np.int64)}


def visible_keys(st, w, h, F, hiz: bool = True, culled: np.ndarray | None = None,
                 build: str | None = None) -> np.ndarray:
    """Depth test over all candidate pixels: (H·W,) int64 keys, KEY_EMPTY where empty.

    Keys are (0x7FFFFFFF − float32 bits of 1/z) << 32 | back << 31 | kept triangle
    index, so a min keeps the nearest triangle and prefers front faces on exact ties
    (silhouettes). ``build``: one of :data:`BUILDS` (default the first available); the
    keys are the same with each.

    With ``hiz`` (numpy build) the front faces go first; then a back face is skipped when
    a min-pyramid of their 1/z (hierarchical z, :func:`hidden_back_faces`) shows it
    behind them over its whole box — on a closed mesh seen from outside, most back faces
    (70 % of the default sphere's). The keys are the same either way.

    ``culled`` (n,) bool: back faces not to test at all, those of closed surfaces seen
    from outside (:func:`closed_back_faces`), which can never be the nearest hit.
    """
    keys = np.full(h * w, KEY_EMPTY, dtype=np.int64)
    coef = (np.ascontiguousarray(st["C"], dtype=np.float32),       # (3 edges, 3, n)
            # 1 / depth = (d · N) / q is linear on screen too: its coefficients
            np.ascontiguousarray(st["N"] / st["q"], dtype=np.float32),    # (3, n)
            np.arange(len(st["q"]), dtype=np.int64) | (st["back"].astype(np.int64) << 31))
    f32 = np.float32
    dx_col = (np.arange(w, dtype=f32) - f32(w / 2.0 - 0.5)) * f32(1.0 / F)  # dx of each column
    front = ~st["back"]
    back = st["back"] if culled is None else st["back"] & ~culled
    if (build or ("c" if c_build_available() else "numpy")) == "c":
        _c_scan(st, keys, np.flatnonzero(front | back), coef, dx_col, w, h, F)
        return keys
    hits = _HitBuffers(dx_col)                                # shared by the two passes
    if hiz and back.any() and front.any():
        _scan(st, keys, np.flatnonzero(front), coef, hits, w, h, F)
        hidden = hidden_back_faces(st, keys, w, h, F, back)
        _scan(st, keys, np.flatnonzero(back & ~hidden), coef, hits, w, h, F)
    else:
        _scan(st, keys, np.flatnonzero(front | back), coef, hits, w, h, F)
    return keys


def c_build_available() -> bool:
    """Whether the C build (``_rasterscan.c``) was compiled when gonio was installed."""
    try:
        # lazy: whether the C build is there is the question (an ImportError when not)
        from . import _rasterscan  # noqa: F401
    except ImportError:
        return False
    return True


def _c_scan(st, keys, sel, coef, dx_col, w, h, F) -> None:
    """:func:`_scan` by the C build (``_rasterscan.c``, its header): the same keys."""
    from ._rasterscan import scan

    C, inv_z, bits = coef
    i64 = (np.ascontiguousarray(st[k], dtype=np.int64) for k in ("x0", "y0", "bw", "bh"))
    scan(C, inv_z, bits, *i64, np.ascontiguousarray(sel, dtype=np.int64), dx_col,
         C.shape[2], sel.size, w, h, float(F), float(np.float32(h / 2.0 - 0.5)),
         float(np.float32(1.0 / F)), float(np.float32(1.0 / NEAR)), FLOAT32_FORM_TOLERANCE,
         keys)


def closed_back_faces(meshes: list[Mesh], st, obj: np.ndarray, pc: np.ndarray,
                       eye: np.ndarray) -> np.ndarray | None:
    """(n,) bool over the kept triangles: the back faces of meshes that are closed
    surfaces facing outwards (``Mesh.closed``) seen from outside — the eye outside the
    mesh's bounding box and every vertex beyond the near plane (no hit of the mesh is
    discarded there, which would show its inside). None when there are none.

    From outside a closed surface every ray that meets it enters through a front face
    before it leaves through a back face; in the rasterizer's arithmetic too, as a
    silhouette edge is the same numbers in the front and the back face that share it. So
    those back faces never win a pixel: not testing them changes no key (a test compares
    against testing every pixel) and saves their scan, ~20 % of the visibility pass on a
    closed mesh.
    """
    cull = np.zeros(len(meshes), bool)
    start = 0
    for i, m in enumerate(meshes):
        stop = start + len(m.vertices)
        if m.closed and stop > start:
            v = np.asarray(m.vertices)
            outside = bool(np.any(eye < v.min(axis=0)) or np.any(eye > v.max(axis=0)))
            cull[i] = outside and bool(pc[start:stop, 2].min() > NEAR)
        start = stop
    if not cull.any():
        return None
    return st["back"] & cull[obj[st["tri"]]]


#: Relative float32 round-off allowed for a linear form dx a + (dy b + c) of float32
#: coefficients evaluated in float32 (the edge functions and 1/z of a hit): ≤ ~4
#: roundings of the sum of its absolute terms, with a margin of 4×.
FLOAT32_FORM_TOLERANCE = 16 * float(np.finfo(np.float32).eps)


def hidden_back_faces(st, keys, w, h, F, back: np.ndarray | None = None) -> np.ndarray:
    """(n,) bool: kept back faces (of ``back``, default all) whose every possible hit lies
    behind the hits already in ``keys`` (hierarchical z; Greene et al. 1993).

    The 1/z of a triangle's plane is linear on screen, so over its box grown by one pixel
    (hits just outside the box by round-off included) it is at most its largest corner
    value, plus :data:`FLOAT32_FORM_TOLERANCE` of the sum of absolute terms for float32
    round-off. Each level of a min-pyramid of the 1/z in ``keys`` (0 where empty: never
    hides) holds the smallest 1/z of 2^L × 2^L pixels; the level whose cells are at least
    the grown box's extent covers it with ≤ 2 × 2 cells. A triangle is hidden if its bound
    is below their minimum: then at each of its hits the pixel holds a nearer face, which
    the key comparison would keep. Whole-screen boxes (near-plane crossing) never are.
    """
    bits = (np.int64(0x7FFFFFFF) - (keys >> 32)).astype(np.int32)
    rz = bits.view(np.float32)
    rz[keys == KEY_EMPTY] = 0.0
    levels = [rz.reshape(h, w)]
    while max(levels[-1].shape) > 1:
        a = levels[-1]
        hh, ww = a.shape
        if hh % 2 or ww % 2:                                  # pad with "empty"
            a = np.pad(a, ((0, hh % 2), (0, ww % 2)))
        levels.append(np.minimum(np.minimum(a[0::2, 0::2], a[1::2, 0::2]),
                                 np.minimum(a[0::2, 1::2], a[1::2, 1::2])))
    cand = np.flatnonzero((st["back"] if back is None else back) & ~st["whole"])
    hidden = np.zeros(len(st["q"]), bool)
    if cand.size == 0:
        return hidden
    gx0 = np.maximum(st["x0"][cand] - 1, 0)
    gy0 = np.maximum(st["y0"][cand] - 1, 0)
    gx1 = np.minimum(st["x0"][cand] + st["bw"][cand], w - 1)
    gy1 = np.minimum(st["y0"][cand] + st["bh"][cand], h - 1)
    iz = st["N"][:, cand] / st["q"][cand]                     # 1/z = d · iz, float64
    dx = (np.stack([gx0, gx1]) + 0.5 - w / 2.0) / F           # (2, m) extreme columns
    dy = (h / 2.0 - 0.5 - np.stack([gy0, gy1])) / F
    bound = (np.maximum(dx[0] * iz[0], dx[1] * iz[0]) + np.maximum(dy[0] * iz[1], dy[1] * iz[1])
             + iz[2])
    bound += FLOAT32_FORM_TOLERANCE * (np.abs(dx).max(0) * np.abs(iz[0])
                                       + np.abs(dy).max(0) * np.abs(iz[1]) + np.abs(iz[2]))
    extent = np.maximum(gx1 - gx0, gy1 - gy0) + 1
    level = np.ceil(np.log2(extent)).astype(np.int64)
    front_min = np.full(cand.size, np.inf)
    for L in np.flatnonzero(np.bincount(level)):              # ≤ log2(size) levels
        at = np.flatnonzero(level == L)
        grid = levels[L]
        cx0, cx1 = gx0[at] >> L, gx1[at] >> L
        cy0, cy1 = gy0[at] >> L, gy1[at] >> L
        front_min[at] = np.minimum(np.minimum(grid[cy0, cx0], grid[cy0, cx1]),
                                   np.minimum(grid[cy1, cx0], grid[cy1, cx1]))
    hidden[cand] = bound < front_min
    return hidden


def _chunks(sizes: np.ndarray, limit: int):
    """Consecutive slices of ``sizes`` whose sums stay ≤ ``limit`` (or one item each)."""
    ends = np.cumsum(sizes)
    start = 0
    while start < len(sizes):
        base = ends[start - 1] if start else 0
        stop = max(int(np.searchsorted(ends, base + limit, side="right")), start + 1)
        yield slice(start, stop)
        start = stop


def _scan(st, keys, sel, coef, hits, w, h, F) -> None:
    """Edge tests of the kept triangles ``sel`` and the scatter-min of their hits' keys
    into ``keys`` (:func:`_visibility`), one row span per triangle and box row.

    Along a row the edge function e_k = dx C_k.x + r_k (r_k = dy C_k.y + C_k.z, the
    float32 form every pixel's test evaluates) is linear in the column, so the pixels
    where all three are ≥ 0 form one span; in float64 each edge's root is affine in the
    row. Columns farther from every root than the float32 round-off of the test
    (:data:`FLOAT32_FORM_TOLERANCE` of its absolute terms) have a sure outcome and are
    taken (or left) without testing; the few within it get the float32 test itself, so
    the result is that of testing every pixel of the box in float32 — shared edges give
    exactly negated e and stay watertight. Triangles go in chunks of :data:`CHUNK_ROWS`
    box rows, hits in chunks of :data:`CHUNK_CANDIDATES` through reused buffers (fresh
    arrays would page-fault), which bounds the memory (a near-plane triangle's box is
    the whole screen).
    """
    if sel.size == 0:
        return
    C, inv_z, tri_bits = coef
    f32 = np.float32
    cy = f32(h / 2.0 - 0.5)
    inv_f = f32(1.0 / F)
    roots = _edge_roots(st, C, w, h, F)
    bh_all = st["bh"][sel]
    for part in _chunks(bh_all, CHUNK_ROWS):
        tris, bh = sel[part], bh_all[part]
        n_pairs = int(bh.sum())
        tri_p = np.repeat(tris, bh)                               # (triangle, row) pairs
        row_p = np.arange(n_pairs) - np.repeat(np.cumsum(bh) - bh - st["y0"][tris], bh)
        lo, li, ui, hi = _row_spans(st, C, roots, tri_p, row_p, cy, inv_f)
        pair_t, col_t = _tested_hits(C, tri_p, row_p, lo, li, ui, hi, hits.dx_col, cy, inv_f)
        # per pair: the 1/z row constant (dy iz.y + iz.z, as each hit adds it), the
        # pixel of column 0, the key's low bits
        dy_p = (cy - row_p.astype(f32)) * inv_f
        pairs = {"rz_const": dy_p * inv_z[1][tri_p] + inv_z[2][tri_p],
                 "iz0": inv_z[0][tri_p], "base": row_p * w, "bits": tri_bits[tri_p]}
        sure_n = (ui - li + 1).astype(np.int64)
        li = li.astype(np.int64)
        for cpart in _chunks(sure_n, CHUNK_CANDIDATES):
            n = int(sure_n[cpart].sum())
            run = np.repeat(np.arange(cpart.start, cpart.stop), sure_n[cpart])
            col = hits.buffer("col", n, np.int64)
            np.take(np.cumsum(sure_n[cpart]) - sure_n[cpart] - li[cpart], run - cpart.start,
                    out=col, mode="clip")
            np.subtract(hits.arange(n), col, out=col)             # li + (i − start)
            hits.scatter(keys, run, col, pairs)
        if pair_t.size:
            hits.scatter(keys, pair_t, col_t, pairs)


def _edge_roots(st, C, w, h, F) -> dict:
    """Per edge (3, n) and triangle, the column of the edge function's root on row y as
    A + B y, with the bounds of :func:`_scan`'s sure and tested runs.

    The root of e_k on row y is cx − (F C.z + (cy − y) C.y) / C.x = A + B y, and the
    round-off of the test in columns, TOL (F |dx|max + |root − cx|), is bounded over the
    box's rows; a lower edge (C.x > 0: col ≥ root) surely passes from root + slack and
    surely fails below root − slack, an upper edge (C.x < 0) the mirror image; ±inf
    offsets leave the other role's bounds alone, and flat edges (C.x = 0, e constant
    along the row: ``flat``, ``any_flat`` per triangle) are handled apart."""
    cx, cy = np.float32(w / 2.0 - 0.5), np.float32(h / 2.0 - 0.5)
    Cx, Cy, Cz = (C[:, i].astype(np.float64) for i in range(3))   # (3 edges, n)
    lower, upper = Cx > 0, Cx < 0
    flat = ~(lower | upper)
    safe_cx = np.where(flat, 1.0, Cx)
    A = float(cx) - (F * Cz + float(cy) * Cy) / safe_cx
    B = np.where(flat, 0.0, Cy / safe_cx)
    y0, y1 = st["y0"], st["y0"] + st["bh"] - 1
    slack = (FLOAT32_FORM_TOLERANCE * np.maximum(np.abs(A + B * y0 - float(cx)),
                                                 np.abs(A + B * y1 - float(cx)))
             + FLOAT32_FORM_TOLERANCE * (w / 2.0 + 1.0))
    return {"B": B, "flat": flat, "any_flat": flat.any(axis=0),
            "sure_lo": np.where(lower, A + slack, -np.inf),
            "out_lo": np.where(lower, A - slack, -np.inf),
            "sure_hi": np.where(upper, A - slack, np.inf),
            "out_hi": np.where(upper, A + slack, np.inf)}


def _row_spans(st, C, roots: dict, tri_p, row_p, cy, inv_f):
    """Per (triangle, row) pair, the columns (float64, whole numbers) of its span
    [lo, hi] and of its sure run [li, ui] inside it (:func:`_scan`); an empty span has
    lo > hi, one without a sure run li = hi + 1, ui = hi (the whole span tested)."""
    n_pairs = tri_p.size
    x0 = st["x0"][tri_p].astype(np.float64)
    sure_lo, out_lo = x0, x0.copy()
    sure_hi = x0 + (st["bw"][tri_p] - 1)
    out_hi = sure_hi.copy()
    row_f = row_p.astype(np.float64)
    by, t = np.empty(n_pairs), np.empty(n_pairs)
    for k in range(3):
        np.take(roots["B"][k], tri_p, out=by, mode="clip")
        by *= row_f
        for A_k, bound, op in ((roots["sure_lo"], sure_lo, np.maximum),
                               (roots["out_lo"], out_lo, np.maximum),
                               (roots["sure_hi"], sure_hi, np.minimum),
                               (roots["out_hi"], out_hi, np.minimum)):
            np.take(A_k[k], tri_p, out=t, mode="clip")
            t += by
            op(bound, t, out=bound)
    empty = None
    flat, flat_p = roots["flat"], np.flatnonzero(roots["any_flat"][tri_p])
    for k in range(3) if flat_p.size else ():
        at = flat_p[flat[k][tri_p[flat_p]]]
        if at.size:                          # e = r exactly on the row: pass iff r ≥ 0
            dy = (cy - row_p[at].astype(np.float32)) * inv_f
            r = dy * C[k, 1][tri_p[at]] + C[k, 2][tri_p[at]]
            bad = at[r < 0]
            empty = bad if empty is None else np.concatenate([empty, bad])
    lo, hi = np.ceil(out_lo, out=out_lo), np.floor(out_hi, out=out_hi)
    li = np.maximum(np.ceil(sure_lo, out=sure_lo), lo, out=sure_lo)
    ui = np.minimum(np.floor(sure_hi, out=sure_hi), hi, out=sure_hi)
    none = lo > hi
    if empty is not None:
        none[empty] = True
    lo[none], hi[none] = 1.0, 0.0
    no_sure = none | (li > ui)
    li[no_sure], ui[no_sure] = hi[no_sure] + 1, hi[no_sure]   # test the whole span
    return lo, li, ui, hi


def _tested_hits(C, tri_p, row_p, lo, li, ui, hi, dx_col, cy, inv_f):
    """The hits (pair, column) of the tested runs [lo, li) and (ui, hi] of each pair:
    the columns within the float32 round-off of an edge, by the float32 test itself."""
    left_n, right_n = (li - lo).astype(np.int64), (hi - ui).astype(np.int64)
    tested = np.flatnonzero(left_n + right_n)
    if not tested.size:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    pair_t = np.concatenate([np.repeat(tested, left_n[tested]),
                             np.repeat(tested, right_n[tested])])
    first = np.concatenate([lo[tested], ui[tested] + 1]).astype(np.int64)
    n_t = np.concatenate([left_n[tested], right_n[tested]])
    col_t = (np.arange(len(pair_t)) - np.repeat(np.cumsum(n_t) - n_t, n_t)
             + np.repeat(first, n_t))
    tp = tri_p[pair_t]
    dy = (cy - row_p[pair_t].astype(np.float32)) * inv_f
    dx = dx_col[col_t]
    m = None
    for k in range(3):                                    # the float32 test
        e = dx * C[k, 0][tp]
        e += dy * C[k, 1][tp] + C[k, 2][tp]
        m = e if m is None else np.minimum(m, e, out=m)
    keep = m >= 0.0
    return pair_t[keep], col_t[keep]


class _HitBuffers:
    """Reused buffers for the hits of :func:`_scan` (fresh arrays of ~10⁵–10⁶ elements
    page-fault on every chunk) and their key scatter."""

    def __init__(self, dx_col: np.ndarray):
        self.dx_col = dx_col
        self._buffers: dict[str, np.ndarray] = {}

    def buffer(self, name: str, n: int, dtype) -> np.ndarray:
        buf = self._buffers.get(name)
        if buf is None or buf.shape[0] < n:
            buf = self._buffers[name] = (np.arange(n, dtype=dtype) if name == "arange"
                                         else np.empty(n, dtype))
        return buf[:n]

    def arange(self, n: int) -> np.ndarray:
        return self.buffer("arange", n, np.int64)

    def scatter(self, keys: np.ndarray, run: np.ndarray, col: np.ndarray, pairs: dict) -> None:
        """Hits at (pair ``run``, column ``col``): 1/z = dx iz.x + (dy iz.y + iz.z) in
        float32 (as a test over the box computes it), key = (0x7FFFFFFF − its bits) << 32
        | back << 31 | triangle, scatter-min into ``keys``."""
        n = run.shape[0]
        if n == 0:                  # a chunk whose spans hold no sure pixel (every one of
            return                  # them within round-off of an edge, so tested)
        # mode="clip" (the indices are valid): with "raise" np.take buffers its output
        rz = np.take(self.dx_col, col, out=self.buffer("rz", n, np.float32), mode="clip")
        tmp = self.buffer("tmp", n, np.float32)
        rz *= np.take(pairs["iz0"], run, out=tmp, mode="clip")
        rz += np.take(pairs["rz_const"], run, out=tmp, mode="clip")
        pix = np.take(pairs["base"], run, out=self.buffer("pix", n, np.int64), mode="clip")
        pix += col
        tb = np.take(pairs["bits"], run, out=self.buffer("tb", n, np.int64), mode="clip")
        if not (rz.min() > 0.0 and rz.max() < np.float32(1.0 / NEAR)):   # near plane
            ok = (rz > 0.0) & (rz < np.float32(1.0 / NEAR))
            rz, pix, tb = rz[ok], pix[ok], tb[ok]
            n = rz.shape[0]
        # nearest = largest 1/z: its float32 bits grow with it, so store their complement
        key = np.subtract(np.int64(0x7FFFFFFF), rz.view(np.int32),
                          out=self.buffer("key", n, np.int64))
        key <<= 32
        key |= tb
        np.minimum.at(keys, pix, key)

#: Triangles per block of the set-up: its ~40 temporaries of 65 536 float64 (0.5 MB each)
#: are reused from the heap instead of page-faulting fresh 8 MB arrays for a 1 M-triangle
#: mesh (measured: 3× faster set-up there; one block for meshes up to 65 536 triangles).
SETUP_BLOCK = 1 << 16


def setup_blocked(pc, faces, handedness, w, h, F) -> dict:
    """:func:`_setup` over blocks of :data:`SETUP_BLOCK` triangles, joined."""
    if len(faces) <= SETUP_BLOCK:
        return setup(pc, faces, handedness, w, h, F)
    parts = []
    for start in range(0, len(faces), SETUP_BLOCK):
        part = setup(pc, faces[start:start + SETUP_BLOCK], handedness, w, h, F)
        part["tri"] = part["tri"] + start
        parts.append(part)
    axis = {"C": 2, "N": 1}
    return {key: np.concatenate([p[key] for p in parts], axis=axis.get(key, 0))
            for key in parts[0]}

