"""Shadows of point and directional lights (stage ``shadows``): shadow maps, filtered.

For each light with ``shadow = true`` the stage gives every G-buffer sample it lights
(N·ωi > 0) a visibility V in [0, 1], which the shading multiplies into the light's
E cos θi (:mod:`.shade`: every material path, printed objects and sparkles). The maps
themselves — one orthographic map per directional light, one perspective map per cube
face of a point light, closed meshes by their far side only — are :mod:`.shadowmap`'s
(Williams 1978; second-depth maps, Wang & Molnar 1994); a scene that is one convex solid
needs none (:func:`.shadowmap.lone_convex`).

**Comparison and bias.** A sample at map position (x, y) with nearness d_r is blocked at
texel t (centre c_t) if the map holds d(t) > d_r + g · (c_t − (x, y)) + b: g is the
gradient of the sample's *facet* plane on the map (the G-buffer's facet normal, not the
interpolated shading normal: a flat receiver is exactly level with its own texels,
whatever its slope), and b = D0 (:data:`BIAS_TEXELS` + :data:`BIAS_SLOPE_TEXELS` tan θi),
with D0 the change of d over one texel of a surface facing the light and tan θi capped
at :data:`~.shadowmap.MAX_SLOPE`. What b covers: a concave bend of an open mesh, whose
next facet rises above the sample's plane by ≈ ψ δ (1 + tan² θi) over δ texels for a bend
of ψ (the constants' comments give the numbers). What it costs: light leaks where a
blocker is within b of the receiver along the light (≈ a texel at 45°: contact points).

**Soft edges** (percentage-closer filtering, Reeves, Salesin & Cook 1987, with the blocker
search of Fernando 2005, "Percentage-closer soft shadows"). The light has a size: a
directional light an angular diameter α (``angular_diameter_deg``, default 0.53°, the
sun's), a point light a radius r_L (``radius``). A blocker at distance Δ in front of a
receiver hides the part of the light's disc that, seen from the receiver, lies behind it;
on the map that disc is, at the blocker's depth, a disc of radius Δ tan(α/2) (directional,
world units) or r_L (1/z_b − 1/z_r) (point, on the face's image plane, × (1 + s²)^¼ for
its obliquity s off the face's axis). V is the fraction of that disc the map does not
block, so the penumbra is Δ tan α wide (directional) or 2 r_L Δ / z_b (point), Δ from
the mean depth of the blockers a first search over the widest disc finds
(:data:`SEARCH_TAPS`; a blocker's depth midway between its near and far side, the plane
of a sphere's outline). The filter radius is at least
:data:`~.shadowmap.MIN_FILTER_TEXELS` (a hard shadow is still smoothed over a texel: no
stair steps); one wider than :data:`FILTER_LEVEL_TEXELS` reads every 2^L-th texel. What
it misses: one blocker depth per sample (blockers at several depths get their mean's
penumbra); a uniform disc of light (no limb darkening); :data:`FILTER_TAPS` bilinear taps
(a penumbra wider than ~8 texels shows steps of 1/16); a uniform texel size over the map
(a receiver seen up close shows the map's texels as a blur one texel wide); a point
light's penumbra cut at the map's margin (:data:`~.shadowmap.MAX_POINT_REACH`).

**Cost.** Most samples need one texel: :func:`~.depthmap.dilate` gives, per texel, bounds
over the widest filter window (the least depth of what blocks, the largest of the nearest
surface), and a sample whose own texel agrees with them is decided there — lit if nothing
in its window rises above its facet plane's highest point in it (+ b), in the umbra if
everything does; the filter runs on the rest (the edges). The price of that test: a
blocker lower than the window's rise (≈ its radius × tan θi, a few texels) loses the
filter's one-texel smoothing on its lit side (its own penumbra is narrower than that).
Measured: docs/render.md, "Shadows"; benchmarks/bench_render_shadow.py.
"""

from __future__ import annotations

import time

import numpy as np

from . import GBuffer, Light, Mesh
from .shadowmap import MIN_FILTER_TEXELS, View, directional_view, lone_convex, point_views

#: A filter wider than this many texels reads every 2^L-th texel (the map 2^L times
#: coarser), so 16 taps still cover it and its cost does not grow: the coarse texels are
#: ≤ 1/8 of its radius, well below the penumbra they sample.
FILTER_LEVEL_TEXELS = 16.0
#: Constant bias, in texels of depth (D0). The planes compared are the samples' facets
#: (the G-buffer's facet normals), exact for a flat receiver; what the bias covers is a
#: concave bend of an open mesh: the neighbouring facet that a texel centre within δ ≤ 2
#: texels (the filter's reach) lies on rises above the sample's plane by ≈ δ ψ (1 + tan²
#: θi) texels of depth for a bend of ψ; 0.25 covers ψ ≤ 7° at normal incidence. Float32
#: round-off (map, positions) is ~1e-4 texel at map sides ≤ 2048.
BIAS_TEXELS = 0.25
#: Slope-scaled bias, texels of depth per unit of tan θi: with the constant, bends ψ ≤
#: (0.25 + tan θi) / (2 (1 + tan² θi)) never shadow themselves: ≥ 3° up to tan θi = 10
#: (θi = 84°, N·L = 0.1, a tenth of the light), 1.5° at tan θi = 19 (the sample sheet's
#: facets are 1.5° apart, the built-in sphere's 2.5°, closed: never compared).
BIAS_SLOPE_TEXELS = 1.0
#: Taps of the blocker search and of the filter (point-symmetric: a straight edge through
#: a sample is seen half lit).
SEARCH_TAPS = 16
FILTER_TAPS = 16
#: Samples per block of the lookup (its ~25 float32 arrays of 65 536 stay in cache), and
#: of the filter (its arrays have a column per tap: 64 × 1024 values).
BLOCK = 65536
FILTER_BLOCK = 1024

_GOLDEN = np.pi * (3.0 - np.sqrt(5.0))


def _disc(n: int, symmetric: bool) -> np.ndarray:
    """(n, 2) points of the unit disc (Vogel's spiral: equal areas), point-symmetric
    (each point and its negative) if ``symmetric``."""
    m = n // 2 if symmetric else n
    k = np.arange(m)
    r = np.sqrt((k + 0.5) / m)
    p = np.stack([r * np.cos(k * _GOLDEN), r * np.sin(k * _GOLDEN)], axis=1)
    return np.concatenate([p, -p]) if symmetric else p


_SEARCH = _disc(SEARCH_TAPS, False)
_FILTER = _disc(FILTER_TAPS, True)
_SEARCH_32, _FILTER_32 = _SEARCH.astype(np.float32), _FILTER.astype(np.float32)


# --------------------------------------------------------------------------- lookup --

def _level(radius):
    """The map level a filter of ``radius`` texels reads: the finest whose texels it
    spans at most :data:`FILTER_LEVEL_TEXELS` of."""
    return np.maximum(np.ceil(np.log2(np.maximum(radius, 1e-9) / FILTER_LEVEL_TEXELS)),
                      0).astype(np.int64)


def _grid(u, step, half, size):
    """Texels (clamped into the map) of level-grid cells u (float32 whole numbers, any
    shape), as float32 whole numbers (exact below 2^24: maps have ≤ 2048² texels)."""
    t = u * step
    t += half
    return np.minimum(np.maximum(t, 0, out=t), np.float32(size - 1), out=t)


def _read(flat, w, tx, ty):
    """The map's values at texels (tx, ty) (float32 whole numbers)."""
    i = ty * np.float32(w)
    i += tx
    return flat[i.astype(np.intp)]


def _steps(level):
    """A level's texel size s = 2^L and its centre's offset s // 2, float32 (m, 1)."""
    step = np.ldexp(np.float32(1), level).astype(np.float32)[:, None]
    return step, np.floor(step * np.float32(0.5))


def _search(view: View, x, y, gx, gy, base, d, kernel, radius) -> np.ndarray:
    """The filter radius (m,) of samples whose blockers may be far: :func:`_filter`'s
    step 1 and 2 (x, y, gx, gy, base: (m, 1) float32 columns)."""
    h, w = view.depth.shape
    step, half = _steps(_level(radius))
    tx = _grid(np.floor((x + radius.astype(np.float32)[:, None] * _SEARCH_32[:, 0]) / step),
               step, half, w)
    ty = _grid(np.floor((y + radius.astype(np.float32)[:, None] * _SEARCH_32[:, 1]) / step),
               step, half, h)
    stored = _read(view.depth.reshape(-1), w, tx, ty)
    b = stored > base + gx * tx + gy * ty
    count = b.sum(axis=1)
    stored += _read(view.front.reshape(-1), w, tx, ty)
    d_b = np.where(count > 0, np.where(b, stored, 0).sum(axis=1) / np.maximum(2 * count, 1),
                   d)
    return np.clip(kernel * (d_b - d), MIN_FILTER_TEXELS, radius)


def _filter(view: View, x, y, d, gx, gy, bias, kernel, radius) -> np.ndarray:
    """Percentage-closer soft shadows at samples near an edge, (m,) float32 arrays.

    1. Blocker search: :data:`SEARCH_TAPS` point taps over ``radius`` texels; a texel
       blocks if it lies above the sample's tangent plane at its centre (+ bias); a
       blocker's depth is midway between its far side (what blocks) and its near side
       (the plane of a sphere's outline; one surface for open meshes); d_b their mean.
    2. The light's disc projected to that depth: radius r = kernel (d_b − d), at least
       :data:`MIN_FILTER_TEXELS`, at most ``radius``.
    3. V = the mean over :data:`FILTER_TAPS` points of that disc of the bilinear blend of
       the four texels' "not blocked". The taps' disc has the radius √(r² − ⅔ s²), so
       that, widened by the blend's tent (variance s² / 6 per axis), it has the variance
       r² / 4 of the disc of radius r.

    Filters wider than :data:`FILTER_LEVEL_TEXELS` read the level-L grid (every 2^L-th
    texel, s = 2^L), so a tap's cost does not grow with the penumbra. Taps are a second
    array axis.
    """
    f32 = np.float32
    h, w = view.depth.shape
    depth = view.depth.reshape(-1)
    x, y, gx, gy = (v.astype(f32)[:, None] for v in (x, y, gx, gy))
    # the tangent plane + bias at texel (tx, ty): base + gx tx + gy ty
    base = (d + bias).astype(f32)[:, None] + gx * (f32(0.5) - x) + gy * (f32(0.5) - y)

    r = np.full(len(d), MIN_FILTER_TEXELS)
    wide = np.flatnonzero(radius > MIN_FILTER_TEXELS)       # else no search can widen it
    if wide.size:
        r[wide] = _search(view, x[wide], y[wide], gx[wide], gy[wide], base[wide],
                          d[wide], kernel[wide], radius[wide])

    step, half = _steps(_level(r))
    r = np.sqrt(np.maximum(r * r - (2.0 / 3.0) * np.square(step[:, 0]), 0.0)).astype(f32)
    u = (x + r[:, None] * _FILTER_32[:, 0]) / step - f32(0.5)               # (m, taps)
    v = (y + r[:, None] * _FILTER_32[:, 1]) / step - f32(0.5)
    cu, cv = np.floor(u), np.floor(v)
    u -= cu                                                  # the blend's fractions
    v -= cv
    tx0, tx1 = _grid(cu, step, half, w), _grid(cu + 1, step, half, w)
    ty0, ty1 = _grid(cv, step, half, h), _grid(cv + 1, step, half, h)
    ax0, ax1, by0, by1 = gx * tx0, gx * tx1, base + gy * ty0, base + gy * ty1
    lit = [(_read(depth, w, tx, ty) <= by + ax).astype(f32)
           for ty, by in ((ty0, by0), (ty1, by1)) for tx, ax in ((tx0, ax0), (tx1, ax1))]
    top = lit[0] + u * (lit[1] - lit[0])
    bottom = lit[2] + u * (lit[3] - lit[2])
    return (top + v * (bottom - top)).mean(axis=1)


def _visibility(view: View, q: np.ndarray, n: np.ndarray, window_test: bool = True):
    """Visibility (m,) float32 of lit samples q (3, m) in the map's frame on facets of
    normal n (3, m), float32, on one map; and how many needed the filter (all of them
    without ``window_test``: :func:`light_visibility`)."""
    f32 = np.float32
    x, y, d, gx, gy, t, d0, kernel = view.project(q, n)
    bias = t * f32(BIAS_SLOPE_TEXELS)
    bias += f32(BIAS_TEXELS)
    bias *= d0
    bias += d                                          # d + b: the level of a flat texel
    w = view.depth.shape[1]
    fx, fy = np.floor(x), np.floor(y)
    idx = fy.astype(np.int64)
    idx *= w
    idx += fx.astype(np.int64)
    fx += 0.5
    fx -= x
    fx *= gx
    fy += 0.5
    fy -= y
    fy *= gy
    fx += fy
    fx += bias                                         # the plane at the texel's centre
    centre = view.depth.reshape(-1).take(idx, mode="clip") > fx
    # the tangent plane's highest point over the bounds' window, + bias
    top = np.abs(gx) + np.abs(gy)
    top *= f32(view.reach + 0.5)
    top += bias
    lo = view.lo.reshape(-1).take(idx, mode="clip")
    hi = view.hi.reshape(-1).take(idx, mode="clip")
    edge = (np.flatnonzero(np.where(centre, lo <= top, hi > top)) if window_test
            else np.arange(d.size))
    vis = np.where(centre, f32(0), f32(1))
    if edge.size:
        kernel = np.broadcast_to(kernel, d.shape)[edge].astype(np.float64)
        radius = np.clip(kernel * (hi[edge] - d[edge]), MIN_FILTER_TEXELS, view.widest)
        bias = bias - d
        for start in range(0, edge.size, FILTER_BLOCK):
            part = slice(start, start + FILTER_BLOCK)
            e = edge[part]
            vis[e] = _filter(view, x[e], y[e], d[e].astype(np.float64), gx[e], gy[e],
                             bias[e], kernel[part], radius[part])
    return vis, edge.size


def light_visibility(light: Light, meshes: list[Mesh], p: np.ndarray, n: np.ndarray,
                     window_test: bool = True):
    """Visibility (m,) float32 of lit samples p (3, m) float32 on facets of normal n
    (3, m) from one light, and counts: the maps' sizes and the samples that needed the
    filter. ``window_test`` False runs the filter at every sample: the one-texel test
    (module docstring) takes the receiver's plane at its highest over the widest window,
    which for a wide light (a region of the sky, :mod:`.occlusion`) at oblique incidence
    rises above blockers whose penumbra does reach the sample; a directional map then
    skips its local bounds (the filter's blocker search starts from the whole map's)."""
    if light.kind == "directional":
        views = [(slice(None), directional_view(light, p, meshes, local=window_test))]
    else:
        views = point_views(light, p, meshes)
    vis = np.empty(p.shape[1], np.float32)
    filtered = 0
    for sel, (view, q) in views:
        # (np.take along an axis: ~6× faster than x[:, indices] in numpy 2)
        ns = n if isinstance(sel, slice) else np.take(n, sel, axis=1)
        vs = np.empty(q.shape[1], np.float32)
        for start in range(0, q.shape[1], BLOCK):
            b = slice(start, start + BLOCK)
            vs[b], n_edge = _visibility(view, q[:, b], ns[:, b], window_test)
            filtered += n_edge
        vis[sel] = vs
    return vis, {"maps": [list(v.depth.shape[::-1]) for _, (v, _) in views],
                 "filtered": filtered}


def shadow_visibility(lights: list[Light], meshes: list[Mesh], gbuffer: GBuffer,
                      stats=None) -> list[np.ndarray | None]:
    """Per light, the visibility (rows,) float32 in [0, 1] of each G-buffer row (1 where
    the light does not reach: N·ωi ≤ 0), or None for a light with ``shadow = false``,
    and for every light when the scene is one convex solid (:func:`.shadowmap.lone_convex`:
    no map). Needs the G-buffer's positions, and takes its facet normals for the
    samples' planes (else the shading normals). Fills ``stats.time_s["shadows"]`` and
    ``stats.counts["shadows"]``: per light its name, map sizes (width, height), lit
    samples, samples filtered, samples shadowed (V < 1) and in the umbra (V = 0); or
    ``skipped`` and why."""
    start = time.perf_counter()
    out: list[np.ndarray | None] = [None] * len(lights)
    casting = [i for i, light in enumerate(lights) if light.shadow]
    if not casting:
        return out
    if lone_convex(meshes):                 # one convex solid: nothing can shadow it
        if stats is not None:
            stats.time_s["shadows"] = time.perf_counter() - start
            stats.counts["shadows"] = [{"name": lights[i].name, "skipped": "one convex solid"}
                                       for i in casting]
        return out
    if gbuffer.position is None:
        raise ValueError("shadows need the G-buffer's positions (rasterize with position=True)")
    f32 = np.float32

    def rows_of(a):                       # (3, rows): the compact G-buffer's own layout
        return (a if a.ndim == 2 else a.reshape(-1, 3)).T.astype(f32, copy=False)

    p, n = rows_of(gbuffer.position), rows_of(gbuffer.normal)
    facet = n if gbuffer.facet_normal is None else rows_of(gbuffer.facet_normal)
    per_light = []
    for i in casting:
        light = lights[i]
        if light.kind == "directional":
            L = np.asarray(light.direction, np.float64)
            L = (L / np.linalg.norm(L)).tolist()
            cos_i = n[0] * L[0] + n[1] * L[1] + n[2] * L[2]
        else:
            to = np.asarray(light.position, np.float64).astype(f32)[:, None] - p
            cos_i = (n[0] * to[0] + n[1] * to[1] + n[2] * to[2]) / np.maximum(
                np.sqrt(to[0] * to[0] + to[1] * to[1] + to[2] * to[2]), f32(1e-30))
        rows = np.flatnonzero(cos_i > 0)   # (the shading leaves out samples not seen)
        vis = np.ones(p.shape[1], f32)
        entry = {"name": light.name, "lit_samples": int(rows.size), "maps": [],
                 "filtered_samples": 0}
        if rows.size:
            vis[rows], got = light_visibility(light, meshes, np.take(p, rows, axis=1),
                                              np.take(facet, rows, axis=1))
            entry.update(maps=got["maps"], filtered_samples=got["filtered"])
        entry["shadowed_samples"] = int(np.count_nonzero(vis < 1))
        entry["umbra_samples"] = int(np.count_nonzero(vis == 0))
        per_light.append(entry)
        out[i] = vis
    if stats is not None:
        stats.time_s["shadows"] = time.perf_counter() - start
        stats.counts["shadows"] = per_light
    return out
