"""What covers one scene object in the shading (:class:`Surface`: a material, a print's
inks and substrate, the lobes or lobe tables of its environment light, its sparkles), and
the checks a surface passes before it is shaded."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from ..errors import InputError
from ..spectra import same_grid


#: Keys of a substrate dict (seed 000 Figure 8's Phong term).
SUBSTRATE_KEYS = ("kd", "ks", "shininess", "spectrum")


# ----------------------------------------------------------------------------- surface --

@dataclass
class Surface:
    """What covers one scene object.

    Attributes
    ----------
    material : a fitted :class:`~gonio_cli.schemas.Material`, or a measured reference
        (anything with ``evaluate_directions(wi, wo, normal) -> (..., n_λ)`` in sr⁻¹,
        :class:`gonio_cli.render.measured.MeasuredMaterial`). None for a printed object.
    inks : three materials (R, G, B ink), for a printed object.
    coverage : callable ``(uv (..., 2), footprint (...,)) -> (..., 3)``, the area-filtered
        coverage of the three inks in [0, 1] (part A's ``MaskPyramid.coverage``).
    substrate : None (black paper) or ``{"kd": .., "ks": .., "shininess": ..,
        "spectrum": (n_λ,) reflectance (optional, default 1)}``, the dim Phong term.
    lobes : a :class:`~gonio_cli.schemas.Lobes` (or one per ink for a printed object),
        needed only under environment light by ``env_method`` "lobes" (seed 001 eqs. 7-9).
    env_method : "lobes" or "model" (:data:`gonio_cli.render.ENVIRONMENT_METHODS`).
    env_tables : for "model", one list of :class:`gonio_cli.render.env_model.LobeTable`
        per material (one, or three inks).
    name : for messages.
    sparkle : a :class:`gonio_cli.sparkle.SparkleTexture` or None (seed 004 eq. 17; a
        material or measured object only).
    glint : a :class:`gonio_cli.glint.GlintLayer` or None (a cook-torrance material
        only), with ``glint_view`` (:class:`gonio_cli.render.glint_term.GlintView`) and
        ``glint_cache`` (its lobe tables per light spectrum, filled by the shading).
    """

    material: Any = None
    inks: Sequence[Any] | None = None
    coverage: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None
    substrate: dict | None = None
    lobes: Any = None
    name: str = ""
    sparkle: Any = None
    env_method: str = "lobes"
    env_tables: Any = None
    glint: Any = None
    glint_view: Any = None
    glint_cache: dict = field(default_factory=dict)

    @property
    def printed(self) -> bool:
        return self.inks is not None


def check_surface(surface: Surface, index: int, wavelength_nm: np.ndarray) -> None:
    """Refuse an incomplete surface, naming the object; validate the substrate dict."""
    where = f"object {index}" + (f" ({surface.name})" if surface.name else "")
    if surface.printed:
        if surface.material is not None:
            raise InputError(f"{where} has both a material and inks", fix="give one of them")
        if len(surface.inks) != 3:
            raise InputError(f"{where} has {len(surface.inks)} inks, not 3 (R, G, B)")
        if surface.coverage is None:
            raise InputError(f"{where} is printed but has no coverage (mask)")
        materials = list(surface.inks)
    else:
        if surface.material is None:
            raise InputError(f"{where} has neither a material nor inks")
        materials = [surface.material]
    if surface.sparkle is not None and surface.printed:
        raise InputError(f"{where} is printed: sparkles need a material",
                         fix="give the sparkle texture to a material object")
    if surface.glint is not None and (surface.printed or surface.glint_view is None):
        raise InputError(f"{where}: glints need a material and the camera's view",
                         fix="give glint_density to a material object")
    for m in materials:
        wl = getattr(m, "wavelength_nm", None)
        if wl is not None and not _same_grid(wl, wavelength_nm):
            raise InputError(f"{where}: a material is on a {np.size(wl)}-sample spectral grid, "
                             f"the render on {wavelength_nm.size}",
                             fix="resample the material onto the render's grid when loading")
    if surface.substrate is not None:
        unknown = sorted(set(surface.substrate) - set(SUBSTRATE_KEYS))
        if unknown:
            raise InputError(f"{where}: unknown substrate key(s) {', '.join(unknown)}",
                             fix=f"allowed: {', '.join(SUBSTRATE_KEYS)}")
        for key in ("kd", "ks", "shininess"):
            v = surface.substrate.get(key, 0.0)
            if not (np.isfinite(v) and v >= 0):
                raise InputError(f"{where}: substrate {key}={v!r} is not a number ≥ 0")


def _same_grid(a, b) -> bool:
    return same_grid(a, b)
