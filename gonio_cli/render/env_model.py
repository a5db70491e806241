"""Environment light through the material's own lobes (``[environment] method = "model"``).

Seed 001 fits a material once to a few cosine lobes and reads one prefiltered map per
lobe; a basis that stops at exponent ~70 cannot show a clear coat of α = 0.02 reflecting
the horizon. Here every lobe of the material's own model (:mod:`gonio_cli.brdf_components`:
the diffuse body, eq. 5's lobe, a coat, a second lobe …) reads a **chain** of prefiltered
maps P_E (``gonio prefilter ENV --chain``: E = 1, 2, 4, … up to a map as sharp as a texel)
as sharp as that lobe is:

    L_o(V) = Σ_k Σ_λ A_k(θv, λ) · [Σ_l w_kl(θv) P_El(d_k)](λ)

* A_k(θv, λ) = ∫ f_k(ωi, V) cos θi dωi, the lobe's directional albedo (its colour and
  energy, and its Fresnel and masking at this view), integrated once per render over a
  quadrature that follows the lobe (:func:`lobe_table`): half-vector nodes for glossy
  lobes, dense from θh = :data:`THETA_H_FIRST` (mirror-like lobes are resolved, so no
  sharp lobe is missed the way hemisphere samples miss it), cosine nodes for diffuse ones.
* d_k(θv), the lobe's mean direction (f cos θi-weighted, luminance): tilted from the
  mirror direction R towards the normal N as the lobe is cut by the horizon (the
  off-specular peak), N for a Lambertian body.
* w_kl(θv) ≥ 0, Σ_l w_kl = 1: the lobe's spread about d_k as a mixture of the chain's
  normalised Phong lobes, fitted (non-negative least squares) to the lobe's cumulative
  distribution over the angle ψ from d_k: a normalised lobe max(0, cos ψ)^E has
  F_E(ψ) = 1 − cos^(E+1) ψ. A GGX lobe is a sharp core with long tails: one Phong
  lobe matched in width would blur the core or lose the tails; the mixture keeps both.
  A Lambertian body is exactly w = 1 on E = 1 (its P_1(N) is irradiance/π: exact).

Colour: the maps hold linear sRGB; ``channel_matrices`` of :mod:`.environment` turns
A_k(λ) into the 3 × 3 (rgb → XYZ) matrix of each view angle, exactly as seed 001's
spectral weights are. Under a constant environment the result is Σ_k A_k = the
material's directional albedo, exactly (the furnace test, ``tests/test_env_model.py``).

What it misses: a lobe is taken as round about d_k (a microfacet lobe seen at grazing
angles is stretched vertically); the environment below the surface's tangent plane
leaks into lobes near the horizon; the scene occludes the sky of the diffuse lobes only
(:func:`surface_environment_xyz`'s ``visibility``, :mod:`gonio_cli.render.occlusion`).
Tables are per material and view angle (:data:`VIEW_ANGLES_DEG`), linear in θv between
them.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from .. import log
from ..brdf_components import DIFFUSE, Component, components
from ..cache import cached_arrays
from ..envmap import direction_to_spherical, lookup_angles
from ..errors import InputError
from ..geometry import Cosines
from ..schemas import Lobes
from ..spectra import cmf_weights
from .env_lookup import c_build_available, c_environment
from .environment import (channel_matrices, environment_xyz, substrate_environment_xyz,
                          view_interpolation)

#: View angles θv (degrees) of the per-material tables; 2° apart, then 89 and 89.9 so
#: silhouette pixels (θv → 90°) interpolate rather than clamp.
VIEW_ANGLES_DEG = np.concatenate([np.arange(0.0, 88.01, 2.0), [89.0, 89.9]])

#: The first half-angle interval of the glossy quadrature (rad): GGX α = 1e-3 (a mirror
#: film) has its half width at θh ≈ α; intervals then double up to π/2.
THETA_H_FIRST = 2.5e-4

#: Gauss–Legendre nodes per θh interval (each doubles the last: 6 nodes integrate a
#: GGX D over its interval to ~1e-6) and azimuth nodes over [0, π] (the BRDF is
#: symmetric about the plane of N and V).
GL_NODES = 6
PHI_NODES = 32

#: Gauss–Legendre nodes in cos θi for diffuse lobes.
COS_NODES = 16

#: Angles ψ (rad) from the lobe's mean direction where the mixture's cumulative
#: distribution is fitted: geometric below 0.1 rad (a sharp core), then every 0.05.
PSI_FIT = np.concatenate([np.geomspace(2e-4, 0.1, 40, endpoint=False),
                          np.arange(0.1, np.pi / 2 + 1e-9, 0.05)])

#: Weight of the row Σ w = 1 against the cumulative-distribution rows.
SUM_ROW_WEIGHT = 100.0

#: Level weights below this (of the lobe's energy) are dropped, the rest renormalised.
WEIGHT_FLOOR = 1e-3

#: Levels a lobe mixes at one view angle: the largest weights of the fit over every
#: level, refitted alone. A GGX coat (α = 0.02) spreads over ~10 levels of a factor-2
#: chain; its three largest keep its cumulative distribution within 0.04 (all: 0.004),
#: and a pixel then reads ≤ 6 maps per lobe (two view-angle rows) instead of every level.
MAX_LEVELS = 3

#: The sharpest map holds half its weight within its half-mass angle ψ½; a lobe holding
#: more than this share within ψ½ is sharper than the chain, and said to be blurred.
SHARPER_SHARE_WARN = 0.75


@dataclass
class LobeTable:
    """One lobe of a material over :data:`VIEW_ANGLES_DEG` (V rows).

    ``albedo``: (V, n_λ) ∫ f_k cos θi dω; ``beta``: (V,) rad, the mean direction's tilt
    from N towards R; ``weights``: (V, L) the chain levels' weights (Σ = 1 per row);
    ``sharper``: the largest share of the lobe's energy within ψ where the sharpest
    map holds half of its own (> 0.5 means the lobe is sharper than the chain)."""

    name: str
    kind: str
    albedo: np.ndarray
    beta: np.ndarray
    weights: np.ndarray
    sharper: float

    @property
    def levels(self) -> np.ndarray:
        """Indices of the chain's levels this lobe mixes at some view angle."""
        return np.flatnonzero(self.weights.max(axis=0) > 0)


@functools.lru_cache(maxsize=None)
def _legendre(n: int) -> tuple[np.ndarray, np.ndarray]:
    return np.polynomial.legendre.leggauss(n)


def _gauss_legendre(edges: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Composite Gauss–Legendre nodes and weights over consecutive ``edges``."""
    x, w = _legendre(n)
    a, b = edges[:-1, None], edges[1:, None]
    return ((a + b) / 2 + (b - a) / 2 * x).ravel(), ((b - a) / 2 * w).ravel()


@functools.lru_cache(maxsize=1)
def _half_vector_nodes():
    edges = [0.0]
    while edges[-1] * 2 < np.pi / 2 or len(edges) == 1:
        edges.append(THETA_H_FIRST if len(edges) == 1 else edges[-1] * 2)
    edges.append(np.pi / 2)
    th, wt = _gauss_legendre(np.asarray(edges), GL_NODES)
    ph = (np.arange(PHI_NODES) + 0.5) * np.pi / PHI_NODES
    th, ph = np.meshgrid(th, ph, indexing="ij")
    w = (wt[:, None] * np.sin(th) * (2 * np.pi / PHI_NODES)).ravel()   # both halves
    h = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)
    h, w = h.reshape(-1, 3), w
    h.flags.writeable = w.flags.writeable = False         # shared by every call (cached)
    return h, w


def _directions(kind: str, wo: np.ndarray):
    """ωi (n, 3), their Cosines and quadrature weights (sr) for one view ``wo``."""
    if kind == DIFFUSE:
        ct, wc = _gauss_legendre(np.array([0.0, 1.0]), COS_NODES)
        ph = (np.arange(PHI_NODES) + 0.5) * np.pi / PHI_NODES
        ct, ph = np.meshgrid(ct, ph, indexing="ij")
        st = np.sqrt(1 - ct * ct)
        wi = np.stack([st * np.cos(ph), st * np.sin(ph), ct], -1).reshape(-1, 3)
        w = np.repeat(wc, PHI_NODES) * (2 * np.pi / PHI_NODES)
        h = wi + wo
        h /= np.linalg.norm(h, axis=1, keepdims=True)
    else:                                   # dωi = 4 (ωo·h) dωh (reflection's Jacobian)
        h, wh = _half_vector_nodes()
        ho = h @ wo
        wi = 2 * ho[:, None] * h - wo
        w = wh * 4 * np.maximum(ho, 0.0)
        keep = (ho > 0) & (wi[:, 2] > 0)
        wi, h, w = wi[keep], h[keep], w[keep]
    cos = Cosines(np.clip(wi[:, 2], 0, 1), np.full(len(wi), wo[2]), np.clip(h[:, 2], 0, 1),
                  np.clip(np.einsum("ij,ij->i", wi, h), 0, 1))
    return wi, cos, w


def _cdf_rows(psi: np.ndarray, mass: np.ndarray) -> np.ndarray:
    """The cumulative distributions (C, len(PSI_FIT)) of ``mass`` (n, C) over ``psi``,
    interpolated in 1 − cos ψ (in which a smooth lobe's distribution starts linearly from
    (0, 0)); a node's mass counts half at its own ψ."""
    x, inverse = np.unique(np.round(1.0 - np.cos(psi), 15), return_inverse=True)
    m = np.zeros((x.size, mass.shape[1]))
    np.add.at(m, inverse.ravel(), mass)
    m /= np.maximum(m.sum(axis=0), 1e-300)
    c = np.vstack([np.zeros((1, m.shape[1])), np.cumsum(m, axis=0) - m / 2])
    xs, xq = np.concatenate([[0.0], x]), 1.0 - np.cos(PSI_FIT)
    return np.stack([np.interp(xq, xs, c[:, j]) for j in range(m.shape[1])])


def level_weights(psi: np.ndarray, mass: np.ndarray, levels: np.ndarray) -> np.ndarray:
    """Non-negative weights (L,) of normalised Phong lobes of exponents ``levels`` whose
    mixture has the cumulative distribution of ``mass`` (n,) over the angles ``psi``
    (rad) from the lobe's axis (module docstring), Σ = 1: the :data:`MAX_LEVELS`
    largest of the fit over every level, refitted alone.

    One mixture for every wavelength (the lobe's luminance): per-wavelength weights
    (a Beckmann m or eq. 5's colour changing across the lobe) moved the matte ink of
    ``tests/test_env_model.py`` by 0.07 CIEDE2000 (1.94 → 1.87) for a 3 × 3 colour
    product per level instead of per lobe."""
    from scipy.optimize import nnls

    basis = 1.0 - np.cos(PSI_FIT)[:, None] ** (levels[None, :] + 1.0)
    a = np.vstack([basis, SUM_ROW_WEIGHT * np.ones((1, levels.size))])
    b = np.concatenate([_cdf_rows(psi, mass[:, None])[0], [SUM_ROW_WEIGHT]])

    def fit(cols):
        w = np.zeros(levels.size)
        w[cols] = nnls(a[:, cols], b)[0]
        w[w < WEIGHT_FLOOR * w.sum()] = 0.0
        return w / w.sum() if w.sum() > 0 else np.eye(levels.size)[cols[0]]

    w = fit(np.arange(levels.size))
    return fit(np.argsort(w)[::-1][:min(MAX_LEVELS, np.count_nonzero(w))])


def lobe_table(component: Component, wavelength_nm, levels: np.ndarray) -> LobeTable:
    """The :class:`LobeTable` of one lobe for the chain's exponents ``levels`` (L,)."""
    ybar = cmf_weights(wavelength_nm)[:, 1]
    rows, n_wl = len(VIEW_ANGLES_DEG), len(wavelength_nm)
    albedo = np.zeros((rows, n_wl))
    beta, weights = np.zeros(rows), np.zeros((rows, levels.size))
    top_half = np.arccos(0.5 ** (1.0 / (levels.max() + 1.0)))   # F_Emax(ψ) = ½
    sharper = 0.0
    for r, tv in enumerate(np.radians(VIEW_ANGLES_DEG)):
        wo = np.array([np.sin(tv), 0.0, np.cos(tv)])
        wi, cos, w = _directions(component.kind, wo)
        f_cos = np.broadcast_to(component.evaluate(cos) * (cos.cos_theta_i * w)[:, None],
                                (len(w), n_wl))                 # an achromatic coat: (n, 1)
        albedo[r] = f_cos.sum(axis=0)
        y = np.maximum(f_cos @ ybar, 0.0)
        if not y.sum() > 0:
            weights[r, 0] = 1.0
            continue
        mean = (wi * y[:, None]).sum(axis=0)
        mean[1] = 0.0                    # the nodes cover φ ∈ [0, π]: their mirror cancels y
        axis = mean / np.linalg.norm(mean)
        beta[r] = np.arctan2(-axis[0], axis[2])            # towards R = (−sin θv, 0, cos θv)
        psi = np.arccos(np.clip(wi @ axis, -1.0, 1.0))
        weights[r] = level_weights(psi, y, levels)
        sharper = max(sharper, float(y[psi < top_half].sum() / y.sum()))
    return LobeTable(component.name, component.kind, albedo, beta, weights, sharper)


def material_tables(material, wavelength_nm, levels: np.ndarray) -> list[LobeTable]:
    """:func:`lobe_table` of every lobe of a fitted material (a ``gonio.material``)."""
    return [lobe_table(c, wavelength_nm, levels)
            for c in components(material.model, material.params)]


#: Version of the cached tables (bump when the quadrature or the fit changes).
TABLES_VERSION = 4


def tables_for(environment, material, wavelength_nm) -> list[LobeTable]:
    """:func:`material_tables` for the chain of ``environment``, from gonio's disk cache
    (keyed by the material's model and parameters, the grid and the chain's exponents:
    :mod:`gonio_cli.cache`), computed and stored on a miss; kept per environment."""
    import hashlib

    levels = np.asarray(environment.exponents, dtype=float)
    wl = np.asarray(wavelength_nm, dtype=float)
    settings = (TABLES_VERSION, MAX_LEVELS, GL_NODES, PHI_NODES, COS_NODES, THETA_H_FIRST,
                WEIGHT_FLOOR, SUM_ROW_WEIGHT, VIEW_ANGLES_DEG.tolist(), PSI_FIT.tolist())
    digest = hashlib.sha256(repr((settings, material.model, levels.tolist(),
                                  wl.tolist())).encode())
    for name in sorted(material.params):
        digest.update(name.encode() + np.asarray(material.params[name], float).tobytes())
    key = digest.hexdigest()[:24]
    if key in environment.tables:
        return environment.tables[key]
    lobes = components(material.model, material.params)

    def compute():
        tables = material_tables(material, wl, levels)
        return {f"{k}.{field}": getattr(t, field) for k, t in enumerate(tables)
                for field in ("albedo", "beta", "weights", "sharper")}

    def check(d):
        return all(f"{k}.weights" in d and d[f"{k}.weights"].shape[1] == levels.size
                   for k in range(len(lobes)))

    d = cached_arrays(f"envlobes-{key}.npz", compute, check)
    tables = [LobeTable(c.name, c.kind, d[f"{k}.albedo"], d[f"{k}.beta"], d[f"{k}.weights"],
                        float(d[f"{k}.sharper"])) for k, c in enumerate(lobes)]
    environment.tables[key] = tables
    return tables


def _tangents(normal, view, cos_v) -> np.ndarray:
    """T (n, 3): the unit tangent at N in the plane of N and V, towards R (0 at θv = 0)."""
    t = cos_v[:, None] * normal - view
    norm = np.sqrt(np.einsum("ij,ij->i", t, t))[:, None]
    return np.divide(t, norm, out=np.zeros_like(t), where=norm > 1e-12)


#: Pixels per block of :func:`model_environment_xyz`: its per-pixel temporaries (angles,
#: axes, lookups) stay ~10 MB, so a 2048² frame costs no more memory than a small one.
BLOCK = 65536


def model_environment_xyz(environment, tables: list[LobeTable], normal: np.ndarray,
                          view: np.ndarray, wavelength_nm,
                          observer: np.ndarray | None = None,
                          build: str | None = None) -> np.ndarray:
    """XYZ (n, C) of the environment reflected by a material's lobes (module docstring).

    ``environment``: :class:`gonio_cli.render.environment.Environment` (its maps are the
    levels, :meth:`~gonio_cli.render.environment.Environment.level`); ``tables``:
    :func:`material_tables` for the environment's exponents; ``normal``, ``view``: (n, 3)
    unit N and V; ``observer`` as in :func:`gonio_cli.render.environment.environment_xyz`.
    ``build``: one of :data:`.env_lookup.BUILDS`, None for the first available (C where it was built):
    the C build runs every pixel in one pass on :func:`gonio_cli.machine.cpu_count`
    threads; the numpy build in blocks of :data:`BLOCK` pixels.
    """
    n = np.shape(normal)[0]
    channels = 3 if observer is None else np.shape(observer)[1]
    out = np.zeros((n, channels))
    matrices = [channel_matrices(t.albedo, "spectral", wavelength_nm, observer)
                for t in tables]                                        # (V, 3, C) each
    if (build or ("c" if c_build_available() else "numpy")) == "c":
        c_environment(environment, tables, matrices, normal, view, out, VIEW_ANGLES_DEG)
        return out
    normal = np.asarray(normal, dtype=float)
    view = np.asarray(view, dtype=float)
    for start in range(0, n, BLOCK):
        b = slice(start, start + BLOCK)
        out[b] = _block_xyz(environment, tables, matrices, normal[b], view[b])
    return out


def _block_xyz(environment, tables, matrices, normal, view) -> np.ndarray:
    """:func:`model_environment_xyz` of one block: per lobe, its axis d_k, the levels it
    mixes at each pixel's view angle (the pixels sorted by view interval, so each level
    reads one slice), then its colour matrices, interpolated in θv."""
    n = normal.shape[0]
    cos_v = np.clip(np.einsum("ij,ij->i", normal, view), 0.0, 1.0)
    i0, _, t = view_interpolation(cos_v, VIEW_ANGLES_DEG)
    order = np.argsort(i0, kind="stable")                 # each view interval a slice
    i0, t, cos_v = i0[order], t[order], cos_v[order]
    normal, view = normal[order], view[order]
    starts = np.searchsorted(i0, np.arange(len(VIEW_ANGLES_DEG) + 1))
    acc = np.zeros((n, matrices[0].shape[-1]))
    tangent = _tangents(normal, view, cos_v)
    for table, m in zip(tables, matrices):
        beta = table.beta[i0] + t * (_next(table.beta, i0) - table.beta[i0])
        axis = np.cos(beta)[:, None] * normal + np.sin(beta)[:, None] * tangent   # d_k
        theta, phi = direction_to_spherical(axis)
        p = np.zeros((n, 3), dtype=np.float32)
        for level in table.levels:
            wl = np.append(table.weights[:, level], table.weights[-1, level])   # row V
            live = np.flatnonzero(np.maximum(wl[:-1], wl[1:]) > 0)
            s = slice(starts[live[0]], starts[live[-1] + 1])      # their pixels: a slice
            if s.start == s.stop:
                continue
            i = i0[s]
            w = (wl[i] + t[s] * (wl[i + 1] - wl[i])).astype(np.float32)
            p[s] += w[:, None] * lookup_angles(environment.level(level), theta[s], phi[s])
        tp = t[:, None] * p
        for r in np.flatnonzero(np.diff(starts)):        # per view interval: 2 products
            s = slice(starts[r], starts[r + 1])
            acc[s] += p[s] @ m[r] + tp[s] @ (m[r + 1] - m[r])
    out = np.empty_like(acc)
    out[order] = acc
    return out


def _next(values: np.ndarray, i0: np.ndarray) -> np.ndarray:
    """``values`` of the next view row (the last row's own at the end: t = 0 there)."""
    return values[np.minimum(i0 + 1, len(values) - 1)]


def _occluded_model_xyz(environment, tables: list[LobeTable], normal, view, wavelength_nm,
                        observer, visibility) -> np.ndarray:
    """:func:`model_environment_xyz` with the light of the diffuse lobes times
    ``visibility`` (n,) (the share of the irradiance the scene lets through,
    :mod:`gonio_cli.render.occlusion`), the glossy lobes as they are; None: unoccluded."""
    diffuse = [t for t in tables if t.kind == DIFFUSE]
    if visibility is None or not diffuse:
        return model_environment_xyz(environment, tables, normal, view, wavelength_nm,
                                     observer)
    out = np.asarray(visibility, float)[:, None] * model_environment_xyz(
        environment, diffuse, normal, view, wavelength_nm, observer)
    glossy = [t for t in tables if t.kind != DIFFUSE]
    if glossy:
        out += model_environment_xyz(environment, glossy, normal, view, wavelength_nm,
                                     observer)
    return out


def surface_environment_xyz(environment, surface, where: str, normal: np.ndarray,
                            view: np.ndarray, cov: np.ndarray | None, wavelength_nm,
                            observer: np.ndarray | None = None,
                            visibility: np.ndarray | None = None) -> np.ndarray:
    """Environment light (n, C) of one object (a :class:`gonio_cli.render.surface.Surface`)
    by its method: its model's lobes (``env_tables``, :func:`model_environment_xyz`) or
    seed 001's lobe weights (``lobes``, :func:`~.environment.environment_xyz`); a printed
    object's inks weighted by their coverage ``cov`` (n, 3), and its substrate's Phong
    term (:func:`~.environment.substrate_environment_xyz`) by what they leave bare.
    ``visibility`` (n,) or None: the share of each pixel's diffuse irradiance the scene
    lets through (:mod:`gonio_cli.render.occlusion`), applied to the diffuse lobes only
    (the model's Lambertian bodies, seed 001's K_D, the substrate's kd)."""
    def one(j: int, n, v, vis=visibility):
        if surface.env_method == "model":
            return _occluded_model_xyz(environment, surface.env_tables[j], n, v,
                                       wavelength_nm, observer, vis)
        return environment_xyz(environment, lobes[j], n, v, wavelength_nm, observer,
                               diffuse_scale=vis)

    lobes = surface.lobes
    fix = "fit its lobe weights with gonio lobes fit and give them in the scene"
    if surface.env_method != "model":
        if not surface.printed and not isinstance(lobes, Lobes):
            raise InputError(f"{where} has no lobes; environment light needs gonio lobes fit",
                             fix=fix)
        if surface.printed and (isinstance(lobes, Lobes) or lobes is None or len(lobes) != 3):
            raise InputError(f"{where} is printed: environment light needs one lobes file "
                             "per ink (3)", fix=fix)
        lobes = lobes if surface.printed else [lobes]
    if not surface.printed:
        return one(0, normal, view)
    out = np.zeros((normal.shape[0], 3 if observer is None else observer.shape[1]))
    for j in range(3):
        sel = cov[:, j] > 0
        if np.any(sel):
            out[sel] += cov[sel, j, None] * one(j, normal[sel], view[sel],
                                                None if visibility is None else visibility[sel])
    bare = np.clip(1.0 - cov.sum(axis=1), 0.0, 1.0)
    if surface.substrate is not None and np.any(bare > 0):
        sel = bare > 0
        out[sel] += bare[sel, None] * substrate_environment_xyz(
            environment, surface.substrate, normal[sel], view[sel], wavelength_nm, observer,
            None if visibility is None else visibility[sel])
    return out


def warn_blurred(tables: list[LobeTable], where: str, environment) -> None:
    """Say when a lobe is sharper than the chain's sharpest map (its reflection blurred)."""
    for table in tables:
        if table.sharper > SHARPER_SHARE_WARN:
            log.warn(f"{where}: {table.sharper:.0%} of its {table.name} lobe is sharper than "
                     f"the sharpest prefiltered map of {environment.path} (E = "
                     f"{environment.exponents.max():g}), so its reflection is blurred; "
                     "prefilter with gonio prefilter ENV --chain")


__all__ = ["LobeTable", "lobe_table", "material_tables", "tables_for", "surface_environment_xyz", "model_environment_xyz",
           "level_weights", "warn_blurred", "VIEW_ANGLES_DEG"]
