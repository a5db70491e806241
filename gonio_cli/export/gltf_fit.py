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
from .standard_fit import ExportFit, FilmStage, Space, fit_standard

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

#: Starts polished on CIEDE2000 (the lowest in the smooth loss; :meth:`Problem.solve`).
POLISHED = 3

#: KHR_materials_iridescence's parameters, appended to :data:`NAMES` for the second
#: stage: ``iridescenceFactor``, ``iridescenceIor`` and the thickness (nm).
FILM_NAMES = ("iridescence", "iridescence_ior", "iridescence_thickness_nm")
#: Film indices searched (the schema's minimum, 1, to a dense oxide's 3) and thicknesses
#: (nm: the first orders of interference in the visible, where the extension's colour is).
FILM_IOR = (1.0, 3.0)
FILM_THICKNESS_NM = (0.0, 1200.0)
#: The grid of films tried on the first stage's material (iridescence 1): indices ×
#: thicknesses; the :data:`FILM_STARTS` best start the second stage.
FILM_GRID_IOR = (1.3, 1.6, 2.0, 2.5)
FILM_GRID_NM = tuple(float(d) for d in range(50, 1001, 25))
FILM_STARTS = 6
#: Of those, the starts continued after :data:`~.standard_fit.SCREEN_NFEV` steps.
FILM_KEEP = 2
#: The film is written only when it lowers the mean CIEDE2000 at the sample set by this.
FILM_GAIN = 0.05

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
    """The :class:`GltfMaterial` of a parameter vector (:data:`NAMES`, and
    :data:`FILM_NAMES` after them when the vector is that long)."""
    f0 = np.asarray(x[6:9], dtype=float)
    top = float(f0.max())
    film = {} if len(x) <= len(NAMES) else dict(zip(FILM_NAMES, (float(v) for v in x[11:14])))
    return GltfMaterial(base_color=tuple(float(v) for v in x[0:3]), metallic=float(x[3]),
                        roughness=float(x[4]), specular=float(x[5]),
                        specular_color=tuple(float(v) for v in (f0 / top if top > 0
                                                                 else np.ones(3))),
                        ior=float(f0_ior(top)) if top > 0 else 1.0,
                        clearcoat=float(x[9]), clearcoat_roughness=float(x[10]), **film)


def starts(base) -> list[np.ndarray]:
    """The vectors of :data:`STARTS` with the base colour ``base`` (3,)."""
    return [np.array([*base, s["metallic"], s["roughness"], 1.0, 0.04, 0.04, 0.04,
                      s["clearcoat"], s["clearcoat_roughness"]], dtype=float)
            for s in STARTS]


def _brdf(cos, x):
    return gltf_brdf(cos, to_material(x))


SPACE = Space(NAMES, LOWER, UPPER, starts, _brdf, to_material, ((0, 1, 2),))
FILM_SPACE = Space(NAMES + FILM_NAMES,
                   np.concatenate([LOWER, [0.0, FILM_IOR[0], FILM_THICKNESS_NM[0]]]),
                   np.concatenate([UPPER, [1.0, FILM_IOR[1], FILM_THICKNESS_NM[1]]]),
                   starts, _brdf, to_material, ((0, 1, 2),))


def plain_variants(x) -> list[np.ndarray]:
    """The first stage's vector ``x`` and its plain dielectric (its base colour and
    roughness, specular 1, F0 0.04, no coat: a film is what tints its lobe then, where
    the first stage had to tint F0)."""
    return [np.asarray(x), np.array([*x[0:3], 0.0, x[4], 1.0, 0.04, 0.04, 0.04, 0.0, x[10]])]


FILM = FilmStage(FILM_SPACE, FILM_GRID_IOR, FILM_GRID_NM, plain_variants,
                 FILM_STARTS, FILM_KEEP, gain=FILM_GAIN)


def fit_gltf(target_rgb: Callable[[Cosines], np.ndarray], directions=None,
             film: bool = True) -> ExportFit:
    """The glTF material closest to ``target_rgb`` (f (..., 3) linear sRGB, sr⁻¹) over
    ``directions`` (default: the fit's hemisphere sample set): the core and its
    extensions from :data:`STARTS`, then (``film``) a KHR_materials_iridescence film
    from the best of a grid, kept when it lowers the mean CIEDE2000 at the sample set
    by :data:`FILM_GAIN` (the material without it then an ``alternative``, which the
    export writes instead if it is closer at the judged configurations)."""
    return fit_standard(target_rgb, SPACE, directions, polish=POLISHED,
                        film=FILM if film else None)
