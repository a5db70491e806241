"""Batched z-buffer rasterizer: :class:`Camera` + meshes → :class:`GBuffer` (numpy only).

Camera (docs/conventions.md): forward f = (target − eye)/|·|, right r = f × up / |·|, true up
u = r × f; ``fov_deg`` is the full vertical field of view. In an H × W image (already
supersampled) the focal length in pixels is F = (H / 2) / tan(fov / 2) and the pixel
centre (col + ½, row + ½) (row 0 the top) looks along the camera-space ray

    d = ((col + ½ − W/2) / F, −(row + ½ − H/2) / F, 1)       (coordinates on r, u, f).

Visibility is exact ray casting restricted to each triangle's screen bounding box
(homogeneous rasterization, Olano & Greer 1997). With camera-space vertices P0, P1, P2
the edge functions e_k = d · (P_{k+1} × P_{k+2}) are linear in the pixel position; the
ray hits the triangle iff e0, e1, e2 share a sign, at barycentrics b_k = e_k / Σe and
depth z = (P0 · N) / Σe, N = Σ_k P_{k+1} × P_{k+2} (so 1/z is linear on screen). So

* interpolation is perspective-correct by construction (b_k is the ray–plane hit);
* adjacent triangles are watertight: a shared edge's e is exactly negated in floating
  point (cross products and dot products of the same numbers in swapped order), and both
  sides include the edge itself (e = 0), depth picks one;
* the near plane: triangles with every vertex nearer than :data:`NEAR` (behind the eye
  or just in front of it) are culled; triangles crossing it are *not clipped* but ray
  cast over the whole screen, keeping only hits with depth > :data:`NEAR` — the same
  pixels a geometric near-plane clip would give, at the cost of a full-screen box for
  those (few) triangles.

Orientation: each triangle's C_k are multiplied by σ = sign(P0 · N), after which a pixel
shows the triangle (hit at depth > 0, all b_k ≥ 0) iff min_k e_k ≥ 0, whichever way the
triangle faces and even when it crosses the eye's plane.

Batching (no Python loop over triangles or pixels): each triangle's box is cut into
rows; along a row every e_k is linear in the column, so the pixels that show the
triangle form one span, found per (triangle, row) pair in float64 (:func:`_scan`).
Pixels farther from an edge than the float32 round-off of its test are taken without
testing; the few within it get the test itself in float32 (the same numbers as testing
every pixel of the box, so the watertight edges stay watertight). Float32 has a 24-bit
mantissa, like a hardware depth buffer. The depth test is a scatter-min
``np.minimum.at`` of a 64-bit key ((complemented float32 bits of 1/z) << 32 | back-face
bit << 31 | triangle), which resolves depth and the winning triangle at once and prefers
a front face on an exact tie (a silhouette edge shared with a back face). Front faces go
first; a back face whose box lies behind them on a min-pyramid of their 1/z (hierarchical
z) is skipped — same keys, most back faces of a closed mesh never tested. The back faces
of a mesh that is a closed surface facing outwards (checked once at load,
``Mesh.closed``), seen from outside it and wholly beyond the near plane, are not tested
at all: there every ray enters through a front face first (:func:`_closed_back_faces`).
Only the winners are then interpolated, in the G-buffer's dtype (the pipeline: float32),
into (c, n) component arrays: normal, view, and position, facet normal, uv and its
footprint when asked.
On this project's 2-core machine, a 512² frame of the 20 448-triangle OBJ sphere (warm
process, median of 9, ``benchmarks/bench_render.py``) takes 3–5 ms set-up, 7–11 ms
visibility (16–17 ms before closed meshes' back faces were skipped) and 5–8 ms
interpolation at ssaa 1, ~5, ~25 and ~25 ms at ssaa 2.

The uv footprint is max(|∂uv/∂x|, |∂uv/∂y|) in uv units per pixel, from the analytic
screen derivatives of the perspective-correct barycentrics (exact, not finite differences
across triangles): an attribute A = (d · G_A) / (d · N) has ∂A/∂x = (G_A.x − A N.x) /
(F d · N) and ∂A/∂y = −(G_A.y − A N.y) / (F d · N).

Back faces are drawn (meshes may be open); their shading normal is flipped towards the
viewer. A face is a back face when its counter-clockwise normal points away from the eye.

Why one module: camera, clipping, the batched z-buffer and the barycentric interpolation
are one pass over the triangles; they share the per-triangle set-up (``_setup``) and the
screen-space arrays, and their timings (above) are measured for the pass as a whole.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import InputError
from . import Camera, GBuffer, Mesh

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
#: Smallest d · N / |N| used at a winner (|d| ≥ 1): keeps depth = q / (d · N) finite
#: (≤ 1e12 × the distance to the plane) where round-off left d · N ≤ 0.
MIN_RAY_PLANE_COS = 1e-12
#: Pixels interpolated per block: (6, 3, 16 384) float64 gathered plane vectors ≈ 2.4 MB,
#: so a block's temporaries stay in cache (and reuse freed heap memory) instead of
#: page-faulting fresh arrays of the whole image.
INTERP_BLOCK = 1 << 14
#: An interpolated normal shorter than this (corner normals that cancel, a broken mesh)
#: is replaced by the view direction.
MIN_NORMAL_LENGTH = 1e-9

_KEY_EMPTY = np.iinfo(np.int64).max
_TRI_INDEX_MASK = np.int64(0x7FFFFFFF)   # low 31 bits of a key; bit 31 = back face


def camera_basis(camera: Camera) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(eye, right, up, forward), each (3,) float64, the last three orthonormal.

    Raises :class:`InputError` if eye = target or up is parallel to the view direction.
    """
    eye = np.asarray(camera.eye, np.float64).reshape(3)
    f = np.asarray(camera.target, np.float64).reshape(3) - eye
    nf = np.linalg.norm(f)
    if not nf > 0:
        raise InputError("camera eye and target coincide", column="[camera]",
                         fix="move the target away from the eye")
    f = f / nf
    r = np.cross(f, np.asarray(camera.up, np.float64).reshape(3))
    nr = np.linalg.norm(r)
    if not nr > 1e-12 * max(1.0, np.linalg.norm(camera.up)):
        raise InputError("camera up is parallel to the view direction", column="[camera]",
                         fix="choose an up vector not along target − eye")
    r = r / nr
    return eye, r, np.cross(r, f), f


def focal_px(camera: Camera, ssaa: int = 1) -> float:
    """Focal length in pixels of the supersampled image: (H / 2) / tan(fov / 2)."""
    return 0.5 * camera.height * ssaa / np.tan(np.radians(camera.fov_deg) / 2.0)


def pixel_rays(camera: Camera, ssaa: int = 1) -> np.ndarray:
    """World-space unit directions through every pixel centre: (H, W, 3), H = ssaa × height."""
    eye, r, u, f = camera_basis(camera)
    h, w = camera.height * ssaa, camera.width * ssaa
    F = focal_px(camera, ssaa)
    x = (np.arange(w) + 0.5 - w / 2.0) / F
    y = -(np.arange(h) + 0.5 - h / 2.0) / F
    d = x[None, :, None] * r + y[:, None, None] * u + f
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _concat(meshes: list[Mesh]):
    """All meshes as one triangle soup: (V, 3) verts, (F, 3) faces, (F,) object id, ..."""
    offsets = np.cumsum([0] + [len(m.vertices) for m in meshes])
    verts = np.concatenate([np.asarray(m.vertices, np.float64) for m in meshes])
    normals = np.concatenate([np.asarray(m.normals, np.float64) for m in meshes])
    faces = np.concatenate([np.asarray(m.faces, np.int64) + o for m, o in zip(meshes, offsets)])
    obj = np.concatenate([np.full(len(m.faces), i, np.int32) for i, m in enumerate(meshes)])
    any_uv = any(m.uvs is not None for m in meshes)
    uvs = None
    if any_uv:
        uvs = np.concatenate([np.asarray(m.uvs, np.float64) if m.uvs is not None
                              else np.zeros((len(m.vertices), 2)) for m in meshes])
    return verts, normals, faces, obj, uvs


def _setup(pc: np.ndarray, faces: np.ndarray, handedness: float, w: int, h: int, F: float):
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


def _visibility(st, w, h, F, hiz: bool = True, culled: np.ndarray | None = None
                ) -> np.ndarray:
    """Depth test over all candidate pixels: (H·W,) int64 keys, _KEY_EMPTY where empty.

    Keys are (0x7FFFFFFF − float32 bits of 1/z) << 32 | back << 31 | kept triangle
    index, so ``np.minimum.at`` keeps the nearest triangle and prefers front faces on
    exact ties (silhouettes). Candidates are generated by :func:`_scan` (row spans).

    With ``hiz`` the front faces go first; then a back face is skipped when a min-pyramid
    of their 1/z (hierarchical z, :func:`_hidden_back_faces`) shows it behind them over
    its whole box — on a closed mesh seen from outside, most back faces (70 % of the
    default sphere's). The keys are the same either way.

    ``culled`` (n,) bool: back faces not to test at all, those of closed surfaces seen
    from outside (:func:`_closed_back_faces`), which can never be the nearest hit.
    """
    keys = np.full(h * w, _KEY_EMPTY, dtype=np.int64)
    coef = (st["C"].astype(np.float32),                             # (3 edges, 3, n)
            # 1 / depth = (d · N) / q is linear on screen too: its coefficients
            (st["N"] / st["q"]).astype(np.float32),                 # (3, n)
            np.arange(len(st["q"]), dtype=np.int64) | (st["back"].astype(np.int64) << 31))
    f32 = np.float32
    dx_col = (np.arange(w, dtype=f32) - f32(w / 2.0 - 0.5)) * f32(1.0 / F)  # dx of each column
    hits = _HitBuffers(dx_col)                                # shared by the two passes
    front = ~st["back"]
    back = st["back"] if culled is None else st["back"] & ~culled
    if hiz and back.any() and front.any():
        _scan(st, keys, np.flatnonzero(front), coef, hits, w, h, F)
        hidden = _hidden_back_faces(st, keys, w, h, F, back)
        _scan(st, keys, np.flatnonzero(back & ~hidden), coef, hits, w, h, F)
    else:
        _scan(st, keys, np.flatnonzero(front | back), coef, hits, w, h, F)
    return keys


def _closed_back_faces(meshes: list[Mesh], st, obj: np.ndarray, pc: np.ndarray,
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


def _hidden_back_faces(st, keys, w, h, F, back: np.ndarray | None = None) -> np.ndarray:
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
    rz[keys == _KEY_EMPTY] = 0.0
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
    cx, cy = f32(w / 2.0 - 0.5), f32(h / 2.0 - 0.5)
    inv_f = f32(1.0 / F)
    dx_col = hits.dx_col
    # column of the root of e_k on row y: cx − (F C.z + (cy − y) C.y) / C.x = A + B y,
    # and the round-off of the test in columns, TOL (F |dx|max + |root − cx|), bounded
    # over the box's rows; a lower edge (C.x > 0: col ≥ root) surely passes from root +
    # slack and surely fails below root − slack, an upper edge (C.x < 0) the mirror
    # image; ±inf offsets leave the other role's bounds alone, and flat edges (C.x = 0,
    # e constant along the row) are handled apart
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
    A_sure_lo = np.where(lower, A + slack, -np.inf)
    A_out_lo = np.where(lower, A - slack, -np.inf)
    A_sure_hi = np.where(upper, A - slack, np.inf)
    A_out_hi = np.where(upper, A + slack, np.inf)
    any_flat = flat.any(axis=0)
    bh_all = st["bh"][sel]
    for part in _chunks(bh_all, CHUNK_ROWS):
        tris, bh = sel[part], bh_all[part]
        n_pairs = int(bh.sum())
        tri_p = np.repeat(tris, bh)                               # (triangle, row) pairs
        row_p = np.arange(n_pairs) - np.repeat(np.cumsum(bh) - bh - st["y0"][tris], bh)
        x0 = st["x0"][tri_p].astype(np.float64)
        sure_lo, out_lo = x0, x0.copy()
        sure_hi = x0 + (st["bw"][tri_p] - 1)
        out_hi = sure_hi.copy()
        row_f = row_p.astype(np.float64)
        by, t = np.empty(n_pairs), np.empty(n_pairs)
        for k in range(3):
            np.take(B[k], tri_p, out=by, mode="clip")
            by *= row_f
            for A_k, bound, op in ((A_sure_lo, sure_lo, np.maximum), (A_out_lo, out_lo, np.maximum),
                                   (A_sure_hi, sure_hi, np.minimum), (A_out_hi, out_hi, np.minimum)):
                np.take(A_k[k], tri_p, out=t, mode="clip")
                t += by
                op(bound, t, out=bound)
        empty = None
        flat_p = np.flatnonzero(any_flat[tri_p])
        for k in range(3) if flat_p.size else ():
            at = flat_p[flat[k][tri_p[flat_p]]]
            if at.size:                          # e = r exactly on the row: pass iff r ≥ 0
                dy = (cy - row_p[at].astype(f32)) * inv_f
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
        # the tested runs [lo, li) and (ui, hi], then hits: the sure runs [li, ui]
        left_n, right_n = (li - lo).astype(np.int64), (hi - ui).astype(np.int64)
        tested = np.flatnonzero(left_n + right_n)
        pair_t = col_t = np.zeros(0, np.int64)
        if tested.size:
            pair_t = np.concatenate([np.repeat(tested, left_n[tested]),
                                     np.repeat(tested, right_n[tested])])
            first = np.concatenate([lo[tested], ui[tested] + 1]).astype(np.int64)
            n_t = np.concatenate([left_n[tested], right_n[tested]])
            col_t = (np.arange(len(pair_t)) - np.repeat(np.cumsum(n_t) - n_t, n_t)
                     + np.repeat(first, n_t))
            tp = tri_p[pair_t]
            dy = (cy - row_p[pair_t].astype(f32)) * inv_f
            dx = dx_col[col_t]
            m = None
            for k in range(3):                                    # the float32 test
                e = dx * C[k, 0][tp]
                e += dy * C[k, 1][tp] + C[k, 2][tp]
                m = e if m is None else np.minimum(m, e, out=m)
            keep = m >= 0.0
            pair_t, col_t = pair_t[keep], col_t[keep]
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


def rasterize(camera: Camera, meshes: list[Mesh], ssaa: int = 1, uv: bool = True, *,
              compact: bool = False, dtype=np.float64, position: bool = True,
              facet: bool = False) -> GBuffer:
    """Rasterize meshes (world space) seen by ``camera`` into a G-buffer.

    Parameters
    ----------
    camera : Camera
    meshes : list of Mesh
        In world space; ``object_id`` in the result indexes this list.
    ssaa : int
        Supersampling factor ≥ 1: the G-buffer is (ssaa · height, ssaa · width); average
        the shaded colours with :func:`downsample`.
    uv : bool
        Interpolate uv and its footprint (when some mesh has uvs). Pass False when no
        object needs a texture (no mask): the target's "leave out what the scene does not
        need"; saves ~5 ms of a 512² frame.
    compact : bool
        Store the attributes of covered samples only (``GBuffer.pixels``): one row per
        covered sample instead of a whole image of mostly-background zeros. The render
        pipeline uses this; the dense layout is for inspection and tests.
    dtype : float dtype of the attributes (the pipeline: float32, half the memory and
        bandwidth; visibility is float32 and the interpolation float64 either way).
    position : bool
        Store world positions (only point lights and shadows read them).
    facet : bool
        Store each sample's facet normal: the unit normal of its triangle's plane
        (world; its sign is arbitrary), the geometry that the shadows compare with.

    Returns
    -------
    GBuffer with object_id (H, W) int32 (−1 background), position / normal / view
    (world; unit normal flipped towards the viewer on back faces; view = unit vector to
    the eye) and, when any mesh has uvs, uv and uv_footprint (zeros on meshes without
    uvs): dense (H, W, ·) with zeros on the background, or compact (n, ·) rows in the
    order of ``pixels``.
    """
    return rasterize_timed(camera, meshes, ssaa, uv, compact=compact, dtype=dtype,
                           position=position, facet=facet)[0]


def gbuffer_bytes(height: int, width: int, ssaa: int, *, uv: bool, position: bool = True,
                  dtype=np.float32, facet: bool = False) -> int:
    """Largest memory (bytes) :func:`rasterize` (compact) needs for an image, whatever
    it covers: the int64 depth keys and the int32 object ids of every sample, plus at
    full coverage the sample and triangle indices and the attribute rows."""
    n = int(height) * int(width) * int(ssaa) ** 2
    item = np.dtype(dtype).itemsize
    per_row = item * (3 * (1 + int(position) + int(facet)) + (3 if uv else 0)) + 4 + 4 + 4
    return n * (8 + 4) + n * per_row


def rasterize_timed(camera: Camera, meshes: list[Mesh], ssaa: int = 1, uv: bool = True, *,
                    compact: bool = False, dtype=np.float64, position: bool = True,
                    facet: bool = False) -> tuple[GBuffer, dict[str, float]]:
    """:func:`rasterize` plus wall times (s) of its passes: ``setup``, ``visibility``,
    ``interpolation`` (for the run report and the benchmark)."""
    ssaa = int(ssaa)
    if ssaa < 1:
        raise InputError(f"ssaa must be an integer ≥ 1, not {ssaa}", column="ssaa")
    times = {"setup": 0.0, "visibility": 0.0, "interpolation": 0.0}
    t_start = time.perf_counter()
    h, w = camera.height * ssaa, camera.width * ssaa
    F = focal_px(camera, ssaa)
    eye, r, u, f = camera_basis(camera)
    has_uv = uv and any(m.uvs is not None for m in meshes)
    gb = GBuffer(object_id=np.full((h, w), -1, np.int32), position=None, normal=None,
                 view=None, ssaa=ssaa)
    pix = np.zeros(0, np.int64)
    k = np.zeros(0, np.int64)
    st = None
    if any(len(m.faces) for m in meshes):
        verts, vnormals, faces, obj, uvs = _concat(meshes)
        uvs = uvs if has_uv else None
        basis = np.stack([r, u, f], axis=1)                   # world → camera: (p − eye) · basis
        pc = (verts - eye) @ basis
        st = _setup_blocked(pc, faces, float(np.sign(np.linalg.det(basis))), w, h, F)
        times["setup"] = time.perf_counter() - t_start
        if len(st["tri"]):
            t0 = time.perf_counter()
            culled = _closed_back_faces(meshes, st, obj, pc, eye)
            keys = _visibility(st, w, h, F, culled=culled)
            times["visibility"] = time.perf_counter() - t0
            pix = np.flatnonzero(keys != _KEY_EMPTY)
            k = keys[pix] & _TRI_INDEX_MASK                   # winning kept-triangle per pixel
            del keys
    # the attribute buffers: dense images, or one row per covered sample — stored as the
    # transpose of (c, n) arrays, so each component is contiguous for the shading
    if compact:
        def buffer(c):
            return np.empty((c, len(pix)), dtype).T if c else np.empty(len(pix), dtype)
    else:
        def buffer(c):
            return np.zeros((h, w, c) if c else (h, w), dtype)
    gb.position = buffer(3) if position else None
    gb.facet_normal = buffer(3) if facet else None
    gb.normal = buffer(3)
    gb.view = buffer(3)
    if has_uv:
        gb.uv = buffer(2)
        gb.uv_footprint = buffer(0)
    if compact:                                               # int32 halves the memory
        gb.pixels = pix.astype(np.int32) if h * w < 2 ** 31 else pix
    if len(pix):
        t0 = time.perf_counter()
        # the plane table only for triangles that won a pixel (on a closed mesh the back
        # faces win none): a mask and a running count renumber them
        used = np.zeros(len(st["tri"]), bool)
        used[k] = True
        won = np.flatnonzero(used)
        if len(won) < len(used):
            k = (np.cumsum(used) - 1)[k]
            st = {key: (v[..., won] if key in ("C", "N") else v[won]) for key, v in st.items()
                  if key in ("tri", "C", "N", "q", "back")}
        _interpolate(gb, pix, k, st, _plane_table(st, vnormals, faces, uvs, dtype), obj,
                     eye, basis, w, h, F)
        times["interpolation"] = time.perf_counter() - t0
    return gb, times


#: Triangles per block of the set-up: its ~40 temporaries of 65 536 float64 (0.5 MB each)
#: are reused from the heap instead of page-faulting fresh 8 MB arrays for a 1 M-triangle
#: mesh (measured: 3× faster set-up there; one block for meshes up to 65 536 triangles).
SETUP_BLOCK = 1 << 16


def _setup_blocked(pc, faces, handedness, w, h, F) -> dict:
    """:func:`_setup` over blocks of :data:`SETUP_BLOCK` triangles, joined."""
    if len(faces) <= SETUP_BLOCK:
        return _setup(pc, faces, handedness, w, h, F)
    parts = []
    for start in range(0, len(faces), SETUP_BLOCK):
        part = _setup(pc, faces[start:start + SETUP_BLOCK], handedness, w, h, F)
        part["tri"] = part["tri"] + start
        parts.append(part)
    axis = {"C": 2, "N": 1}
    return {key: np.concatenate([p[key] for p in parts], axis=axis.get(key, 0))
            for key in parts[0]}


#: Smallest corner-normal length for which a triangle's interpolated normals are known to
#: stay longer than :data:`MIN_NORMAL_LENGTH`: if no two corner normals point apart
#: (n_i · n_j ≥ 0), |Σ b_k n_k|² = Σ b_i b_j n_i · n_j ≥ Σ b_k² |n_k|² ≥ min |n_k|² / 3.
SAFE_NORMAL_LENGTH = 1e-6


def _plane_table(st, vnormals, faces, uvs, dtype=np.float64) -> tuple[np.ndarray, np.ndarray]:
    """Per kept triangle, the vectors that interpolate its attributes, and which
    triangles need the short-normal check.

    An attribute A with corner values A_k interpolates perspective-correctly as
    A = Σ_k e_k A_k / Σ_k e_k = (d · G_A) / (d · N) with G_A = Σ_k C_k A_k, so per pixel
    it costs one dot product with d = (dx, dy, 1). Returns ``table`` (3 K, n) in
    ``dtype`` — rows 3a, 3a + 1, 3a + 2 the x, y, z of G for attribute a: 0–2 the
    normal's x, y, z (sign-flipped on back faces), 3 N (the plane: d · N = Σ e), then 4–5
    u, v when the meshes have uvs; the triangle axis last so that gathering winners gives
    contiguous rows — and ``risky`` (n,) bool: triangles whose corner normals may cancel
    (:data:`SAFE_NORMAL_LENGTH`).
    """
    corners = faces[st["tri"]].T                              # (3 corners, n)
    attrs = [vnormals[:, i] for i in range(3)] + ([uvs[:, 0], uvs[:, 1]] if uvs is not None
                                                  else [])
    C = st["C"]
    flip = np.where(st["back"], -1.0, 1.0)
    table = np.empty((1 + len(attrs), 3, C.shape[2]), dtype)
    table[3] = st["N"]
    cn = []
    for a, values in enumerate(attrs):                        # ≤ 5 attributes
        corner_values = values[corners]                       # (3 corners, n)
        if a < 3:
            corner_values = corner_values * flip
            cn.append(corner_values)
        table[a if a < 3 else a + 1] = (C[0] * corner_values[0] + C[1] * corner_values[1]
                                        + C[2] * corner_values[2])
    def dot(i, j):                                            # corner normals n_i · n_j
        return cn[0][i] * cn[0][j] + cn[1][i] * cn[1][j] + cn[2][i] * cn[2][j]

    risky = ~((np.minimum(np.minimum(dot(0, 1), dot(1, 2)), dot(2, 0)) >= 0)
              & (np.minimum(np.minimum(dot(0, 0), dot(1, 1)), dot(2, 2))
                 >= SAFE_NORMAL_LENGTH ** 2))
    return table.reshape(-1, C.shape[2]), risky


def _interpolate(gb, pix, k, st, plane, obj, eye, basis, w, h, F) -> None:
    """Fill the G-buffer at covered pixels ``pix`` (flat) won by kept triangles ``k``.

    Values are A = (d · G_A) / (d · N) (:func:`_plane_table`); a uv's screen derivatives
    are ∂A/∂x = (G_A.x − A N.x) / (F d · N) and ∂A/∂y = −(G_A.y − A N.y) / (F d · N).
    The arithmetic is in the table's dtype (the pipeline: float32, which the G-buffer
    stores anyway), in blocks of :data:`INTERP_BLOCK` pixels so the temporaries stay in
    cache; d · N is formed only where depth, uv or a risky normal needs it.
    """
    table, risky = plane
    object_of = obj[st["tri"]]
    ids = gb.object_id.reshape(-1)
    if object_of.min() == object_of.max():                  # one object: no gather
        ids[pix] = object_of[0]
    else:
        ids[pix] = object_of[k]
    # the rows of the table this frame reads: normal, then the plane N where depth, uv
    # or a risky normal needs d · N, then u, v
    n_attr = table.shape[0] // 3
    risky_any = bool(risky.any())
    need_plane = (gb.position is not None or gb.facet_normal is not None or gb.uv is not None
                  or risky_any)
    attrs = [0, 1, 2] + ([3] if need_plane else []) + ([4, 5] if n_attr > 4 else [])
    rows_of = np.concatenate([[3 * a, 3 * a + 1, 3 * a + 2] for a in attrs])
    table = np.ascontiguousarray(table[rows_of])
    for start in range(0, len(pix), INTERP_BLOCK):
        block = slice(start, start + INTERP_BLOCK)
        _interpolate_block(gb, pix[block], k[block], st, table, attrs,
                           risky if risky_any else None, eye, basis, w, h, F, block)


def _interpolate_block(gb, pix, k, st, table, attrs, risky, eye, basis, w, h, F,
                       rows) -> None:
    """:func:`_interpolate` for one block of pixels (``rows``: their rows in a compact
    G-buffer); ``table`` holds the rows of the attributes ``attrs`` (:func:`_plane_table`
    numbering), ``risky`` is None when no triangle can have a short normal."""
    t = table.dtype.type
    # image row and column: floor((pix + ½) / w) in float64 is exact (the fraction stays
    # ≥ ½ / w from an integer) and much faster than an integer division
    row = np.floor((pix + 0.5) * (1.0 / w))
    col = pix - row * w
    dx = col.astype(table.dtype)
    dx += t(0.5 - w / 2.0)
    dx *= t(1.0 / F)
    dy = row.astype(table.dtype)
    np.subtract(t(h / 2.0 - 0.5), dy, out=dy)
    dy *= t(1.0 / F)
    need_plane = 3 in attrs
    g = np.take(table, k, axis=1)                             # (3 · attrs, m) contiguous
    dot = {}
    for j, a in enumerate(attrs):                             # d · G_a
        v = g[3 * j] * dx
        v += g[3 * j + 2]
        tmp = g[3 * j + 1] * dy
        v += tmp
        dot[a] = v
    n = np.stack([dot[0], dot[1], dot[2]])                    # Σ e_k n_k (positive factor)
    ln = np.sqrt(np.einsum("im,im->m", n, n))
    if need_plane:
        # d · N > 0 at every winner in exact arithmetic; a float32 edge test can pass a
        # pixel where the sum rounds to ≤ 0 (a triangle seen almost edge-on): floor it
        gN = g[3 * attrs.index(3):3 * attrs.index(3) + 3]
        s = np.maximum(dot[3], t(MIN_RAY_PLANE_COS) * np.sqrt(np.einsum("im,im->m", gN, gN)))
    ray = basis[:, 0, None].astype(table.dtype) * dx          # (3, m) world ray, |(dx,dy,1)|
    ray += basis[:, 1, None].astype(table.dtype) * dy
    ray += basis[:, 2, None].astype(table.dtype)
    inv_len = dx * dx
    inv_len += dy * dy
    inv_len += t(1)
    np.sqrt(inv_len, out=inv_len)
    np.divide(t(-1), inv_len, out=inv_len)                    # −1 / |ray|: the view
    view = ray * inv_len
    if risky is not None:   # opposite corner normals cancel (broken mesh): the view instead
        bad = risky[k] & (ln <= t(MIN_NORMAL_LENGTH) * s)
        if bad.any():
            n[:, bad] = view[:, bad]
            ln[bad] = 1.0
    n /= ln
    # compact: contiguous columns of this block; dense: the pixels' places in the image
    compact = gb.pixels is not None

    def store(name, v):
        target = getattr(gb, name)
        if compact:
            if v.ndim == 1:
                target[rows] = v
            else:
                target.T[:, rows] = v
        elif v.ndim == 1:
            target.reshape(-1)[pix] = v
        else:
            target.reshape(-1, v.shape[0])[pix] = v.T

    store("normal", n)
    store("view", view)
    if gb.position is not None:
        depth = st["q"][k] / s                                # along d = (dx, dy, 1)
        store("position", eye[:, None] + depth * ray)
    if gb.facet_normal is not None:                           # N = (P1 − P0) × (P2 − P0)
        gN = g[3 * attrs.index(3):3 * attrs.index(3) + 3]
        b = basis.astype(table.dtype)                         # camera → world
        fn = b[:, 0, None] * gN[0] + b[:, 1, None] * gN[1] + b[:, 2, None] * gN[2]
        fn /= np.sqrt(np.einsum("im,im->m", fn, fn))
        store("facet_normal", fn)
    if gb.uv is not None:
        gu = 3 * attrs.index(4)
        uv = np.stack([dot[4], dot[5]]) / s
        scale = 1.0 / (F * s)
        fx = (g[[gu, gu + 3]] - uv * g[3 * attrs.index(3)]) * scale
        fy = (g[[gu + 1, gu + 4]] - uv * g[3 * attrs.index(3) + 1]) * scale
        store("uv", uv)
        store("uv_footprint", np.sqrt(np.maximum(fx[0] ** 2 + fx[1] ** 2,
                                                 fy[0] ** 2 + fy[1] ** 2)))


def downsample(image: np.ndarray, ssaa: int, dtype=np.float64) -> np.ndarray:
    """Box-filter a supersampled image back to output size.

    Parameters
    ----------
    image : (ssaa·H, ssaa·W[, C]) array
    ssaa : int
        The supersampling factor (1 returns the image unchanged, as ``dtype``).
    dtype : of the sums and the result.

    Returns
    -------
    (H, W[, C]) — the mean of each ssaa × ssaa block: one reshape to
    (H, ssaa, W, ssaa[, C]), then the ssaa² strided sub-images added (measured ~7× faster
    than ``mean(axis=(1, 3))``, whose reduction over two strided axes runs short inner
    loops) and divided by ssaa².
    """
    img = np.asarray(image)
    ssaa = int(ssaa)
    if ssaa == 1:
        return img.astype(dtype, copy=False)
    hh, ww = img.shape[:2]
    if hh % ssaa or ww % ssaa:
        raise ValueError(f"a {hh} × {ww} image cannot be reduced by {ssaa}")
    blocks = img.reshape(hh // ssaa, ssaa, ww // ssaa, ssaa, *img.shape[2:])
    out = blocks[:, 0, :, 0].astype(dtype)
    for i in range(ssaa):
        for j in range(ssaa):
            if i or j:
                out += blocks[:, i, :, j]
    out *= 1.0 / (ssaa * ssaa)
    return out
