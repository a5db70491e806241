"""The glTF 2.0 metallic-roughness BRDF and its ratified extensions, written once.

What a glTF viewer computes for a material of ``gonio export --to gltf``, so that the
export can be fitted to a gonio material and judged against it (docs/export.md). Every
function is the glTF 2.0 specification's, Appendix B ("BRDF Implementation"), or the
extension's own README, in gonio's geometry (:class:`gonio_cli.geometry.Cosines`; L is
the light ωi, V the viewer ωo, docs/conventions.md):

* ``specular_brdf(α) = V D`` with α = roughness²: Trowbridge–Reitz/GGX D (the same
  function as seed 000 eq. 3, :func:`gonio_cli.brdf.ggx_d`) and the height-correlated
  Smith visibility V = 1 / (2 (|N·V| √(α² + (1 − α²)(N·L)²) + |N·L| √(α² + (1 − α²)(N·V)²)));
* ``metal_brdf = specular_brdf · (baseColor + (1 − baseColor)(1 − |V·H|)⁵)`` (Schlick,
  :func:`gonio_cli.brdf.schlick_fresnel`);
* ``dielectric_brdf = F · specular_brdf + (1 − max(F)) · baseColor / π`` with
  F = specular · Schlick(min(((ior − 1)/(ior + 1))² · specularColor, 1)): the core's
  F0 = 0.04 (ior 1.5, specular 1, specularColor 1) as changed by ``KHR_materials_ior``
  and ``KHR_materials_specular`` (whose ``fresnel_mix`` weights the diffuse base by
  1 − max over the channels);
* ``material = (1 − metallic) · dielectric_brdf + metallic · metal_brdf``;
* ``KHR_materials_iridescence`` (when ``iridescence`` > 0): the extension's
  ``iridescent_conductor_layer`` and ``iridescent_dielectric_layer`` — the metal's
  Schlick F and the dielectric's specular · F mixed by ``iridescence`` with the thin-film
  Fresnel of :func:`gonio_cli.export.gltf_iridescence.iridescent_fresnel` (Belcour &
  Barla 2017 as the extension writes it; F0 the metal's ``baseColor``, the dielectric's
  specular · min(F0(ior) · specularColor, 1)), the dielectric's diffuse base weighted by
  1 − max over the channels of that mix (the extension's ``rgb_mix``);
* ``KHR_materials_clearcoat``: ``mix(material, specular_brdf(clearcoatRoughness²),
  clearcoat · Fc)``, Fc = 0.04 + 0.96 (1 − |N·V|)⁵ (the coat's Fresnel at the *view*
  angle, as the extension writes it: so a coated material is not reciprocal).

Colours are linear sRGB (glTF's colour space for factors); values are BRDFs in sr⁻¹
without the cosine of incidence, shape (..., 3).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from ..brdf import ggx_d, schlick_fresnel
from ..geometry import Cosines
from .gltf_iridescence import iridescent_fresnel

#: The core's dielectric index of refraction (glTF 2.0 Appendix B: F0 = 0.04).
DEFAULT_IOR = 1.5

#: F0 of the clear coat (KHR_materials_clearcoat: ior 1.5, fixed).
CLEARCOAT_F0 = 0.04

#: α below this is raised to it: α = roughness² = 0 makes GGX a delta (the specification
#: says to clamp); 1e-6 keeps D = 1/(π α²) ≈ 3e11 finite and far below float64's range.
ALPHA_MIN = 1e-6

#: Cosines at or below this are below the horizon for the Heaviside factors χ⁺ of the
#: specification (light or viewer behind the surface: the BRDF is 0 there).
COS_EPS = 1e-7


def parameters_dict(material) -> dict:
    """A standard material's parameters as plain JSON numbers (colours as lists), its
    ``name`` left out: what the export report and the writers read."""
    d = asdict(material)
    d.pop("name", None)
    return {k: ([float(x) for x in v] if isinstance(v, (tuple, list)) else float(v))
            for k, v in d.items()}


@dataclass(frozen=True)
class GltfMaterial:
    """The parameters of a glTF 2.0 material with the extensions gonio writes.

    ``base_color``, ``specular_color``: (3,) linear sRGB; the rest scalars, each as the
    glTF property of the same name (``metallicFactor``, ``roughnessFactor``,
    ``specularFactor``, ``ior``, ``clearcoatFactor``, ``clearcoatRoughnessFactor``,
    ``iridescenceFactor``, ``iridescenceIor``; ``iridescence_thickness_nm`` is
    ``iridescenceThicknessMaximum``, the film's thickness without a texture).
    """

    base_color: tuple = (1.0, 1.0, 1.0)
    metallic: float = 1.0
    roughness: float = 1.0
    specular: float = 1.0
    specular_color: tuple = (1.0, 1.0, 1.0)
    ior: float = DEFAULT_IOR
    clearcoat: float = 0.0
    clearcoat_roughness: float = 0.0
    iridescence: float = 0.0
    iridescence_ior: float = 1.3
    iridescence_thickness_nm: float = 400.0
    name: str = field(default="", compare=False)

    def to_dict(self) -> dict:
        return parameters_dict(self)


def ior_f0(ior) -> np.ndarray:
    """((ior − 1)/(ior + 1))², the dielectric F0 from an index of refraction
    (KHR_materials_ior; 0.04 at 1.5). ``ior`` 0 is the extension's "infinite" index: 1."""
    n = np.asarray(ior, dtype=float)
    return np.where(n == 0.0, 1.0, ((n - 1.0) / np.where(n == 0.0, 1.0, n + 1.0)) ** 2)


def f0_ior(f0) -> np.ndarray:
    """The index of refraction whose :func:`ior_f0` is ``f0`` in [0, 1): (1 + √F0)/(1 − √F0)."""
    s = np.sqrt(np.clip(np.asarray(f0, dtype=float), 0.0, None))
    return (1.0 + s) / (1.0 - s)


def visibility(cos_theta_i, cos_theta_o, alpha) -> np.ndarray:
    """Height-correlated Smith visibility V = G / (4 |N·L| |N·V|) (glTF 2.0 Appendix B,
    Heitz 2014), (...,) in sr⁰; 0 where either cosine is at or below :data:`COS_EPS`."""
    ci = np.clip(np.asarray(cos_theta_i, dtype=float), 0.0, 1.0)
    co = np.clip(np.asarray(cos_theta_o, dtype=float), 0.0, 1.0)
    a2 = np.maximum(np.asarray(alpha, dtype=float), ALPHA_MIN) ** 2
    denom = (co * np.sqrt(a2 + (1.0 - a2) * ci * ci)
             + ci * np.sqrt(a2 + (1.0 - a2) * co * co))
    above = (ci > COS_EPS) & (co > COS_EPS)
    return np.where(above, 0.5 / np.where(above, denom, 1.0), 0.0)


def specular_brdf(cos: Cosines, alpha) -> np.ndarray:
    """glTF's ``specular_brdf(α)`` = V D (...,), sr⁻¹ (α the GGX α = roughness²)."""
    a = np.maximum(np.asarray(alpha, dtype=float), ALPHA_MIN)
    return visibility(cos.cos_theta_i, cos.cos_theta_o, a) * ggx_d(cos.cos_theta_h, a)


def dielectric_fresnel(cos_theta_d, specular, specular_color, ior) -> np.ndarray:
    """F (..., 3) of the dielectric BRDF: specular · Schlick(min(F0(ior) · specularColor, 1))
    at cos θd = V·H (KHR_materials_specular with KHR_materials_ior); F90 = specular."""
    f0 = np.minimum(ior_f0(ior) * np.asarray(specular_color, dtype=float), 1.0)
    return float(specular) * schlick_fresnel(cos_theta_d, f0)


def core_brdf(cos: Cosines, m: GltfMaterial) -> np.ndarray:
    """The metallic-roughness material (with KHR_materials_specular, _ior and
    _iridescence), (..., 3)."""
    base = np.asarray(m.base_color, dtype=float)
    lobe = specular_brdf(cos, float(m.roughness) ** 2)[..., None]
    f_d = dielectric_fresnel(cos.cos_theta_d, m.specular, m.specular_color, m.ior)
    f_m = schlick_fresnel(cos.cos_theta_d, base)
    if m.iridescence > 0.0:
        s = float(m.iridescence)
        film = lambda f0: iridescent_fresnel(cos.cos_theta_o, m.iridescence_ior,  # noqa: E731
                                             m.iridescence_thickness_nm, f0)
        f0_d = float(m.specular) * np.minimum(ior_f0(m.ior)
                                              * np.asarray(m.specular_color, dtype=float), 1.0)
        f_d = (1.0 - s) * f_d + s * film(f0_d)
        f_m = (1.0 - s) * f_m + s * film(base)
    dielectric = f_d * lobe + (1.0 - f_d.max(axis=-1, keepdims=True)) * base / np.pi
    f = (1.0 - m.metallic) * dielectric + m.metallic * f_m * lobe
    above = (cos.cos_theta_i > COS_EPS) & (cos.cos_theta_o > COS_EPS)
    return np.where(above[..., None], f, 0.0)


def clearcoat_fresnel(cos_theta_o) -> np.ndarray:
    """Fc = 0.04 + 0.96 (1 − |N·V|)⁵ (...,): KHR_materials_clearcoat's layering weight,
    at the viewer's angle."""
    return schlick_fresnel(cos_theta_o, np.array([CLEARCOAT_F0]))[..., 0]


def gltf_brdf(cos: Cosines, m: GltfMaterial) -> np.ndarray:
    """The whole material: :func:`core_brdf` under KHR_materials_clearcoat, (..., 3) sr⁻¹."""
    f = core_brdf(cos, m)
    if m.clearcoat <= 0.0:
        return f
    w = (float(m.clearcoat) * clearcoat_fresnel(cos.cos_theta_o))[..., None]
    coat = specular_brdf(cos, float(m.clearcoat_roughness) ** 2)[..., None]
    return (1.0 - w) * f + w * coat
