"""Every model of :data:`gonio_cli.brdf.MODELS` written as the sum of its lobes.

A layered material reflects light in distinct lobes: a diffuse body about the normal, and
one glossy lobe per microfacet population (seed 000 eq. 5's structural-colour lobe, a
clear coat, a second coloured lobe, Cook–Torrance's Beckmann lobes), each about the mirror
direction with a width of its own. Environment light treats each lobe separately
(:mod:`gonio_cli.render.env_model`): a coat of α = 0.02 reflects the sky as sharply as its
lobe says, while the body under it reflects a blurred sky.

Each entry of :data:`COMPONENTS` takes a material's parameters and returns its
:class:`Component` list, whose values add up to :func:`gonio_cli.brdf.evaluate` exactly
(``tests/test_env_model.py`` checks every model): the lobes are the model's own terms,
evaluated by the functions of :mod:`gonio_cli.brdf`, never written again here.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import brdf
from .errors import InputError
from .geometry import Cosines, refracted_cosines

#: A lobe about the normal (diffuse bodies; its environment light is the irradiance map).
DIFFUSE = "diffuse"
#: A lobe about the mirror direction (microfacet populations).
GLOSSY = "glossy"


@dataclass(frozen=True)
class Component:
    """One lobe of a material: ``name`` (for messages and reports), ``kind``
    (:data:`DIFFUSE` or :data:`GLOSSY`) and ``evaluate(cos) -> (..., n_λ)`` in sr⁻¹
    (no cos θi factor), the lobe's share of f."""

    name: str
    kind: str
    evaluate: Callable[[Cosines], np.ndarray]


def _diffuse(rho_d) -> Component:
    rho_d = np.asarray(rho_d, dtype=float)
    return Component("diffuse", DIFFUSE,
                     lambda cos: np.broadcast_to(brdf.lambertian(rho_d),
                                                 np.shape(cos.cos_theta_i) + rho_d.shape[-1:]))


def _eq5(p: dict, name: str = "eq5") -> Component:
    return Component(name, GLOSSY,
                     lambda cos: brdf.goniochromatic(cos, p["alpha"], p["rho"], p["c"]))


def _coat(p: dict) -> Component:
    f0 = np.atleast_1d(np.asarray(p["f0_coat"], dtype=float))
    return Component("coat", GLOSSY, lambda cos: float(p["k_coat"]) * brdf.torrance_sparrow(
        cos, p["alpha_coat"], f0))


def _goniochromatic(p):
    return [_eq5(p)]


def _torrance_sparrow(p):
    return [Component("specular", GLOSSY,
                      lambda cos: brdf.torrance_sparrow(cos, p["alpha"], p["f0"]))]


def _cook_torrance_lobes(kd, f0, lobes) -> list[Component]:
    out = [_diffuse(kd)]
    for j, (ks, m) in enumerate(lobes):
        out.append(Component(f"specular_{j + 1}" if len(lobes) > 1 else "specular", GLOSSY,
                             lambda cos, ks=ks, m=m: brdf.cook_torrance(cos, 0.0, ks, m, f0)))
    return out


def _cook_torrance(p):
    return _cook_torrance_lobes(p["kd"], p["f0"], [(p["ks"], p["m"])])


def _cook_torrance_n(n: int):
    return lambda p: _cook_torrance_lobes(
        p["kd"], p["f0"], [(float(p[f"ks_{j}"]), float(p[f"m_{j}"])) for j in range(1, n + 1)])


def _goniochromatic_diffuse(p):
    return [_diffuse(p["rho_d"]), _eq5(p)]


def _goniochromatic_coat(p):
    return [_diffuse(p["rho_d"]), _eq5(p), _coat(p)]


def _goniochromatic_backscatter(p):
    rho_d = np.asarray(p["rho_d"], dtype=float)
    body = Component("diffuse", DIFFUSE,
                     lambda cos: brdf.backscatter_diffuse(cos, rho_d, p["b0"], p["h"]))
    return [body, _eq5(p), _coat(p)]


def _goniochromatic_undercoat(p):
    """The body and eq. 5 seen through the coat (:func:`gonio_cli.brdf.
    goniochromatic_undercoat`): each its own lobe, × T(θi) T(θo) at refracted angles."""
    rho_d = np.asarray(p["rho_d"], dtype=float)
    n = brdf.UNDERCOAT_INDEX

    def through(f):
        return lambda cos: (brdf.coat_transmission(cos)[..., None]
                            * f(refracted_cosines(cos, n)))

    body = _diffuse(rho_d)
    return [Component("diffuse", DIFFUSE, through(body.evaluate)),
            Component("eq5", GLOSSY, through(_eq5(p).evaluate)), _coat(p)]


def _goniochromatic_two_lobe(p):
    rho_2 = np.asarray(p["rho_2"], dtype=float)
    second = Component("lobe_2", GLOSSY,
                       lambda cos: rho_2 * brdf.ggx_lobe(cos, p["alpha_2"])[..., None])
    return [_diffuse(p["rho_d"]), _eq5(p), second]


def _sheen(p):
    """The body, the Charlie sheen (ρ_sheen D V, grazing rather than about the mirror, but
    integrated over the whole hemisphere all the same) and the achromatic specular lobe."""
    zero = np.zeros_like(np.asarray(p["rho_d"], dtype=float))
    fibres = Component("sheen", GLOSSY, lambda cos: brdf.sheen(
        cos, p["r_sheen"], p["alpha"], 0.0, zero, p["rho_sheen"]))
    spec = Component("specular", GLOSSY, lambda cos: float(p["k_spec"]) * brdf.torrance_sparrow(
        cos, p["alpha"], brdf.FIBRE_F0) * np.ones_like(zero))
    return [_diffuse(p["rho_d"]), fibres, spec]


def _tabulated_colour(p):
    zero = np.zeros_like(np.asarray(p["rho_d"], dtype=float))
    table = {k: p[k] for k in brdf.MODELS["tabulated-colour"].table_params}
    lobe = Component("table", GLOSSY, lambda cos: brdf.tabulated_colour(
        cos, p["alpha"], zero, **table))
    return [_diffuse(p["rho_d"]), lobe]


#: Model name → its lobes (one entry per model of :data:`gonio_cli.brdf.MODELS`).
COMPONENTS: dict[str, Callable[[dict], list[Component]]] = {
    "goniochromatic": _goniochromatic,
    "torrance-sparrow": _torrance_sparrow,
    "cook-torrance": _cook_torrance,
    "goniochromatic-diffuse": _goniochromatic_diffuse,
    "goniochromatic-coat": _goniochromatic_coat,
    "goniochromatic-backscatter": _goniochromatic_backscatter,
    "goniochromatic-undercoat": _goniochromatic_undercoat,
    "goniochromatic-two-lobe": _goniochromatic_two_lobe,
    "cook-torrance-2": _cook_torrance_n(2),
    "cook-torrance-3": _cook_torrance_n(3),
    "sheen": _sheen,
    "tabulated-colour": _tabulated_colour,
}


def components(model: str, params: dict) -> list[Component]:
    """The lobes of a material (``model`` a key of :data:`gonio_cli.brdf.MODELS`)."""
    if model not in COMPONENTS:
        raise InputError(f"model {model!r} has no lobe decomposition",
                         fix=f"use one of {', '.join(COMPONENTS)}")
    return COMPONENTS[model](params)


__all__ = ["Component", "COMPONENTS", "components", "DIFFUSE", "GLOSSY"]
