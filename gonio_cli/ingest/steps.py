"""The ingest steps on read spectra, in the order :func:`gonio_cli.ingest.ingest` runs them:
the file's grid against the working grid (crop, cover), ``--dark`` and negative values,
the merge of several files and the average of repeated configurations."""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Sequence

import numpy as np

from ..csvio import WAVELENGTH, Spectra, Table, grid_text
from ..csvlayouts import rounded_keys
from ..errors import InputError
from ..spectra import WAVELENGTH_TOL_NM, covers, resample, same_grid

#: A negative value more negative than this fraction of the file's largest value is not
#: noise: a spectrometer with the 900:1 dynamic range of seed 004 §3 has a noise floor of
#: ~0.1 % of full scale; 1 % leaves a factor ~10 for dark drift between dark and sample.
#: Smaller negatives are noise around a zero signal and are clipped to 0 (counted).
NEGATIVE_NOISE_FRACTION = 0.01

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


def spectrum_on(wl_in, values_in, table: Table, wl: np.ndarray, role: str,
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
    d = spectrum_on(wl, v, table, spectra.wavelength_nm, "dark", spectra.path)
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
    in_plane = all(p.phi_o_deg is None for p in parts)
    return Spectra(", ".join(p.path for p in parts), "+".join(p.layout for p in parts),
                   first.wavelength_nm,
                   np.concatenate([p.theta_i_deg for p in parts]),
                   np.concatenate([p.theta_o_deg for p in parts]),
                   np.concatenate([p.values for p in parts]),
                   np.concatenate([p.lines for p in parts]), first.columns,
                   phi_o_deg=None if in_plane else np.concatenate(
                       [np.zeros(p.theta_i_deg.shape) if p.phi_o_deg is None else p.phi_o_deg
                        for p in parts]))


def _first_difference(a: np.ndarray, b: np.ndarray) -> str:
    """The first wavelength where grids ``a`` and ``b`` differ, as text."""
    n = min(a.size, b.size)
    diff = np.flatnonzero(np.abs(a[:n] - b[:n]) > WAVELENGTH_TOL_NM)
    k = int(diff[0]) if diff.size else n
    return f"{a[k]:g} nm" if k < a.size else f"{b[k]:g} nm (missing)"


def average_repeats(theta_i_deg, theta_o_deg, values, phi_o_deg=None):
    """Average the rows of each configuration and keep their sample standard deviation.

    Parameters
    ----------
    theta_i_deg, theta_o_deg : (n,) float, degrees; rows agreeing to
        :data:`ANGLE_DECIMALS` decimals (with ``phi_o_deg``, if given) are one
        configuration.
    values : (n, n_λ) float.
    phi_o_deg : (n,) float, degrees (canonical), or None: every row in plane.

    Returns
    -------
    theta_i_deg, theta_o_deg : (m,) float, configurations sorted by θi then θo (then φo).
    mean : (m, n_λ) float.
    std : (m, n_λ) float, sample standard deviation (ddof = 1), 0 for a single row.
    n_repeats : (m,) int.
    phi_o_deg : (m,) float, or None when none was given.
    """
    cols = [np.asarray(theta_i_deg, float), np.asarray(theta_o_deg, float)]
    if phi_o_deg is not None:
        cols.append(np.asarray(phi_o_deg, float))
    keys, inv = np.unique(rounded_keys(*cols), axis=0, return_inverse=True)
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
    return (keys[:, 0], keys[:, 1], mean, std, counts,
            None if phi_o_deg is None else keys[:, 2])


def distinct(values: np.ndarray) -> np.ndarray:
    """``np.unique(values)`` (the sorted distinct values) without the ``numpy.ma`` import
    that ``np.unique`` makes when asked for the values alone (see :func:`median_of`)."""
    a = np.sort(np.asarray(values).ravel())
    return a[np.r_[True, a[1:] != a[:-1]]] if a.size else a
