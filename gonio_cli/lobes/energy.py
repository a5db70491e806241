"""What the fitted lobes hold against the material's albedo (issue 26's energy check).

:func:`lobe_energy` integrates each fitted term as the renderer does (seed 001 eqs. 7-9
with P_E = 1); :func:`energy_excess`, :func:`energy_note` and :func:`check_energy` compare
a :class:`~gonio_cli.lobes.solve.WeightTable` with the material's directional albedo
(:data:`ENERGY_EXCESS_WARN`, :data:`ENERGY_EXCESS_MAX`, :data:`ALBEDO_FLOOR_REL`).
Re-exported by :mod:`gonio_cli.lobes`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..errors import FitError
from . import ALBEDO_FLOOR_REL, ENERGY_EXCESS_MAX, ENERGY_EXCESS_WARN, lobe_integral

if TYPE_CHECKING:
    from .solve import WeightTable


def lobe_energy(exponents, view_angle_deg, diffuse, directional_diffuse, gloss) -> np.ndarray:
    """What each fitted term sends towards the viewer under unit radiance from everywhere,
    as the renderer integrates it (module docstring; seed 001 eqs. 7-9 with P_E = 1):
    π K_D, cos θv K_DD,i 2π/(E_i+1) (R·N = cos θv) and K_G,i 2π/(E_i+1).

    diffuse (V, C), directional_diffuse and gloss (V, m, C) → (V, 1 + 2m, C) in
    :func:`design_matrix`'s column order (unitless, comparable with the albedo)."""
    integral = lobe_integral(exponents)[None, :, None]
    cos_v = np.cos(np.radians(np.asarray(view_angle_deg, dtype=float)))[:, None, None]
    return np.concatenate([np.pi * np.asarray(diffuse)[:, None, :],
                           cos_v * integral * np.asarray(directional_diffuse),
                           integral * np.asarray(gloss)], axis=1)


def energy_excess(energy: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """(V, C) fitted energy (summed over terms) ÷ the albedo, each channel's albedo floored
    at :data:`ALBEDO_FLOOR_REL` of its view's brightest (0 where the view is black)."""
    floor = ALBEDO_FLOOR_REL * albedo.max(axis=1, keepdims=True)
    ref = np.maximum(albedo, floor)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ref > 0, energy / np.where(ref > 0, ref, 1.0),
                        np.where(energy > 0, np.inf, 0.0))


def _term_name(k: int, exponents) -> str:
    m = len(exponents)
    if k == 0:
        return "the diffuse term"
    kind = "directional-diffuse" if k <= m else "gloss"
    return f"the {kind} lobe E={float(exponents[(k - 1) % m]):g}"


def energy_note(table: WeightTable, limit: float = ENERGY_EXCESS_WARN) -> str | None:
    """The sentence that says the weights hold more than ``limit`` × the light the material
    reflects, at the worst view angle and channel (the ratio, the integral against the
    albedo, the term holding most of it, its weight); None when they do not."""
    ratio = energy_excess(table.energy, table.albedo)
    worst = float(np.nanmax(ratio, initial=0.0))
    if not worst > limit:
        return None
    v, c = np.unravel_index(int(np.nanargmax(ratio)), ratio.shape)
    terms = table.energy_terms
    k = int(np.argmax(terms[v, :, c]))
    e = table.exponents
    m = len(e)
    weight = (table.diffuse[v, c] if k == 0 else (table.directional_diffuse[v, k - 1, c]
              if k <= m else table.gloss[v, k - 1 - m, c]))
    label = table.channels[c]
    channel = f"{label:g} nm" if isinstance(label, float) else str(label)
    return (f"view angle {table.view_angle_deg[v]:g} deg: the fitted lobes hold {worst:.3g}x "
            f"the light the material reflects at {channel} (their integral "
            f"{table.energy[v, c]:.3g} against its albedo {table.albedo[v, c]:.3g}), "
            f"{terms[v, k, c] / table.energy[v, c]:.0%} of it in {_term_name(k, e)} (weight "
            f"{weight:.3g} /sr), so a render would be that much too bright there; fit on "
            "samples that hold the gloss's energy (--samples hemisphere --mirror-dense) or "
            "use lobes as sharp as the material's gloss (gonio lobes basis on it)")


def check_energy(table: WeightTable, max_ratio: float = ENERGY_EXCESS_MAX) -> None:
    """Refuse weights that hold more than ``max_ratio`` (:data:`ENERGY_EXCESS_MAX`) × the
    light the material reflects at some view angle and channel: FitError with
    :func:`energy_note`'s sentence (view, channel, ratio, the term holding most of it)."""
    note = energy_note(table, max_ratio)
    if note is not None:
        worst = float(np.nanmax(energy_excess(table.energy, table.albedo)))
        text, _, fix = note.rpartition("; ")
        raise FitError(f"{text} (limit {max_ratio:g}x)",
                       fix=f"{fix}, or accept it with --max-energy-ratio {_round_up(worst):g}")


def _round_up(x: float) -> float:
    """``x`` rounded up to two significant digits (21.39 → 22, 5.1e13 → 5.2e13)."""
    if not np.isfinite(x) or x <= 0:
        return x
    step = 10.0 ** (np.floor(np.log10(x)) - 1)
    return float(np.ceil(x / step) * step)
