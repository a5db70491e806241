"""Batched z-buffer rasterizer: :class:`Camera` + meshes → :class:`GBuffer`.

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
* the near plane: triangles with every vertex nearer than :data:`.visibility.NEAR` (behind the eye
  or just in front of it) are culled; triangles crossing it are *not clipped* but ray
  cast over the whole screen, keeping only hits with depth > :data:`.visibility.NEAR` — the same
  pixels a geometric near-plane clip would give, at the cost of a full-screen box for
  those (few) triangles.

Orientation: each triangle's C_k are multiplied by σ = sign(P0 · N), after which a pixel
shows the triangle (hit at depth > 0, all b_k ≥ 0) iff min_k e_k ≥ 0, whichever way the
triangle faces and even when it crosses the eye's plane.

The depth test (which triangle each pixel shows) is :mod:`.visibility`'s: a C build
(``_rasterscan.c``) and a numpy one giving the same keys bit for bit. Only the winners are
then interpolated here, in the G-buffer's dtype (the pipeline: float32), into (c, n)
component arrays: normal, view, and position, facet normal, uv and its footprint when
asked. On this project's 2-core machine, a 512² frame of the 20 448-triangle OBJ sphere
(``benchmarks/bench_render_raster.py``) takes ~5 ms set-up, ~2 ms visibility in C (7–11 ms
in numpy) and 5–8 ms interpolation.

The uv footprint is max(|∂uv/∂x|, |∂uv/∂y|) in uv units per pixel, from the analytic
screen derivatives of the perspective-correct barycentrics (exact, not finite differences
across triangles): an attribute A = (d · G_A) / (d · N) has ∂A/∂x = (G_A.x − A N.x) /
(F d · N) and ∂A/∂y = −(G_A.y − A N.y) / (F d · N).

Back faces are drawn (meshes may be open); their shading normal is flipped towards the
viewer. A face is a back face when its counter-clockwise normal points away from the eye.

Why the depth test apart: it is the one part with two builds; camera, set-up and
interpolation share the per-triangle arrays of :func:`.visibility.setup`.
"""

from __future__ import annotations

import functools
import time

import numpy as np

from ..errors import InputError
from . import Camera, GBuffer, Mesh
from .visibility import (KEY_EMPTY, TRI_INDEX_MASK, closed_back_faces, setup_blocked,
                         visible_keys)

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
        st = setup_blocked(pc, faces, float(np.sign(np.linalg.det(basis))), w, h, F)
        times["setup"] = time.perf_counter() - t_start
        if len(st["tri"]):
            t0 = time.perf_counter()
            culled = closed_back_faces(meshes, st, obj, pc, eye)
            keys = visible_keys(st, w, h, F, culled=culled)
            times["visibility"] = time.perf_counter() - t0
            pix = np.flatnonzero(keys != KEY_EMPTY)
            k = keys[pix] & TRI_INDEX_MASK                   # winning kept-triangle per pixel
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
    dx, dy = _pixel_offsets(pix, w, h, F, table.dtype)
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
    store = functools.partial(_store, gb, pix, rows)
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


def _pixel_offsets(pix, w: int, h: int, F: float, dtype) -> tuple[np.ndarray, np.ndarray]:
    """(dx, dy) of the flat pixels ``pix`` in ``dtype``: the direction (dx, dy, 1) through
    their centres in camera space (x right, y up, focal length F pixels)."""
    t = np.dtype(dtype).type
    # image row and column: floor((pix + ½) / w) in float64 is exact (the fraction stays
    # ≥ ½ / w from an integer) and much faster than an integer division
    row = np.floor((pix + 0.5) * (1.0 / w))
    col = pix - row * w
    dx = col.astype(dtype)
    dx += t(0.5 - w / 2.0)
    dx *= t(1.0 / F)
    dy = row.astype(dtype)
    np.subtract(t(h / 2.0 - 0.5), dy, out=dy)
    dy *= t(1.0 / F)
    return dx, dy


def _store(gb, pix, rows, name: str, v: np.ndarray) -> None:
    """Put one attribute of a block into the G-buffer: (c, m) or (m,) values ``v``, at
    the block's contiguous rows ``rows`` (compact) or at its pixels ``pix`` (dense)."""
    target = getattr(gb, name)
    if gb.pixels is not None:
        if v.ndim == 1:
            target[rows] = v
        else:
            target.T[:, rows] = v
    elif v.ndim == 1:
        target.reshape(-1)[pix] = v
    else:
        target.reshape(-1, v.shape[0])[pix] = v.T


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
