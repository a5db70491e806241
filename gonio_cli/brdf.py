"""Every reflectance model of gonio, each equation once (STYLE 2).

All models are BRDFs in sr⁻¹ **without** the cosine of incidence (docs/conventions.md): outgoing
radiance is L_o = f · E · cos θi. They take :class:`gonio_cli.geometry.Cosines` of shape
(...,) and spectral parameters of shape (..., n_λ) (wavelength last, STYLE 6), and return
(..., n_λ): geometry broadcasts against the parameters' leading axes, so a single
configuration, a batch of configurations or an image of pixels all work.

Seed 000 (Pranovich et al. 2024): eq. 1 (half vector, in :mod:`gonio_cli.geometry`),
eq. 2 (Torrance–Sparrow), eq. 3 (GGX D), eq. 4 (the goniochromatic term E), eq. 5 (the
goniochromatic BRDF), eq. 6 (cos((θi+θo)/2), in :mod:`gonio_cli.geometry`), eq. 7 (eq. 5
at the mirror configuration). Seed 004 (Ďurikovič & Mihálik 2013): eq. 9 (Beckmann D),
eq. 10 (V-groove G), eq. 11 (Cook–Torrance, also summed over two or three lobes), eq. 12
(Schlick's Fresnel).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from .errors import InputError
from .brdf_surfaces import FIBRE_F0, TABLE_PARAMS, charlie_sheen, table_colour
from .geometry import Cosines, cos_half_sum, refracted_cosines

#: Exponent ceiling for exp(): exp(700) ≈ 1e304 is still finite in float64, so a huge c
#: or a tiny α gives a huge but finite value instead of inf (and inf·0 = NaN downstream).
LOG_MAX = 700.0

#: Cosines below this are treated as grazing (1e-7 rad from the horizon). Used only where a
#: model divides by cos θi cos θo (eq. 2, seed 004 eq. 11); the product stays > 1e-14.
COS_EPS = 1e-7


#: The ¼ of seed 000 eq. (5), f = D/4 · E: the microfacet denominator 4 cos θi cos θo with
#: the paper's implicit G = cos θi cos θo. Every form of eq. (5) takes it from here
#: (:func:`log_goniochromatic_d4`, :func:`goniochromatic_d4`, :func:`goniochromatic_d4_into`).
EQ5_QUARTER = 0.25

#: log 4 = −log :data:`EQ5_QUARTER`, subtracted in the log form of eq. (5).
LOG4 = float(np.log(4.0))


def _col(x) -> np.ndarray:
    """Geometry (...,) → (..., 1) so it broadcasts against spectra (..., n_λ)."""
    return np.asarray(x, dtype=float)[..., None]


# --------------------------------------------------------------------------- seed 000 --

def ggx_d(cos_theta_h, alpha) -> np.ndarray:
    """GGX / Trowbridge–Reitz normal distribution, seed 000 eq. (3), in sr⁻¹.

    D = α² / (π ((α² − 1) cos²θh + 1)²). ``cos_theta_h``: (...,) cosine of the half angle;
    ``alpha``: scalar or broadcastable roughness in (0, 1] (the GGX α, not squared again).
    Normalised so that ∫ D cos θh dω = 1 over the hemisphere.
    """
    return np.exp(log_ggx_d(cos_theta_h, alpha))


def ggx_d_into(cos_theta_h, alpha: float, scratch) -> np.ndarray:
    """:func:`ggx_d` in the input's dtype, into buffers from ``scratch(name, n)`` (the
    renderer's float32 hot path): D = α² / (π (α² cos²θh + sin²θh)²), seed 000
    eq. (3), sin²θh = (1 − cos θh)(1 + cos θh) (no cancellation at cos θh → 1); cos θh in
    [0, 1], α ≥ 0.05 in float32 (the renderer's ``FLOAT32_MIN_ALPHA``) (D ≤ 1/(π α²), no overflow)."""
    m = cos_theta_h.shape[0]
    t = cos_theta_h.dtype.type
    a2 = alpha * alpha
    d = np.multiply(cos_theta_h, cos_theta_h, out=scratch("ggx", m))
    d *= t(a2)
    s = np.subtract(t(1), cos_theta_h, out=scratch("ggx_s", m))
    u = np.add(cos_theta_h, t(1), out=scratch("ggx_u", m))
    s *= u
    d += s
    d *= d
    return np.divide(t(a2 / np.pi), d, out=d)


def log_ggx_d(cos_theta_h, alpha) -> np.ndarray:
    """log of seed 000 eq. (3), finite for α down to 1e-150 and at cos θh = 1.

    The denominator (α² − 1) cos²θh + 1 = α² cos²θh + sin²θh is written in that form,
    which has no cancellation when α is tiny and cos θh → 1.
    """
    ch = np.clip(np.asarray(cos_theta_h, dtype=float), 0.0, 1.0)
    a2 = np.asarray(alpha, dtype=float) ** 2
    sin2 = (1.0 - ch) * (1.0 + ch)  # exact near cos θh = 1, unlike 1 − cos²
    denom = a2 * ch * ch + sin2
    return np.log(a2) - np.log(np.pi) - 2.0 * np.log(denom)


def goniochromatic_exponent_arg(cos_theta_i, cos_theta_o) -> np.ndarray:
    """1 − cos((θi + θo)/2), the factor c(λ) multiplies in seed 000 eq. (4)."""
    return 1.0 - cos_half_sum(cos_theta_i, cos_theta_o)


def goniochromatic_exponent_arg_into(cos_theta_i, cos_theta_o, scratch) -> np.ndarray:
    """:func:`goniochromatic_exponent_arg` in the inputs' dtype, into buffers from
    ``scratch(name, n)`` (the renderer's float32 hot path): x = 1 − cos((θi+θo)/2)
    = 1 − (√((1 + cos θi)(1 + cos θo)) − √((1 − cos θi)(1 − cos θo)))/2 (seed 000 eq. 6),
    cosines in [0, 1] (as :func:`gonio_cli.geometry.cosines_from_dots_into` leaves them)."""
    m = cos_theta_i.shape[0]
    one = cos_theta_i.dtype.type(1)
    p = np.add(cos_theta_i, one, out=scratch("x", m))
    q = np.add(cos_theta_o, one, out=scratch("x_q", m))
    p *= q
    np.sqrt(p, out=p)
    np.subtract(one, cos_theta_i, out=q)
    r = np.subtract(one, cos_theta_o, out=scratch("x_r", m))
    q *= r
    np.sqrt(q, out=q)
    p -= q
    p *= cos_theta_i.dtype.type(-0.5)
    p += one
    return p


def log_goniochromatic_d4(cos_theta_h, alpha) -> np.ndarray:
    """log(D(θh; α)/4), the part of log f of seed 000 eq. (5) that depends on α and not on
    λ: log f = this + log ρ(λ) + c(λ) x. ``cos_theta_h`` (...,), ``alpha`` broadcastable
    against it (the fits pass (G, 1) trial values). Returns (...,), finite for α > 0."""
    return log_ggx_d(cos_theta_h, alpha) - LOG4


def goniochromatic_d4(cos_theta_h, alpha) -> np.ndarray:
    """D(θh; α)/4 of seed 000 eq. (5) (sr⁻¹, (...,)), capped at exp(:data:`LOG_MAX`):
    f = this · ρ(λ) exp(c(λ) x), linear in ρ (the layered fit's column)."""
    return np.exp(np.minimum(log_goniochromatic_d4(cos_theta_h, alpha), LOG_MAX))


def goniochromatic_d4_into(cos_theta_h, alpha: float, scratch) -> np.ndarray:
    """:func:`goniochromatic_d4` in the input's dtype, into a buffer of ``scratch`` (the
    renderer's float32 hot path): :func:`ggx_d_into` times :data:`EQ5_QUARTER`. The
    conditions of :func:`ggx_d_into` apply (α ≥ 0.05 in float32: no cap needed)."""
    d = ggx_d_into(cos_theta_h, alpha, scratch)
    d *= d.dtype.type(EQ5_QUARTER)
    return d


def log_goniochromatic(cos: Cosines, alpha, rho, c) -> np.ndarray:
    """log f of seed 000 eq. (5); −inf where ρ = 0. Shape (..., n_λ)."""
    x = _col(goniochromatic_exponent_arg(cos.cos_theta_i, cos.cos_theta_o))
    with np.errstate(divide="ignore"):
        log_rho = np.log(np.asarray(rho, dtype=float))
    return (_col(log_goniochromatic_d4(cos.cos_theta_h, alpha)) + log_rho
            + np.asarray(c, dtype=float) * x)


def goniochromatic(cos: Cosines, alpha, rho, c) -> np.ndarray:
    """The goniochromatic microfacet BRDF, seed 000 eq. (5), in sr⁻¹ (no cos θi factor).

    f = α² ρ(λ) exp(c(λ)(1 − cos((θi+θo)/2))) / (4π((α² − 1)cos²θh + 1)²)
      = D(θh) / 4 · E(θi, θo, λ)   with D of eq. (3) and E of eq. (4),

    and cos((θi+θo)/2) from eq. (6). ``cos``: :class:`Cosines` (...,); ``alpha``: scalar;
    ``rho``, ``c``: (..., n_λ). Returns (..., n_λ), finite for any finite input.
    """
    return np.exp(np.minimum(log_goniochromatic(cos, alpha, rho, c), LOG_MAX))


def goniochromatic_mirror(cos_theta_i, alpha, rho, c) -> np.ndarray:
    """Seed 000 eq. (7): eq. (5) at the mirror configuration ωo = mirror of ωi.

    f = ρ(λ) exp(c(λ)(1 − cos θi)) / (4π α²). ``cos_theta_i``: (...,). Returns (..., n_λ).
    """
    x = 1.0 - _col(cos_theta_i)
    with np.errstate(divide="ignore"):
        log_rho = np.log(np.asarray(rho, dtype=float))
    log_f = (log_rho + np.asarray(c, dtype=float) * x
             - np.log(4.0 * np.pi * np.asarray(alpha, dtype=float) ** 2))
    return np.exp(np.minimum(log_f, LOG_MAX))


def smith_g1_ggx(cos_theta, alpha) -> np.ndarray:
    """Smith masking G1 for GGX (Walter et al. 2007, seed 000 ref. 12).

    G1 = 2 cos θ / (cos θ + sqrt(α² + (1 − α²) cos²θ)); 0 at grazing, 1 at normal.
    """
    ct = np.clip(np.asarray(cos_theta, dtype=float), 0.0, 1.0)
    a2 = np.asarray(alpha, dtype=float) ** 2
    denom = ct + np.sqrt(a2 + (1.0 - a2) * ct * ct)  # ≥ α > 0 unless α = cos θ = 0
    return 2.0 * ct / np.maximum(denom, COS_EPS)


def smith_g_ggx(cos: Cosines, alpha) -> np.ndarray:
    """Separable Smith shadowing-masking G = G1(ωi) G1(ωo) for GGX."""
    return smith_g1_ggx(cos.cos_theta_i, alpha) * smith_g1_ggx(cos.cos_theta_o, alpha)


def schlick_fresnel(cos_theta, f0) -> np.ndarray:
    """Schlick's Fresnel, seed 004 eq. (12) (seed 000 ref. 26): F0 + (1 − F0)(1 − cos θ)⁵.

    ``cos_theta``: (...,); ``f0``: (..., n_λ) reflectance at normal incidence in [0, 1].
    """
    m = _col((1.0 - np.clip(np.asarray(cos_theta, dtype=float), 0.0, 1.0)) ** 5)
    f0 = np.asarray(f0, dtype=float)
    return f0 + (1.0 - f0) * m


def torrance_sparrow(cos: Cosines, alpha, f0) -> np.ndarray:
    """The "standard model" of seed 000: Torrance–Sparrow, eq. (2), with GGX D (eq. 3),
    separable Smith G and Schlick's F(cos θd), in sr⁻¹.

    f = F(cos θd, λ) G D / (4 cos θi cos θo). Zero where either cosine is below
    :data:`COS_EPS` (G vanishes there faster than the denominator).
    """
    return schlick_fresnel(cos.cos_theta_d, f0) * _col(ggx_lobe(cos, alpha))


def ggx_lobe(cos: Cosines, alpha) -> np.ndarray:
    """G D / (4 cos θi cos θo) (...,), sr⁻¹: the Torrance–Sparrow lobe of seed 000 eq. (2)
    without its Fresnel factor (GGX D of eq. 3, separable Smith G), so F · this is
    :func:`torrance_sparrow`. Zero where either cosine is below :data:`COS_EPS`."""
    ci, co = cos.cos_theta_i, cos.cos_theta_o
    valid = ~((ci <= COS_EPS) | (co <= COS_EPS))  # NaN cosines stay NaN, not 0
    return np.where(valid, smith_g_ggx(cos, alpha) * ggx_d(cos.cos_theta_h, alpha)
                    / (4.0 * np.maximum(ci, COS_EPS) * np.maximum(co, COS_EPS)), 0.0)


# --------------------------------------------------------------------------- seed 004 --

def beckmann_d(cos_theta_h, m) -> np.ndarray:
    """Beckmann distribution as written in seed 004 eq. (9): exp(−tan²θh/m²)/(m² cos⁴θh).

    ``m``: RMS microfacet slope, scalar or (..., n_λ) (per wavelength in seed 004 §5.2);
    ``cos_theta_h``: (...,). Returns the broadcast of ``cos_theta_h[..., None]`` and ``m``.
    The 1/π of the normalised Beckmann D sits in eq. (11)'s denominator instead.
    """
    ch = _col(np.clip(np.asarray(cos_theta_h, dtype=float), COS_EPS, 1.0))
    m2 = np.asarray(m, dtype=float) ** 2
    tan2 = (1.0 - ch * ch) / (ch * ch)
    return np.exp(-tan2 / m2) / (m2 * ch ** 4)


def vgroove_g(cos: Cosines) -> np.ndarray:
    """Cook–Torrance V-groove shadowing/masking, seed 004 eq. (10).

    G = min(1, 2 (H·N)(V·N)/(V·H), 2 (H·N)(L·N)/(V·H)); V·H = L·H = cos θd.
    """
    vh = np.maximum(cos.cos_theta_d, COS_EPS)
    g = np.minimum(2.0 * cos.cos_theta_h * cos.cos_theta_o / vh,
                   2.0 * cos.cos_theta_h * cos.cos_theta_i / vh)
    return np.clip(g, 0.0, 1.0)


def cook_torrance_specular_geometry(cos: Cosines, m) -> np.ndarray:
    """D G / (π cos θi cos θo) of seed 004 eq. (11), (..., n_λ); zero at grazing."""
    ci, co = cos.cos_theta_i, cos.cos_theta_o
    valid = ~((ci <= COS_EPS) | (co <= COS_EPS))  # NaN cosines stay NaN, not 0
    geo = np.where(valid, vgroove_g(cos) / (np.pi * np.maximum(ci, COS_EPS)
                                            * np.maximum(co, COS_EPS)), 0.0)
    return beckmann_d(cos.cos_theta_h, m) * _col(geo)


def cook_torrance(cos: Cosines, kd, ks, m, f0) -> np.ndarray:
    """Cook–Torrance BRDF of seed 004 eq. (11), in sr⁻¹:

    f = kd/π + ks F(θ) D G / (π cos θi cos θo),

    D of eq. (9), G of eq. (10), F of eq. (12) at θ = the angle between L and H (θd).
    ``kd``, ``ks``, ``m``, ``f0``: (..., n_λ), all per wavelength as in seed 004 §5.2.
    """
    kd = np.asarray(kd, dtype=float)
    spec = np.asarray(ks, dtype=float) * schlick_fresnel(cos.cos_theta_d, f0)
    return kd / np.pi + spec * cook_torrance_specular_geometry(cos, m)


def cook_torrance_lobes(cos: Cosines, kd, f0, lobes) -> np.ndarray:
    """Cook–Torrance with several Beckmann lobes (a clear coat and flake lobes), sr⁻¹:

    f = kd(λ)/π + Σ_j ks_j F(θd; F0(λ)) D(θh; m_j) G / (π cos θi cos θo),

    seed 004 eq. (11) per lobe (:func:`cook_torrance` with kd = 0 for every lobe after the
    first), one spectral F0 shared by the lobes. ``kd``, ``f0``: (..., n_λ); ``lobes``:
    [(ks_j, m_j)] scalars.
    """
    (ks, m), rest = lobes[0], lobes[1:]
    f = cook_torrance(cos, kd, float(ks), float(m), f0)
    for ks, m in rest:
        f = f + cook_torrance(cos, 0.0, float(ks), float(m), f0)
    return f


def cook_torrance_2(cos: Cosines, kd, f0, ks_1, m_1, ks_2, m_2) -> np.ndarray:
    """:func:`cook_torrance_lobes` with two lobes (``cook-torrance-2``), m_1 ≤ m_2."""
    return cook_torrance_lobes(cos, kd, f0, ((ks_1, m_1), (ks_2, m_2)))


def cook_torrance_3(cos: Cosines, kd, f0, ks_1, m_1, ks_2, m_2, ks_3, m_3) -> np.ndarray:
    """:func:`cook_torrance_lobes` with three lobes (``cook-torrance-3``), m_1 ≤ m_2 ≤ m_3."""
    return cook_torrance_lobes(cos, kd, f0, ((ks_1, m_1), (ks_2, m_2), (ks_3, m_3)))


# ------------------------------------------------------------------ real surfaces --

def lambertian(rho_d) -> np.ndarray:
    """A Lambertian term ρ_d(λ)/π in sr⁻¹ (paper, binder, a diffuse base coat)."""
    return np.asarray(rho_d, dtype=float) / np.pi


def goniochromatic_diffuse(cos: Cosines, alpha, rho, c, rho_d) -> np.ndarray:
    """Seed 000 eq. (5) plus a Lambertian term: f = ρ_d(λ)/π + eq. 5(α, ρ, c), sr⁻¹.

    The structural-colour layer over a diffusely reflecting substrate or binder. ``rho_d``:
    (..., n_λ) diffuse albedo; the rest as :func:`goniochromatic`.
    """
    return lambertian(rho_d) + goniochromatic(cos, alpha, rho, c)


def goniochromatic_coat(cos: Cosines, alpha, rho, c, rho_d, alpha_coat, k_coat,
                        f0_coat) -> np.ndarray:
    """Seed 000 eq. (5), a Lambertian term and an achromatic clear coat, sr⁻¹:

    f = ρ_d(λ)/π + eq. 5(α, ρ, c) + k_coat F(θd; F0_coat) G D(θh; α_coat) / (4 cos θi cos θo),

    the coat a Torrance–Sparrow lobe (:func:`torrance_sparrow`, GGX D, Smith G, Schlick F)
    with one F0 for every wavelength (a clear dielectric over the colour-shifting layer:
    F0 = ((n − 1)/(n + 1))², 0.04 for n = 1.5) and a scale ``k_coat`` (1 for a coat that
    covers the sample and reflects as a smooth dielectric; less for a partial or thin one).
    """
    coat = torrance_sparrow(cos, alpha_coat, np.atleast_1d(np.asarray(f0_coat, dtype=float)))
    return goniochromatic_diffuse(cos, alpha, rho, c, rho_d) + float(k_coat) * coat


def opposition_surge(cos_theta_d, b0, h) -> np.ndarray:
    """Hapke's shadow-hiding opposition effect (Hapke 1986; *Theory of Reflectance and
    Emittance Spectroscopy*, 2nd ed. 2012, eq. 9.22): B(g) = B0 / (1 + tan(g/2)/h).

    g is the phase angle, between the directions to the light and to the viewer
    (ωi·ωo = cos g; g = 0 at retro-reflection), so g/2 = θd and tan(g/2) = tan θd: the
    light's own shadows in a porous layer are hidden from a viewer beside the light.
    ``b0`` ≥ 0 the amplitude (B0 ≤ 1 for shadow hiding alone), ``h`` > 0 the angular width
    (the half width at half maximum of the surge is g ≈ 2h rad for small h; h grows with
    the layer's porosity). Written B0 h cos θd / (h cos θd + sin θd): finite everywhere,
    B0 at retro-reflection, 0 at cos θd = 0. ``cos_theta_d``: (...,). Returns (...,).
    """
    cd = np.clip(np.asarray(cos_theta_d, dtype=float), 0.0, 1.0)
    sd = np.sqrt((1.0 - cd) * (1.0 + cd))
    hc = float(h) * cd
    return float(b0) * hc / np.maximum(hc + sd, COS_EPS)


def backscatter_diffuse(cos: Cosines, rho_d, b0, h) -> np.ndarray:
    """A diffuse body with the opposition effect: ρ_d(λ)/π · (1 + B(g)), sr⁻¹, B of
    :func:`opposition_surge` (achromatic: it multiplies the body reflection, as in Hapke's
    model where it multiplies the single-scattering term). ``rho_d``: (..., n_λ)."""
    return lambertian(rho_d) * _col(1.0 + opposition_surge(cos.cos_theta_d, b0, h))


def goniochromatic_backscatter(cos: Cosines, alpha, rho, c, rho_d, alpha_coat, k_coat,
                               f0_coat, b0, h) -> np.ndarray:
    """:func:`goniochromatic_coat` whose diffuse term has the opposition effect, sr⁻¹:

    f = ρ_d(λ)/π (1 + B0/(1 + tan(g/2)/h)) + eq. 5(α, ρ, c) + the clear coat,

    for matte, porous pigment layers (a binder's surface reflection is the coat), B of
    :func:`opposition_surge`; with B0 = 0 it is :func:`goniochromatic_coat`.
    """
    coat = goniochromatic_coat(cos, alpha, rho, c, np.zeros_like(np.asarray(rho_d, float)),
                               alpha_coat, k_coat, f0_coat)
    return backscatter_diffuse(cos, rho_d, b0, h) + coat


#: Refractive index of the clear layer over ``goniochromatic-undercoat``'s colour layer:
#: clear coats, binders, varnishes and waxes are 1.45–1.6; 1.5 gives F0 = 0.04.
UNDERCOAT_INDEX = 1.5


def coat_transmission(cos: Cosines, n: float = UNDERCOAT_INDEX) -> np.ndarray:
    """T(θi) T(θo) (...,): the share of light a smooth layer of index ``n`` lets in at θi
    and out at θo, T = 1 − F with Schlick's F (seed 004 eq. 12) at F0 = ((n − 1)/(n + 1))²."""
    f0 = np.array([((n - 1.0) / (n + 1.0)) ** 2])
    return ((1.0 - schlick_fresnel(cos.cos_theta_i, f0)[..., 0])
            * (1.0 - schlick_fresnel(cos.cos_theta_o, f0)[..., 0]))


def goniochromatic_undercoat(cos: Cosines, alpha, rho, c, rho_d, alpha_coat, k_coat,
                             f0_coat) -> np.ndarray:
    """Seed 000 eq. (5) and a Lambertian term *under* a clear coat, seen through it, sr⁻¹:

    f = T(θi) T(θo) [ρ_d(λ)/π + eq. 5(α, ρ, c) at θi', θo'] + the coat of
    :func:`goniochromatic_coat`,

    θ' the directions refracted into the coat (index :data:`UNDERCOAT_INDEX`, Snell;
    :func:`gonio_cli.geometry.refracted_cosines`) and T = 1 − F the Fresnel transmission
    in and out (:func:`coat_transmission`). This is how a colour layer under a clear coat
    is seen (the car-paint models of Ershov et al. 2001 and Rump et al. 2008 evaluate the
    flake layer at the refracted angles): at grazing incidence the coat reflects more and
    lets less through, and the layer sees the light at ≤ 42°, so the grazing highlight is
    the coat's colour, not the layer's. Radiance crossing the interface in and out gives
    f = T T f_inner / n²; the constant 1/n² is taken into ρ and ρ_d. Reciprocal (every
    factor is symmetric in θi, θo); with T ≤ 1 the layer's share is never more than its own.
    """
    under = goniochromatic_diffuse(refracted_cosines(cos, UNDERCOAT_INDEX), alpha, rho, c,
                                   rho_d)
    coat = torrance_sparrow(cos, alpha_coat, np.atleast_1d(np.asarray(f0_coat, dtype=float)))
    return _col(coat_transmission(cos)) * under + float(k_coat) * coat


def goniochromatic_two_lobe(cos: Cosines, alpha, rho, c, rho_d, alpha_2, rho_2) -> np.ndarray:
    """Seed 000 eq. (5), a Lambertian term and a second, coloured GGX lobe, sr⁻¹:

    f = ρ_d(λ)/π + eq. 5(α, ρ, c) + ρ_2(λ) G D(θh; α_2) / (4 cos θi cos θo),

    the second lobe a Torrance–Sparrow lobe (seed 000 eq. 2; GGX D, separable Smith G,
    :func:`ggx_lobe`) whose Fresnel factor is a reflectance ρ_2(λ) of its own, constant in
    angle, as a coloured conductor's (Mitsuba's ``roughconductor`` with a
    ``specular_reflectance``). Two superposed microfacet populations of different
    roughness and colour — a sharp lobe of one colour near the mirror over a broad one of
    another off it, as in a blend of two coloured metals or interference pigments over
    coloured flakes (Ngan et al. 2005 fit measured BRDFs with two specular lobes; here
    each has its own colour) — which no model with an achromatic coat can show. Linear in
    ρ_d, ρ and ρ_2: for fixed α, α_2 and c(λ) each wavelength is a three-column
    non-negative least-squares problem. Reciprocal (every factor is symmetric in θi, θo).
    """
    return (goniochromatic_diffuse(cos, alpha, rho, c, rho_d)
            + np.asarray(rho_2, dtype=float) * _col(ggx_lobe(cos, alpha_2)))


def sheen(cos: Cosines, r_sheen, alpha, k_spec, rho_d, rho_sheen) -> np.ndarray:
    """Fabric (felt, satin), sr⁻¹: ρ_d(λ)/π + ρ_sheen(λ) D V (the Charlie sheen,
    :func:`gonio_cli.brdf_surfaces.charlie_sheen`) + k_spec :func:`torrance_sparrow` (α, 0.04)."""
    return (lambertian(rho_d) + np.asarray(rho_sheen, dtype=float) * _col(charlie_sheen(
        cos, r_sheen, COS_EPS)) + float(k_spec) * torrance_sparrow(cos, alpha, FIBRE_F0))


def tabulated_colour(cos: Cosines, alpha, rho_d, colour_table, theta_h_nodes_deg,
                     theta_d_nodes_deg) -> np.ndarray:
    """ρ_d/π + T(θh, θd, λ) :func:`ggx_lobe` (α) in sr⁻¹, T of :mod:`.brdf_surfaces`."""
    t = table_colour(cos, colour_table, theta_h_nodes_deg, theta_d_nodes_deg)
    return lambertian(rho_d) + t * _col(ggx_lobe(cos, alpha))


# ----------------------------------------------------------------------------- registry --

@dataclass(frozen=True)
class Model:
    """A reflectance model: its name, parameters and evaluation.

    ``scalar_params`` are wavelength independent (e.g. ``alpha``), ``spectral_params`` are
    (n_λ,) arrays, ``table_params`` a table (n_h, n_d, n_λ) and its nodes; ``evaluate(cos,
    **params)`` returns f in sr⁻¹, shape (..., n_λ)."""
    name: str
    scalar_params: tuple[str, ...]
    spectral_params: tuple[str, ...]
    evaluate: Callable[..., np.ndarray]
    citation: str
    table_params: tuple[str, ...] = ()


MODELS: dict[str, Model] = {
    "goniochromatic": Model("goniochromatic", ("alpha",), ("rho", "c"), goniochromatic,
                            "seed 000 eq. 5"),
    "torrance-sparrow": Model("torrance-sparrow", ("alpha",), ("f0",), torrance_sparrow,
                              "seed 000 eq. 2 with GGX D, Smith G, Schlick F"),
    "cook-torrance": Model("cook-torrance", (), ("kd", "ks", "m", "f0"), cook_torrance,
                           "seed 004 eqs. 9-12"),
    "goniochromatic-diffuse": Model("goniochromatic-diffuse", ("alpha",), ("rho", "c", "rho_d"),
                                    goniochromatic_diffuse, "seed 000 eq. 5 + Lambertian"),
    "goniochromatic-coat": Model("goniochromatic-coat",
                                 ("alpha", "alpha_coat", "k_coat", "f0_coat"),
                                 ("rho", "c", "rho_d"), goniochromatic_coat,
                                 "seed 000 eq. 5 + Lambertian + GGX clear coat"),
    "goniochromatic-backscatter": Model(
        "goniochromatic-backscatter",
        ("alpha", "alpha_coat", "k_coat", "f0_coat", "b0", "h"), ("rho", "c", "rho_d"),
        goniochromatic_backscatter,
        "seed 000 eq. 5 + Lambertian with Hapke's opposition effect + GGX clear coat"),
    "goniochromatic-undercoat": Model(
        "goniochromatic-undercoat", ("alpha", "alpha_coat", "k_coat", "f0_coat"),
        ("rho", "c", "rho_d"), goniochromatic_undercoat,
        "seed 000 eq. 5 + Lambertian under a GGX clear coat, at refracted angles"),
    "goniochromatic-two-lobe": Model(
        "goniochromatic-two-lobe", ("alpha", "alpha_2"), ("rho", "c", "rho_d", "rho_2"),
        goniochromatic_two_lobe,
        "seed 000 eq. 5 + Lambertian + a coloured GGX Torrance-Sparrow lobe (seed 000 eq. 2, "
        "F = rho_2(lambda))"),
    "cook-torrance-2": Model("cook-torrance-2", ("ks_1", "m_1", "ks_2", "m_2"), ("kd", "f0"),
                             cook_torrance_2, "seed 004 eqs. 9-12, two Beckmann lobes"),
    "cook-torrance-3": Model("cook-torrance-3", ("ks_1", "m_1", "ks_2", "m_2", "ks_3", "m_3"),
                             ("kd", "f0"), cook_torrance_3,
                             "seed 004 eqs. 9-12, three Beckmann lobes"),
    "sheen": Model("sheen", ("r_sheen", "alpha", "k_spec"), ("rho_d", "rho_sheen"), sheen,
                   "Lambertian + Charlie sheen (Estevez & Kulla 2017; KHR_materials_sheen) + GGX"),
    "tabulated-colour": Model("tabulated-colour", ("alpha",), ("rho_d",), tabulated_colour,
                              "Lambertian + GGX lobe x (theta_h, theta_d) table (AxF CPA2)",
                              TABLE_PARAMS),
}


def evaluate(model: str, cos: Cosines, params: dict) -> np.ndarray:
    """Evaluate a registered model by name with a parameter dict (as in a material)."""
    if model not in MODELS:
        raise InputError(f"unknown model {model!r}", fix=f"use one of {', '.join(MODELS)}")
    spec = MODELS[model]
    kwargs = {k: params[k] for k in spec.scalar_params + spec.spectral_params
              + spec.table_params}
    return spec.evaluate(cos, **kwargs)
