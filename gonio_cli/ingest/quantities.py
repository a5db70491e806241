"""What instruments report and its conversion to BRDF in sr⁻¹ (:data:`QUANTITIES`, seed 004
eqs. 5, 7, 8): the quantity of a file or of the options, the white standard, the
receptor's solid angle."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ..csvio import VALUE, header_wavelength, read_spectrum
from ..errors import InputError
from ..names import choices_fix
from ..schemas import MAX_MAGNITUDE
from ..spectra import DEFAULT_GRID_NM, parse_grid
from .formats import input_format
from .steps import spectrum_on

#: Reflectance of the white standard when ``--white-reflectance`` is not given: the 99 %
#: Spectralon of seed 000 ("Preparation and measurement"), docs/conventions.md.
DEFAULT_WHITE_REFLECTANCE = 0.99


# ------------------------------------------------------------------------ data types --

@dataclass(frozen=True)
class Quantity:
    """What an instrument reports, and its conversion to BRDF (sr⁻¹, no cos θi factor).

    ``convert(values, theta_o_deg=, white=, solid_angle_sr=)`` maps (n, n_λ) values to BRDF;
    ``options`` names the CLI options it needs (refused for the other quantities).
    ``level(values, brdf)`` is the (n, n_λ) figure :func:`check_percent` compares with
    :data:`PERCENT_MEDIAN_LIMIT` (``level_name`` says what it is in messages), and
    ``percent_fix`` the options that read percent values of this quantity.
    """

    name: str
    formula: str
    citation: str
    options: tuple[str, ...]
    convert: Callable[..., np.ndarray]
    level: Callable[[np.ndarray, np.ndarray], np.ndarray]
    level_name: str
    percent_fix: str


# ---------------------------------------------------------------------- quantities --

def receptor_solid_angle(aperture_mm: float, distance_mm: float) -> float:
    """Solid angle (sr) of a circular receptor aperture, seed 004 eq. (7).

    Δω = π w² / (4 d²), ``aperture_mm`` the diameter w, ``distance_mm`` the distance d from
    the sample (small-aperture approximation; seed 004 uses w = 4 mm, d = 400 mm).

    >>> round(receptor_solid_angle(4.0, 400.0), 10)
    7.85398e-05
    """
    return math.pi * aperture_mm ** 2 / (4.0 * distance_mm ** 2)


def _from_brdf(values, **_):
    return values


def _from_reflectance_factor(values, **_):
    return values / np.pi


def _from_ratio_to_white(values, *, white, **_):
    return values * white / np.pi


def _from_flux_ratio(values, *, theta_o_deg, solid_angle_sr, **_):
    cos_theta_o = np.cos(np.radians(theta_o_deg))  # > 0: |θo| < 90° is checked on read
    return values / (cos_theta_o[:, None] * solid_angle_sr)


def _value_level(values, brdf):
    """The values themselves: fractions of a white diffuser's (or sr⁻¹), at most ~1 at
    most configurations of any real sample."""
    return values


def _reflectance_factor_level(values, brdf):
    """π f, the reflectance factor: flux ratios scale with the aperture, so their own
    size says nothing."""
    return np.pi * brdf


_PERCENT_FIX = "pass --scale 0.01 if they are percent"

#: Measured quantities and their conversion to BRDF in sr⁻¹ (STYLE 3).
QUANTITIES: dict[str, Quantity] = {
    "brdf": Quantity(
        "brdf", "f = value", "docs/conventions.md", (), _from_brdf, _value_level,
        "BRDF (sr^-1)", "pass --quantity reflectance-factor --scale 0.01 if they are "
        "reflectance factors in percent (as instruments export them), --scale 0.01 alone "
        "if a BRDF in percent"),
    "ratio-to-white": Quantity(
        "ratio-to-white", "f = ratio · R_white(λ) / π",
        "seed 004 eq. 8 with a Lambertian standard f_rs = R_white/π; seed 000 "
        "'Preparation and measurement'", ("white_reflectance",), _from_ratio_to_white,
        _value_level, "ratio to white", _PERCENT_FIX),
    "reflectance-factor": Quantity(
        "reflectance-factor", "f = R / π", "docs/conventions.md", (),
        _from_reflectance_factor, _value_level, "reflectance factor", _PERCENT_FIX),
    "flux-ratio": Quantity(
        "flux-ratio", "f = (ΔΦr/ΔΦi) / (cos θo · Δω), Δω = π w² / (4 d²)",
        "seed 004 eqs. 5 and 7", ("aperture_mm", "distance_mm"), _from_flux_ratio,
        _reflectance_factor_level, "reflectance factor pi*f", _PERCENT_FIX),
}

#: The quantity when ``--quantity`` is not given.
DEFAULT_QUANTITY = "brdf"

#: Layouts whose instruments export reflectance factors, not BRDFs: ingesting one
#: without ``--quantity`` warns (multi-angle spectrophotometers, ASTM E2194).
REFLECTANCE_FACTOR_LAYOUTS = ("multi-angle",)

_OPTION_FLAGS = {"white_reflectance": "--white-reflectance", "aperture_mm": "--aperture-mm",
                 "distance_mm": "--distance-mm"}


def resolve_parameters(paths: Sequence[str | os.PathLike], *, quantity: str | None = None,
                       white_reflectance: float | str | None = None,
                       aperture_mm: float | None = None, distance_mm: float | None = None,
                       dark: str | os.PathLike | None = None,
                       grid_nm: str | None = None, scale: float | None = None,
                       sample: str | None = None, theta_i_deg: str | None = None,
                       theta_o_deg: str | None = None, phi_o_deg: str | None = None,
                       mirror_deg: str | None = None) -> dict[str, Any]:
    """Check the options against each other and fill in defaults.

    Returns the effective parameters (recorded in the artifact): ``quantity`` (default
    :data:`DEFAULT_QUANTITY`), ``white_reflectance`` (a number, a CSV path, or None when
    not used), ``aperture_mm``, ``distance_mm``, ``dark`` (path or None), ``grid_nm``,
    ``scale`` (default 1) and ``sample`` (or None). An option the quantity does not use is
    an error (it would be silently ignored otherwise, STYLE 7).
    """
    where = os.fspath(paths[0]) if paths else None
    fmt = input_format(paths)
    if fmt is not None:
        return fmt.load().resolve_parameters(
            paths, theta_i_deg=theta_i_deg, theta_o_deg=theta_o_deg, phi_o_deg=phi_o_deg,
            mirror_deg=mirror_deg, grid_nm=grid_nm, quantity=quantity, white_reflectance=white_reflectance, aperture_mm=aperture_mm,
            distance_mm=distance_mm, dark=dark, scale=scale, sample=sample)
    for flag, value in (("--theta-i-deg", theta_i_deg), ("--theta-o-deg", theta_o_deg),
                        ("--phi-o-deg", phi_o_deg), ("--mirror-deg", mirror_deg)):
        if value is not None:
            raise InputError(f"{flag} is for an RGL .bsdf input (its grid); a CSV holds its "
                             "own angles (a phi_o_deg column out of plane)", path=where,
                             fix=f"drop {flag}")
    quantity = DEFAULT_QUANTITY if quantity is None else quantity
    if quantity not in QUANTITIES:
        raise InputError(f"--quantity {quantity!r} is not known", path=where,
                         fix=choices_fix(quantity, QUANTITIES))
    needs = QUANTITIES[quantity].options
    given = {"white_reflectance": white_reflectance, "aperture_mm": aperture_mm,
             "distance_mm": distance_mm}
    for name, value in given.items():
        if value is not None and name not in needs:
            users = [q for q, spec in QUANTITIES.items() if name in spec.options]
            raise InputError(f"{_OPTION_FLAGS[name]} is only used with --quantity "
                             f"{' or '.join(users)}, not {quantity}", path=where,
                             fix=f"drop {_OPTION_FLAGS[name]} or pass the right --quantity")
    if quantity == "ratio-to-white":
        white_reflectance = _white_option(white_reflectance, where)
    if quantity == "flux-ratio":
        _receptor_options(aperture_mm, distance_mm, where)
    grid = grid_nm if grid_nm is not None else DEFAULT_GRID_NM
    parse_grid(grid)  # refuse a bad --grid-nm before reading anything
    scale = 1.0 if scale is None else float(scale)
    if not (math.isfinite(scale) and 0 < scale <= MAX_MAGNITUDE):
        raise InputError(f"--scale {scale:g} is not a positive number up to "
                         f"{MAX_MAGNITUDE:g}", path=where,
                         fix="the factor the values are multiplied by, e.g. --scale 0.01 "
                             "for percent")
    if sample is not None and not str(sample).strip():
        raise InputError("--sample is empty", path=where,
                         fix="name the sample as the file's Name (or Sample, ID) column has it")
    return {"quantity": quantity, "white_reflectance": white_reflectance,
            "aperture_mm": aperture_mm, "distance_mm": distance_mm,
            "dark": os.fspath(dark) if dark is not None else None, "grid_nm": grid,
            "scale": scale, "sample": None if sample is None else str(sample).strip()}


def _white_option(value: float | str | None, where: str | None) -> float | str:
    """``--white-reflectance``: a number in (0, 1] (default 0.99) or a CSV path."""
    if value is None:
        return DEFAULT_WHITE_REFLECTANCE
    number = header_wavelength(str(value))
    if number is None:
        if not Path(str(value)).is_file():
            raise InputError(f"--white-reflectance {value!r} is neither a number nor a file",
                             path=where, fix="give the white standard's reflectance as a "
                             "fraction with a '.' (e.g. 0.99) or a CSV wavelength_nm,value")
        return os.fspath(value)
    if not 0 < number <= 1:
        raise InputError(f"--white-reflectance {number:g} is outside (0, 1]", path=where,
                         fix="the reflectance of the white standard as a fraction "
                             "(0.99 for 99 % Spectralon)")
    return number


#: Smallest aperture / distance of a flux-ratio receptor: below it Δω = π w²/(4 d²) is under
#: 1e-12 sr and a flux ratio divided by it overflows (a real receptor subtends ~1e-4 sr).
MIN_APERTURE_RATIO = 1e-6


def _receptor_options(aperture_mm, distance_mm, where) -> None:
    """flux-ratio needs the receptor's aperture and distance (seed 004 eq. 7)."""
    if aperture_mm is None or distance_mm is None:
        missing = [f for f, v in (("--aperture-mm", aperture_mm),
                                  ("--distance-mm", distance_mm)) if v is None]
        raise InputError(f"--quantity flux-ratio needs {' and '.join(missing)} (receptor "
                         "aperture diameter and its distance from the sample, seed 004 "
                         "eq. 7)", path=where,
                         fix="e.g. --aperture-mm 4 --distance-mm 400")
    if not (math.isfinite(aperture_mm) and math.isfinite(distance_mm)
            and MIN_APERTURE_RATIO * distance_mm <= aperture_mm < distance_mm
            and distance_mm <= MAX_MAGNITUDE):
        raise InputError(f"--aperture-mm {aperture_mm:g} and --distance-mm {distance_mm:g} "
                         f"need 0 < aperture < distance (seed 004 eq. 7 is for a small "
                         f"aperture), aperture >= {MIN_APERTURE_RATIO:g} × distance and "
                         f"distance <= {MAX_MAGNITUDE:g}",
                         path=where, fix="both in mm, e.g. 4 and 400")


def white_spectrum(white: float | str, wavelength_nm: np.ndarray, target: str) -> np.ndarray:
    """R_white (n_λ,) on ``wavelength_nm``: a constant, or a CSV spectrum resampled there.

    A CSV must hold fractions in (0, 1] and cover the wavelengths of ``target``.
    """
    if not isinstance(white, str):
        return np.full(wavelength_nm.shape, float(white))
    wl, v, table = read_spectrum(white, "white standard")
    bad = np.flatnonzero(~((v > 0) & (v <= 1)))
    if bad.size:
        k = int(bad[0])
        raise InputError(f"white reflectance {v[k]:g} at {wl[k]:g} nm is outside (0, 1]",
                         path=white, row=int(table.lines[k]), column=VALUE,
                         fix="a fraction (0.99, not 99 %)" if v[k] > 1
                         else "a white standard reflects; check the file")
    return spectrum_on(wl, v, table, wavelength_nm, "white standard", target)
