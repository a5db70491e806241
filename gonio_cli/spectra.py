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

from .cache import cached_arrays
from .errors import InputError
from .names import pick
from .numbers import NumberList
from .schemas import WAVELENGTH_MAX_NM

DEFAULT_GRID_NM = "380:780:10"

#: Two wavelengths closer than this (nm) are the same sample (float noise in CSV headers).
WAVELENGTH_TOL_NM = 1e-6


#: Most samples a working grid may have: 0.1 nm steps over 380–780 nm. Every table of a
#: render and every fit scale with it; beyond, a typo (a step of 1e-300) would ask for
#: more memory than any machine has.
MAX_GRID_SAMPLES = 4001


#: ``--grid-nm`` (and a scene's ``[output] grid_nm``): one inclusive range of wavelengths.
GRID_NM = NumberList("--grid-nm", DEFAULT_GRID_NM, unit="nm", lo=0.0, lo_open=True,
                     hi=WAVELENGTH_MAX_NM, one_range=True, max_count=MAX_GRID_SAMPLES,
                     noun="samples")


def parse_grid(spec: str = DEFAULT_GRID_NM) -> np.ndarray:
    """``"START:STOP:STEP"`` in nm (inclusive) → (n_λ,) float array (:data:`GRID_NM`).

    >>> parse_grid("380:400:10")
    array([380., 390., 400.])
    """
    grid = GRID_NM.parse(spec)
    if len(grid) < 2:
        raise GRID_NM.error(spec, "needs START < STOP")
    return np.asarray(grid)


def grid_spec(wavelength_nm) -> str | None:
    """``"START:STOP:STEP"`` of an evenly spaced grid (as ``--grid-nm`` takes it), or None
    for an uneven one: the inverse of :func:`gonio_cli.spectra.parse_grid`.

    >>> grid_spec([400.0, 410.0, 420.0])
    '400:420:10'
    """
    w = np.asarray(wavelength_nm, dtype=float)
    if w.size < 2:
        return None
    steps = np.diff(w)
    if np.ptp(steps) > WAVELENGTH_TOL_NM:
        return None
    return f"{w[0]:g}:{w[-1]:g}:{steps[0]:g}"


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
COLOUR_TABLES_VERSION = 3


@functools.lru_cache(maxsize=1)
def colour_tables() -> dict[str, np.ndarray]:
    """The colour-science tables gonio uses, cached on disk (:mod:`gonio_cli.cache`).

    colour-science takes ~1.5 s to import; its CMFs, illuminants, the sRGB matrix and the
    Mallett–Yuksel basis are read once from it and kept in a cache file named by the
    colour-science version, so a render or a report does not pay the import again.
    """
    from importlib.metadata import version

    name = (f"colour-tables-v{COLOUR_TABLES_VERSION}-"
            f"colour-science-{version('colour-science')}.npz")
    return cached_arrays(name, _colour_tables,
                         check=lambda d: {"cmfs_wl", "cmfs10_values", "srgb_matrix",
                                          "basis_wl", "acescg_matrix"} <= set(d))


#: RGB colour spaces whose tables are cached (key → colour-science's name): primaries,
#: white point and XYZ → RGB matrix (``{key}_primaries``, ``{key}_whitepoint``,
#: ``{key}_matrix``). The matrices are colour-science's normalised primary matrices.
RGB_SPACES = {"srgb": "sRGB", "acescg": "ACEScg"}


def _colour_tables() -> dict[str, np.ndarray]:
    import colour  # the only place gonio imports colour-science for its data

    cmfs = colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"]
    cmfs10 = colour.MSDS_CMFS["CIE 1964 10 Degree Standard Observer"]
    basis = colour.recovery.MSDS_BASIS_FUNCTIONS_sRGB_MALLETT2019
    out = {"cmfs_wl": np.asarray(cmfs.wavelengths, dtype=float),
           "cmfs_values": np.asarray(cmfs.values, dtype=float),
           "cmfs10_wl": np.asarray(cmfs10.wavelengths, dtype=float),
           "cmfs10_values": np.asarray(cmfs10.values, dtype=float),
           "basis_wl": np.asarray(basis.wavelengths, dtype=float),
           "basis_values": np.asarray(basis.values, dtype=float)}
    for key in RGB_SPACES:                      # primaries (3, 2), white (2,), matrix (3, 3)
        space = colour.RGB_COLOURSPACES[RGB_SPACES[key]]
        out[f"{key}_primaries"] = np.asarray(space.primaries, dtype=float)
        out[f"{key}_whitepoint"] = np.asarray(space.whitepoint, dtype=float)
        out[f"{key}_matrix"] = np.asarray(space.matrix_XYZ_to_RGB, dtype=float)
    names = sorted(colour.SDS_ILLUMINANTS)
    out["illuminant_names"] = np.array(names)
    for k, n in enumerate(names):
        sd = colour.SDS_ILLUMINANTS[n]
        out[f"illuminant{k}_wl"] = np.asarray(sd.wavelengths, dtype=float)
        out[f"illuminant{k}_values"] = np.asarray(sd.values, dtype=float)
    return out


#: Standard observers by their field of view in degrees: the key of their tables.
OBSERVERS = {2: "cmfs", 10: "cmfs10"}


@functools.lru_cache(maxsize=8)
def _cmfs_cached(grid_key: tuple[float, ...], observer: int) -> np.ndarray:
    t = colour_tables()
    key = OBSERVERS[observer]
    return np.stack([np.interp(grid_key, t[f"{key}_wl"], t[f"{key}_values"][:, k])
                     for k in range(3)], axis=-1)


def cmfs(grid_nm, observer: int = 2) -> np.ndarray:
    """Colour-matching functions on the grid, (n_λ, 3): CIE 1931 2° (``observer=2``, the
    renderer's, docs/conventions.md) or CIE 1964 10° (``observer=10``, what multi-angle
    instruments report L*a*b* with)."""
    return _cmfs_cached(tuple(float(x) for x in np.asarray(grid_nm)), observer).copy()


def cmf_weights(grid_nm, observer: int = 2) -> np.ndarray:
    """cmf / Σλ ȳ (n_λ, 3): the XYZ of a spectrum L (..., n_λ) on the grid is L @ this
    (docs/conventions.md), so an equal-energy spectrum of 1 has Y = 1. The one place the
    colour-matching functions are normalised; ``observer`` as in :func:`cmfs`."""
    cm = cmfs(grid_nm, observer)
    return cm / cm[:, 1].sum()


def spectrum_to_xyz(radiance, grid_nm) -> np.ndarray:
    """XYZ of spectra (..., n_λ): Σλ L cmf / Σλ ȳ (docs/conventions.md). Returns (..., 3)."""
    return np.asarray(radiance, dtype=float) @ cmf_weights(grid_nm)


def luminance(spectrum, grid_nm, observer: int = 2) -> np.ndarray:
    """Y = Σλ S ȳ / Σλ ȳ of spectra (..., n_λ) → (...): the ȳ-weighted mean of S."""
    return np.asarray(spectrum, dtype=float) @ cmf_weights(grid_nm, observer)[:, 1]


def unit_luminance(spectrum, grid_nm, observer: int = 2) -> np.ndarray:
    """A light's spectrum S (..., n_λ) scaled so that Σ S ȳ / Σ ȳ = 1 (docs/conventions.md:
    every light and illuminant is normalised so). S must have Y > 0 (:func:`luminance`;
    a caller that reads S from a user's file checks it first)."""
    s = np.asarray(spectrum, dtype=float)
    return s / luminance(s, grid_nm, observer)[..., None]


def reflectance_to_xyz(reflectance, grid_nm, illuminant_name: str = "D65",
                       observer: int = 10) -> np.ndarray:
    """XYZ (..., 3) of reflectance factors (..., n_λ) under an illuminant, white Y = 1.

    X = Σ R S x̄ / Σ S ȳ, the way instruments compute colour (CIE 15, with the tables
    sampled on the grid instead of ASTM E308 weights: < 0.05 CIEDE2000 apart at 10 nm).
    A reflectance factor is R = π f for a BRDF f (docs/conventions.md).
    """
    g = np.asarray(grid_nm, dtype=float)
    s = unit_luminance(illuminant(illuminant_name, g), g, observer)   # Y = 1 for this observer
    return (np.asarray(reflectance, dtype=float) * s) @ cmf_weights(g, observer)


#: CIE 1976 L*a*b*: the cube root's linear segment below (6/29)³ (CIE 15:2004 §8.2.1).
_LAB_EPS = (6.0 / 29.0) ** 3


def xyz_to_lab(xyz, white_xyz) -> np.ndarray:
    """CIE 1976 L*a*b* (..., 3) of XYZ (..., 3) relative to the white ``white_xyz`` (3,)."""
    r = np.asarray(xyz, dtype=float) / np.asarray(white_xyz, dtype=float)
    f = np.where(r > _LAB_EPS, np.cbrt(r), r / (3 * (6.0 / 29.0) ** 2) + 4.0 / 29.0)
    return np.stack([116.0 * f[..., 1] - 16.0, 500.0 * (f[..., 0] - f[..., 1]),
                     200.0 * (f[..., 1] - f[..., 2])], axis=-1)


def delta_e_2000(lab_1, lab_2) -> np.ndarray:
    """CIEDE2000 colour difference (...,) between two L*a*b* arrays (..., 3).

    Sharma, Wu & Dalal (2005) with k_L = k_C = k_H = 1. Written here rather than called
    from colour-science because ``gonio fit`` reports it on every run and importing
    colour-science costs ~1.5 s; the tests check it against colour-science and against
    Sharma's published test pairs.
    """
    L1, a1, b1 = np.moveaxis(np.asarray(lab_1, dtype=float), -1, 0)
    L2, a2, b2 = np.moveaxis(np.asarray(lab_2, dtype=float), -1, 0)
    c_mean = (np.hypot(a1, b1) + np.hypot(a2, b2)) / 2.0
    c7 = c_mean ** 7
    g = 0.5 * (1.0 - np.sqrt(c7 / (c7 + 25.0 ** 7)))
    a1p, a2p = (1.0 + g) * a1, (1.0 + g) * a2
    c1p, c2p = np.hypot(a1p, b1), np.hypot(a2p, b2)
    h1p = np.degrees(np.arctan2(b1, a1p)) % 360.0
    h2p = np.degrees(np.arctan2(b2, a2p)) % 360.0
    d_lp, d_cp = L2 - L1, c2p - c1p
    dh = h2p - h1p
    dh = np.where(dh > 180.0, dh - 360.0, np.where(dh < -180.0, dh + 360.0, dh))
    dh = np.where(c1p * c2p == 0.0, 0.0, dh)
    d_hp = 2.0 * np.sqrt(c1p * c2p) * np.sin(np.radians(dh / 2.0))
    l_mean, cp_mean = (L1 + L2) / 2.0, (c1p + c2p) / 2.0
    h_sum = h1p + h2p
    h_mean = np.where(np.abs(h1p - h2p) <= 180.0, h_sum / 2.0,
                      np.where(h_sum < 360.0, (h_sum + 360.0) / 2.0, (h_sum - 360.0) / 2.0))
    h_mean = np.where(c1p * c2p == 0.0, h_sum, h_mean)
    t = (1.0 - 0.17 * np.cos(np.radians(h_mean - 30.0)) + 0.24 * np.cos(np.radians(2 * h_mean))
         + 0.32 * np.cos(np.radians(3 * h_mean + 6.0))
         - 0.20 * np.cos(np.radians(4 * h_mean - 63.0)))
    d_theta = 30.0 * np.exp(-(((h_mean - 275.0) / 25.0) ** 2))
    cp7 = cp_mean ** 7
    r_c = 2.0 * np.sqrt(cp7 / (cp7 + 25.0 ** 7))
    l50 = (l_mean - 50.0) ** 2
    s_l = 1.0 + 0.015 * l50 / np.sqrt(20.0 + l50)
    s_c = 1.0 + 0.045 * cp_mean
    s_h = 1.0 + 0.015 * cp_mean * t
    r_t = -np.sin(np.radians(2.0 * d_theta)) * r_c
    return np.sqrt((d_lp / s_l) ** 2 + (d_cp / s_c) ** 2 + (d_hp / s_h) ** 2
                   + r_t * (d_cp / s_c) * (d_hp / s_h))


def xyz_to_linear_srgb_matrix() -> np.ndarray:
    """IEC 61966-2-1 XYZ → linear sRGB matrix (D65 white), from colour-science. (3, 3)."""
    return rgb_space_matrix("srgb")


def xyz_to_linear_srgb(xyz) -> np.ndarray:
    """XYZ (..., 3) → linear sRGB (..., 3), no chromatic adaptation (docs/conventions.md)."""
    return np.asarray(xyz, dtype=float) @ xyz_to_linear_srgb_matrix().T


#: Cone-response matrices of von Kries chromatic adaptation transforms (XYZ → sharpened
#: cone space, rows L, M, S), published constants. ``bradford``: Lam 1985 as linearised for
#: ICC.1:2010 Annex E (the CAT of ICC colour management, hence of proofing); ``cat16``:
#: Li et al. 2017, "Comprehensive colour appearance model (CAM16)", Color Res. Appl. 42.
#: tests/test_render_proof.py checks both against colour-science.
CAT_MATRICES = {
    "bradford": np.array([[0.8951, 0.2664, -0.1614],
                          [-0.7502, 1.7135, 0.0367],
                          [0.0389, -0.0685, 1.0296]]),
    "cat16": np.array([[0.401288, 0.650173, -0.051461],
                       [-0.250268, 1.204414, 0.045854],
                       [-0.002079, 0.048952, 0.953127]]),
}


def chromatic_adaptation_matrix(white_src_xyz, white_dst_xyz, method: str = "bradford"
                                ) -> np.ndarray:
    """Von Kries adaptation (3, 3) taking colours seen under ``white_src_xyz`` (3,) to
    their corresponding colours under ``white_dst_xyz`` (3,): M⁻¹ diag(M w_dst / M w_src) M
    with M = :data:`CAT_MATRICES` [method] (complete adaptation, D = 1). Apply as
    ``xyz @ A.T``; the source white maps to the destination white exactly."""
    m = pick(CAT_MATRICES, method, "chromatic adaptation")
    gain = (m @ np.asarray(white_dst_xyz, float)) / (m @ np.asarray(white_src_xyz, float))
    return np.linalg.solve(m, gain[:, None] * m)


def srgb_white_xyz() -> np.ndarray:
    """XYZ (3,) of linear sRGB (1, 1, 1): the display white (D65, Y = 1) of the IEC matrix."""
    return np.linalg.solve(xyz_to_linear_srgb_matrix(), np.ones(3))


def rgb_space_matrix(key: str) -> np.ndarray:
    """XYZ → linear RGB (3, 3) of an RGB space of :data:`RGB_SPACES` (colour-science's
    normalised primary matrix, no chromatic adaptation): its white has RGB (1, 1, 1)."""
    return colour_tables()[f"{key}_matrix"].copy()


def rgb_space_white_xyz(key: str) -> np.ndarray:
    """XYZ (3,), Y = 1, of RGB (1, 1, 1) in an RGB space of :data:`RGB_SPACES`."""
    return np.linalg.solve(rgb_space_matrix(key), np.ones(3))


def rgb_space_chromaticities(key: str) -> tuple[float, ...]:
    """CIE xy of the red, green and blue primaries and of the white of an RGB space of
    :data:`RGB_SPACES`: 8 floats in the order of OpenEXR's ``chromaticities`` attribute."""
    t = colour_tables()
    return tuple(float(v) for v in np.concatenate([t[f"{key}_primaries"].ravel(),
                                                   t[f"{key}_whitepoint"]]))


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

    >>> round(float(srgb_decode(np.float32(0.5))), 6)
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
    return unit_luminance(s, grid_nm)


def rgb_spectral_basis(grid_nm) -> np.ndarray:
    """(n_λ, 3): a linear-sRGB radiance ``rgb`` is the spectrum ``basis @ rgb``.

    docs/conventions.md: D65(λ) · Σc rgb_c B_c(λ), with B_c the Mallett–Yuksel 2019 sRGB basis and
    D65 scaled to Y = 1, so (1, 1, 1) is D65 with Y = 1 and each channel is carried alone.
    """
    g = np.asarray(grid_nm, dtype=float)
    return illuminant("D65", g)[:, None] * rgb_reflectance_basis(g)


def rgb_reflectance_basis(grid_nm) -> np.ndarray:
    """(n_λ, 3): a linear-sRGB reflectance (or BRDF) ``rgb`` is the spectrum ``basis @ rgb``.

    The Mallett–Yuksel 2019 sRGB basis B_c(λ) alone, the conventions' RGB → spectrum
    without its D65 factor: (1, 1, 1) → 1 at every wavelength, and under D65 the spectrum
    shows the colour ``rgb``. Defined on :func:`rgb_reflectance_basis_range_nm` (held
    constant beyond it).
    """
    t = colour_tables()
    g = np.asarray(grid_nm, dtype=float)
    return np.stack([np.interp(g, t["basis_wl"], t["basis_values"][:, k]) for k in range(3)],
                    axis=-1)


def rgb_reflectance_basis_range_nm() -> tuple[float, float]:
    """The wavelengths (nm) the Mallett–Yuksel basis is tabulated on: (380, 780)."""
    wl = colour_tables()["basis_wl"]
    return float(wl[0]), float(wl[-1])
