"""Are a file's values fractions (or sr⁻¹), as gonio reads them, or percent?

``gonio ingest`` refuses values that look like percent (:func:`check_percent`), unless the
user states their units with an explicit ``--scale`` (``--scale 1``: "these are right").
The figure compared is the median of the quantity's level over the configurations away
from the mirror direction: there a real sample stays below a reflectance factor of ~1,
however glossy; near the mirror a glossy lobe is far above it, so a measurement sampled
densely around the mirror says nothing about its units and gets a warning, not an error.
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from .errors import InputError

#: A file whose median value is above this, in the quantity's :attr:`Quantity.level`, is
#: in percent (``--scale 0.01``), not fractions. A perfect white diffuser has reflectance
#: factor 1 at every geometry and matte samples stay below it (the MA-T12 green earth of
#: tests/fixtures/real: median 0.50); a glossy sample exceeds 1 only near the specular
#: direction (the sample red ink: median BRDF 0.040 sr^-1, peak 7.2; an RGL colour-shifting
#: wrap in plane: median 0.018 sr^-1, peak 22), which :data:`NEAR_SPECULAR_DEG` leaves out.
#: Percent data lands above 1.5 unless the sample reflects under 1.5 % at most geometries
#: (then it cannot be told from fractions). For ``brdf`` the limit is 1.5 sr^-1, a
#: reflectance factor of 4.7 at most configurations.
PERCENT_MEDIAN_LIMIT = 1.5

#: Configurations whose detector is less than this far from the mirror direction
#: (|θo − θi| < 15°, in plane) are left out of the median: a glossy lobe lives there (a GGX
#: α = 0.1 Torrance–Sparrow surface is above 1.5 sr⁻¹ to ~8° off the mirror, α = 0.3 metal
#: to ~12°). 15° is also the nearest aspecular angle of ASTM E2194's multi-angle
#: geometries (45as15), whose readings therefore still count.
NEAR_SPECULAR_DEG = 15.0


def median_of(values: np.ndarray) -> float:
    """``float(np.median(values))`` over every value (NaN if any is NaN), without the
    ``numpy.ma`` import that ``np.median`` makes on its first call (~10 ms of a run)."""
    a = np.asarray(values).ravel()
    if a.size == 0 or np.isnan(a).any():
        return math.nan
    k = a.size // 2
    if a.size % 2:
        return float(np.partition(a, k)[k])
    part = np.partition(a, (k - 1, k))
    return float(np.mean(part[k - 1:k + 1]))


def off_specular(theta_i_deg: np.ndarray, theta_o_deg: np.ndarray) -> np.ndarray:
    """(n,) bool: the configurations at least :data:`NEAR_SPECULAR_DEG` from the mirror
    direction θo = θi (docs/conventions.md, in-plane geometry)."""
    return np.abs(np.asarray(theta_o_deg) - np.asarray(theta_i_deg)) >= NEAR_SPECULAR_DEG


def check_percent(parts: Sequence, brdf: np.ndarray, params: dict[str, Any], quantity, *,
                  units_confirmed: bool = False) -> list[str]:
    """Refuse a file whose values look like percent, not fractions; return warnings.

    Per file (``parts``, :class:`~gonio_cli.csvio.Spectra` whose rows are ``brdf``'s
    (n, n_λ) rows in order), the median of ``quantity.level`` over the off-specular
    configurations (:func:`off_specular`) must not exceed :data:`PERCENT_MEDIAN_LIMIT`.
    The error names the value nearest the median and the options that read percent or
    confirm the units. A file with no off-specular configuration whose median is above the
    limit gets a warning instead (its units cannot be told). ``units_confirmed`` (an
    explicit ``--scale 1``) skips the check: the user stated the values are right.
    """
    if units_confirmed:
        return []
    notes, start = [], 0
    for part in parts:
        rows = slice(start, start + part.values.shape[0])
        start = rows.stop
        level = quantity.level(part.values, brdf[rows])
        off = off_specular(part.theta_i_deg, part.theta_o_deg)
        median = median_of(level[off] if off.any() else level)
        if not median > PERCENT_MEDIAN_LIMIT:
            continue
        if not off.any():
            notes.append(
                f"{part.path}: every configuration is within {NEAR_SPECULAR_DEG:g} deg of "
                f"the mirror direction, where a glossy sample's {quantity.level_name} "
                f"exceeds {PERCENT_MEDIAN_LIMIT:g}, so the units of its values (median "
                f"{median:.4g}) cannot be checked; pass --scale 0.01 if they are percent, "
                "--scale 1 to confirm them and silence this")
            continue
        level = np.where(off[:, None], level, np.nan)
        r, c = np.unravel_index(np.nanargmin(np.abs(level - median)), level.shape)
        after = f" after --scale {params['scale']:g}" if params["scale"] != 1.0 else ""
        # percent of anything real stays below 100 x the limit; beyond, another unit
        percent = median <= 100 * PERCENT_MEDIAN_LIMIT
        raise InputError(
            f"the values {'look like percent' if percent else 'are far too large'}: their "
            f"median {quantity.level_name}{after} is {median:.4g} (at least "
            f"{NEAR_SPECULAR_DEG:g} deg off the mirror), above {PERCENT_MEDIAN_LIMIT:g}, "
            "which a real sample exceeds only near the specular direction (an explicit "
            "--scale 1 keeps values known to be right)", path=part.path,
            row=int(part.lines[r, c]), column=part.columns[c],
            fix=quantity.percent_fix if percent else
            "check --quantity and its options, or give the factor to fractions with --scale")
    return notes
