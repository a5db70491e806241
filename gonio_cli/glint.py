"""Glints of metallic paint: flakes as tiny mirrors, counted per pixel footprint.

Seed 004 §6–7: "The flake faces act as tiny mirrors … Flakes seen directly are the
brightest spots, that look like sparkles." A paint's flake lobe (the glossy Beckmann lobe
of its Cook–Torrance fit, seed 004 eqs. 9–11) is the average of many such mirrors; here a
share ``s`` of it is rendered as the mirrors themselves (discrete microfacets: Jakob et al.
2014, Zirr & Kaplanyan 2016, Deliot & Belcour 2023), the rest stays smooth:

    f = f_diffuse + (1 − s) f_lobe + s f_lobe · r,     r = D_glint(h) / D(h),

so the render's mean over flake seeds is the smooth BRDF whenever E[r] = 1.

**The flakes** are a Poisson point process fixed on the object (not its UVs): each flake
has a position on the surface and a normal. Positions are counted in the plane of the
object's coordinate axis nearest the surface normal (a triplanar projection, so no UV
stretch and no tiling) with density ρ_p = ``density`` per square scene unit of that
plane; normals are slopes x̃ = (−m_t/m_n, −m_b/m_n) in the local frame (t, b, n) with the
slope density p22 of the flake lobe (Beckmann: p22 = exp(−|x̃|²/m²)/(π m²), so
D(h) = p22(x̃_h)/cos⁴θh is seed 004's eq. 9 over π). The process is split into
(spatial cell × slope bin) pairs whose flake counts are independent Poisson numbers
(thinning), drawn from a hash of the pair: the same flakes for every pixel, frame and
camera. A pair's mean is ρ_p c² · p22(bin centre) · b²; a flake drawn uniformly in its bin
carries the weight w = p22(x̃_m) / p22(bin centre), so the flakes' slope density is p22
exactly.

**A pixel's glints** (a sample at x with view v, light half vector h): every flake k
with screen offset s_k (in units of the sample spacing Δ, the tangent-plane offset
foreshortened by cos θo along the view) and slope x̃_k adds

    G = Σ_k f(s_k) · K(x̃_h − x̃_k) · w_k,
    f(s) = 3/π (1 − |s|²)² for |s| < 1           (the pixel filter, ∫ f d²s = 1),
    K(d) = profile(|d|) / area                    (the flake's mirror cone, ∫ K d²x̃ = 1),

and r = G / (ρ_p Δ² |n_a| / cos θo · p22(x̃_h)); ρ_p Δ² |n_a| / cos θo = ∫ ρ_p f d²q is
the expected flake count under the filter (n_a: the normal's component along the projection
axis). Then E[G] = ρ_p Δ² |n_a| / cos θo · (p22 ∗ K)(x̃_h): E[r] = 1 up to K's blur of p22
(relative error ≈ r²/m² ≈ 0.3 % for a cone of r ≈ 1°, m = 0.3). The cone is the light's
disc in h (radius ρ_s, a quarter of its angular diameter) seen through the flake's
spread (radius ρ_f): its profile is flat to |ρ_s − ρ_f| and falls linearly to 0 at
ρ_s + ρ_f (:func:`cone_profile`, a stand-in for the two discs' convolution), so a flake
is never brighter than F · L_source, exactly that for a perfect flake (ρ_f = 0) inside
the disc, and fades at the cone's edge instead of popping when the camera moves.

Only pairs that can matter are drawn: the 2 × 2 cells around the nearest cell corner of
x (cells are at least twice the filter's reach) and the 2 × 2 slope bins around the
nearest bin corner of x̃_h (bins are 2 (ρ_s + ρ_f) wide for the largest light). Samples
where the footprint is wider than the finest cells take coarser cells (level L: 2^L c₀,
an independent process of the same density); samples where glints are too rare
(< :data:`MIN_GLINTS` expected) or too dense (a pair's mean above :data:`MAX_PAIR_MEAN`)
keep r = 1: the smooth lobe, which is the glints' expectation, so the choice adds no
bias.

The core is pure numpy (STYLE 1); :mod:`gonio_cli.render.glint_term` applies it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .brdf import beckmann_d
from .errors import InputError

#: Expected flakes in a finest cell (ρ c₀²). 16 makes c₀ = 4 / √ρ, so the filter's reach
#: (≤ c₀ / 2) holds up to π · 2² ≈ 12 flakes before a coarser level takes over.
CELL_FLAKES = 16.0
#: Coarsest level: cells 2^MAX_LEVEL c₀ (a footprint 256 × wider than the finest).
MAX_LEVEL = 8
#: Largest Poisson count drawn per (cell, bin) pair. Pairs whose mean exceeds
#: :data:`MAX_PAIR_MEAN` are not drawn (smooth), so P(count > 8 | μ ≤ 1.5) = 2e-5 is the
#: largest share of flakes the cap drops.
MAX_COUNT = 8
#: Above this mean per pair the footprint holds many glinting flakes: the sample keeps the
#: smooth lobe (their expectation) instead of drawing them.
MAX_PAIR_MEAN = 1.5
#: Below this expected number of glinting flakes under a sample's filter, the sample keeps
#: the smooth lobe (none of the mean is lost: the lobe is the glints' expectation); up to
#: ten times it, r is blended towards 1 by log10(glints / MIN_GLINTS), so the lobe's
#: dimming by s (where no flake glints) fades in instead of showing the boundary. What it
#: drops: on the demo sphere (512² samples) the 12 000 samples below it expect 0.6 glints
#: in all, and drawing them would cost 20 % more samples.
MIN_GLINTS = 1e-4
#: Below this share of active samples they are gathered before drawing; above it, drawing
#: them all and keeping the active ones is cheaper than the gathers (measured: 62 k
#: samples, 90 % active: 10 ms of gathers against 3 ms of extra draws).
GATHER_SHARE = 0.7
#: Smallest p22 divided by (a floor for r's denominator, far below any glinting slope).
P22_FLOOR = 1e-300
#: Largest 1 / cos θo of the filter's foreshortening: near the silhouette the footprint is
#: no longer stretched (it would reach past the cells); the normalisation uses the same cap,
#: so r stays unbiased.
MAX_STRETCH = 4.0

# 64-bit hash (the splitmix64 / MurmurHash3 finaliser) and odd multipliers for the keys.
_M1, _M2 = np.uint64(0xFF51AFD7ED558CCD), np.uint64(0xC4CEB9FE1A85EC53)
_K = [np.uint64(k) for k in (0x9E3779B97F4A7C15, 0xBF58476D1CE4E5B9, 0x94D049BB133111EB,
                             0xD6E8FEB86659FD93, 0xA0761D6478BD642F, 0xE7037ED1A0B428DB,
                             0x8EBC6AF09C88C6E3, 0x589965CC75374CC3)]
_S33, _S16, _S11 = np.uint64(33), np.uint64(16), np.uint64(11)


def beckmann_p22(slope_x, slope_y, m: float) -> np.ndarray:
    """Seed 004 eq. (9) in slope space (:func:`gonio_cli.brdf.beckmann_d`, the one copy of
    the equation): the density of microfacet slopes x̃ = (−n_x/n_z, −n_y/n_z) per unit
    slope², p22 = D(θh) cos⁴θh / π with tan²θh = |x̃|² (= exp(−|x̃|²/m²) / (π m²):
    ∫ p22 d²x̃ = 1, a Gaussian of variance m²/2 per axis)."""
    c = 1.0 / np.sqrt(1.0 + np.square(slope_x) + np.square(slope_y))
    return beckmann_d(c, m)[..., 0] * np.square(np.square(c)) / np.pi


def mix(x: np.ndarray) -> np.ndarray:
    """A 64-bit avalanche (MurmurHash3's fmix64) of uint64 keys, elementwise."""
    x = x ^ (x >> _S33)
    x = x * _M1
    x ^= x >> _S33
    x *= _M2
    x ^= x >> _S33
    return x


def _u(x: np.ndarray) -> np.ndarray:
    """uint64 → uniform [0, 1) from its top 53 bits."""
    return (x >> _S11).astype(np.float64) * (1.0 / 9007199254740992.0)


@dataclass
class GlintLayer:
    """The flakes of one object.

    density : flakes per square scene unit (of the projection plane), ρ_p > 0.
    share : s in [0, 1], the share of the flake lobe drawn as glints.
    angle_rad : the flake's angular spread (radius of its mirror cone in h), ≥ 0.
    m : Beckmann RMS slope of the flake normals (the paint's lobe).
    seed : integer; another seed is another set of flakes of the same statistics.
    rotation, translation : world → object, p_obj = rotation.T @ (p − translation), so
        the flakes stay on the object when it turns (turntables).
    """

    density: float
    share: float
    angle_rad: float
    m: float
    seed: int = 0
    rotation: np.ndarray | None = None
    translation: np.ndarray | None = None

    @property
    def cell(self) -> float:
        """c₀, the finest cell's side (scene units): ρ c₀² = :data:`CELL_FLAKES`."""
        return float(np.sqrt(CELL_FLAKES / self.density))

    def to_object(self, p: np.ndarray, n: np.ndarray, v: np.ndarray, h: np.ndarray):
        """World (n, 3) position, normal, view and half vector → the object's frame."""
        r = np.eye(3) if self.rotation is None else np.asarray(self.rotation, float)
        t = np.zeros(3) if self.translation is None else np.asarray(self.translation, float)
        if np.array_equal(r, np.eye(3)):
            return p - t, n, v, h
        return tuple(np.einsum("ij,jk->ik", x, r) for x in (p - t, n, v, h))


def check_layer(layer: GlintLayer, where: str = "glints") -> None:
    """Refuse impossible parameters, naming them."""
    for name, value, ok, fix in (
            ("density", layer.density, layer.density > 0, "flakes per square scene unit > 0"),
            ("share", layer.share, 0.0 <= layer.share <= 1.0, "a share in [0, 1]"),
            # 0.25 rad (14°): a flake spread near the lobe's own width (m ≈ 0.3) is no mirror
            ("angle", layer.angle_rad, 0.0 <= layer.angle_rad < 0.25,
             "an angle in [0, 14) deg"),
            ("m", layer.m, layer.m > 0, "a material with a flake lobe (m > 0)")):
        if not (np.isfinite(value) and ok):
            raise InputError(f"{where}: {name} = {value!r} is impossible", fix=f"give {fix}")


def _frame(n: np.ndarray):
    """Projection axis a (n,) = argmax |n_k|, the in-plane axes (u, w) and the tangent
    frame t, b (n, 3): t is the u axis made tangent (|e_u − n_u n|² = 1 − n_u²), b = n × t,
    so the frame is continuous wherever the axis is."""
    a = np.argmax(np.abs(n), axis=1)
    u_ax, w_ax = (a + 1) % 3, (a + 2) % 3
    rows = np.arange(n.shape[0])
    n_u = n[rows, u_ax]
    t = -n_u[:, None] * n
    t[rows, u_ax] += 1.0
    t /= np.sqrt(np.maximum(1.0 - n_u * n_u, 1e-12))[:, None]
    b = np.empty_like(t)
    b[:, 0] = n[:, 1] * t[:, 2] - n[:, 2] * t[:, 1]
    b[:, 1] = n[:, 2] * t[:, 0] - n[:, 0] * t[:, 2]
    b[:, 2] = n[:, 0] * t[:, 1] - n[:, 1] * t[:, 0]
    return a, u_ax, w_ax, t, b


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of (n, 3) arrays: (n,)."""
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def cone_area(cone: tuple[float, float]) -> float:
    """∫ of the cone profile (slope units²): a flat top to r_in, a linear ramp to r_out
    (a frustum's volume, π (r_in² + r_in r_out + r_out²) / 3); K is the profile over it."""
    r_in, r_out = cone
    return float(np.pi * (r_in * r_in + r_in * r_out + r_out * r_out) / 3.0)


def cone_profile(d2: np.ndarray, cone: tuple[float, float]) -> np.ndarray:
    """The cone's profile at squared slope distances d2: 1 inside r_in, falling linearly to
    0 at r_out (the source's disc seen through the flake's spread, module docstring)."""
    r_in, r_out = cone
    if r_out <= r_in:
        return (d2 < r_out * r_out).astype(float)
    return np.clip((r_out - np.sqrt(d2)) / (r_out - r_in), 0.0, 1.0)


def glint_ratio(p, n, v, h, spacing, layer: GlintLayer, cone: tuple[float, float],
                bin_width: float) -> tuple[np.ndarray, dict]:
    """r = D_glint(h) / D(h) per sample (module docstring); 1 where the smooth lobe is kept.

    Parameters
    ----------
    p, n, v, h : (N, 3) world position, unit normal, unit view ωo and unit half vector.
    spacing : (N,) Δ, the distance between neighbouring samples on the plane facing the
        camera at the sample's depth (scene units).
    cone : (r_in, r_out), the mirror cone in slope units (:func:`cone_profile`), r_out ≤
        ``bin_width`` / 2; bin_width : the slope bins' side b (the same for every light).

    Returns
    -------
    (N,) float64 r ≥ 0, and counts: ``samples`` drawn, ``flakes`` evaluated, ``glints``
    (flakes inside their cone and filter).
    """
    if cone[1] > 0.5 * bin_width * (1 + 1e-9) or not 0 <= cone[0] <= cone[1]:
        raise InputError(f"a glint cone {cone} does not fit slope bins of {bin_width:g}")
    p, n, v, h = layer.to_object(np.asarray(p, float), np.asarray(n, float),
                                 np.asarray(v, float), np.asarray(h, float))
    size = p.shape[0]
    r = np.ones(size)
    counts = {"samples": 0, "flakes": 0, "glints": 0}
    if size == 0 or layer.share == 0.0:
        return r, counts
    hn, cos_o = _dot(h, n), _dot(v, n)
    ok = (hn > 0) & (cos_o > 0)
    hn = np.where(ok, hn, 1.0)
    tan_h = np.sqrt(np.maximum(1.0 / (hn * hn) - 1.0, 0.0))         # |x̃_h| = tan θh
    p22_h = beckmann_p22(tan_h, 0.0, layer.m)
    stretch = 1.0 / np.clip(cos_o, 1.0 / MAX_STRETCH, 1.0)
    expected = layer.density * spacing ** 2 * np.abs(n).max(axis=1) * stretch  # |n_a|
    glints = expected * p22_h * cone_area(cone)
    level = np.ceil(np.log2(np.maximum(2.0 * spacing * stretch / layer.cell, 1.0)))
    active = ok & (glints >= MIN_GLINTS) & (level <= MAX_LEVEL)
    idx = np.flatnonzero(active)
    if idx.size == 0:
        return r, counts
    if idx.size < GATHER_SHARE * size:           # else draw them all, keep the active
        p, n, v, h, hn, spacing, stretch, level = (
            x[idx] for x in (p, n, v, h, hn, spacing, stretch, level))
    else:
        idx = np.arange(size)
    a, u_ax, w_ax, t, b = _frame(n)
    sx, sy = -_dot(h, t) / hn, -_dot(h, b) / hn
    g, kept = _draw(p, n, v, sx, sy, spacing, stretch, a, u_ax, w_ax,
                    np.minimum(level, MAX_LEVEL).astype(np.int64), layer, cone, bin_width,
                    counts)
    kept &= active[idx]
    done = idx[kept]
    blend = np.clip(np.log10(glints[done] / MIN_GLINTS), 0.0, 1.0)
    r[done] = 1.0 + blend * (g[kept] / (expected[done] * np.maximum(p22_h[done], P22_FLOOR))
                             - 1.0)
    counts["samples"] = int(np.count_nonzero(kept))
    return r, counts


def _corners(q, level, a, sx, sy, layer, bin_width):
    """Each sample's corner cell c0 (n, 2) and bin i0 (n, 2) (the nearest lattice corners
    − 1, so the 2 × 2 cells and bins from them reach ≥ half a cell or bin beyond the
    sample), the cells' side (n,), and a uint64 key of (level, axis, c0, i0): samples with
    the same key see the same 16 pairs."""
    side = layer.cell * np.exp2(level)
    c0 = np.floor(q / side[:, None] + 0.5).astype(np.int64) - 1
    i0 = np.floor(np.stack([sx, sy], 1) / bin_width + 0.5).astype(np.int64) - 1
    key = mix(c0[:, 0].astype(np.uint64) * _K[0] + c0[:, 1].astype(np.uint64) * _K[1]
              + (level * 3 + a).astype(np.uint64) * _K[2]
              + i0[:, 0].astype(np.uint64) * _K[4] + i0[:, 1].astype(np.uint64) * _K[5])
    return c0, i0, side, key


def _pairs(c0, i0, level, a, side, layer, bin_width):
    """The 16 (cell, bin) pairs of each corner, pair j = 4 · cell + bin (offsets
    :data:`_OFF`): keys (u, 16) uint64 and Poisson means (u, 16), ρ side² p22(bin centre) b²."""
    cells = c0[:, None, :] + _OFF[None]                              # (u, 4, 2)
    bins = i0[:, None, :] + _OFF[None]
    base = np.uint64((int(layer.seed) * int(_K[3])) % 2 ** 64)
    ku = (cells[..., 0].astype(np.uint64) * _K[0] + cells[..., 1].astype(np.uint64) * _K[1]
          + ((level * 3 + a).astype(np.uint64) * _K[2] + base)[:, None])
    kb = bins[..., 0].astype(np.uint64) * _K[4] + bins[..., 1].astype(np.uint64) * _K[5]
    keys = mix((ku[:, :, None] + kb[:, None, :]).reshape(-1, 16))
    p_bin = beckmann_p22((bins[..., 0] + 0.5) * bin_width, (bins[..., 1] + 0.5) * bin_width,
                         layer.m) * bin_width ** 2                   # (u, 4)
    mean = (layer.density * side ** 2)[:, None, None] * p_bin[:, None, :]
    return keys, np.broadcast_to(mean, (p_bin.shape[0], 4, 4)).reshape(-1, 16)


#: (cell or bin) offsets of the 2 × 2 pairs around a corner; pair j = 4 · cell + bin.
_OFF = np.array([[0, 0], [0, 1], [1, 0], [1, 1]], np.int64)


def _poisson(u: np.ndarray, mean: np.ndarray) -> np.ndarray:
    """The Poisson count whose CDF first exceeds u (inversion), at most :data:`MAX_COUNT`."""
    p = np.exp(-mean)
    cdf = p.copy()
    k = np.zeros(u.shape, np.int64)
    for j in range(1, MAX_COUNT + 1):
        more = u >= cdf
        if not more.any():
            break
        k += more
        p = p * mean / j
        cdf = cdf + p
    return k


def _flakes(c0, i0, side, keys, mean, kept, layer, bin_width):
    """The flakes of every corner's 16 pairs: their corner (f,), plane position (f, 2),
    slope (f,), (f,) and weight w = p22(slope) / p22(bin centre) (f,)."""
    u = _u(keys)
    ci, pj = np.nonzero((u >= np.exp(-mean)) & kept[:, None])      # count ≥ 1
    count = _poisson(u[ci, pj], mean[ci, pj])
    # one row per flake: the pair repeated count times, k its index within the pair
    fi = np.repeat(np.arange(ci.size), count)
    k = np.arange(fi.size) - np.repeat(np.cumsum(count) - count, count)
    c_of, pf = ci[fi], pj[fi]
    y = mix(keys[c_of, pf] ^ ((k.astype(np.uint64) + np.uint64(1)) * _K[6]))
    u4 = [(((y >> np.uint64(16 * j)) & np.uint64(0xFFFF)).astype(np.float64) + 0.5) / 65536.0
          for j in range(4)]
    cell = c0[c_of] + _OFF[pf // 4]
    bn = i0[c_of] + _OFF[pf % 4]
    fq = (cell + np.stack(u4[:2], 1)) * side[c_of][:, None]          # flake in the plane
    mx = (bn[:, 0] + u4[2]) * bin_width                              # its slope
    my = (bn[:, 1] + u4[3]) * bin_width
    w = beckmann_p22(mx, my, layer.m) / beckmann_p22((bn[:, 0] + 0.5) * bin_width,
                                                      (bn[:, 1] + 0.5) * bin_width, layer.m)
    return c_of, fq, mx, my, w


def _draw(p, n, v, sx, sy, spacing, stretch, a, u_ax, w_ax, level, layer, cone, bin_width,
          counts):
    """G (n,) of :func:`glint_ratio` at its active samples, and which samples were drawn
    (False where a pair's mean exceeds :data:`MAX_PAIR_MEAN`). The pairs and flakes are
    made once per distinct corner (neighbouring samples share them)."""
    rows = np.arange(p.shape[0])
    q = np.stack([p[rows, u_ax], p[rows, w_ax]], 1)
    c0, i0, side, key = _corners(q, level, a, sx, sy, layer, bin_width)
    _, first, inv = np.unique(key, return_index=True, return_inverse=True)
    keys, mean = _pairs(c0[first], i0[first], level[first], a[first], side[first], layer,
                        bin_width)
    kept_c = mean.max(axis=1) <= MAX_PAIR_MEAN
    kept = kept_c[inv]
    c_of, fq, mx, my, w = _flakes(c0[first], i0[first], side[first], keys, mean, kept_c,
                                  layer, bin_width)
    g = np.zeros(p.shape[0])
    if c_of.size == 0:
        return g, kept
    counts["flakes"] += int(c_of.size)
    # (sample, flake) rows: each sample meets the flakes of its corner; the cone test
    # first (cheap, passed by ~π/16 of them), then the filter on those left
    per = np.bincount(c_of, minlength=first.size)
    start = np.cumsum(per) - per
    m_s = per[inv]
    s_of = np.repeat(rows, m_s)
    f_of = np.repeat(start[inv] - (np.cumsum(m_s) - m_s), m_s) + np.arange(s_of.size)
    dk2 = np.square(sx[s_of] - mx[f_of]) + np.square(sy[s_of] - my[f_of])
    near = np.flatnonzero(dk2 < cone[1] * cone[1])
    s_of, f_of, dk2 = s_of[near], f_of[near], dk2[near]
    s2 = _screen_offset2(fq[f_of] - q[s_of], n, v, (rows, u_ax, w_ax, a), s_of, stretch)
    s2 /= np.square(spacing[s_of])
    inside = s2 < 1.0
    contrib = np.where(inside, 3.0 / np.pi * np.square(1.0 - s2) * cone_profile(dk2, cone)
                       * (w[f_of] / cone_area(cone)), 0.0)
    counts["glints"] += int(np.count_nonzero(inside))
    return np.bincount(s_of, weights=contrib, minlength=p.shape[0]), kept


def _screen_offset2(d, n, v, axes, s_of, stretch):
    """|s|² Δ² of the flakes at plane offsets d (m, 2) from samples ``s_of`` (m,): the
    offset lifted along the projection axis onto the sample's tangent plane
    (d_a = −(n_u d_u + n_w d_w) / n_a), its component along the view's tangent direction
    shrunk by cos θo (foreshortening, capped at 1 / :data:`MAX_STRETCH`), the other kept.
    ``axes``: (rows, u, w, a) of the samples (:func:`_frame`)."""
    rows, u_ax, w_ax, a = axes
    seen = np.zeros(rows.size, bool)
    seen[s_of] = True
    tv = np.zeros_like(n)
    k = np.flatnonzero(seen)                       # the view's tangent, where it is needed
    tv[k] = v[k] - _dot(v[k], n[k])[:, None] * n[k]
    norm = np.sqrt(_dot(tv[k], tv[k]))
    tv[k] /= np.maximum(norm, 1e-12)[:, None]
    along_n = k[norm <= 1e-12]                     # seen along the normal: any tangent
    if along_n.size:
        tv[along_n] = _any_tangent(n[along_n])
    nu, nw, na = (n[rows, x][s_of] for x in (u_ax, w_ax, a))
    tu, tw, ta = (tv[rows, x][s_of] for x in (u_ax, w_ax, a))
    du, dw = d[:, 0], d[:, 1]
    da = -(nu * du + nw * dw) / na
    along = du * tu + dw * tw + da * ta
    return np.square(along / stretch[s_of]) + du * du + dw * dw + da * da - along * along


def _any_tangent(n):
    """A unit vector ⟂ n (n, 3), for a view along the normal (no preferred direction)."""
    e = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    t = np.cross(n, e)
    return t / np.linalg.norm(t, axis=1, keepdims=True)
