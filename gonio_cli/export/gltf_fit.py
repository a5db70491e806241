"""Choose a glTF material for a gonio material: glTF's parameters as a fit space.

``gonio export --to gltf`` fits glTF's own BRDF (:mod:`gonio_cli.export.gltf_brdf`) to the
material with the loop every standard target shares
(:func:`gonio_cli.export.standard_fit.fit_standard`: where, what and how close); this
module says what is fitted: :data:`NAMES` between :data:`LOWER` and :data:`UPPER`, from
the starts of :data:`STARTS`.

The dielectric F0 is fitted as one colour ``f0`` in [0, :data:`F0_MAX`]; it is written as
KHR_materials_ior's ``ior`` (whose F0 is the largest channel) and
KHR_materials_specular's ``specularColorFactor`` (``f0`` over that channel, in [0, 1]).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..geometry import Cosines
from .gltf_brdf import GltfMaterial, f0_ior, gltf_brdf
from .standard_fit import ExportFit, Space, fit_standard

#: Smallest roughness searched (α = roughness² ≥ 1e-4): below, the lobe is narrower than
#: any half-vector sample of the fit's directions (0.25°) and cannot be fitted.
ROUGHNESS_MIN = 0.01

#: Largest dielectric F0 searched (ior ≈ 38): a dielectric that reflects more is a metal.
F0_MAX = 0.9

#: The parameter vector: its names (in order) and bounds.
NAMES = ("base_r", "base_g", "base_b", "metallic", "roughness", "specular",
         "f0_r", "f0_g", "f0_b", "clearcoat", "clearcoat_roughness")
LOWER = np.array([0, 0, 0, 0, ROUGHNESS_MIN, 0, 0, 0, 0, 0, ROUGHNESS_MIN], dtype=float)
UPPER = np.array([1, 1, 1, 1, 1, 1, F0_MAX, F0_MAX, F0_MAX, 1, 1], dtype=float)

#: Fixed starts (base colour from the material): a plastic, a rough and a smooth metal,
#: and a plastic under a smooth and a hazy clear coat.
STARTS = (
    dict(metallic=0.0, roughness=0.5, clearcoat=0.0, clearcoat_roughness=0.3),
    dict(metallic=1.0, roughness=0.5, clearcoat=0.0, clearcoat_roughness=0.3),
    dict(metallic=1.0, roughness=0.2, clearcoat=0.0, clearcoat_roughness=0.3),
    dict(metallic=0.0, roughness=0.5, clearcoat=1.0, clearcoat_roughness=0.1),
    dict(metallic=0.0, roughness=0.5, clearcoat=1.0, clearcoat_roughness=0.35),
)


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


def starts(base) -> list[np.ndarray]:
    """The vectors of :data:`STARTS` with the base colour ``base`` (3,)."""
    return [np.array([*base, s["metallic"], s["roughness"], 1.0, 0.04, 0.04, 0.04,
                      s["clearcoat"], s["clearcoat_roughness"]], dtype=float)
            for s in STARTS]


SPACE = Space(NAMES, LOWER, UPPER, starts, lambda cos, x: gltf_brdf(cos, to_material(x)),
              to_material)


def fit_gltf(target_rgb: Callable[[Cosines], np.ndarray], directions=None) -> ExportFit:
    """The glTF material closest to ``target_rgb`` (f (..., 3) linear sRGB, sr⁻¹) over
    ``directions`` (default: the fit's hemisphere sample set)."""
    return fit_standard(target_rgb, SPACE, directions)
