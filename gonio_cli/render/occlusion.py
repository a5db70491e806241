"""Occlusion of environment light by the scene (stage ``occlusion``).

The prefiltered maps light every sample with the whole sky above its tangent plane; a
floor under a sphere, or Spot's belly over its hooves, sees part of that sky hidden by
the scene. This stage gives every G-buffer sample the share of its **diffuse
irradiance** that the scene lets through,

    V(p, N) = ∫ L(ω) v(p, ω) max(0, N·ω) dω / ∫ L(ω) max(0, N·ω) dω
            ≈ Σ_k Φ_k V_k(p) max(0, N·ω_k) / Σ_k Φ_k max(0, N·ω_k),

a ratio estimator over the K regions of equal flux of the (sun-removed) environment
(:mod:`.skycut`: region k has flux Φ_k, direction ω_k, solid angle Ω_k), where V_k is
the share of region k, seen as a disc of solid angle Ω_k, that reaches p: the soft
shadow of a directional light of that angular size (:func:`.shadow.light_visibility`,
the shadow maps of :mod:`.shadowmap`: closed meshes by their far side, so a concave
closed mesh (Spot) shadows itself and a convex one never; open meshes by both sides).
The shading multiplies the environment light of **diffuse lobes** by V (the model
method's Lambertian bodies, seed 001's K_D term, a substrate's kd): their light is
P_1(N) × albedo, exactly the irradiance V is the share of. Under a uniform sky V is the
sky view factor of the sample (tests/test_render_occlusion.py checks it against the
closed form under a sphere).

**Glossy lobes are not occluded** (the coat, eq. 5's lobe, seed 001's gloss and
directional-diffuse terms): what they miss is the reflection of the scene itself — a
coat near Spot's hooves still mirrors the sky where it would mirror the floor or the
body. Nor is any light bounced between objects (the floor under a sphere gets none of
the light the sphere's underside reflects onto it: docs/render.md measures it).

**Cost** (samples, not directions, are what numpy pays for): V is computed at a coarse
grid of *nodes*, one sample every :data:`STRIDE_PX` output pixels in each direction,
and carried to the other samples by bilinear weights over the four nodes around each,
kept only where a node lies on the same object and on the sample's tangent plane
(|N · (p_node − p)| ≤ :data:`PLANE_TOLERANCE` |p_node − p|: a joint bilateral
upsampling, Kopf et al. 2007, with the plane as its range term); samples that no node
agrees with (silhouettes, thin parts) get their own V. Per region only the samples some
mesh may hide are looked up (:func:`_may_be_hidden`: below the top of its bounding box
along the region, within its outline widened by the penumbra; a mesh that cannot occlude
itself, :func:`occludes_itself`, is no caster for its own samples); the maps are fitted
to them and made of coarse stand-ins of the meshes (:func:`proxy_mesh`). A scene that is
one convex solid needs no occlusion (:func:`.shadowmap.lone_convex`): skipped, and said
so in the run report.
"""

from __future__ import annotations

import time
import weakref

import numpy as np

from . import GBuffer, Light, Mesh
from .shadow import BLOCK as SHADOW_BLOCK
from .shadow import light_visibility
from .shadowmap import light_basis, lone_convex
from .skycut import SkyDirections
from .solid import is_convex

#: Directions (regions of the sky) when ``[environment] occlusion = true``: 24 regions of
#: a 1k sky are ~0.5 sr each (~45° across, :data:`.skycut.MAX_SPREAD_DEG` at most), so the
#: K soft shadows overlap into one smooth occlusion. Measured: under a uniform sky, V
#: within 0.041 of the closed form (16: 0.06, 64: 0.028; tests/test_render_occlusion.py);
#: on the sphere over a floor under quarry_01 (benchmarks/bench_render_env.py) the
#: umbra's luminance over Mitsuba's is 1.090 at 16, 1.070 at 24, 1.059 at 64 (none: 1.243).
DEFAULT_DIRECTIONS = 24
#: Most directions a scene may ask for (each is a shadow map: the cost grows with K).
MAX_DIRECTIONS = 256
#: Spacing of the nodes where V is computed, in output pixels (× ssaa in samples): the
#: occlusion of sky regions 20–60° wide varies over distances of the blocker's size,
#: many pixels. Measured on the bench's sphere on a floor: the umbra's luminance moves by
#: < 0.5 % from 4 to 6 pixels, and the lookups cost (6/4)² = 2.25 × less.
STRIDE_PX = 6
#: A node's V is carried to a sample when the node lies within this slope of the
#: sample's tangent plane (|N·Δp| ≤ 0.3 |Δp|, ~17°): the next node on a smooth surface
#: (a sphere seen with 6-pixel steps at ≥ 36 px a radian of its surface) is within ~10°;
#: a node across a depth step (a leg in front of the body) lies far off it.
PLANE_TOLERANCE = 0.3
#: Cells across a mesh's largest extent of its stand-in for the maps (:func:`proxy_mesh`):
#: the maps over the nodes have ~2 texels a node, texels ~1/70 of the bench's scene (a
#: sphere on a 12-unit floor): a stand-in within half a cell (1/32 of the object) is about
#: that; the built-in sphere's 20 448 triangles become ~2 150 and Spot's 5 856 ~1 150 (a
#: map's cost is its triangles). Measured: 16, 24 or 48 cells give the bench's umbra to
#: 0.1 %.
PROXY_CELLS = 16
#: A mesh is flat (cannot occlude itself, :func:`occludes_itself`) when its vertices
#: spread across their best plane by less than this share of its size (rms): float64
#: round-off of a placed plane is ~1e-16 of it.
FLAT_TOLERANCE = 1e-9
#: Margin of a caster's outline seen along a region (:func:`_may_be_hidden`), as a share
#: of the scene's size: the filter's smallest radius (a texel, ~1/70 of it) and the
#: stand-in's deviation from its mesh (≤ half a cell, 1/32 of the mesh) fall within it.
BOX_MARGIN = 0.03
#: A sample whose nodes' kept bilinear weights sum to less than this gets its own V: a
#: share below it carries one node's value over ≥ 1/WEIGHT_FLOOR of its distance.
WEIGHT_FLOOR = 1e-3

_PROXIES: dict[int, tuple[weakref.ref, Mesh]] = {}


def proxy_mesh(mesh: Mesh, cells: int = PROXY_CELLS) -> Mesh:
    """A coarse stand-in of ``mesh`` for the occlusion's maps: vertex clustering
    (Rossignac & Borrel 1993) on a grid of cubes 1/``cells`` of the mesh's largest
    extent, each cluster at its vertices' mean, faces with two corners in one cluster
    dropped; the faces keep their orientation (and the mesh its ``closed``: the maps
    take a closed mesh by its far side). Vertex normals are not kept (zeros: the maps do
    not read them). Kept per mesh object while it lives; a mesh with at most
    ``cells`` × 64 faces is its own proxy."""
    if len(mesh.faces) <= 64 * cells:
        return mesh
    kept = _PROXIES.get(id(mesh))
    if kept is not None and kept[0]() is mesh:
        return kept[1]
    v = np.asarray(mesh.vertices, np.float64)
    lo = v.min(axis=0)
    size = float((v.max(axis=0) - lo).max()) or 1.0
    q = np.minimum(np.floor((v - lo) * (cells / size)), cells).astype(np.int64)
    code = (q[:, 0] * (cells + 1) + q[:, 1]) * (cells + 1) + q[:, 2]
    _, cluster = np.unique(code, return_inverse=True)
    cluster = cluster.ravel()
    count = np.bincount(cluster)
    centre = np.stack([np.bincount(cluster, v[:, k]) / count for k in range(3)], axis=1)
    f = cluster[np.asarray(mesh.faces, np.int64)]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    proxy = Mesh(centre, f, np.zeros_like(centre), name=f"{mesh.name} (proxy)",
                 closed=mesh.closed)
    for key in [k for k, (ref, _) in _PROXIES.items() if ref() is None]:
        del _PROXIES[key]
    _PROXIES[id(mesh)] = (weakref.ref(mesh), proxy)
    return proxy


def directional_lights(sky: SkyDirections) -> list[Light]:
    """Each region of ``sky`` as a shadowing directional :class:`Light` of its angular
    diameter (spectrum and irradiance unused: only its shadow is asked for)."""
    return [Light("directional", np.ones(1), direction=np.asarray(d, float), irradiance=1.0,
                  name=f"sky region {k}", angular_diameter_deg=float(a))
            for k, (d, a) in enumerate(zip(sky.direction, sky.angular_diameter_deg))]


def occludes_itself(mesh: Mesh) -> bool:
    """Whether a mesh can hide part of the sky from a point on itself: not a convex
    solid (:func:`.solid.is_convex`) and not flat (its vertices within
    :data:`FLAT_TOLERANCE` of its size of one plane: a floor)."""
    v = np.asarray(mesh.vertices, np.float64)
    if len(mesh.faces) == 0 or is_convex(mesh):
        return False
    x = v - v.mean(axis=0)
    size = float(np.ptp(v, axis=0).max()) or 1.0
    thinnest = np.linalg.eigvalsh(x.T @ x)[0] / len(v)            # variance across
    return bool(thinnest > (FLAT_TOLERANCE * size) ** 2)


def _boxes(meshes: list[Mesh]) -> list[np.ndarray]:
    """The 8 corners (3, 8) of each mesh's bounding box (an empty mesh: none)."""
    out = []
    for m in meshes:
        v = np.asarray(m.vertices, np.float64)
        if len(v) == 0:
            out.append(np.zeros((3, 0)))
            continue
        lo, hi = v.min(axis=0), v.max(axis=0)
        out.append(np.array([[(hi if i & 1 else lo)[0], (hi if i & 2 else lo)[1],
                              (hi if i & 4 else lo)[2]] for i in range(8)]).T)
    return out


def _may_be_hidden(light: Light, p: np.ndarray, owner: np.ndarray, boxes, self_hiding,
                   margin: float) -> np.ndarray:
    """(m,) bool: the samples p (3, m) of mesh ``owner`` (m,) that some caster may hide
    from the disc of ``light``: below the top of its bounding box along the light and,
    seen along the light, within its box's outline widened by the penumbra's reach
    (the top's height above the sample × tan(α/2)) + ``margin``. A mesh that cannot
    occlude itself (``self_hiding`` False) is no caster for its own samples."""
    L = np.asarray(light.direction, np.float64)
    basis = light_basis(-L)                                   # rows: right, up, forward
    x, y = (np.float32(r[0]) * p[0] + np.float32(r[1]) * p[1] + np.float32(r[2]) * p[2]
            for r in basis[:2].tolist())
    h = L.astype(np.float32) @ p
    tan_half = np.float32(np.tan(np.radians(light.angular_diameter_deg) / 2.0))
    out = np.zeros(p.shape[1], bool)
    for b, corners in enumerate(boxes):
        if corners.shape[1] == 0:
            continue
        bx, by, top = basis[0] @ corners, basis[1] @ corners, float((L @ corners).max())
        reach = np.maximum(np.float32(top) - h, 0) * tan_half + np.float32(margin)
        near = ((h < top) & (x >= bx.min() - reach) & (x <= bx.max() + reach)
                & (y >= by.min() - reach) & (y <= by.max() + reach))
        if not self_hiding[b]:
            near &= owner != b
        out |= near
    return out


def visible_fraction(sky: SkyDirections, meshes: list[Mesh], p: np.ndarray, n: np.ndarray,
                     facet: np.ndarray, owner: np.ndarray | None = None,
                     casters: list[Mesh] | None = None) -> tuple[np.ndarray, list]:
    """V (m,) float32 in [0, 1] (module docstring) at samples p (3, m) float32 on mesh
    ``owner`` (m,) (indices into ``meshes``; None: any) with unit shading normals n
    (3, m) and facet normals ``facet`` (3, m); and the map sizes (one list per
    direction). The maps are made of ``casters`` (stand-ins of the meshes, default the
    meshes), only over the samples some mesh may hide (:func:`_may_be_hidden`); the
    others see the region whole. A sample facing no region (Σ weights = 0) gets 1."""
    casters = meshes if casters is None else casters
    owner = np.full(p.shape[1], -1) if owner is None else owner
    boxes = _boxes(meshes)
    self_hiding = [occludes_itself(m) for m in meshes]
    margin = BOX_MARGIN * max((float(np.ptp(c, axis=1).max()) for c in boxes if c.size),
                              default=1.0)
    num = np.zeros(p.shape[1], np.float32)
    den = np.zeros(p.shape[1], np.float32)
    maps = []
    for light, flux in zip(directional_lights(sky), sky.flux):
        w = light.direction.astype(np.float32) @ n
        w *= np.float32(flux)
        w = np.maximum(w, 0, out=w)
        den += w
        rows = np.flatnonzero((w > 0) & _may_be_hidden(light, p, owner, boxes, self_hiding,
                                                       margin))
        vis = np.ones(p.shape[1], np.float32)
        maps.append([])
        if rows.size:
            vis[rows], got = light_visibility(light, casters, np.take(p, rows, axis=1),
                                              np.take(facet, rows, axis=1),
                                              window_test=False)
            maps[-1] = got["maps"]
        num += w * vis
    return np.divide(num, den, out=np.ones_like(num), where=den > 0), maps


def _nodes(gbuffer: GBuffer, stride: int):
    """The node grid of a G-buffer: the covered rows, their sample row and column
    (int32), and the G-buffer row of every node (Gh, Gw) int64 (−1 where uncovered)."""
    h, w = gbuffer.object_id.shape
    obj = gbuffer.row_object_id()
    pix = np.arange(h * w) if gbuffer.pixels is None else np.asarray(gbuffer.pixels)
    covered = np.flatnonzero(obj >= 0)
    if covered.size < obj.size:
        pix = pix[covered]
    row_of = np.full(h * w, -1, np.int64)
    row_of[pix] = covered
    gr, gc = np.arange(0, h, stride), np.arange(0, w, stride)
    node = row_of[(gr[:, None] * w + gc[None, :]).ravel()].reshape(gr.size, gc.size)
    pix = pix.astype(np.int32)
    return covered, pix // np.int32(w), pix % np.int32(w), node


def _on_plane(normal, d0, d1, d2, tol) -> np.ndarray:
    """|N·Δp| ≤ √tol |Δp| (squared; Δp = 0 passes): Δp = (d0, d1, d2) lies within the
    tolerance of the plane of unit normal ``normal`` (3, m)."""
    along = normal[0] * d0 + normal[1] * d1 + normal[2] * d2
    return along * along <= tol * (d0 * d0 + d1 * d1 + d2 * d2)


def _smooth_cells(node_p, node_n, node_obj, corners, tol) -> np.ndarray:
    """(cells,) bool: the four nodes ``corners`` (4, cells) exist, lie on one object, and
    corners 01, 10, 11 lie on the tangent plane of corner 00 and it on theirs."""
    k00 = corners[0]
    ok = k00 >= 0
    for k in corners[1:]:
        ok &= (k >= 0) & (node_obj[k] == node_obj[k00])
        d = [node_p[i][k] - node_p[i][k00] for i in range(3)]
        ok &= _on_plane(node_n[:, k00], *d, tol) & _on_plane(node_n[:, k], *d, tol)
    return ok


def _upsample_weights(p, n, obj, rows, r, c, node, stride):
    """Per covered sample (``rows`` into the G-buffer's (3, rows) ``p``, ``n`` and its
    ``obj``; sample coordinates r, c), its four nodes (4, m) int32 (indices into the
    nodes, ``node[node >= 0]``; −1 for none) and their kept bilinear weights (4, m)
    float32 (module docstring), in blocks of :data:`~.shadow.BLOCK` samples. A sample
    in a smooth cell (:func:`_smooth_cells`) on its object and its corner 00's plane
    takes the four plain; the others are tested node by node."""
    gh, gw = node.shape
    live = node.ravel() >= 0
    compact = np.full(node.size + 1, -1, np.int32)           # grid cell → node, last: none
    compact[np.flatnonzero(live)] = np.arange(np.count_nonzero(live), dtype=np.int32)
    at = node.ravel()[live]
    node_p = np.append(np.take(p, at, axis=1), np.zeros((3, 1), p.dtype), axis=1)
    node_n = np.append(np.take(n, at, axis=1), np.zeros((3, 1), n.dtype), axis=1)
    node_obj = np.append(obj[at], -1)                         # (nodes + 1,): −1 for none
    ga, gb = np.divmod(np.arange(gh * gw), gw)
    ga1, gb1 = np.minimum(ga + 1, gh - 1), np.minimum(gb + 1, gw - 1)
    corners = np.stack([compact[ga * gw + gb], compact[ga * gw + gb1],
                        compact[ga1 * gw + gb], compact[ga1 * gw + gb1]])   # (4, cells)
    f32, m = np.float32, rows.size
    tol = f32(PLANE_TOLERANCE * PLANE_TOLERANCE)
    smooth = _smooth_cells(node_p, node_n, node_obj, corners, tol)
    ids = np.empty((4, m), np.int32)
    bil = np.empty((4, m), f32)
    for start in range(0, m, SHADOW_BLOCK):
        b = slice(start, start + SHADOW_BLOCK)
        rb, cb = r[b], c[b]
        a0, b0 = rb // stride, cb // stride
        ta = (rb - a0 * stride).astype(f32) / f32(stride)
        tb = (cb - b0 * stride).astype(f32) / f32(stride)
        cell = a0 * gw + b0
        ids[:, b] = corners[:, cell]
        bil[:, b] = ((1 - ta) * (1 - tb), (1 - ta) * tb, ta * (1 - tb), ta * tb)
        ps, ns = np.take(p, rows[b], axis=1), np.take(n, rows[b], axis=1)
        os_ = obj[rows[b]]
        k = ids[0, b]
        fast = smooth[cell] & (node_obj[k] == os_)
        fast &= _on_plane(ns, *(np.take(node_p[i], k) - ps[i] for i in range(3)), tol)
        slow = np.flatnonzero(~fast)
        if slow.size == 0:
            continue
        ps, ns, os_ = ps[:, slow], ns[:, slow], os_[slow]
        for j in range(4):
            k = ids[j, b][slow]                               # −1: index of "none"
            ok = _on_plane(ns, *(np.take(node_p[i], k) - ps[i] for i in range(3)), tol)
            ok &= node_obj[k] == os_
            ids[j, start + slow] = np.where(ok, k, -1)
            bil[j, start + slow] = np.where(ok, bil[j, start + slow], f32(0))
    return ids, bil


def occlusion_visibility(sky: SkyDirections, meshes: list[Mesh], gbuffer: GBuffer,
                         stats=None) -> np.ndarray | None:
    """V (rows,) float32 in [0, 1] for every row of the G-buffer (module docstring; 1 on
    uncovered rows of a dense G-buffer), or None when the scene is one convex solid
    (nothing can occlude its sky). Needs the G-buffer's positions (and takes its facet
    normals where it has them). Fills ``stats.time_s["occlusion"]`` and
    ``stats.counts["occlusion"]``: directions, nodes, samples that got their own V,
    samples computed, map sizes, samples occluded (V < 1) and their mean V; or
    ``skipped`` and why."""
    start = time.perf_counter()
    k = len(sky.flux)
    if lone_convex(meshes):
        if stats is not None:
            stats.time_s["occlusion"] = time.perf_counter() - start
            stats.counts["occlusion"] = {"directions": k, "skipped": "one convex solid"}
        return None
    if gbuffer.position is None:
        raise ValueError("occlusion needs the G-buffer's positions (rasterize with "
                         "position=True)")

    def rows_of(a):                       # (3, rows): the compact G-buffer's own layout
        return (a if a.ndim == 2 else a.reshape(-1, 3)).T.astype(np.float32, copy=False)

    p, n = rows_of(gbuffer.position), rows_of(gbuffer.normal)
    facet = n if gbuffer.facet_normal is None else rows_of(gbuffer.facet_normal)
    obj = gbuffer.row_object_id()
    stride = STRIDE_PX * gbuffer.ssaa
    rows, r, c, node = _nodes(gbuffer, stride)
    ids, bil = _upsample_weights(p, n, obj, rows, r, c, node, stride)
    total = bil.sum(axis=0)
    alone = total < WEIGHT_FLOOR
    own = rows[alone]
    nodes = node[node >= 0]
    computed = np.concatenate([nodes, own])
    vis_at, maps = visible_fraction(sky, meshes, np.take(p, computed, axis=1),
                                    np.take(n, computed, axis=1),
                                    np.take(facet, computed, axis=1), obj[computed],
                                    [proxy_mesh(m) for m in meshes])
    at_node = np.append(vis_at[:nodes.size], np.float32(1))       # last: "none" (−1)
    acc = bil[0] * at_node[ids[0]]
    for j in range(1, 4):
        acc += bil[j] * at_node[ids[j]]
    acc /= np.where(alone, np.float32(1), total)
    acc[alone] = vis_at[nodes.size:]
    vis = np.ones(obj.size, np.float32)
    vis[rows] = acc
    if stats is not None:
        occluded = vis[rows] < 1
        stats.time_s["occlusion"] = time.perf_counter() - start
        stats.counts["occlusion"] = {
            "directions": k, "nodes": int(nodes.size), "own_samples": int(own.size),
            "computed_samples": int(computed.size), "maps": maps,
            "occluded_samples": int(np.count_nonzero(occluded)),
            "mean_visibility": float(vis[rows].mean()) if rows.size else 1.0}
    return vis
