"""Shadow maps (:mod:`.shadow`'s first half): each light's depth maps, fitted to the
samples they answer for, and how world points land on them.

A directional light gets one orthographic map, d = distance towards the light (world
units) from the farthest sample; a point light one perspective map per cube face that
holds lit samples, d = 1 / z along the face's axis (affine on its image plane). Each map
covers its samples' bounding box on it plus the widest filter's reach (blockers there
shadow them), with :data:`TEXELS_PER_SAMPLE` texels per sample, at most
:data:`MAX_MAP_SIDE` a side. Two maps per view (:func:`render_maps`): what blocks — every
face of open meshes, the faces of closed meshes turned away from the light (the
second-depth map of Wang & Molnar 1994) — and the nearest surface of all (``front``), for
the bounds of the lookup and the blockers' depth. :class:`View` holds them with their
dilated bounds (:func:`.depthmap.dilate`) and projects samples onto them.

A lone convex closed mesh cannot shadow itself: :func:`lone_convex` says when a scene is
one, so the stage can skip its maps (the output is the same, tests/test_render_shadow.py).
"""

from __future__ import annotations

import weakref
from dataclasses import dataclass

import numpy as np

from . import Light, Mesh
from .depthmap import clip_near, dilate, empty_map, rasterize_depth
from .solid import is_convex

#: Texels per lit sample: a map side is √(2 n) for n samples in a square, ~1.4 texels
#: across a sample, so a shadow edge (located to ±½ texel by the map, smoothed over ≥ 1
#: texel by the filter) falls within a pixel of its place.
TEXELS_PER_SAMPLE = 2.0
#: Map side limits (texels): a 2048² float32 map, its front map and their two bounds
#: are 64 MB.
MIN_MAP_SIDE = 64
MAX_MAP_SIDE = 2048
#: Smallest filter radius (texels): a hard shadow is still smoothed over a texel.
MIN_FILTER_TEXELS = 1.0
#: Largest tan θ of a sample's plane to the light (θ = 89.4°): a plane the light grazes
#: has no finite slope on the map.
MAX_SLOPE = 100.0
#: A point light's near plane, as a fraction of the nearest lit sample's depth on the
#: face: blockers nearer the light than that are inside the lamp.
NEAR_FRACTION = 1e-3
#: Largest margin of a point light's map beyond its samples, in units of the image plane
#: (tan of the angle, 8.5°): a blocker right at the lamp would ask for an unbounded one;
#: a penumbra wider than that (r_L / z_b > 0.15) is cut at the edges of the samples' window.
MAX_POINT_REACH = 0.15
#: Floor of a map window's extent, relative to the scene's size (directional) or in units
#: of the image plane (point), so samples on one line along the light still get an area.
MIN_EXTENT = 1e-6
#: Triangles per block of a map's rasterization: ~20 float64 arrays of their corners
#: (≤ 30 MB) at a time, whatever the mesh's size.
CASTER_BLOCK = 1 << 16


def _rotate(basis: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Components (3, ...) of vectors ``v`` (3, ...) on the rows of ``basis`` (3, 3), in
    v's dtype, written out (a BLAS product of tall arrays may start threads that cost
    milliseconds on a busy machine)."""
    b = basis.tolist()                                 # Python floats keep v's dtype
    return np.stack([r[0] * v[0] + r[1] * v[1] + r[2] * v[2] for r in b])


def light_basis(forward: np.ndarray) -> np.ndarray:
    """(3, 3) rows right, up, forward: an orthonormal frame around ``forward``."""
    f = forward / np.linalg.norm(forward)
    helper = np.array([0.0, 1.0, 0.0]) if abs(f[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    r = np.cross(f, helper)
    r /= np.linalg.norm(r)
    return np.stack([r, np.cross(r, f), f])


@dataclass
class View:
    """One shadow map and how world points land on it.

    ``depth`` (h, w) float32 nearness (−inf where empty) of what blocks (the second-depth
    map, :func:`render_maps`), ``front`` of the nearest surface; ``lo`` the least depth
    and ``hi`` the largest front within ``reach`` texels of each texel
    (:func:`~.depthmap.dilate`), enough for filters of radius ≤ ``widest`` ; ``basis``
    (3, 3) rows: the map's right, up and forward (away from the light) ; ``origin`` (3,) the point
    light (zeros for a directional map) ; ``perspective`` ; ``scale`` texels per unit
    (world, or the image plane's) ; ``x0``, ``y1`` the window's left and top (same units) ;
    ``far`` an orthographic map's reference depth (d = far − z) ; ``kernel`` the filter
    radius in texels per unit of d (orthographic: scale tan(α/2); perspective: scale r_L).
    """

    depth: np.ndarray
    front: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    reach: int
    widest: float
    basis: np.ndarray
    origin: np.ndarray
    perspective: bool
    scale: float
    x0: float
    y1: float
    far: float
    kernel: float

    def project(self, q: np.ndarray, n: np.ndarray):
        """Samples q (3, m) in the map's frame (:meth:`frame`) on facets of unit normal n
        (3, m, world, either sign), float32 → map x, y (texels), nearness d, the facet's
        plane's gradient gx, gy (d per texel), its tan θ to the light (≤
        :data:`MAX_SLOPE`), D0 (d per texel of a surface facing the light) and the
        filter radius per unit of d (each (m,) or a scalar)."""
        X, Y, Z = q
        nx, ny, nz = _rotate(self.basis, n)
        s = self.scale
        floor = np.float32(1.0 / np.sqrt(1.0 + MAX_SLOPE ** 2))      # cos θ at MAX_SLOPE
        if self.perspective:
            d = 1.0 / np.maximum(Z, np.float32(1e-30))              # a sample at the lamp
            su, sv = X * d, Y * d
            # the plane n · (P − q) = 0 has 1/z = (nx su + ny sv + nz) / (n · q) on the
            # image plane; n · q = c |q|, c the cosine to the light (capped away from 0)
            r = np.sqrt(X * X + Y * Y + Z * Z)
            c = (nx * X + ny * Y + nz * Z) / r
            c = np.where(np.abs(c) < floor, np.copysign(floor, c), c)
            inv = 1.0 / (c * r * s)
            d0 = d / s
            kernel = self.kernel * np.sqrt(np.sqrt(1.0 + su * su + sv * sv))
        else:
            d = self.far - Z
            su, sv = X, Y
            # z = z_r − (nx Δx + ny Δy) / nz on the plane; nz: the cosine to the light
            c = np.where(np.abs(nz) < floor, np.copysign(floor, nz), nz)
            inv = 1.0 / (c * s)
            d0, kernel = 1.0 / s, self.kernel
        tan = np.sqrt(np.maximum(1.0 - c * c, 0.0)) / np.abs(c)
        return ((su - self.x0) * s, (self.y1 - sv) * s, d, nx * inv, -ny * inv, tan, d0,
                kernel)

    def frame(self, p: np.ndarray) -> np.ndarray:
        """World points p (3, m) in the map's frame (3, m), in p's dtype."""
        return _rotate(self.basis, p - self.origin.astype(p.dtype)[:, None])


def _make_view(depth, front, samples_d_min, kernel_max, cap, local: bool = True,
               **fields) -> View:
    """A :class:`View` with its bounds over the widest filter its samples can ask for:
    the nearest surface in the map in front of the farthest sample (radius ``widest``,
    at most ``cap`` texels: the map's margin beyond the samples). Its taps read texels
    up to widest + s + ½ from the sample (s ≤ max(1, widest / 8): the texel of the
    filter's bilinear taps, :mod:`.shadow`; ½: the sample anywhere in its own texel).
    Without ``local`` the bounds are the whole map's ((1, 1) arrays, which a clipped
    lookup reads at every texel): for lookups that filter every sample anyway."""
    nearest = float(front.max())                     # −inf where empty: never a blocker
    nearest = nearest if np.isfinite(nearest) else samples_d_min
    widest = max(min(kernel_max * (nearest - samples_d_min), cap), MIN_FILTER_TEXELS)
    reach = int(np.ceil(widest + max(1.0, widest / 8.0) + 0.5))
    if not local:
        return View(depth, front, np.full((1, 1), depth.min(), np.float32),
                    np.full((1, 1), front.max(), np.float32), reach, widest, **fields)
    return View(depth, front, dilate(depth, reach, np.minimum),
                dilate(front, reach, np.maximum), reach, widest, **fields)


#: Meshes of at most this many faces keep their caster blocks (:func:`_mesh_blocks`,
#: ~100 bytes a face) while they live: the occlusion of the environment
#: (:mod:`.occlusion`) renders a map of the same meshes for each of its directions.
KEEP_CASTERS_MAX_FACES = CASTER_BLOCK

_KEPT: dict[int, tuple[weakref.ref, list]] = {}


def _mesh_blocks(m: Mesh) -> list:
    """A mesh's triangles in blocks of (corners (3 corners, 3, t) world float64, their
    face normals (3, t) unnormalised, e1 × e2: outwards on a closed mesh); kept per mesh
    object up to :data:`KEEP_CASTERS_MAX_FACES` faces (the mesh is not changed in place
    after loading)."""
    kept = _KEPT.get(id(m))
    if kept is not None and kept[0]() is m:
        return kept[1]
    vt = np.ascontiguousarray(np.asarray(m.vertices, np.float64).T)         # (3, V)
    faces = np.asarray(m.faces, np.int64)
    blocks = []
    for start in range(0, len(faces), CASTER_BLOCK):
        f = faces[start:start + CASTER_BLOCK].T                        # (3 corners, t)
        c = np.stack([np.stack([vt[k][f[j]] for k in range(3)]) for j in range(3)])
        e1, e2 = c[1] - c[0], c[2] - c[0]
        blocks.append((c, np.stack([e1[1] * e2[2] - e1[2] * e2[1],
                                    e1[2] * e2[0] - e1[0] * e2[2],
                                    e1[0] * e2[1] - e1[1] * e2[0]])))
    if len(faces) <= KEEP_CASTERS_MAX_FACES:
        for key in [k for k, (ref, _) in _KEPT.items() if ref() is None]:
            del _KEPT[key]                                        # meshes since freed
        _KEPT[id(m)] = (weakref.ref(m), blocks)
    return blocks


def _casters(meshes: list[Mesh], closed: bool):
    """The triangles of the open (``closed`` False) or of the closed meshes, in blocks
    of (corners (3 corners, 3, t) world float64, face normals (3, t)): :func:`_mesh_blocks`."""
    for m in meshes:
        if bool(m.closed) == closed:
            yield from _mesh_blocks(m)


def render_maps(meshes: list[Mesh], towards, project, width: int, height: int):
    """The two depth maps of a light: ``depth`` (what blocks: every face of open meshes,
    the faces of closed ones turned away from the light, the second-depth map) and
    ``front`` (the nearest surface of all), each (height, width) float32.
    ``towards(corner0 (3, t))`` is the direction to the light ((3,) or (3, t)),
    ``project(corners (3, 3, t))`` gives the rasterizer's X, Y, D (module :mod:`.depthmap`)."""
    depth = empty_map(width, height)
    for c, _ in _casters(meshes, closed=False):
        rasterize_depth(*project(c), depth)
    front = depth.copy()
    for c, normal in _casters(meshes, closed=True):
        t = np.asarray(towards(c[0])).reshape(3, -1)
        away = (normal[0] * t[0] + normal[1] * t[1] + normal[2] * t[2]) < 0
        rasterize_depth(*project(c[:, :, away]), depth)
        rasterize_depth(*project(c[:, :, ~away]), front)
    # from inside a closed mesh (a lamp in a room) its far side can be the nearest
    return depth, np.maximum(front, depth, out=front)


def _scene_size(meshes: list[Mesh]) -> float:
    """The diagonal of the meshes' bounding box (1 without vertices)."""
    boxes = [(np.min(m.vertices, axis=0), np.max(m.vertices, axis=0))
             for m in meshes if len(m.vertices)]
    if not boxes:
        return 1.0
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    return float(np.linalg.norm(hi - lo))


def _fit(u: np.ndarray, v: np.ndarray, floor: float, margin: float):
    """A window over points (u, v) (map-plane units): scale (texels per unit), x0, y1,
    width, height, with :data:`TEXELS_PER_SAMPLE` texels per point, and all round
    ``margin`` units (the widest filter's reach beyond the points: blockers there shadow
    them) + 3 texels (a filter's bilinear taps)."""
    u_lo, u_hi, v_lo, v_hi = (float(u.min()), float(u.max()), float(v.min()), float(v.max()))
    du, dv = max(u_hi - u_lo, floor), max(v_hi - v_lo, floor)
    extent = max(du, dv) + 2 * margin
    scale = np.sqrt(TEXELS_PER_SAMPLE * u.size / (du * dv))
    scale = max(min(scale, (MAX_MAP_SIDE - 6) / extent), (MIN_MAP_SIDE - 6) / extent)
    pad = margin + 3.0 / scale
    w = int(min(MAX_MAP_SIDE, np.ceil((du + 2 * pad) * scale)))
    h = int(min(MAX_MAP_SIDE, np.ceil((dv + 2 * pad) * scale)))
    return float(scale), u_lo - pad, v_hi + pad, w, h


def _box_corners(meshes: list[Mesh]) -> np.ndarray:
    """(3, 8 k) the corners of the meshes' bounding boxes, world."""
    out = []
    for m in meshes:
        if len(m.vertices):
            lo, hi = np.min(m.vertices, axis=0), np.max(m.vertices, axis=0)
            out += [[(hi if i & 1 else lo)[0], (hi if i & 2 else lo)[1],
                     (hi if i & 4 else lo)[2]] for i in range(8)]
    return np.asarray(out, np.float64).reshape(-1, 3).T


def directional_view(light: Light, p: np.ndarray, meshes: list[Mesh], local: bool = True):
    """The orthographic map of a directional light over lit samples ``p`` (3, m): the
    :class:`View` and the samples in its frame (3, m); ``local``: as :func:`_make_view`."""
    L = np.asarray(light.direction, np.float64)
    L = L / np.linalg.norm(L)
    basis = light_basis(-L)
    q = _rotate(basis, p)
    far = float(q[2].max())                       # d = far − z ≥ 0 at every sample
    tan_half = np.tan(np.radians(light.angular_diameter_deg) / 2.0)
    # the widest penumbra: the nearest caster (its box) in front of the farthest sample
    boxes = _rotate(basis, _box_corners(meshes))
    reach = tan_half * max(far - float(boxes[2].min(initial=far)), 0.0)
    scale, x0, y1, w, h = _fit(q[0], q[1], MIN_EXTENT * _scene_size(meshes), reach)
    def project(c):                                                      # (3, 3, t)
        X, Y, Z = _rotate(basis, c.transpose(1, 0, 2))
        return (X - x0) * scale, (y1 - Y) * scale, far - Z

    depth, front = render_maps(meshes, lambda c0: L, project, w, h)
    return _make_view(depth, front, 0.0, scale * tan_half,
                      reach * scale + MIN_FILTER_TEXELS, local, basis=basis, origin=np.zeros(3),
                      perspective=False, scale=scale, x0=x0, y1=y1, far=far,
                      kernel=scale * tan_half), q


#: The six cube faces of a point light: the forward axis of each.
_FACES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]],
                  np.float64)


def _nearest_vertex(meshes: list[Mesh], basis, o, near: float, su, sv) -> float:
    """The least depth (beyond ``near``) of the meshes' vertices, seen from the light
    ``o`` in the face ``basis``, that land on the image plane within
    :data:`MAX_POINT_REACH` of the samples' window (su, sv): the nearest caster whose
    penumbra can reach them (a large triangle may come nearer between its corners: its
    penumbra is then cut at the map's margin). inf if none."""
    lo_u, hi_u = float(su.min()) - MAX_POINT_REACH, float(su.max()) + MAX_POINT_REACH
    lo_v, hi_v = float(sv.min()) - MAX_POINT_REACH, float(sv.max()) + MAX_POINT_REACH
    best = np.inf
    for m in meshes:
        if not len(m.vertices):
            continue
        X, Y, Z = _rotate(basis, np.asarray(m.vertices, np.float64).T - o[:, None])
        with np.errstate(divide="ignore", invalid="ignore"):
            u, v = X / Z, Y / Z
        inside = (Z > near) & (u >= lo_u) & (u <= hi_u) & (v >= lo_v) & (v <= hi_v)
        if inside.any():
            best = min(best, float(Z[inside].min()))
    return best


def point_views(light: Light, p: np.ndarray, meshes: list[Mesh]):
    """The perspective maps of a point light, one per cube face that holds lit samples
    ``p`` (3, m): a list of (the face's samples (indices), (its :class:`View`, those
    samples in its frame (3, m_face)))."""
    o = np.asarray(light.position, np.float64)
    q = p - o.astype(p.dtype)[:, None]
    axis = np.argmax(np.abs(q), axis=0)
    face = 2 * axis + (np.take_along_axis(q, axis[None, :], 0)[0] < 0)
    views = []
    for k in np.unique(face):
        basis = light_basis(_FACES[k])
        sel = np.flatnonzero(face == k)
        qs = _rotate(basis, np.take(q, sel, axis=1))
        su, sv = qs[0] / qs[2], qs[1] / qs[2]
        obliquity = np.sqrt(np.sqrt(1.0 + float(np.max(su * su + sv * sv))))
        near = NEAR_FRACTION * float(qs[2].min())
        # the widest penumbra: the nearest caster vertex that lands near the samples, in
        # front of the farthest sample, on the image plane (at most MAX_POINT_REACH)
        z_near = _nearest_vertex(meshes, basis, o, near, su, sv)
        reach = min(MAX_POINT_REACH, float(light.radius) * obliquity
                    * max(1.0 / min(z_near, float(qs[2].min())) - 1.0 / float(qs[2].max()),
                          0.0))
        scale, x0, y1, w, h = _fit(su, sv, MIN_EXTENT, reach)

        def project(c, basis=basis, near=near, x0=x0, y1=y1, scale=scale):
            P = _rotate(basis, (c - o[None, :, None]).transpose(1, 0, 2))
            P = clip_near(P.transpose(1, 0, 2), near)                    # (3 corners, 3, t)
            inv = 1.0 / P[:, 2]
            return (P[:, 0] * inv - x0) * scale, (y1 - P[:, 1] * inv) * scale, inv

        depth, front = render_maps(meshes, lambda c0: o[:, None] - c0, project, w, h)
        kernel = scale * float(light.radius)
        views.append((sel, (_make_view(depth, front, 1.0 / float(qs[2].max()),
                                       kernel * obliquity, reach * scale + MIN_FILTER_TEXELS,
                                       basis=basis, origin=o, perspective=True, scale=scale,
                                       x0=x0, y1=y1, far=0.0, kernel=kernel), qs)))
    return views


# ------------------------------------------------------------------ convex solids --

def lone_convex(meshes: list[Mesh]) -> bool:
    """True when the scene holds one mesh with faces and it is a convex solid
    (:func:`.solid.is_convex`): no lit point of it can be shadowed (every ray from its
    surface towards a light it faces leaves the solid for good), so no map is needed."""
    solid = [m for m in meshes if len(m.faces)]
    return len(solid) == 1 and is_convex(solid[0])
