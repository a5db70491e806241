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

Batching (no Python loop over triangles or pixels): boxes larger than :data:`TILE` are
cut into tiles; boxes are grouped by size class (:data:`SIZE_CLASSES` per axis, so a
box is tested over a window at most 1.5× its extent per axis); each class is one set of
(ch, cw, n) float32 arrays — boxes on the last axis so every broadcast operation runs
long inner loops — holding the three edge functions (one add each), their minimum, and
1/z (linear on screen) at the hits. Float32 has a 24-bit mantissa, like a hardware depth
buffer; watertightness does not depend on precision. The depth test is one scatter-min
``np.minimum.at`` per class of a 64-bit key ((complemented float32 bits of 1/z) << 32 |
back-face bit << 31 | triangle), which resolves depth and the winning triangle at once
and prefers a front face on an exact tie (a silhouette edge shared with a back face).
Only the winners are then interpolated, in float64: position, smooth normal, view, uv and
the uv footprint. On this project's shared 2-core machine a 512² frame of the
20 448-triangle default sphere takes ~5 ms set-up, ~12 ms visibility and ~19 ms
interpolation, ~40 ms in all (``benchmarks/bench_render_raster.py``, best of 10).

The uv footprint is max(|∂uv/∂x|, |∂uv/∂y|) in uv units per pixel, from the analytic
screen derivatives of the perspective-correct barycentrics (exact, not finite differences
across triangles): an attribute A = (d · G_A) / (d · N) has ∂A/∂x = (G_A.x − A N.x) /
(F d · N) and ∂A/∂y = −(G_A.y − A N.y) / (F d · N).

Back faces are drawn (meshes may be open); their shading normal is flipped towards the
viewer. A face is a back face when its counter-clockwise normal points away from the eye.
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
#: Boxes larger than TILE pixels in either direction are cut into TILE × TILE tiles, so
#: one big (or near-plane-crossing, full-screen) triangle costs no more memory per array
#: than many small ones.
TILE = 64
#: Window sizes (pixels, per axis) of the size classes: a box of extent b is tested over
#: the smallest class ≥ b, so at most 1.5× (1.33× on average) the box per axis is wasted,
#: with few classes (≤ 12² groups of boxes, each one vectorised pass).
SIZE_CLASSES = np.array([1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, TILE])
#: Most candidate pixels per vectorised chunk: three reused 2 M-float32 scratch arrays
#: (24 MB) plus the hits' indices and keys (≤ ~50 MB at full coverage).
CHUNK_CANDIDATES = 1 << 21
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
            "back": handedness * p0n[tri] > 0,
            "x0": x0[tri].astype(np.int64), "y0": y0[tri].astype(np.int64),
            "bw": (x1 - x0 + 1)[tri].astype(np.int64), "bh": (y1 - y0 + 1)[tri].astype(np.int64)}


def _tiles(x0, y0, bw, bh):
    """Cut boxes larger than TILE into TILE × TILE tiles: (owner, x0, y0, bw, bh) per tile."""
    nx = (bw + TILE - 1) // TILE
    ny = (bh + TILE - 1) // TILE
    nt = nx * ny
    owner = np.repeat(np.arange(len(bw)), nt)
    k = np.arange(len(owner)) - np.repeat(np.cumsum(nt) - nt, nt)
    ky, kx = np.divmod(k, nx[owner])
    tx0 = x0[owner] + kx * TILE
    ty0 = y0[owner] + ky * TILE
    return (owner, tx0, ty0, np.minimum(bw[owner] - kx * TILE, TILE),
            np.minimum(bh[owner] - ky * TILE, TILE))


def _size_class(extent: np.ndarray) -> np.ndarray:
    """Index of the smallest of SIZE_CLASSES ≥ extent (extent ≤ TILE)."""
    return np.searchsorted(SIZE_CLASSES, extent)


def _visibility(st, w, h, F) -> np.ndarray:
    """Depth test over all candidate pixels: (H·W,) int64 keys, _KEY_EMPTY where empty.

    Boxes (tiles) are grouped by size class (ch, cw); a group of n boxes is one
    (ch, cw, n) array per quantity, built by broadcasting per-box coefficients against the
    class's pixel offsets (no per-pixel gathers). A window is shifted left / up inside the
    image when it would stick out, so every candidate is a real pixel; each appears once per
    box. Keys are (0x7FFFFFFF − float32 bits of 1/z) << 32 | back << 31 | kept triangle
    index, so ``np.minimum.at`` keeps the nearest triangle and prefers front faces on
    exact ties (silhouettes).
    """
    keys = np.full(h * w, _KEY_EMPTY, dtype=np.int64)
    owner, x0, y0, bw, bh = _tiles(st["x0"], st["y0"], st["bw"], st["bh"])
    cls = _size_class(bh) * len(SIZE_CLASSES) + _size_class(bw)
    order = np.argsort(cls, kind="stable")
    cls_sorted = cls[order]
    starts = np.flatnonzero(np.r_[True, cls_sorted[1:] != cls_sorted[:-1]])
    ends = np.r_[starts[1:], len(order)]
    C = st["C"].astype(np.float32)                                # (3 edges, 3, n)
    # 1 / depth = (d · N) / q is linear on screen too: its coefficients per triangle
    inv_z = (st["N"] / st["q"]).astype(np.float32)                # (3, n)
    tri_bits = np.arange(len(st["q"]), dtype=np.int64) | (st["back"].astype(np.int64) << 31)
    cx, cy = np.float32(w / 2.0 - 0.5), np.float32(h / 2.0 - 0.5)
    inv_f = np.float32(1.0 / F)
    inv_near = np.float32(1.0 / NEAR)
    # scratch buffers reused by every chunk (fresh arrays would page-fault each time)
    scratch = np.empty((3, CHUNK_CANDIDATES), np.float32)
    offsets: dict[tuple[int, int], np.ndarray] = {}

    def window_offsets(ch: int, cw: int) -> np.ndarray:
        """(ch · cw,) flat-image offsets of a window's pixels from its top-left one."""
        if (ch, cw) not in offsets:
            offsets[ch, cw] = (np.arange(ch)[:, None] * w + np.arange(cw)).ravel()
        return offsets[ch, cw]

    for a, b in zip(starts, ends):                                # one pass per size class
        ch = min(int(SIZE_CLASSES[cls_sorted[a] // len(SIZE_CLASSES)]), h)
        cw = min(int(SIZE_CLASSES[cls_sorted[a] % len(SIZE_CLASSES)]), w)
        step = max(1, CHUNK_CANDIDATES // (ch * cw))
        for c0 in range(a, b, step):                              # memory-bounded chunks
            sel = order[c0:min(b, c0 + step)]
            own = owner[sel]
            n = len(sel)
            size = n * ch * cw
            wx0 = np.minimum(x0[sel], w - cw)                     # keep the window on screen
            wy0 = np.minimum(y0[sel], h - ch)
            # boxes on the last axis: (ch, cw, n) arrays, so that every broadcast
            # operation runs long inner loops over boxes (not over a window's few columns)
            dx = (np.arange(cw, dtype=np.float32)[:, None]
                  + (wx0 - cx).astype(np.float32)) * inv_f       # (cw, n)
            dy = ((cy - wy0).astype(np.float32)
                  - np.arange(ch, dtype=np.float32)[:, None]) * inv_f   # (ch, n)
            Ck = C[:, :, own]                                     # (3 edges, 3, n)
            # e_k = d · C_k = dx C_k.x + (dy C_k.y + C_k.z): one full-size add per edge;
            # inside ⟺ min_k e_k ≥ 0 (C oriented in _setup)
            m = scratch[0, :size].reshape(ch, cw, n)
            e = scratch[1, :size].reshape(ch, cw, n)
            np.add(dx * Ck[0, 0], (dy * Ck[0, 1] + Ck[0, 2])[:, None, :], out=m)
            for k in (1, 2):
                np.add(dx * Ck[k, 0], (dy * Ck[k, 1] + Ck[k, 2])[:, None, :], out=e)
                np.minimum(m, e, out=m)
            idx = np.flatnonzero(m.reshape(-1) >= 0.0)
            if len(idx) == 0:
                continue
            iz = inv_z[:, own]                                    # (3, n)
            rz = scratch[2, :size].reshape(ch, cw, n)
            np.add(dx * iz[0], (dy * iz[1] + iz[2])[:, None, :], out=rz)
            rem, j = np.divmod(idx, n)                            # offset in window, box
            rz_hit = rz.reshape(-1)[idx]
            pix_hit = (wy0 * w + wx0)[j] + window_offsets(ch, cw)[rem]
            tb = tri_bits[own[j]]
            ok = (rz_hit > 0.0) & (rz_hit < inv_near)            # in front of the near plane
            if not ok.all():
                rz_hit, pix_hit, tb = rz_hit[ok], pix_hit[ok], tb[ok]
            # nearest = largest 1/z: its float32 bits grow with it, so store their complement
            key = ((np.int64(0x7FFFFFFF) - rz_hit.view(np.int32)).astype(np.int64) << 32) | tb
            np.minimum.at(keys, pix_hit, key)
    return keys


def rasterize(camera: Camera, meshes: list[Mesh], ssaa: int = 1, uv: bool = True, *,
              compact: bool = False, dtype=np.float64, position: bool = True) -> GBuffer:
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
        Store world positions (only point lights read them).

    Returns
    -------
    GBuffer with object_id (H, W) int32 (−1 background), position / normal / view
    (world; unit normal flipped towards the viewer on back faces; view = unit vector to
    the eye) and, when any mesh has uvs, uv and uv_footprint (zeros on meshes without
    uvs): dense (H, W, ·) with zeros on the background, or compact (n, ·) rows in the
    order of ``pixels``.
    """
    return rasterize_timed(camera, meshes, ssaa, uv, compact=compact, dtype=dtype,
                           position=position)[0]


def gbuffer_bytes(height: int, width: int, ssaa: int, *, uv: bool, position: bool = True,
                  dtype=np.float32) -> int:
    """Largest memory (bytes) :func:`rasterize` (compact) needs for an image, whatever
    it covers: the int64 depth keys and the int32 object ids of every sample, plus at
    full coverage the sample and triangle indices and the attribute rows."""
    n = int(height) * int(width) * int(ssaa) ** 2
    item = np.dtype(dtype).itemsize
    per_row = item * (3 * (1 + int(position)) + (3 if uv else 0)) + 4 + 4 + 4
    return n * (8 + 4) + n * per_row


def rasterize_timed(camera: Camera, meshes: list[Mesh], ssaa: int = 1, uv: bool = True, *,
                    compact: bool = False, dtype=np.float64, position: bool = True
                    ) -> tuple[GBuffer, dict[str, float]]:
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
            keys = _visibility(st, w, h, F)
            times["visibility"] = time.perf_counter() - t0
            pix = np.flatnonzero(keys != _KEY_EMPTY)
            k = keys[pix] & _TRI_INDEX_MASK                   # winning kept-triangle per pixel
            del keys
            if h * w < 2 ** 31:                               # halve the index memory
                pix = pix.astype(np.int32)
            k = k.astype(np.int32)
    # the attribute buffers: dense images, or one row per covered sample
    shape = (len(pix),) if compact else (h, w)
    zeros = np.zeros if not compact else np.empty
    gb.position = zeros(shape + (3,), dtype) if position else None
    gb.normal = zeros(shape + (3,), dtype)
    gb.view = zeros(shape + (3,), dtype)
    if has_uv:
        gb.uv = zeros(shape + (2,), dtype)
        gb.uv_footprint = zeros(shape, dtype)
    if compact:
        gb.pixels = pix
    if len(pix):
        t0 = time.perf_counter()
        if len(st["tri"]) > len(pix):        # more triangles than winners: keep winners only
            won, k = np.unique(k, return_inverse=True)
            k = k.ravel()
            st = {key: (v[..., won] if key in ("C", "N") else v[won]) for key, v in st.items()
                  if key in ("tri", "C", "N", "q", "back")}
        _interpolate(gb, pix, k, st, _plane_table(st, vnormals, faces, uvs), obj, eye,
                     basis, w, h, F)
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


def _plane_table(st, vnormals, faces, uvs) -> np.ndarray:
    """Per kept triangle, the vectors that interpolate its attributes: (K, 3, n) float64.

    An attribute A with corner values A_k interpolates perspective-correctly as
    A = Σ_k e_k A_k / Σ_k e_k = (d · G_A) / (d · N) with G_A = Σ_k C_k A_k, so per pixel
    it costs one dot product with d = (dx, dy, 1). Rows: 0 N, 1–3 G of the normal's x, y,
    z (sign-flipped on back faces), then 4–5 G of u, v when the meshes have uvs. The
    triangle axis is last so that gathering winners gives contiguous rows.
    """
    corners = faces[st["tri"]].T                              # (3 corners, n)
    attrs = [vnormals[:, i] for i in range(3)] + ([uvs[:, 0], uvs[:, 1]] if uvs is not None
                                                  else [])
    C = st["C"]
    flip = np.where(st["back"], -1.0, 1.0)
    table = np.empty((1 + len(attrs), 3, C.shape[2]))
    table[0] = st["N"]
    for a, values in enumerate(attrs):                        # ≤ 5 attributes
        corner_values = values[corners]                       # (3 corners, n)
        if a < 3:
            corner_values = corner_values * flip
        table[1 + a] = (C[0] * corner_values[0] + C[1] * corner_values[1]
                        + C[2] * corner_values[2])
    return table


def _interpolate(gb, pix, k, st, table, obj, eye, basis, w, h, F) -> None:
    """Fill the G-buffer at covered pixels ``pix`` (flat) won by kept triangles ``k``.

    Values are A = (d · G_A) / (d · N) (:func:`_plane_table`); a uv's screen derivatives
    are ∂A/∂x = (G_A.x − A N.x) / (F d · N) and ∂A/∂y = −(G_A.y − A N.y) / (F d · N).
    Pixels go in blocks of :data:`INTERP_BLOCK` so the temporaries stay in cache.
    """
    for start in range(0, len(pix), INTERP_BLOCK):
        block = slice(start, start + INTERP_BLOCK)
        _interpolate_block(gb, pix[block], k[block], st, table, obj, eye, basis, w, h, F,
                           block)


def _interpolate_block(gb, pix, k, st, table, obj, eye, basis, w, h, F, rows) -> None:
    """:func:`_interpolate` for one block of pixels (``rows``: their rows in a compact
    G-buffer)."""
    row, col = np.divmod(pix, w)
    dx = (col + 0.5 - w / 2.0) / F
    dy = (h / 2.0 - 0.5 - row) / F
    g = np.take(table.reshape(-1, table.shape[-1]), k, axis=1).reshape(
        table.shape[0], 3, len(k))                            # (K, 3, N) contiguous rows
    dot = g[:, 0] * dx + g[:, 1] * dy + g[:, 2]               # (K, N): d · G
    # d · N > 0 at every winner in exact arithmetic; a float32 edge test can pass a pixel
    # where the float64 sum rounds to ≤ 0 (a triangle seen almost edge-on): floor it
    N_len = np.sqrt(g[0, 0] ** 2 + g[0, 1] ** 2 + g[0, 2] ** 2)
    s = np.maximum(dot[0], MIN_RAY_PLANE_COS * N_len)
    depth = st["q"][k] / s
    ray = basis[:, 0, None] * dx + basis[:, 1, None] * dy + basis[:, 2, None]  # (3, N) world
    inv_len = 1.0 / np.sqrt(ray[0] ** 2 + ray[1] ** 2 + ray[2] ** 2)
    # normal: Σ e_k n_k (the positive factor 1 / Σe does not change the direction)
    n = dot[1:4]
    ln = np.sqrt(n[0] ** 2 + n[1] ** 2 + n[2] ** 2)
    bad = ln <= MIN_NORMAL_LENGTH * s
    if bad.any():   # opposite corner normals cancel (broken mesh): use the view direction
        n[:, bad] = -ray[:, bad] * inv_len[bad]
        ln[bad] = 1.0
    gb.object_id.reshape(-1)[pix] = obj[st["tri"][k]]
    # compact: contiguous rows of this block; dense: the pixels' places in the image
    at = rows if gb.pixels is not None else pix
    values = {"normal": n / ln, "view": -ray * inv_len}
    if gb.position is not None:
        values["position"] = eye[:, None] + depth * ray
    if gb.uv is not None:
        uv = dot[4:6] / s
        scale = 1.0 / (F * s)
        fx = (g[4:6, 0] - uv * g[0, 0]) * scale
        fy = (g[4:6, 1] - uv * g[0, 1]) * scale
        values["uv"] = uv
        gb.uv_footprint.reshape(-1)[at] = np.sqrt(np.maximum(
            fx[0] ** 2 + fx[1] ** 2, fy[0] ** 2 + fy[1] ** 2))
    for name, v in values.items():                            # (c, N) → rows (N, c)
        target = getattr(gb, name)
        target.reshape(-1, v.shape[0])[at] = v.T


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
