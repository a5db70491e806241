"""gonio's reflectance models in Dr.Jit: the port of :mod:`gonio_cli.brdf` that the exported
Mitsuba 3 plugin evaluates (``gonio export --to mitsuba``).

Written once, here, and copied verbatim next to the plugin (it imports nothing of gonio,
only ``drjit``), so a folder made by ``gonio export`` renders without gonio installed.
Each function names the numpy function of :mod:`gonio_cli.brdf` (or
:mod:`gonio_cli.geometry`) it ports and keeps its equation, argument names and
convention: a BRDF in sr⁻¹ **without** the cosine of incidence (docs/conventions.md).
``tests/test_export_mitsuba.py`` evaluates both on random directions and parameters and
asserts they agree to float32 precision, which keeps the two from drifting apart.

Arguments are Dr.Jit values of any flavour the active Mitsuba variant uses: Python floats
(scalar variants), ``Float`` arrays (LLVM), and for spectral parameters ``Spectrum``
values (the parameter at the wavelengths a path carries) or Python floats (one grid
wavelength at a time, as the plugin's RGB path sums them). Geometry broadcasts against
the spectral parameters the way ``(...,)`` broadcasts against ``(..., n_λ)`` in numpy.
The cosines are the four of :class:`gonio_cli.geometry.Cosines`, clamped to [0, 1].

Float32 differences from the float64 numpy versions, on purpose:

* exp() overflows float32 above ~88, so seed 000 eq. 5's exponent is capped at
  :data:`EXP_MAX` (numpy caps its log at 700 for float64);
* GGX D is computed directly, D = α² / (π (α² cos²θh + sin²θh)²) (as
  ``brdf.ggx_d_into``, the renderer's float32 form), not through its logarithm.
"""

from __future__ import annotations

import drjit as dr

#: Same as ``gonio_cli.brdf.COS_EPS``: cosines below it are grazing where a model divides by
#: cos θi cos θo (eq. 2, seed 004 eq. 11).
COS_EPS = 1e-7

#: exp(EXP_MAX) ≈ 5.5e34 is finite in float32 (its maximum is 3.4e38, exp(88.7)); the
#: numpy form caps the log at 700 for float64 (``gonio_cli.brdf.LOG_MAX``).
EXP_MAX = 80.0

INV_PI = 1.0 / dr.pi


def _clip01(x):
    return dr.clip(x, 0.0, 1.0)


# --------------------------------------------------------------------------- seed 000 --

def cos_half_sum(cos_theta_i, cos_theta_o):
    """cos((θi + θo)/2), seed 000 eq. (6); port of ``gonio_cli.geometry.cos_half_sum``."""
    ci, co = _clip01(cos_theta_i), _clip01(cos_theta_o)
    return 0.5 * (dr.sqrt((1.0 + ci) * (1.0 + co)) - dr.sqrt((1.0 - ci) * (1.0 - co)))


def goniochromatic_exponent_arg(cos_theta_i, cos_theta_o):
    """x = 1 − cos((θi + θo)/2) of seed 000 eq. (4); port of
    ``gonio_cli.brdf.goniochromatic_exponent_arg``."""
    return 1.0 - cos_half_sum(cos_theta_i, cos_theta_o)


def ggx_d(cos_theta_h, alpha):
    """GGX D, seed 000 eq. (3), sr⁻¹; port of ``gonio_cli.brdf.ggx_d``:
    D = α² / (π (α² cos²θh + sin²θh)²), sin²θh = (1 − cos θh)(1 + cos θh)."""
    ch = _clip01(cos_theta_h)
    a2 = alpha * alpha
    denom = a2 * ch * ch + (1.0 - ch) * (1.0 + ch)
    return a2 * INV_PI / (denom * denom)


def goniochromatic(cos, alpha, rho, c):
    """Seed 000 eq. (5): f = D(θh; α)/4 · ρ(λ) exp(c(λ) x), sr⁻¹; port of
    ``gonio_cli.brdf.goniochromatic``. ``cos``: (cos θi, cos θo, cos θh, cos θd)."""
    ci, co, ch, _ = cos
    x = goniochromatic_exponent_arg(ci, co)
    return (0.25 * ggx_d(ch, alpha)) * rho * dr.exp(dr.minimum(c * x, EXP_MAX))


def smith_g1_ggx(cos_theta, alpha):
    """Smith G1 for GGX (Walter et al. 2007); port of ``gonio_cli.brdf.smith_g1_ggx``."""
    ct = _clip01(cos_theta)
    a2 = alpha * alpha
    denom = ct + dr.sqrt(a2 + (1.0 - a2) * ct * ct)
    return 2.0 * ct / dr.maximum(denom, COS_EPS)


def schlick_fresnel(cos_theta, f0):
    """Schlick's Fresnel, seed 004 eq. (12); port of ``gonio_cli.brdf.schlick_fresnel``."""
    m = 1.0 - _clip01(cos_theta)
    m2 = m * m
    return f0 + (1.0 - f0) * (m2 * m2 * m)


def _valid(ci, co):
    """Both cosines above :data:`COS_EPS` (``brdf.torrance_sparrow``'s ``valid``)."""
    return (ci > COS_EPS) & (co > COS_EPS)


def ggx_lobe(cos, alpha):
    """G D / (4 cos θi cos θo), zero at grazing; port of ``gonio_cli.brdf.ggx_lobe``."""
    ci, co, ch, _ = cos
    geo = (smith_g1_ggx(ci, alpha) * smith_g1_ggx(co, alpha) * ggx_d(ch, alpha)
           / (4.0 * dr.maximum(ci, COS_EPS) * dr.maximum(co, COS_EPS)))
    return dr.select(_valid(ci, co), geo, 0.0)


def torrance_sparrow(cos, alpha, f0):
    """Seed 000 eq. (2) with GGX D, Smith G, Schlick F(cos θd): F G D / (4 cos θi cos θo);
    port of ``gonio_cli.brdf.torrance_sparrow``."""
    return schlick_fresnel(cos[3], f0) * ggx_lobe(cos, alpha)


# --------------------------------------------------------------------------- seed 004 --

def beckmann_d(cos_theta_h, m):
    """Beckmann D as seed 004 eq. (9), exp(−tan²θh/m²)/(m² cos⁴θh) (the 1/π is in eq. 11);
    port of ``gonio_cli.brdf.beckmann_d``."""
    ch = dr.clip(cos_theta_h, COS_EPS, 1.0)
    c2 = ch * ch
    m2 = m * m
    return dr.exp(-((1.0 - c2) / c2) / m2) / (m2 * c2 * c2)


def vgroove_g(cos):
    """Cook–Torrance V-groove G, seed 004 eq. (10); port of ``gonio_cli.brdf.vgroove_g``."""
    ci, co, ch, cd = cos
    vh = dr.maximum(cd, COS_EPS)
    return _clip01(dr.minimum(2.0 * ch * co / vh, 2.0 * ch * ci / vh))


def cook_torrance_specular_geometry(cos, m):
    """D G / (π cos θi cos θo) of seed 004 eq. (11); port of
    ``gonio_cli.brdf.cook_torrance_specular_geometry``."""
    ci, co, ch, _ = cos
    geo = vgroove_g(cos) * INV_PI / (dr.maximum(ci, COS_EPS) * dr.maximum(co, COS_EPS))
    return beckmann_d(ch, m) * dr.select(_valid(ci, co), geo, 0.0)


def cook_torrance(cos, kd, ks, m, f0):
    """Seed 004 eq. (11): kd/π + ks F(θd) D G / (π cos θi cos θo); port of
    ``gonio_cli.brdf.cook_torrance``."""
    return (kd * INV_PI
            + ks * schlick_fresnel(cos[3], f0) * cook_torrance_specular_geometry(cos, m))


def cook_torrance_lobes(cos, kd, f0, lobes):
    """Cook–Torrance with Beckmann lobes [(ks_j, m_j)] and one F0; port of
    ``gonio_cli.brdf.cook_torrance_lobes``."""
    (ks, m), rest = lobes[0], lobes[1:]
    f = cook_torrance(cos, kd, ks, m, f0)
    for ks, m in rest:
        f = f + cook_torrance(cos, 0.0, ks, m, f0)
    return f


def cook_torrance_2(cos, kd, f0, ks_1, m_1, ks_2, m_2):
    """Port of ``gonio_cli.brdf.cook_torrance_2``."""
    return cook_torrance_lobes(cos, kd, f0, ((ks_1, m_1), (ks_2, m_2)))


def cook_torrance_3(cos, kd, f0, ks_1, m_1, ks_2, m_2, ks_3, m_3):
    """Port of ``gonio_cli.brdf.cook_torrance_3``."""
    return cook_torrance_lobes(cos, kd, f0, ((ks_1, m_1), (ks_2, m_2), (ks_3, m_3)))


# ------------------------------------------------------------------ real surfaces --

def lambertian(rho_d):
    """ρ_d/π; port of ``gonio_cli.brdf.lambertian``."""
    return rho_d * INV_PI


def goniochromatic_diffuse(cos, alpha, rho, c, rho_d):
    """ρ_d/π + seed 000 eq. (5); port of ``gonio_cli.brdf.goniochromatic_diffuse``."""
    return lambertian(rho_d) + goniochromatic(cos, alpha, rho, c)


def goniochromatic_coat(cos, alpha, rho, c, rho_d, alpha_coat, k_coat, f0_coat):
    """ρ_d/π + eq. (5) + k_coat · Torrance–Sparrow(α_coat, F0_coat); port of
    ``gonio_cli.brdf.goniochromatic_coat``."""
    return (goniochromatic_diffuse(cos, alpha, rho, c, rho_d)
            + k_coat * torrance_sparrow(cos, alpha_coat, f0_coat))


def opposition_surge(cos_theta_d, b0, h):
    """Hapke's shadow-hiding opposition effect B0 / (1 + tan θd / h); port of
    ``gonio_cli.brdf.opposition_surge``."""
    cd = _clip01(cos_theta_d)
    sd = dr.sqrt((1.0 - cd) * (1.0 + cd))
    hc = h * cd
    return b0 * hc / dr.maximum(hc + sd, COS_EPS)


def goniochromatic_backscatter(cos, alpha, rho, c, rho_d, alpha_coat, k_coat, f0_coat, b0, h):
    """ρ_d/π (1 + B(g)) + eq. (5) + the clear coat; port of
    ``gonio_cli.brdf.goniochromatic_backscatter``."""
    return (lambertian(rho_d) * (1.0 + opposition_surge(cos[3], b0, h))
            + goniochromatic_coat(cos, alpha, rho, c, 0.0, alpha_coat, k_coat, f0_coat))


#: Same as ``gonio_cli.brdf.UNDERCOAT_INDEX``: the clear coat's refractive index.
UNDERCOAT_INDEX = 1.5


def refracted_cosines(cos, n):
    """The four cosines of both directions refracted into a layer of index ``n`` (Snell);
    port of ``gonio_cli.geometry.refracted_cosines`` (through ``cosines_from_dots``)."""
    ci, co, _, cd = cos
    inv_n2 = 1.0 / (n * n)
    ci_r = dr.sqrt(dr.maximum(1.0 - (1.0 - ci * ci) * inv_n2, 0.0))
    co_r = dr.sqrt(dr.maximum(1.0 - (1.0 - co * co) * inv_n2, 0.0))
    dot = (2.0 * cd * cd - 1.0 - ci * co) * inv_n2 + ci_r * co_r
    sq = 2.0 + 2.0 * dot
    safe = sq > 1e-12
    inv = dr.rsqrt(dr.select(safe, sq, 1.0))
    ch = dr.select(safe, (ci_r + co_r) * inv, 1.0)
    cd_r = dr.select(safe, (1.0 + dot) * inv, ci_r)
    return _clip01(ci_r), _clip01(co_r), _clip01(ch), _clip01(cd_r)


def coat_transmission(cos, n=UNDERCOAT_INDEX):
    """T(θi) T(θo) = (1 − F(θi))(1 − F(θo)), Schlick at F0 = ((n − 1)/(n + 1))²; port of
    ``gonio_cli.brdf.coat_transmission``."""
    f0 = ((n - 1.0) / (n + 1.0)) ** 2
    return (1.0 - schlick_fresnel(cos[0], f0)) * (1.0 - schlick_fresnel(cos[1], f0))


def goniochromatic_undercoat(cos, alpha, rho, c, rho_d, alpha_coat, k_coat, f0_coat):
    """T T [ρ_d/π + eq. (5)] at the refracted angles + the clear coat; port of
    ``gonio_cli.brdf.goniochromatic_undercoat``."""
    under = goniochromatic_diffuse(refracted_cosines(cos, UNDERCOAT_INDEX), alpha, rho, c,
                                   rho_d)
    return coat_transmission(cos) * under + k_coat * torrance_sparrow(cos, alpha_coat, f0_coat)


def goniochromatic_two_lobe(cos, alpha, rho, c, rho_d, alpha_2, rho_2):
    """ρ_d/π + eq. (5) + ρ_2 G D(α_2) / (4 cos θi cos θo); port of
    ``gonio_cli.brdf.goniochromatic_two_lobe``."""
    return goniochromatic_diffuse(cos, alpha, rho, c, rho_d) + rho_2 * ggx_lobe(cos, alpha_2)


#: The models by ``gonio_cli.brdf.MODELS`` name, with the same keyword parameters.
MODELS = {
    "goniochromatic": goniochromatic,
    "torrance-sparrow": torrance_sparrow,
    "cook-torrance": cook_torrance,
    "goniochromatic-diffuse": goniochromatic_diffuse,
    "goniochromatic-coat": goniochromatic_coat,
    "goniochromatic-backscatter": goniochromatic_backscatter,
    "goniochromatic-undercoat": goniochromatic_undercoat,
    "goniochromatic-two-lobe": goniochromatic_two_lobe,
    "cook-torrance-2": cook_torrance_2,
    "cook-torrance-3": cook_torrance_3,
}


def cosines(wi, wo):
    """(cos θi, cos θo, cos θh, cos θd) of two unit directions in the local frame (normal
    +z), as ``gonio_cli.geometry.cosines``: ωh = (ωi + ωo)/‖ωi + ωo‖ (seed 000 eq. 1), the
    normal where ωi + ωo vanishes. ``wi``, ``wo``: anything with ``.x``, ``.y``, ``.z``
    (Mitsuba's ``Vector3f``)."""
    sx, sy, sz = wi.x + wo.x, wi.y + wo.y, wi.z + wo.z
    n2 = sx * sx + sy * sy + sz * sz
    safe = n2 > 1e-12  # as ``geometry.HALF_SQ_EPS``: below it ωo = −ωi, never lit and seen
    inv = dr.rsqrt(dr.select(safe, n2, 1.0))
    ch = dr.select(safe, sz * inv, 1.0)
    cd = dr.select(safe, (wi.x * sx + wi.y * sy + wi.z * sz) * inv, wi.z)
    return _clip01(wi.z), _clip01(wo.z), _clip01(ch), _clip01(cd)
