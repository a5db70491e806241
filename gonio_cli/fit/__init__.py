"""``gonio fit``: reflectance models fitted to a measurement (seed 000, seed 004).

The registry :data:`FITTERS` maps a model name (``--model``) to its fitter; each takes
:class:`~.common.FitData` and :class:`~.common.FitOptions` and returns a
:class:`~.common.ModelFit` with one :class:`~.common.FitReport` per method.

- ``goniochromatic`` (default): seed 000 eq. 5; :mod:`.goniochromatic`
- ``torrance-sparrow``: seed 000 eq. 2 with GGX, Smith G, Schlick F0(λ); :mod:`.torrance_sparrow`
- ``cook-torrance``: seed 004 eqs. 9–12 per wavelength; :mod:`.cook_torrance`
"""

from __future__ import annotations

from typing import Callable

from ..errors import InputError
from ..schemas import Material
from . import cook_torrance, goniochromatic, torrance_sparrow
from .common import FitData, FitOptions, ModelFit

FITTERS: dict[str, Callable[[FitData, FitOptions], ModelFit]] = {
    "goniochromatic": goniochromatic.fit,
    "torrance-sparrow": torrance_sparrow.fit,
    "cook-torrance": cook_torrance.fit,
}


def fit(data: FitData, model: str = "goniochromatic",
        options: FitOptions | None = None) -> ModelFit:
    """Fit ``model`` (a key of :data:`FITTERS`) to prepared data."""
    if model not in FITTERS:
        raise InputError(f"--model {model!r} is unknown", fix=f"use one of {', '.join(FITTERS)}")
    return FITTERS[model](data, options or FitOptions())


def to_material(result: ModelFit) -> Material:
    """The material artifact's content: final parameters plus every method's report."""
    return Material(result.model, result.wavelength_nm, dict(result.params),
                    result.result.status,
                    {"final": result.final, "excluded": result.excluded,
                     "methods": {k: r.to_dict() for k, r in result.reports.items()}})
