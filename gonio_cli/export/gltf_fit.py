"""Choose a glTF material for a gonio material: a least-squares fit of glTF's own BRDF.

A glTF material cannot hold a spectral, goniochromatic BRDF, so ``gonio export --to gltf``
chooses the parameters of :mod:`gonio_cli.export.gltf_brdf` whose reflectance is closest
to the material's over the hemisphere (:func:`fit_gltf`), rather than mapping one
parameter onto another:

* **Where.** :func:`hemisphere_directions`: lights at θi = 0–80°, and for each a fan of
  half vectors (θh from 0 to 75°, dense near 0 where a clear coat's peak is a degree
  wide; five azimuths over the half plane y ≥ 0, the materials being symmetric about the
  plane of incidence); the viewer is the light mirrored about the half vector. In-plane
  configurations are the φh = 0 and 180° rows.
* **What.** Both BRDFs as linear sRGB reflectance factors R = π f under D65 (the
  material's spectrum through the same weights as the Mitsuba export's RGB variants,
  :func:`gonio_cli.export.mitsuba.rgb_weights`; glTF's factors are linear sRGB).
* **How close.** Residuals in the cube root of R (L*'s response), per channel, each pair
  scaled by 1 / max(1, Y) of the material's R (a highlight counts by its relative error,
  as the judgement's CIEDE2000 does); ``scipy.optimize.least_squares`` (trust region,
  bounded) from the fixed starts of :data:`STARTS`, the best kept: deterministic.

The dielectric F0 is fitted as one colour ``f0`` in [0, :data:`F0_MAX`]; it is written as
KHR_materials_ior's ``ior`` (whose F0 is the largest channel) and
KHR_materials_specular's ``specularColorFactor`` (``f0`` over that channel, in [0, 1]).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..geometry import Cosines, cosines, in_plane_directions
from .gltf_brdf import GltfMaterial, f0_ior, gltf_brdf

#: Residuals are colour differences in units of this (10 → 1): only for the solver's
#: scaling, the optimum does not depend on it.
DE_UNIT = 10.0
#: Evaluations of the last step, the best start polished on CIEDE2000 itself (not smooth
#: where a difference is 0, so the smooth stand-in does the search).
POLISH_NFEV = 60
#: CIE94's (and CIEDE2000's) chroma weight: S_C = 1 + 0.045 C* (CIE 116-1995).
CHROMA_WEIGHT = 0.045

#: Smallest roughness searched (α = roughness² ≥ 1e-4): below, the lobe is narrower than
#: any half-vector sample of :func:`hemisphere_directions` (0.25°) and cannot be fitted.
ROUGHNESS_MIN = 0.01

#: Largest dielectric F0 searched (ior ≈ 38): a dielectric that reflects more is a metal.
F0_MAX = 0.9

#: Light angles θi (degrees) of the fit's sample set.
THETA_I_DEG = (0.0, 10.0, 20.0, 30.0, 40.0, 50.0, 60.0, 70.0, 80.0)
#: Half-vector polar angles θh (degrees): dense near the mirror for sharp lobes.
THETA_H_DEG = (0.0, 0.25, 0.5, 1.0, 1.5, 2.0, 3.0, 4.5, 6.5, 9.0, 12.0, 16.0, 21.0, 27.0,
               34.0, 42.0, 51.0, 62.0, 75.0)
#: Half-vector azimuths (degrees) from the plane of incidence, towards +y.
PHI_H_DEG = (0.0, 45.0, 90.0, 135.0, 180.0)
#: In-plane viewers (degrees, signed as docs/conventions.md) added for every θi: the
#: plane a goniometer measures in, where the export is judged (:mod:`.judge`).
THETA_O_DEG = tuple(float(t) for t in range(-85, 86, 5))
#: A viewer closer to the horizon than this (cos θo) is left out of the fit (86°; an
#: instrument's last angle is 85°).
COS_O_MIN = float(np.cos(np.radians(86.0)))

#: The parameter vector: its names (in order) and bounds.
NAMES = ("base_r", "base_g", "base_b", "metallic", "roughness", "specular",
         "f0_r", "f0_g", "f0_b", "clearcoat", "clearcoat_roughness")
LOWER = np.array([0, 0, 0, 0, ROUGHNESS_MIN, 0, 0, 0, 0, 0, ROUGHNESS_MIN], dtype=float)
UPPER = np.array([1, 1, 1, 1, 1, 1, F0_MAX, F0_MAX, F0_MAX, 1, 1], dtype=float)

#: Fixed starts (base colour from the material where ``None``): a plastic, a rough and a
#: smooth metal, and a plastic under a smooth and a hazy clear coat.
STARTS = (
    dict(metallic=0.0, roughness=0.5, clearcoat=0.0, clearcoat_roughness=0.3),
    dict(metallic=1.0, roughness=0.5, clearcoat=0.0, clearcoat_roughness=0.3),
    dict(metallic=1.0, roughness=0.2, clearcoat=0.0, clearcoat_roughness=0.3),
    dict(metallic=0.0, roughness=0.5, clearcoat=1.0, clearcoat_roughness=0.1),
    dict(metallic=0.0, roughness=0.5, clearcoat=1.0, clearcoat_roughness=0.35),
)


def hemisphere_directions() -> tuple[np.ndarray, np.ndarray]:
    """(ωi, ωo), each (N, 3): the fit's sample set (module docstring), light on the −x
    side as in docs/conventions.md, viewers below :data:`COS_O_MIN` left out."""
    ti = np.radians(np.asarray(THETA_I_DEG))[:, None, None]
    th = np.radians(np.asarray(THETA_H_DEG))[None, :, None]
    ph = np.radians(np.asarray(PHI_H_DEG))[None, None, :]
    ti, th, ph = np.broadcast_arrays(ti, th, ph)
    wi = np.stack([-np.sin(ti), np.zeros_like(ti), np.cos(ti)], axis=-1)
    wh = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=-1)
    wo = 2.0 * np.sum(wi * wh, axis=-1, keepdims=True) * wh - wi
    pi, po = in_plane_directions(np.asarray(THETA_I_DEG)[:, None], np.asarray(THETA_O_DEG))
    wi = np.concatenate([wi.reshape(-1, 3), pi.reshape(-1, 3)])
    wo = np.concatenate([wo.reshape(-1, 3), po.reshape(-1, 3)])
    keep = wo[:, 2] > COS_O_MIN
    return wi[keep], wo[keep]


def material_rgb(material) -> Callable[[Cosines], np.ndarray]:
    """f (..., 3) of a :class:`gonio_cli.schemas.Material` as linear sRGB under D65."""
    from .mitsuba import rgb_weights

    w = rgb_weights(np.asarray(material.wavelength_nm, dtype=float)).T     # (n_λ, 3)
    return lambda cos: material.evaluate(cos) @ w


def rgb_to_xyz(rgb) -> np.ndarray:
    """XYZ (..., 3) of linear sRGB (..., 3) (the inverse of the conventions' matrix)."""
    from ..spectra import xyz_to_linear_srgb_matrix

    return np.asarray(rgb, dtype=float) @ np.linalg.inv(xyz_to_linear_srgb_matrix()).T


def perceived(r_ref) -> Callable[[np.ndarray], np.ndarray]:
    """L*a*b* (..., 3) of linear-sRGB reflectance factors, each configuration scaled by
    1 / max(1, Y) of ``r_ref`` (..., 3) there (the judgement's scaling of a highlight,
    as `gonio fit`'s verdict does), white D65 (sRGB's (1, 1, 1))."""
    from ..spectra import xyz_to_lab

    scale = (1.0 / np.maximum(1.0, rgb_to_xyz(r_ref)[..., 1]))[..., None]
    white = rgb_to_xyz(np.ones(3))
    return lambda rgb: xyz_to_lab(rgb_to_xyz(rgb) * scale, white)


def to_material(x) -> GltfMaterial:
    """The :class:`GltfMaterial` of a parameter vector (:data:`NAMES`)."""
    f0 = np.asarray(x[6:9], dtype=float)
    top = float(f0.max())
    return GltfMaterial(base_color=tuple(float(v) for v in x[0:3]), metallic=float(x[3]),
                        roughness=float(x[4]), specular=float(x[5]),
                        specular_color=tuple(float(v) for v in (f0 / top if top > 0
                                                                 else np.ones(3))),
                        ior=float(f0_ior(top)) if top > 0 else 1.0,
                        clearcoat=float(x[9]), clearcoat_roughness=float(x[10]))


def _start(s: dict, base) -> np.ndarray:
    x = np.array([*base, s["metallic"], s["roughness"], 1.0, 0.04, 0.04, 0.04,
                  s["clearcoat"], s["clearcoat_roughness"]], dtype=float)
    return np.clip(x, LOWER, UPPER)


@dataclass
class GltfFit:
    """The fitted glTF material and how it was obtained (STYLE 9)."""

    material: GltfMaterial
    success: bool
    message: str
    evaluations: int
    rms_residual: float         # RMS of the cube-root residuals at the optimum
    samples: int
    starts: int
    time_s: float

    def to_dict(self) -> dict:
        return {"success": self.success, "message": self.message,
                "evaluations": self.evaluations, "rms_cube_root_residual": self.rms_residual,
                "samples": self.samples, "starts": self.starts, "time_s": self.time_s,
                "optimizer": "scipy.optimize.least_squares (trf, bounded)"}


def fit_gltf(target_rgb: Callable[[Cosines], np.ndarray], directions=None) -> GltfFit:
    """The glTF material closest to ``target_rgb`` (f (..., 3) linear sRGB, sr⁻¹) over
    ``directions`` ((ωi, ωo), default :func:`hemisphere_directions`); module docstring."""
    from scipy.optimize import least_squares

    from ..spectra import delta_e_2000

    t0 = time.perf_counter()
    wi, wo = directions if directions is not None else hemisphere_directions()
    cos = cosines(wi, wo)
    r_t = np.pi * np.asarray(target_rgb(cos), dtype=float)             # (N, 3)
    lab = perceived(r_t)
    lab_t = lab(r_t)
    # CIE94's chroma weighting S_C = 1 + 0.045 C* of the material's colour on a* and b*: a
    # smooth stand-in for CIEDE2000, which discounts chroma differences of vivid colours
    w = np.ones_like(lab_t)
    w[:, 1:] = 1.0 / (1.0 + CHROMA_WEIGHT * np.hypot(lab_t[:, 1], lab_t[:, 2]))[:, None]

    def residuals(x):
        return (w * (lab(np.pi * gltf_brdf(cos, to_material(x))) - lab_t) / DE_UNIT).ravel()

    # a Lambertian base colour's first guess: the material's R at θi = 0, far off the mirror
    far = (cos.cos_theta_h < np.cos(np.radians(40.0))) & (cos.cos_theta_h > 0.5)
    base = np.clip(np.median(r_t[far], axis=0) if far.any() else np.full(3, 0.5), 0.0, 1.0)
    best, evaluations = None, 0
    for s in STARTS:
        res = least_squares(residuals, _start(s, base), bounds=(LOWER, UPPER), method="trf",
                            x_scale="jac", max_nfev=400)
        evaluations += int(res.nfev)
        if best is None or res.cost < best.cost:
            best = res

    def residuals_2000(x):
        return delta_e_2000(lab_t, lab(np.pi * gltf_brdf(cos, to_material(x)))) / DE_UNIT

    polished = least_squares(residuals_2000, best.x, bounds=(LOWER, UPPER), method="trf",
                             x_scale="jac", max_nfev=POLISH_NFEV)
    evaluations += int(polished.nfev)
    best = polished
    rms = float(np.sqrt(2.0 * best.cost / best.fun.size))
    return GltfFit(to_material(best.x), bool(best.success), str(best.message), evaluations,
                   rms, int(cos.cos_theta_i.size), len(STARTS), time.perf_counter() - t0)
