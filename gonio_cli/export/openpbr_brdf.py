"""The OpenPBR Surface BRDF for the parameters gonio exports, written once.

What a renderer following the OpenPBR Surface specification (v1.1, Academy Software
Foundation; "the spec" below) computes for a material of ``gonio export --to openpbr``, so
that the export can be fitted to a gonio material and judged against it
(docs/export.md). gonio's geometry (:class:`gonio_cli.geometry.Cosines`; ωi the light,
ωo the viewer, docs/conventions.md); values are BRDFs in sr⁻¹ without the cosine of
incidence, shape (..., 3), colours linear Rec.709/sRGB (``lin_rec709``).

The spec defines the ground truth as light transport through its slabs and leaves the
layering to the implementation; gonio takes the spec's own "reduction to a mixture of
lobes" (non-reciprocal albedo scaling, as its MaterialX reference implementation does):

* ``f = C f_coat + lerp(1, T_coat (1 − E_coat(ωo)), C) f_base``, C = ``coat_weight``;
* ``f_base = lerp(f_dielectric, f_conductor, M)``, M = ``base_metalness``;
* ``f_dielectric = f_spec + (1 − E_spec(ωo)) base_weight base_color / π`` (glossy-diffuse
  with ``base_diffuse_roughness`` 0: the EON diffuse lobe is then Lambertian);
* every specular lobe a GGX microfacet BRDF, α = roughness², with the height-correlated
  Smith masking (:func:`gonio_cli.export.gltf_brdf.specular_brdf`, GGX D of
  :func:`gonio_cli.brdf.ggx_d`), its missing multiple scattering put back by Turquin
  2019's factor 1 + F0 (1 − E₁(ωo)) / E₁(ωo) (one of the two schemes the spec names);
  E the directional albedos, tabulated once by quadrature (:func:`albedo_tables`);
* ``f_spec``: ``specular_color`` × the exact dielectric Fresnel at the spec's modulated
  IOR ratio (``specular_weight`` scales F0, eq. modulated_ior; under a coat the ratio is
  lerp(n_b, n_b/n_c, C), with the spec's TIR fix n_c/n_b where the coat is denser);
* ``f_conductor``: ``specular_weight`` × F82-tint (Kutz 2021) with F0 =
  ``base_weight`` ``base_color`` and the edge tint ``specular_color`` at μ̄ = 1/7;
* ``f_coat``: the exact dielectric Fresnel of ``coat_ior``; ``T_coat`` =
  ``coat_color`` ^ ((1/μti + 1/μto)/2), the spec's view-dependent absorption (μt the
  cosines refracted into the coat); the base's roughness widened by the coat's
  (the spec's "Roughening" formula).

* the thin film (``thin_film_weight``, ``_thickness`` in µm, ``_ior``): the base lobes'
  Fresnel (dielectric and metal) mixed by the weight with Belcour & Barla 2017's
  two-interface term in KHR_materials_iridescence's approximation (:func:`film_fresnel`,
  the same function as glTF's, at V·H, from air); the directional albedos that weight
  the diffuse base stay the film-less lobe's (an approximation, within the film's
  change of F: the spec leaves the layering to the implementation).

Not modelled: coat darkening (the export writes ``coat_darkening`` 0, whose meaning by
the spec, the coated base's albedo F + E_b (1 − F), is what albedo scaling gives),
fuzz, transmission, subsurface, anisotropy (all written at their off values).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from ..cache import cached_arrays
from ..geometry import Cosines
from .gltf_brdf import (ALPHA_MIN, COS_EPS, ior_f0, parameters_dict, specular_brdf,
                        visibility)
from .gltf_iridescence import iridescent_fresnel

#: μ̄ of F82-tint: the cosine (about 82°) where ``specular_color`` sets the metal's edge.
MU_BAR = 1.0 / 7.0

#: What gonio computes for ``coat_darkening`` (module docstring): written so.
COAT_DARKENING = 0.0

#: Version of the albedo tables' computation (part of their cache key).
TABLE_VERSION = 1
#: Cosines of the viewer in the albedo tables: E is smooth in μ above ~0.05, and the
#: fit never looks below cos 86° = 0.07.
TABLE_MU = np.linspace(0.02, 1.0, 50)
#: Roughnesses in the tables: the fit's range, every 0.033.
TABLE_ROUGHNESS = np.linspace(0.01, 1.0, 31)
#: √F0 of the dielectric in the tables (F0 ≤ 0.49: IOR ratios up to 5.8).
TABLE_SQRT_F0 = np.linspace(0.0, 0.7, 15)
#: Gauss–Legendre nodes in u (GGX's CDF of θh) and midpoints in φ of the quadrature.
TABLE_NODES = 48


@dataclass(frozen=True)
class OpenPbrMaterial:
    """The ``open_pbr_surface`` inputs gonio exports, each as the spec's input of the same
    name; colours (3,) linear Rec.709. Defaults are the spec's."""

    base_weight: float = 1.0
    base_color: tuple = (0.8, 0.8, 0.8)
    base_metalness: float = 0.0
    specular_weight: float = 1.0
    specular_color: tuple = (1.0, 1.0, 1.0)
    specular_roughness: float = 0.3
    specular_ior: float = 1.5
    coat_weight: float = 0.0
    coat_color: tuple = (1.0, 1.0, 1.0)
    coat_roughness: float = 0.0
    coat_ior: float = 1.6
    thin_film_weight: float = 0.0
    thin_film_thickness: float = 0.5        # µm, the spec's unit for this input
    thin_film_ior: float = 1.4
    name: str = field(default="", compare=False)

    def to_dict(self) -> dict:
        return parameters_dict(self)


# ------------------------------------------------------------------------ Fresnel --

def fresnel_dielectric(cos_theta, eta) -> np.ndarray:
    """Unpolarised Fresnel reflectance (...,) of a dielectric interface of relative index
    ``eta`` at incidence cosine ``cos_theta`` (Walter et al. 2007 eq. 22); 1 under total
    internal reflection (eta < 1)."""
    c = np.clip(np.asarray(cos_theta, dtype=float), 0.0, 1.0)
    g2 = np.asarray(eta, dtype=float) ** 2 - 1.0 + c * c
    g = np.sqrt(np.maximum(g2, 0.0))
    a = (g - c) / np.maximum(g + c, COS_EPS)
    b = (c * (g + c) - 1.0) / np.maximum(c * (g - c) + 1.0, COS_EPS)
    return np.where(g2 > 0.0, 0.5 * a * a * (1.0 + b * b), 1.0)


def modulated_eta(eta, specular_weight) -> float:
    """The spec's eq. modulated_ior: the IOR ratio whose normal-incidence Fresnel is
    ξ F_s, ξ = ``specular_weight`` clamped to [0, 1/F_s]."""
    f_s = float(ior_f0(eta))
    xi = float(np.clip(specular_weight, 0.0, 1.0 / f_s if f_s > 0 else 1.0))
    eps = np.sign(float(eta) - 1.0) * np.sqrt(xi * f_s)
    return float((1.0 + eps) / (1.0 - eps)) if eps < 1.0 else np.inf


def specular_eta(m: OpenPbrMaterial) -> float:
    """η'_s of the dielectric base: eq. specular_ior_ratio (the coat's presence), with the
    TIR fix (n_c/n_b where n_c > n_b), then :func:`modulated_eta`."""
    n_b, n_c = float(m.specular_ior), float(m.coat_ior)
    eta_bc = n_c / n_b if n_c > n_b else n_b / n_c
    eta = (1.0 - m.coat_weight) * n_b + m.coat_weight * eta_bc
    return modulated_eta(eta, m.specular_weight)


def f82_tint(cos_theta, f0, specular_color) -> np.ndarray:
    """The metal's F82-tint Fresnel (..., 3) (Kutz 2021, the spec's Metal section):
    Schlick(F0) − b μ (1 − μ)⁶, b set so that F(μ̄) = ``specular_color`` Schlick(μ̄)."""
    f0 = np.asarray(f0, dtype=float)
    mu = np.clip(np.asarray(cos_theta, dtype=float), 0.0, 1.0)[..., None]
    schlick = lambda u: f0 + (1.0 - f0) * (1.0 - u) ** 5  # noqa: E731
    b = schlick(MU_BAR) * (1.0 - np.asarray(specular_color, dtype=float)) \
        / (MU_BAR * (1.0 - MU_BAR) ** 6)
    return schlick(mu) - b * mu * (1.0 - mu) ** 6


def coated_roughness(m: OpenPbrMaterial) -> float:
    """The base's roughness under the coat (the spec's "Roughening"):
    lerp(r_B, min(1, r_B⁴ + 2 r_C⁴)^¼, C)."""
    r_b, r_c = float(m.specular_roughness), float(m.coat_roughness)
    widened = min(1.0, r_b ** 4 + 2.0 * r_c ** 4) ** 0.25
    return (1.0 - m.coat_weight) * r_b + m.coat_weight * widened


# ----------------------------------------------------------------- albedo tables --

def _albedo_slab(mu_o: np.ndarray, alpha: float, etas: np.ndarray) -> np.ndarray:
    """E (n_eta + 1, n_μ) of the GGX lobe with the dielectric Fresnel of each ``etas``
    and (last row) F = 1, at viewer cosines ``mu_o``: ∫ F V D 4 μi … by quadrature over
    half vectors drawn by GGX's own CDF (D cos θh dωh = du dφ / 2π)."""
    x, wx = np.polynomial.legendre.leggauss(TABLE_NODES)
    u, wu = 0.5 * (x + 1.0), 0.5 * wx
    phi = (np.arange(TABLE_NODES) + 0.5) * np.pi / TABLE_NODES      # half plane, × 2
    th = np.arctan(alpha * np.sqrt(u / (1.0 - u)))[:, None]
    h = np.stack(np.broadcast_arrays(np.sin(th) * np.cos(phi), np.sin(th) * np.sin(phi),
                                     np.cos(th)), axis=-1).reshape(-1, 3)
    w = np.repeat(wu, TABLE_NODES) / TABLE_NODES
    wo = np.stack([np.sqrt(1.0 - mu_o ** 2), np.zeros_like(mu_o), mu_o], axis=-1)
    oh = wo @ h.T                                                        # (n_μ, n_h)
    mu_i = 2.0 * oh * h[:, 2] - mu_o[:, None]
    ok = (oh > 0.0) & (mu_i > 0.0)
    g = np.where(ok, 4.0 * visibility(mu_i, mu_o[:, None], alpha) * mu_i * oh / h[:, 2], 0.0)
    f = fresnel_dielectric(oh[None], etas[:, None, None])
    return np.concatenate([np.sum(f * g * w, axis=-1), np.sum(g * w, axis=-1)[None]])


def _compute_tables() -> dict[str, np.ndarray]:
    s = TABLE_SQRT_F0
    etas = (1.0 + s) / (1.0 - s)
    out = np.stack([_albedo_slab(TABLE_MU, max(r * r, ALPHA_MIN), etas)
                    for r in TABLE_ROUGHNESS])                           # (n_r, n_s+1, n_μ)
    return {"e_f": out[:, :-1, :], "e_1": out[:, -1, :]}


@lru_cache(maxsize=1)
def albedo_tables() -> dict[str, np.ndarray]:
    """``e_f`` (n_r, n_s, n_μ): directional albedo E(μo) of the GGX lobe with the
    dielectric Fresnel of F0 = s², on :data:`TABLE_ROUGHNESS` × :data:`TABLE_SQRT_F0` ×
    :data:`TABLE_MU`; ``e_1`` (n_r, n_μ) the same with F = 1. Cached on disk."""
    name = (f"openpbr_albedo_v{TABLE_VERSION}_{TABLE_MU.size}x{TABLE_ROUGHNESS.size}x"
            f"{TABLE_SQRT_F0.size}x{TABLE_NODES}.npz")
    shape = (TABLE_ROUGHNESS.size, TABLE_SQRT_F0.size, TABLE_MU.size)
    return cached_arrays(name, _compute_tables,
                         lambda d: d.get("e_f") is not None and d["e_f"].shape == shape)


def _lerp_axis(grid: np.ndarray, value: float) -> tuple[int, float]:
    k = int(np.clip(np.searchsorted(grid, value) - 1, 0, grid.size - 2))
    t = float(np.clip((value - grid[k]) / (grid[k + 1] - grid[k]), 0.0, 1.0))
    return k, t


class _Memo:
    """Values of a pure function of (an array, scalars), kept for the last array seen
    (by identity): the export's fit evaluates the BRDF thousands of times at one sample
    set, most Jacobian columns at the same roughness. Callers never change a value."""

    def __init__(self, size: int = 64):
        self.owner, self.values, self.size = None, {}, size

    def get(self, owner, key, compute):
        if self.owner is not owner:
            self.owner, self.values = owner, {}
        value = self.values.get(key)
        if value is None:
            if len(self.values) >= self.size:
                self.values.clear()
            value = self.values[key] = compute()
        return value


_ALBEDO, _LOBE = _Memo(), _Memo()


def lobe_albedo(mu_o, roughness: float, eta: float | None) -> np.ndarray:
    """E(μo) (...,) of the GGX lobe of ``roughness`` with the dielectric Fresnel of
    ``eta`` (None: F = 1), interpolated in :func:`albedo_tables`."""
    return _ALBEDO.get(mu_o, (float(roughness), None if eta is None else float(eta)),
                       lambda: _lobe_albedo(mu_o, roughness, eta))


def _lobe_albedo(mu_o, roughness: float, eta: float | None) -> np.ndarray:
    t = albedo_tables()
    k, a = _lerp_axis(TABLE_ROUGHNESS, float(roughness))
    if eta is None:
        row = (1.0 - a) * t["e_1"][k] + a * t["e_1"][k + 1]
    else:
        j, b = _lerp_axis(TABLE_SQRT_F0, float(np.sqrt(ior_f0(eta))))
        e = t["e_f"]
        row = ((1 - a) * ((1 - b) * e[k, j] + b * e[k, j + 1])
               + a * ((1 - b) * e[k + 1, j] + b * e[k + 1, j + 1]))
    return np.interp(np.clip(mu_o, TABLE_MU[0], 1.0), TABLE_MU, row)


def compensation(mu_o, roughness: float, f0) -> np.ndarray:
    """Turquin 2019's multiple-scattering factor 1 + F0 (1 − E₁) / E₁ (..., k) at the
    viewer, F0 (k,) the lobe's normal-incidence Fresnel."""
    e1 = lobe_albedo(mu_o, roughness, None)[..., None]
    return 1.0 + np.asarray(f0, dtype=float) * (1.0 - e1) / e1


# -------------------------------------------------------------------------- lobes --

def _lobe(cos: Cosines, roughness: float) -> np.ndarray:
    return _LOBE.get(cos, float(roughness),
                     lambda: specular_brdf(cos, float(roughness) ** 2)[..., None])


def dielectric_lobe(cos: Cosines, roughness: float, eta: float, tint,
                    m: OpenPbrMaterial | None = None) -> tuple:
    """(f (..., 3), E(ωo) (..., 3)) of a compensated GGX dielectric reflection, tinted;
    under ``m``'s thin film (:func:`film_fresnel`) when ``m`` has one."""
    f0 = float(ior_f0(eta))
    comp = compensation(cos.cos_theta_o, roughness, np.array([f0]))
    tint = np.asarray(tint, dtype=float)
    fresnel = film_fresnel(cos, m, fresnel_dielectric(cos.cos_theta_d, eta)[..., None],
                           np.full(3, f0))
    f = tint * fresnel * _lobe(cos, roughness)
    e = tint * (lobe_albedo(cos.cos_theta_o, roughness, eta)[..., None] * comp)
    return f * comp, e


def film_fresnel(cos: Cosines, m: OpenPbrMaterial | None, fresnel, f0) -> np.ndarray:
    """``fresnel`` (..., 3) of a base lobe of normal-incidence reflectance ``f0`` (3,)
    under ``m``'s thin film: lerp(F, F_film, ``thin_film_weight``), F_film the
    Belcour & Barla 2017 two-interface term as KHR_materials_iridescence writes it
    (:func:`gonio_cli.export.gltf_iridescence.iridescent_fresnel`), at the microfacet's
    angle (V·H), from air (the coat's interface with the film left out, as glTF does),
    ``thin_film_thickness`` in µm."""
    if m is None or m.thin_film_weight <= 0.0:
        return fresnel
    film = iridescent_fresnel(cos.cos_theta_d, m.thin_film_ior,
                              1000.0 * float(m.thin_film_thickness), f0)
    return (1.0 - m.thin_film_weight) * fresnel + m.thin_film_weight * film


def coat_transmittance(cos: Cosines, m: OpenPbrMaterial) -> np.ndarray:
    """T_coat (..., 3) = ``coat_color`` ^ ((1/μti + 1/μto)/2) (the spec's view-dependent
    absorption; ``coat_color`` at normal incidence)."""
    inv_n2 = 1.0 / float(m.coat_ior) ** 2
    path = sum(1.0 / np.sqrt(1.0 - (1.0 - np.clip(c, 0.0, 1.0) ** 2) * inv_n2)
               for c in (cos.cos_theta_i, cos.cos_theta_o))
    return np.asarray(m.coat_color, dtype=float) ** (0.5 * path[..., None])


def base_brdf(cos: Cosines, m: OpenPbrMaterial) -> np.ndarray:
    """The base substrate (..., 3): lerp(glossy-diffuse dielectric, F82 metal, M)."""
    r = coated_roughness(m)
    f_spec, e_spec = dielectric_lobe(cos, r, specular_eta(m), m.specular_color, m)
    diffuse = float(m.base_weight) * np.asarray(m.base_color, dtype=float) / np.pi
    dielectric = f_spec + (1.0 - e_spec) * diffuse
    f0 = float(m.base_weight) * np.asarray(m.base_color, dtype=float)
    metal = (float(m.specular_weight)
             * film_fresnel(cos, m, f82_tint(cos.cos_theta_d, f0, m.specular_color), f0)
             * _lobe(cos, r) * compensation(cos.cos_theta_o, r, f0))
    return (1.0 - m.base_metalness) * dielectric + m.base_metalness * metal


def openpbr_brdf(cos: Cosines, m: OpenPbrMaterial) -> np.ndarray:
    """The whole surface (..., 3) sr⁻¹: the base under the coat (module docstring)."""
    f = base_brdf(cos, m)
    if m.coat_weight > 0.0:
        f_coat, e_coat = dielectric_lobe(cos, m.coat_roughness, float(m.coat_ior), (1, 1, 1))
        under = coat_transmittance(cos, m) * (1.0 - e_coat)
        f = m.coat_weight * f_coat + ((1.0 - m.coat_weight) + m.coat_weight * under) * f
    above = (cos.cos_theta_i > COS_EPS) & (cos.cos_theta_o > COS_EPS)
    return np.where(above[..., None], f, 0.0)
