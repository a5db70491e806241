"""KHR_materials_iridescence's thin-film Fresnel term, written once.

The extension (ratified 2022, its specification's "Iridescence Fresnel" section) models a
thin dielectric film on the base as Belcour & Barla 2017 ("A Practical Extension to
Microfacet Theory for the Modeling of Varying Iridescence", ACM TOG 36(4) 65), in the
approximation the specification writes in GLSL and the Khronos glTF Sample Renderer
(``iridescence.glsl``, ``evalIridescence``) runs; :func:`iridescent_fresnel` is that
code line for line in numpy:

* two interfaces, outside → film (``R12`` = Schlick of F0 = ((n_f − n_o)/(n_f + n_o))²
  at cos θ1) and film → base (``R23`` = Schlick of F0 = ((n_b − n_f)/(n_b + n_f))² at
  cos θ2, Snell's law in the film; the base's index from its F0, n_b = (1 + √F0)/(1 −
  √F0), F0 clamped to 0.9999); total internal reflection gives 1;
* the film's index goes to the outside's as the thickness goes to 0 (the Sample
  Renderer's ``mix(outsideIOR, eta2, smoothstep(0, 0.03, thickness))``: no film, no
  effect);
* phase shifts 0 or π per interface (π where the light meets a lower index), the optical
  path difference OPD = 2 n_f d cos θ2 (d in nm);
* the spectral integral in Fourier space: I = R12 + Rs + Σ_{m=1,2} C_m 2 S(m OPD, m φ),
  Rs = T121² R23 / (1 − R12 R23), C_m = (Rs − T121) (R12 R23)^{m/2}, with S the
  sensitivity of CIE XYZ fitted by Gaussians (:func:`eval_sensitivity`) taken to linear
  Rec.709 by the specification's matrix; negative channels clamped to 0.

The angle θ1 is the viewing angle: the specification evaluates "the iridescence Fresnel
for the viewing angle", and the Sample Renderer (as three.js) calls it with N·V once per
shading point; gonio does the same, so the film (like KHR_materials_clearcoat's Fresnel)
depends on the viewer's angle only.
"""

from __future__ import annotations

import numpy as np

#: The specification's XYZ → linear Rec.709 matrix (its GLSL ``mat3`` is column-major).
XYZ_TO_REC709 = np.array([[3.2404542, -1.5371385, -0.4985314],
                          [-0.9692660, 1.8760108, 0.0415560],
                          [0.0556434, -0.2040259, 1.0572252]])

#: Gaussian fits of the CIE XYZ sensitivities in Fourier space (Belcour & Barla 2017,
#: supplemental; the specification's ``evalSensitivity``): amplitude, position, variance.
SENS_VAL = np.array([5.4856e-13, 4.4201e-13, 5.2481e-13])
SENS_POS = np.array([1.6810e+06, 1.7953e+06, 2.2084e+06])
SENS_VAR = np.array([4.3278e+09, 9.3046e+09, 6.6121e+09])
#: The second Gaussian of x̄ (its blue lobe) and the normalisation of the sum.
SENS_X2 = (9.7470e-14, 2.2399e+06, 4.5282e+09)
SENS_NORM = 1.0685e-7

#: Thickness (nm) below which the film fades into the outside medium (smoothstep edge).
FADE_NM = 0.03
#: Largest F0 of the base the model takes (its index stays finite).
BASE_F0_MAX = 0.9999


def schlick(f0, cos_theta):
    """Schlick's Fresnel with F90 = 1, f0 + (1 − f0)(1 − cos θ)⁵ (broadcasting)."""
    return f0 + (1.0 - f0) * (1.0 - np.clip(cos_theta, 0.0, 1.0)) ** 5


def eval_sensitivity(opd_nm, shift) -> np.ndarray:
    """The specification's ``evalSensitivity``: linear Rec.709 (..., 3) of the Fourier
    transform of the XYZ sensitivities at optical path difference ``opd_nm`` (...,) with
    the per-channel phase ``shift`` (..., 3)."""
    phase = (2.0 * np.pi * 1e-9 * np.asarray(opd_nm, dtype=float))[..., None]
    shift = np.asarray(shift, dtype=float)
    xyz = (SENS_VAL * np.sqrt(2.0 * np.pi * SENS_VAR) * np.cos(SENS_POS * phase + shift)
           * np.exp(-phase ** 2 * SENS_VAR))
    a, pos, var = SENS_X2
    x2 = a * np.sqrt(2.0 * np.pi * var) * np.cos(pos * phase[..., 0] + shift[..., 0]) \
        * np.exp(-var * phase[..., 0] ** 2)
    xyz = np.concatenate([(xyz[..., 0] + x2)[..., None], xyz[..., 1:]], axis=-1)
    return (xyz / SENS_NORM) @ XYZ_TO_REC709.T


def iridescent_fresnel(cos_theta1, film_ior, thickness_nm, base_f0,
                       outside_ior: float = 1.0) -> np.ndarray:
    """F_iridescence (..., 3) of KHR_materials_iridescence (module docstring): a film of
    index ``film_ior`` and thickness ``thickness_nm`` on a base of normal-incidence
    reflectance ``base_f0`` (3,) or (..., 3), seen at ``cos_theta1`` (...,) from a medium
    of index ``outside_ior``."""
    c1 = np.clip(np.asarray(cos_theta1, dtype=float), 0.0, 1.0)[..., None]
    d = float(thickness_nm)
    x = min(max(d / FADE_NM, 0.0), 1.0)
    n_o = float(outside_ior)
    n_f = n_o + (float(film_ior) - n_o) * x * x * (3.0 - 2.0 * x)
    c2sq = 1.0 - (n_o / n_f) ** 2 * (1.0 - c1 * c1)
    c2 = np.sqrt(np.maximum(c2sq, 0.0))
    r12 = schlick(((n_f - n_o) / (n_f + n_o)) ** 2, c1)                  # (..., 1)
    t121 = 1.0 - r12
    phi21 = np.pi - (np.pi if n_f < n_o else 0.0)
    s = np.sqrt(np.clip(np.asarray(base_f0, dtype=float), 0.0, BASE_F0_MAX))
    n_b = (1.0 + s) / (1.0 - s)
    r23 = schlick(((n_b - n_f) / (n_b + n_f)) ** 2, c2)                  # (..., 3)
    phi = phi21 + np.where(n_b < n_f, np.pi, 0.0)
    opd = 2.0 * n_f * d * c2[..., 0]
    r123 = np.clip(r12 * r23, 1e-5, 0.9999)
    rs = t121 ** 2 * r23 / (1.0 - r123)
    total = r12 + rs
    cm = rs - t121
    for m in (1, 2):
        cm = cm * np.sqrt(r123)
        total = total + cm * 2.0 * eval_sensitivity(m * opd, m * phi * np.ones_like(total))
    return np.where(c2sq < 0.0, 1.0, np.maximum(total, 0.0))
