"""The ingest stage: goniometer CSV spectra → one :class:`~gonio_cli.schemas.Measurement`.

Pure numpy core (STYLE 1): it never imports typer and never prints. Warnings go through
:func:`gonio_cli.log.warn`, and only once everything has been read and checked, so a run
that fails prints exactly one line (the error). Everything the user can fix raises
:class:`~gonio_cli.errors.InputError` naming the file, the line (1-based, as an editor
shows it), the column, the value and the fix.

Pipeline of :func:`ingest`, per input file and then for all of them:

1. :func:`read_spectra` reads a CSV in one of the :data:`LAYOUTS` (long, wide,
   multi-angle; detected from the header), with ``,`` / ``;`` / tab delimiters, a decimal
   comma when the delimiter is ``;``, a UTF-8 BOM and ``#`` comment lines; it checks every
   cell (numeric, finite), the angles (ranges, radians) and the wavelengths (increasing,
   unique). Instrument exports as a spreadsheet saves them are read too: preamble lines
   before the header (the header is the first line that is one of a layout's), label
   columns (:data:`LABEL_COLUMNS`: ``Name``, ``Date/Time`` …) set aside, and of a file
   that holds several samples the one ``--sample`` names.
2. The file's grid must cover the working grid (``--grid-nm``); wavelengths the
   resampling does not use are dropped (seed 000 trims its spectra to 380–780 nm).
3. ``--dark`` is subtracted (seed 004 §3), the values are multiplied by ``--scale``, then
   negative values are checked: beyond noise they are an error, small ones are clipped
   after averaging (step 6).
4. Files merge (they must share their grid) and the values are converted to BRDF in sr⁻¹
   by the quantity's rule (:data:`QUANTITIES`, seed 004 eqs. 5, 7, 8). A file whose values
   look like percent (:func:`~gonio_cli.percent.check_percent`) is refused.
5. Repeated rows of one configuration are averaged, their sample standard deviation kept
   (seed 000 averages ten spectra per configuration).
6. Small negative means are clipped to 0 (counted), and everything is resampled onto
   the working grid (:func:`gonio_cli.spectra.resample`), with a warning if the grid
   differs.

Arrays: wavelength is the last axis (STYLE 6); ``values`` are (n_spectra, n_λ).

Step 1, the CSV layer, is :mod:`gonio_cli.csvio` (its names are re-exported here). Why
one module for the rest: steps 2-6 run in this order on the same :class:`Spectra` and
share their checks (grid cover, percent, negatives) and the summary that reports them;
each step is a few short functions, and apart they would only pass the same state along.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from . import log
from .csvio import (ANGLE_DECIMALS, DELIMITERS, GEOMETRY, HEADER_SEARCH_LINES,
                    LABEL_COLUMNS, LAYOUTS, MAX_LISTED_SAMPLES, RADIAN_LIMIT, THETA_I,
                    THETA_O, VALUE, WAVELENGTH, WAVELENGTH_DECIMALS, Layout, Spectra, Table,
                    aspecular_angles, detect_layout, grid_text, header_wavelength,
                    is_layout_header, label_kind, read_columns, read_spectra, read_spectrum,
                    read_table, rounded_keys, select_sample, split_labels)
from .errors import InputError
from .names import choices_fix
from .percent import PERCENT_MEDIAN_LIMIT, check_percent, median_of  # noqa: F401 (API)
from .schemas import MAX_MAGNITUDE, Measurement
from .spectra import DEFAULT_GRID_NM, WAVELENGTH_TOL_NM, covers, parse_grid, resample, same_grid

# The CSV layer (tables, delimiters, header detection, label columns, the layouts and the
# readers of small CSVs) is gonio_cli.csvio; its names are imported above and stay
# importable from here.

# ------------------------------------------------------------------------- constants --

#: A negative value more negative than this fraction of the file's largest value is not
#: noise: a spectrometer with the 900:1 dynamic range of seed 004 §3 has a noise floor of
#: ~0.1 % of full scale; 1 % leaves a factor ~10 for dark drift between dark and sample.
#: Smaller negatives are noise around a zero signal and are clipped to 0 (counted).
NEGATIVE_NOISE_FRACTION = 0.01

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


# ------------------------------------------------------------------ grid handling --

def used_wavelengths(wavelength_nm: np.ndarray, grid_nm: np.ndarray) -> slice:
    """The input samples :func:`gonio_cli.spectra.resample` onto ``grid_nm`` can use.

    Resampling looks at most one grid step beyond the grid's ends (the hat average of finer
    input, and its check that a hat lies inside the input); linear interpolation uses the
    samples bracketing the ends. Keeping every sample within one step of the grid plus the
    first one at or beyond that step on each side leaves the resampled values unchanged
    for a uniform input grid; the rest is dropped (seed 000 trims its spectra to
    380–780 nm). ``wavelength_nm`` (n,) must cover ``grid_nm``.
    """
    w, g = np.asarray(wavelength_nm, float), np.asarray(grid_nm, float)
    step = float(np.min(np.diff(g)))
    below = np.flatnonzero(w <= g[0] - step + WAVELENGTH_TOL_NM)
    above = np.flatnonzero(w >= g[-1] + step - WAVELENGTH_TOL_NM)
    lo = int(below[-1]) if below.size else 0
    hi = int(above[0]) if above.size else w.size - 1
    return slice(lo, hi + 1)


def _require_cover(wl: np.ndarray, columns: Sequence[str], grid: np.ndarray, path: str,
                   line: int | None, what: str, fix: str) -> None:
    """Refuse wavelengths ``wl`` that do not span ``grid`` (no extrapolation), naming the
    column at the short end."""
    if covers(wl, grid):
        return
    short_end = 0 if wl[0] > grid[0] + WAVELENGTH_TOL_NM else -1
    raise InputError(f"wavelengths {wl[0]:g}-{wl[-1]:g} nm do not cover {what} "
                     f"{grid[0]:g}-{grid[-1]:g} nm", path=path, row=line,
                     column=columns[short_end], fix=fix)


def _wavelength_column_names(spectra: Spectra) -> tuple[list[str], int | None]:
    """Column names of the wavelengths and the header line, for messages."""
    if spectra.layout == "long":
        return [WAVELENGTH] * spectra.wavelength_nm.size, None
    return spectra.columns, spectra.info.get("header_line")


def crop(spectra: Spectra, grid: np.ndarray) -> Spectra:
    """Check that ``spectra`` cover ``grid`` and keep only the wavelengths it needs
    (:func:`used_wavelengths`); the number dropped goes to ``info``."""
    names, line = _wavelength_column_names(spectra)
    _require_cover(spectra.wavelength_nm, names, grid, spectra.path, line, "the working grid",
                   fix=f"measure over the whole grid or choose one inside the data, e.g. "
                       f"--grid-nm {_inner_grid(spectra.wavelength_nm)}")
    keep = used_wavelengths(spectra.wavelength_nm, grid)
    info = dict(spectra.info, wavelengths_dropped=int(spectra.wavelength_nm.size
                                                      - (keep.stop - keep.start)))
    return replace(spectra, wavelength_nm=spectra.wavelength_nm[keep],
                   values=spectra.values[:, keep], lines=spectra.lines[:, keep],
                   columns=spectra.columns[keep], info=info)


def _inner_grid(wl: np.ndarray) -> str:
    """A 10 nm ``--grid-nm`` inside the data's range (for a message's fix)."""
    lo, hi = math.ceil(wl[0] / 10) * 10, math.floor(wl[-1] / 10) * 10
    return f"{lo}:{hi}:10" if hi > lo else "START:STOP:STEP"


def _spectrum_on(wl_in, values_in, table: Table, wl: np.ndarray, role: str,
                 target: str) -> np.ndarray:
    """A single spectrum (white standard, dark) resampled onto the wavelengths ``wl``."""
    _require_cover(wl_in, [f"{w:g}" for w in wl_in], wl, table.path, None,
                   f"those of {target}",
                   fix=f"give the {role} spectrum over at least {wl[0]:g}-{wl[-1]:g} nm")
    return resample(wl_in, values_in, wl)


# ------------------------------------------------------------------ dark, negatives --

def subtract_dark(spectra: Spectra, dark: tuple[np.ndarray, np.ndarray, Table]) -> Spectra:
    """Subtract a dark/background spectrum from every row (seed 004 §3).

    ``dark`` is (wavelength_nm (m,), value (m,), table) from :func:`read_spectrum`, in the
    **same units as the file's value column** (the dark reading normalised exactly as the
    sample readings: for ratio-to-white divided by the white signal, for flux-ratio by the
    incident flux, for brdf already a BRDF offset). It is resampled onto the file's
    wavelengths, which it must cover.
    """
    wl, v, table = dark
    d = _spectrum_on(wl, v, table, spectra.wavelength_nm, "dark", spectra.path)
    return replace(spectra, values=spectra.values - d)


def check_negatives(spectra: Spectra) -> int:
    """Refuse values below −:data:`NEGATIVE_NOISE_FRACTION` × the file's peak; return how
    many small negatives (noise) remain (they are clipped after averaging)."""
    peak = max(float(spectra.values.max()), 0.0)
    limit = -NEGATIVE_NOISE_FRACTION * peak
    bad = spectra.values < limit
    if bad.any():
        r, c = np.unravel_index(np.argmin(np.where(bad, spectra.values, np.inf)),
                                spectra.values.shape)
        raise InputError(f"value {spectra.values[r, c]:.4g} at "
                         f"{spectra.wavelength_nm[c]:g} nm is negative beyond noise "
                         f"(below {NEGATIVE_NOISE_FRACTION:.0%} of the file's peak "
                         f"{peak:.4g})", path=spectra.path, row=int(spectra.lines[r, c]),
                         column=spectra.columns[c],
                         fix="check the dark subtraction, the sign and the quantity")
    return int(np.count_nonzero(spectra.values < 0))


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
                       theta_o_deg: str | None = None) -> dict[str, Any]:
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
            paths, theta_i_deg=theta_i_deg, theta_o_deg=theta_o_deg, grid_nm=grid_nm,
            quantity=quantity, white_reflectance=white_reflectance, aperture_mm=aperture_mm,
            distance_mm=distance_mm, dark=dark, scale=scale, sample=sample)
    for flag, value in (("--theta-i-deg", theta_i_deg), ("--theta-o-deg", theta_o_deg)):
        if value is not None:
            raise InputError(f"{flag} is for an RGL .bsdf input (its in-plane grid); a CSV "
                             "holds its own angles", path=where, fix=f"drop {flag}")
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
    return _spectrum_on(wl, v, table, wavelength_nm, "white standard", target)


# ----------------------------------------------------------------- merge, repeats --

def merge(parts: Sequence[Spectra], grids: Sequence[np.ndarray]) -> Spectra:
    """Concatenate the spectra of several files; they must have read the same grid.

    ``grids`` are the files' wavelengths as read (before cropping), (n_λ,) each.
    """
    first = parts[0]
    for part, grid in zip(parts[1:], grids[1:]):
        if not same_grid(grid, grids[0]):
            names, line = _wavelength_column_names(part)
            raise InputError(f"its wavelengths ({grid_text(grid)}) differ from those of "
                             f"{first.path} ({grid_text(grids[0])}) from "
                             f"{_first_difference(grid, grids[0])} on", path=part.path,
                             row=line, column=names[0],
                             fix="ingest files from one instrument set-up together, or "
                                 "export them on the same wavelengths")
    if len(parts) == 1:
        return first
    return Spectra(", ".join(p.path for p in parts), "+".join(p.layout for p in parts),
                   first.wavelength_nm,
                   np.concatenate([p.theta_i_deg for p in parts]),
                   np.concatenate([p.theta_o_deg for p in parts]),
                   np.concatenate([p.values for p in parts]),
                   np.concatenate([p.lines for p in parts]), first.columns)


def _first_difference(a: np.ndarray, b: np.ndarray) -> str:
    """The first wavelength where grids ``a`` and ``b`` differ, as text."""
    n = min(a.size, b.size)
    diff = np.flatnonzero(np.abs(a[:n] - b[:n]) > WAVELENGTH_TOL_NM)
    k = int(diff[0]) if diff.size else n
    return f"{a[k]:g} nm" if k < a.size else f"{b[k]:g} nm (missing)"


def average_repeats(theta_i_deg, theta_o_deg, values):
    """Average the rows of each configuration and keep their sample standard deviation.

    Parameters
    ----------
    theta_i_deg, theta_o_deg : (n,) float, degrees; rows agreeing to
        :data:`ANGLE_DECIMALS` decimals are one configuration.
    values : (n, n_λ) float.

    Returns
    -------
    theta_i_deg, theta_o_deg : (m,) float, configurations sorted by θi then θo.
    mean : (m, n_λ) float.
    std : (m, n_λ) float, sample standard deviation (ddof = 1), 0 for a single row.
    n_repeats : (m,) int.
    """
    keys, inv = np.unique(rounded_keys(np.asarray(theta_i_deg, float),
                                        np.asarray(theta_o_deg, float)),
                          axis=0, return_inverse=True)
    inv = inv.reshape(-1)
    values = np.asarray(values, dtype=float)
    order = np.argsort(inv, kind="stable")
    sorted_inv = inv[order]
    starts = np.flatnonzero(np.r_[True, sorted_inv[1:] != sorted_inv[:-1]])
    counts = np.diff(np.r_[starts, inv.size])
    v = values[order]
    mean = np.add.reduceat(v, starts, axis=0) / counts[:, None]
    sq = np.add.reduceat((v - mean[sorted_inv]) ** 2, starts, axis=0)
    std = np.sqrt(sq / np.maximum(counts - 1, 1)[:, None]) * (counts > 1)[:, None]
    return keys[:, 0], keys[:, 1], mean, std, counts


# ------------------------------------------------------------- other input formats --

@dataclass(frozen=True)
class InputFormat:
    """An input format besides CSV, routed by file suffix to its own module.

    The module (imported on first use, so a CSV run never loads it) has the three
    functions the CSV path has here: ``resolve_parameters(paths, **options)``,
    ``ingest(paths, **options)`` and ``file_lines(info)`` (its ``--summary`` lines).
    """

    name: str
    suffix: str
    module: str

    def load(self):
        import importlib

        return importlib.import_module(self.module)


#: Input formats besides CSV by name; :func:`input_format` picks one by file suffix.
FORMATS = {"rgl-bsdf": InputFormat("rgl-bsdf", ".bsdf", "gonio_cli.rgl")}


def input_format(paths: Sequence[str | os.PathLike]) -> InputFormat | None:
    """The :data:`FORMATS` entry of the first input with its suffix (any case), or None
    for CSV input."""
    for p in paths:
        suffix = Path(p).suffix.lower()
        for fmt in FORMATS.values():
            if suffix == fmt.suffix:
                return fmt
    return None


# ------------------------------------------------------------------------ the stage --

def ingest(paths: Sequence[str | os.PathLike], *, quantity: str | None = None,
           white_reflectance: float | str | None = None, aperture_mm: float | None = None,
           distance_mm: float | None = None, dark: str | os.PathLike | None = None,
           grid_nm: str | None = None, scale: float | None = None,
           sample: str | None = None, theta_i_deg: str | None = None,
           theta_o_deg: str | None = None) -> Measurement:
    """Read goniometer CSVs and return one measurement on the working grid.

    Parameters
    ----------
    paths : sequence of path, at least one CSV (any of :data:`LAYOUTS`); several files
        merge (e.g. one per angle of incidence) and must share their wavelengths.
    quantity : key of :data:`QUANTITIES`, what the files hold (default ``"brdf"``; not
        given, a multi-angle file gets a warning that such instruments export reflectance
        factors).
    white_reflectance : number in (0, 1] or path of a ``wavelength_nm,value`` CSV, the
        white standard's reflectance for ``ratio-to-white`` (default 0.99).
    aperture_mm, distance_mm : receptor aperture diameter and distance for ``flux-ratio``
        (seed 004 eq. 7).
    dark : path of a ``wavelength_nm,value`` CSV subtracted from every row before the
        conversion, in the units of the files' value columns (:func:`subtract_dark`).
    grid_nm : working grid ``"START:STOP:STEP"`` in nm (default ``"380:780:10"``).
    scale : positive factor the values are multiplied by after the dark subtraction and
        before the conversion (``0.01`` for percent; default 1). Values that still look
        like percent are refused (:func:`~gonio_cli.percent.check_percent`), unless
        ``scale`` is given as 1: the user confirms the values are in the quantity's units.
    sample : of files holding several samples (a ``Name``, ``Sample`` or ``ID`` column
        with several values), the one to read (:func:`select_sample`).
    theta_i_deg, theta_o_deg : for an input of another format (:data:`FORMATS`, e.g. an
        RGL ``.bsdf``, read by :func:`gonio_cli.rgl.ingest`), the in-plane grid to
        evaluate it at; refused for CSV input.

    Returns
    -------
    Measurement
        ``brdf`` (n_cfg, n_λ) in sr⁻¹ without the cosine factor, ``brdf_std`` where a
        configuration repeated, ``n_repeats`` and a ``summary`` (:func:`format_summary`).
    """
    if not paths:
        raise InputError("no input files", fix="gonio ingest INPUT.csv [...] -o OUT.json")
    fmt = input_format(paths)
    if fmt is not None:
        return fmt.load().ingest(
            paths, theta_i_deg=theta_i_deg, theta_o_deg=theta_o_deg, grid_nm=grid_nm,
            quantity=quantity, white_reflectance=white_reflectance, aperture_mm=aperture_mm,
            distance_mm=distance_mm, dark=dark, scale=scale, sample=sample)
    params = resolve_parameters(paths, quantity=quantity, white_reflectance=white_reflectance,
                                aperture_mm=aperture_mm, distance_mm=distance_mm, dark=dark,
                                grid_nm=grid_nm, scale=scale, sample=sample,
                                theta_i_deg=theta_i_deg, theta_o_deg=theta_o_deg)
    _refuse_repeated_inputs(paths)
    grid = parse_grid(params["grid_nm"])
    dark_spectrum = read_spectrum(dark, "dark") if dark is not None else None
    parts, grids, negatives = [], [], 0
    for path in log.progress(paths, "reading CSV files", total=len(paths)):
        spectra = read_spectra(path, params["sample"])
        grids.append(spectra.wavelength_nm)
        spectra = crop(spectra, grid)
        if dark_spectrum is not None:
            spectra = subtract_dark(spectra, dark_spectrum)
        if params["scale"] != 1.0:
            spectra = replace(spectra, values=spectra.values * params["scale"])
        negatives += check_negatives(spectra)
        parts.append(spectra)
    merged = merge(parts, grids)
    brdf = _convert(merged, params)
    # an explicit --scale 1 states that the values are in the quantity's units
    confirmed = scale is not None and float(scale) == 1.0
    percent_notes = check_percent(parts, brdf, params, QUANTITIES[params["quantity"]],
                                  units_confirmed=confirmed)
    ti, to, mean, std, counts = average_repeats(merged.theta_i_deg, merged.theta_o_deg, brdf)
    clipped = int(np.count_nonzero(mean < 0))
    mean = np.maximum(mean, 0.0)
    notes = _quantity_notes(parts, quantity is not None) + percent_notes
    notes += _grid_notes(parts, grids, grid, params["grid_nm"])
    if clipped:
        notes.append(f"clipped {clipped} small negative value{'s' if clipped > 1 else ''} "
                     f"(noise, above -{NEGATIVE_NOISE_FRACTION:.0%} of the peak) to 0 "
                     f"after averaging repeats")
    wl = merged.wavelength_nm
    repeated = bool(counts.max() > 1)
    m = Measurement(grid, ti, to, resample(wl, mean, grid),
                    resample(wl, std, grid) if repeated else None, counts,
                    params["quantity"])
    resampled = not all(same_grid(g, grid) for g in grids)
    m.summary = _summary(m, parts, params, resampled, negatives, clipped, notes)
    for note in notes:  # only now: a failing run prints one line, its error
        log.warn(note)
    return m


def _refuse_repeated_inputs(paths: Sequence[str | os.PathLike]) -> None:
    """The same file twice would count its rows as repeats with a spread of 0."""
    seen: dict[str, str] = {}
    for p in paths:
        key = os.path.realpath(p)
        if key in seen:
            raise InputError(f"is given twice (also as {seen[key]})", path=p,
                             fix="pass each file once; check overlapping wildcards")
        seen[key] = os.fspath(p)


def distinct(values: np.ndarray) -> np.ndarray:
    """``np.unique(values)`` (the sorted distinct values) without the ``numpy.ma`` import
    that ``np.unique`` makes when asked for the values alone (see :func:`median_of`)."""
    a = np.sort(np.asarray(values).ravel())
    return a[np.r_[True, a[1:] != a[:-1]]] if a.size else a


def _quantity_notes(parts: Sequence[Spectra], quantity_given: bool) -> list[str]:
    """The warning for a multi-angle file read as BRDF because ``--quantity`` was not
    given (:data:`REFLECTANCE_FACTOR_LAYOUTS`)."""
    if quantity_given:
        return []
    return [f"{p.path}: a {p.layout} file read as BRDF in sr^-1 (the default --quantity "
            f"{DEFAULT_QUANTITY}), but {p.layout} instruments export reflectance factors: "
            "pass --quantity reflectance-factor if these are (f = R/pi), or --quantity "
            f"{DEFAULT_QUANTITY} to keep them and silence this"
            for p in parts if p.layout in REFLECTANCE_FACTOR_LAYOUTS]


def _convert(spectra: Spectra, params: dict[str, Any]) -> np.ndarray:
    """Values → BRDF (sr⁻¹) by the quantity's rule (:data:`QUANTITIES`)."""
    q = QUANTITIES[params["quantity"]]
    white = (white_spectrum(params["white_reflectance"], spectra.wavelength_nm,
                            spectra.path) if "white_reflectance" in q.options else None)
    omega = (receptor_solid_angle(params["aperture_mm"], params["distance_mm"])
             if "aperture_mm" in q.options else None)
    return q.convert(spectra.values, theta_o_deg=spectra.theta_o_deg, white=white,
                     solid_angle_sr=omega)


def _grid_notes(parts, grids, grid, grid_spec) -> list[str]:
    """The resampling (or trimming) warning per file (docs/conventions.md: never silent)."""
    notes = []
    for part, read in zip(parts, grids):
        if same_grid(read, grid):
            continue
        how = "trimmed to" if same_grid(part.wavelength_nm, grid) else "resampled onto"
        notes.append(f"{part.path}: wavelengths {grid_text(read)} {how} the working grid "
                     f"{grid_spec} ({grid.size} samples)")
    return notes


def _summary(m: Measurement, parts, params, resampled, negatives, clipped,
             notes) -> dict[str, Any]:
    """What was read, dropped, clipped and resampled (JSON-ready; :func:`format_summary`)."""
    per_theta_i = []
    theta_i = distinct(m.theta_i_deg)
    for t in theta_i:
        sel = m.theta_i_deg == t
        per_theta_i.append({"theta_i_deg": float(t),
                            "theta_o_min_deg": float(m.theta_o_deg[sel].min()),
                            "theta_o_max_deg": float(m.theta_o_deg[sel].max()),
                            "configurations": int(sel.sum())})
    return {
        "files": [p.info for p in parts],
        "quantity": params["quantity"],
        "conversion": QUANTITIES[params["quantity"]].formula,
        "scale": params["scale"],
        "theta_i_deg": [float(t) for t in theta_i],
        "theta_o_by_theta_i": per_theta_i,
        "working_grid_nm": params["grid_nm"],
        "resampled": resampled,
        "configurations": m.n_configurations,
        "spectra": int(m.n_repeats.sum()),
        "repeats_min": int(m.n_repeats.min()),
        "repeats_max": int(m.n_repeats.max()),
        "brdf_min_per_sr": float(m.brdf.min()),
        "brdf_max_per_sr": float(m.brdf.max()),
        "negative_values_read": negatives,
        "clipped_to_zero": clipped,
        "warnings": list(notes),
    }


#: Lines without data that ``format_summary`` reports as skipped (``Spectra.info`` keys).
_SKIPPED = {"preamble_lines": "preamble lines", "comment_lines": "comment lines",
            "empty_rows": "empty rows", "rows_other_samples": "rows of other samples"}


def format_summary(summary: dict[str, Any]) -> str:
    """The human summary printed by ``gonio ingest --summary`` (a string, not printed)."""
    out = []
    for f in summary["files"]:
        if f.get("format") in FORMATS:
            out += FORMATS[f["format"]].load().file_lines(f)
            continue
        out.append(f"read {f['path']}: {f['layout']} layout, {f['delimiter']}-delimited"
                   f"{', decimal comma' if f['decimal_comma'] else ''}, {f['rows']} rows, "
                   f"{f['spectra']} spectra, {f['wavelength_nm']}")
        skipped = [f"{f[k]} {what}" for k, what in _SKIPPED.items() if f.get(k)]
        dropped = f.get("wavelengths_dropped", 0)
        out.append(f"  skipped: {', '.join(skipped) or 'nothing'}; dropped: "
                   + (f"{dropped} wavelengths outside the working grid" if dropped
                      else "nothing"))
        if f.get("label_columns"):
            n = len(f.get("samples") or ())
            of = f" (1 of {n} in the file)" if n > 1 else ""
            sample = (f"; sample {f['sample']}{of} from column {f['sample_column']}"
                      if f.get("sample_column") else "")
            out.append(f"  label columns set aside: {', '.join(f['label_columns'])}{sample}")
    scale = summary.get("scale", 1.0)
    out.append(f"quantity: {summary['quantity']} ({summary['conversion']})"
               + (f", values x {scale:g} (--scale)" if scale != 1.0 else ""))
    out.append("angles of incidence (deg): "
               + ", ".join(f"{t:g}" for t in summary["theta_i_deg"]))
    for row in summary["theta_o_by_theta_i"]:
        out.append(f"  theta_i {row['theta_i_deg']:g}: theta_o {row['theta_o_min_deg']:g} "
                   f"to {row['theta_o_max_deg']:g} deg, {row['configurations']} "
                   "configurations")
    out.append(f"grid: {summary['working_grid_nm']} nm"
               f"{' (resampled)' if summary['resampled'] else ''}")
    lo, hi = summary["repeats_min"], summary["repeats_max"]
    rep = ("no repeats" if hi == 1 else f"{lo} repeats each" if lo == hi
           else f"{lo}-{hi} repeats each")
    out.append(f"configurations: {summary['configurations']} from {summary['spectra']} "
               f"spectra ({rep})")
    out.append(f"BRDF: {summary['brdf_min_per_sr']:.4g} to {summary['brdf_max_per_sr']:.4g} "
               "sr^-1")
    out.append(f"clipped to 0: {summary['clipped_to_zero']} (of "
               f"{summary['negative_values_read']} small negative values read)")
    for note in summary["warnings"]:
        out.append(f"warning: {note}")
    return "\n".join(out)
