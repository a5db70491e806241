"""The working spectral grid, resampling onto it, and colour helpers (colour-science).

Wavelengths are nanometres (``wavelength_nm``) and always the last array axis. The default
grid is 380–780 nm in 10 nm steps (41 samples, seed 000). Colour follows docs/conventions.md:
XYZ = Σλ L(λ) cmf(λ) / Σλ ȳ(λ) with the CIE 1931 2° observer sampled on the working grid,
light spectra scaled so that Σ S ȳ / Σ ȳ = 1, linear sRGB by the IEC 61966-2-1 matrix.

colour-science takes ~1.5 s to import, so it is imported on first use only: a stage that
needs no colour (ingest, fit) never pays for it.
"""

from __future__ import annotations

import functools

import numpy as np

from .errors import InputError

DEFAULT_GRID_NM = "380:780:10"

#: Two wavelengths closer than this (nm) are the same sample (float noise in CSV headers).
WAVELENGTH_TOL_NM = 1e-6


def parse_grid(spec: str = DEFAULT_GRID_NM) -> np.ndarray:
    """``"START:STOP:STEP"`` in nm (inclusive) → (n_λ,) float array.

    >>> parse_grid("380:400:10")
    array([380., 390., 400.])
    """
    parts = str(spec).split(":")
    try:
        start, stop, step = (float(p) for p in parts)
    except ValueError:
        raise InputError(f"--grid-nm {spec!r} is not START:STOP:STEP in nm",
                         fix="e.g. --grid-nm 380:780:10") from None
    if not (np.isfinite([start, stop, step]).all() and step > 0 and stop > start and start > 0):
        raise InputError(f"--grid-nm {spec!r} needs 0 < START < STOP and STEP > 0",
                         fix="e.g. --grid-nm 380:780:10")
    n = (stop - start) / step
    if abs(n - round(n)) > 1e-6:
        raise InputError(f"--grid-nm {spec!r}: STOP - START is not a multiple of STEP",
                         fix="e.g. --grid-nm 380:780:10")
    return start + step * np.arange(int(round(n)) + 1)


def covers(wavelength_nm_in, grid_nm) -> bool:
    """True if the input wavelengths span the whole grid (no extrapolation needed)."""
    w = np.asarray(wavelength_nm_in, dtype=float)
    g = np.asarray(grid_nm, dtype=float)
    return bool(w.min() <= g.min() + WAVELENGTH_TOL_NM and w.max() >= g.max() - WAVELENGTH_TOL_NM)


def same_grid(a, b) -> bool:
    """True if two wavelength lists are the same samples."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.all(np.abs(a - b) <= WAVELENGTH_TOL_NM))


def resample(wavelength_nm_in, values, grid_nm) -> np.ndarray:
    """Resample spectra (..., n_in) given at ``wavelength_nm_in`` onto ``grid_nm``.

    Where the input is finer than the grid step, each grid sample is the average of the
    input under a triangle (hat) of the grid's step width, the projection onto the grid's
    linear-interpolation basis, so instrument noise at 1 nm is averaged rather than
    point-sampled (aliased). Where the input is as coarse or coarser, linear interpolation.
    Both are shape preserving: non-negative in, non-negative out (no overshoot).
    The input must cover the grid (:func:`covers`); extrapolation is refused by callers.
    """
    w = np.asarray(wavelength_nm_in, dtype=float)
    g = np.asarray(grid_nm, dtype=float)
    v = np.asarray(values, dtype=float)
    if same_grid(w, g):
        return v.copy()
    step_in = np.min(np.diff(w)) if w.size > 1 else np.inf
    step_out = np.min(np.diff(g)) if g.size > 1 else np.inf
    interp = np.apply_along_axis(lambda row: np.interp(g, w, row), -1, v)
    if step_in >= step_out:
        return interp
    # Hat weights (n_grid, n_in), rows normalised to 1.
    weights = np.maximum(0.0, 1.0 - np.abs(w[None, :] - g[:, None]) / step_out)
    total = weights.sum(axis=1, keepdims=True)
    # Every input sample with non-zero weight under a hat must exist: a half hat at a
    # just-covered end is a one-sided mean, biased by about slope × step / 3, so those
    # samples keep linear interpolation.
    reach = step_out - step_in - WAVELENGTH_TOL_NM
    ok = (total[:, 0] > 0) & (g - reach >= w.min()) & (g + reach <= w.max())
    weights = np.where(ok[:, None], weights / np.where(total > 0, total, 1.0), 0.0)
    hat = v @ weights.T
    return np.where(ok, hat, interp)


# ----------------------------------------------------------------------------- colour --

#: Version of the cached colour tables (bump when :func:`_colour_tables` changes).
COLOUR_TABLES_VERSION = 1


@functools.lru_cache(maxsize=1)
def colour_tables() -> dict[str, np.ndarray]:
    """The colour-science tables gonio uses, cached on disk (:mod:`gonio_cli.cache`).

    colour-science takes ~1.5 s to import; its CMFs, illuminants, the sRGB matrix and the
    Mallett–Yuksel basis are read once from it and kept in a cache file named by the
    colour-science version, so a render or a report does not pay the import again.
    """
    from importlib.metadata import version

    from .cache import cached_arrays

    name = (f"colour-tables-v{COLOUR_TABLES_VERSION}-"
            f"colour-science-{version('colour-science')}.npz")
    return cached_arrays(name, _colour_tables,
                         check=lambda d: {"cmfs_wl", "srgb_matrix", "basis_wl"} <= set(d))


def _colour_tables() -> dict[str, np.ndarray]:
    import colour  # the only place gonio imports colour-science for its data

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    basis = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    out = {"cmfs_wl": np.asarray(cmfs.wavelengths, dtype=float),
           "cmfs_values": np.asarray(cmfs.values, dtype=float),
           "srgb_matrix": np.asarray(colour.RGB_COLOURSPACES["sRGB"].matrix_XYZ_to_RGB,
                                     dtype=float),
           "basis_wl": np.asarray(basis.wavelengths, dtype=float),
           "basis_values": np.asarray(basis.values, dtype=float)}
    names = sorted(colour.SDS_ILLUMINANTS)
    out["illuminant_names"] = np.array(names)
    for k, n in enumerate(names):
        sd = colour.SDS_ILLUMINANTS[n]
        out[f"illuminant{k}_wl"] = np.asarray(sd.wavelengths, dtype=float)
        out[f"illuminant{k}_values"] = np.asarray(sd.values, dtype=float)
    return out


@functools.lru_cache(maxsize=8)
def _cmfs_cached(grid_key: tuple[float, ...]) -> np.ndarray:
    t = colour_tables()
    return np.stack([np.interp(grid_key, t["cmfs_wl"], t["cmfs_values"][:, k])
                     for k in range(3)], axis=-1)


def cmfs(grid_nm) -> np.ndarray:
    """CIE 1931 2° colour-matching functions on the grid, (n_λ, 3)."""
    return _cmfs_cached(tuple(float(x) for x in np.asarray(grid_nm))).copy()


def spectrum_to_xyz(radiance, grid_nm) -> np.ndarray:
    """XYZ of spectra (..., n_λ): Σλ L cmf / Σλ ȳ (docs/conventions.md). Returns (..., 3)."""
    cm = cmfs(grid_nm)
    return np.asarray(radiance, dtype=float) @ cm / cm[:, 1].sum()


def xyz_to_linear_srgb_matrix() -> np.ndarray:
    """IEC 61966-2-1 XYZ → linear sRGB matrix (D65 white), from colour-science. (3, 3)."""
    return colour_tables()["srgb_matrix"].copy()


def xyz_to_linear_srgb(xyz) -> np.ndarray:
    """XYZ (..., 3) → linear sRGB (..., 3), no chromatic adaptation (docs/conventions.md)."""
    return np.asarray(xyz, dtype=float) @ xyz_to_linear_srgb_matrix().T


def srgb_encode(linear) -> np.ndarray:
    """IEC 61966-2-1 transfer function, linear [0, 1] → encoded [0, 1] (clipped)."""
    x = np.clip(np.asarray(linear, dtype=float), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


#: sRGB (IEC 61966-2-1) decode: encoded values up to this are on the linear segment.
SRGB_DECODE_BREAK = 0.04045

def srgb_decode(encoded: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB transfer function inverted: encoded [0, 1] → linear [0, 1].

    The inverse of :func:`srgb_encode` (same standard, same break
    point); float32 in, float32 out, shape kept.

    >>> float(srgb_decode(np.float32(0.5)).round(6))
    0.214041
    """
    x = np.clip(np.asarray(encoded, dtype=np.float32), 0.0, 1.0)
    return np.where(x <= SRGB_DECODE_BREAK, x / np.float32(12.92),
                    ((x + np.float32(0.055)) / np.float32(1.055)) ** np.float32(2.4)
                    ).astype(np.float32)


def illuminant_names() -> list[str]:
    """Names of the CIE illuminants colour-science knows (``D65``, ``A``, ``FL2`` …)."""
    return [str(n) for n in colour_tables()["illuminant_names"]]


def illuminant(name: str, grid_nm) -> np.ndarray:
    """A CIE illuminant by name (``D65``, ``A``, ``FL2`` …) on the grid, scaled so that
    Σ S ȳ / Σ ȳ = 1 (docs/conventions.md). (n_λ,)."""
    t = colour_tables()
    names = illuminant_names()
    if name not in names:
        raise InputError(f"unknown illuminant {name!r}",
                         fix=f"use one of {', '.join(names[:12])}, ... or a CSV")
    k = names.index(name)
    s = np.interp(np.asarray(grid_nm, dtype=float), t[f"illuminant{k}_wl"],
                  t[f"illuminant{k}_values"])
    ybar = cmfs(grid_nm)[:, 1]
    return s * ybar.sum() / (s @ ybar)


def rgb_spectral_basis(grid_nm) -> np.ndarray:
    """(n_λ, 3): a linear-sRGB radiance ``rgb`` is the spectrum ``basis @ rgb``.

    docs/conventions.md: D65(λ) · Σc rgb_c B_c(λ), with B_c the Mallett–Yuksel 2019 sRGB basis and
    D65 scaled to Y = 1, so (1, 1, 1) is D65 with Y = 1 and each channel is carried alone.
    """
    t = colour_tables()
    g = np.asarray(grid_nm, dtype=float)
    basis = np.stack([np.interp(g, t["basis_wl"], t["basis_values"][:, k]) for k in range(3)],
                     axis=-1)
    return illuminant("D65", g)[:, None] * basis
