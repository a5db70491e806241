"""Spectral kernels of the shading stage and their registry (the ``"table"`` path of
:mod:`gonio_cli.render.shade`).

A kernel is the spectral part of one material under one light spectrum: it maps the
cosines of n pixels and their E cos θi to XYZ (n, 3). :data:`TABLE_KERNELS` holds the
models with a faster form than the 41-wavelength sum (the goniochromatic table, the
separable Torrance–Sparrow and Cook–Torrance forms), :data:`SINGLE_PRECISION` the ones
that run in float32, and :func:`make_kernel` picks one (or the exact sum). The equations
and measured tolerances are in :mod:`gonio_cli.render.shade`'s docstring; the dispatch
over objects, lights and pixels stays there. Re-exported by :mod:`gonio_cli.render.shade`.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from ..brdf import (cook_torrance_specular_geometry, goniochromatic_d4_into,
                    goniochromatic_exponent_arg_into, schlick_fresnel, torrance_sparrow)
from ..geometry import Cosines, reflect
from ..lobes import phong_lobe
from ..schemas import Material
from ..spectra import cmf_weights

# ------------------------------------------------------------------------ constants --

#: Smallest goniochromatic table (entries over x ∈ [0, 1]); doubled (as 2^k + 1) until
#: :data:`TABLE_REL_TOL` holds.
TABLE_MIN_SIZE = 33

#: Largest table size tried (~1e-9 relative for c ≤ 10 if ever reached).
TABLE_MAX_SIZE = 65537

#: Largest relative error of the table's linear interpolation, measured at the midpoints
#: between entries. 1e-5 is ~1e-3 CIEDE2000 units, far below what a print shows.
TABLE_REL_TOL = 1e-5

#: Smallest GGX α whose goniochromatic table kernel runs in float32: the float32 G-buffer
#: normal and float32 dot products leave ~4e-7 of round-off in sin²θh = (1 − cos θh)(1 +
#: cos θh), which moves D (seed 000 eq. 3, denominator α² cos²θh + sin²θh) by ~4e-7 / α²
#: relative on its peak: ≤ 1.6e-4 from α = 0.05 (far below a visible colour difference).
#: Sharper lobes take float64 (from the same float32 G-buffer rows).
FLOAT32_MIN_ALPHA = 0.05

#: Pixels per block of the exact path: a block's (n, n_λ) spectra take ~21 MB in float64.
EXACT_BLOCK = 65536


class Scratch:
    """Named 1-D buffers of one dtype, reused by every block of the direct-light loop
    (fresh arrays would page-fault and leave the cache): ``scratch(name, m)`` is the
    first m elements of the buffer ``name`` (another dtype: its third argument)."""

    def __init__(self, dtype, size: int):
        self.dtype, self.size = np.dtype(dtype), max(int(size), 1)
        self._buffers: dict[str, np.ndarray] = {}

    def __call__(self, name: str, m: int, dtype=None) -> np.ndarray:
        buf = self._buffers.get(name)
        if buf is None or buf.shape[0] < m:
            buf = self._buffers[name] = np.empty(max(m, self.size), dtype or self.dtype)
        return buf[:m]


# ------------------------------------------------------------------------ spectral kernels --
#
# A kernel is the spectral part of one material under one light spectrum: called with the
# :class:`Cosines` of n pixels, the factor E cos θi (n,) (0 where the pixel is unlit) and a
# zero-argument callable giving the directions (ωi, ωo, N) (n, 3) for kernels that need
# them (the measured reference, the Phong substrate), it returns XYZ (n, 3). ``cheap``
# kernels cost a few array passes per pixel and run on unlit pixels too (their scale is
# 0), which is cheaper than compacting; the others run on lit pixels only.

Directions = Callable[[], tuple[np.ndarray, np.ndarray, np.ndarray]]
Kernel = Callable[[Cosines, np.ndarray, Directions], np.ndarray]


def xyz_weights(spectrum: np.ndarray, wavelength_nm: np.ndarray,
                observer: np.ndarray | None = None) -> np.ndarray:
    """S(λ) cmf(λ) / Σ ȳ: (n_λ, 3), so XYZ of a reflected spectrum f·S is f @ this.

    ``observer`` (n_λ, C) replaces cmf / Σ ȳ: every kernel is linear in these weights
    and returns C channels, so columns of the identity give the radiance at C
    wavelengths (the spectral image, :func:`gonio_cli.render.spectral_pass.spectral_radiance`)."""
    if observer is None:
        observer = cmf_weights(wavelength_nm)
    return np.asarray(spectrum, dtype=float)[:, None] * np.asarray(observer, dtype=float)


def goniochromatic_table(rho: np.ndarray, c: np.ndarray, weights: np.ndarray,
                         rel_tol: float = TABLE_REL_TOL) -> np.ndarray:
    """T(x) = Σλ ρ exp(c x) S cmf / Σ ȳ on x ∈ [0, 1] (seed 000 eqs. 4-5 without D/4).

    Parameters
    ----------
    rho, c : (n_λ,) the ink's spectral parameters (eq. 5).
    weights : (n_λ, 3) S cmf / Σ ȳ (:func:`xyz_weights`).
    rel_tol : largest relative error of linear interpolation, checked at the midpoints.

    Returns
    -------
    (n_x, 3) float64, entries at x = k / (n_x − 1); n_x = 2^j + 1 ≥ :data:`TABLE_MIN_SIZE`.
    """
    w = np.asarray(rho, dtype=float)[:, None] * weights                  # (n_λ, 3)
    c = np.asarray(c, dtype=float)
    n = TABLE_MIN_SIZE
    while True:
        x = np.linspace(0.0, 1.0, 2 * n - 1)                            # entries + midpoints
        values = np.exp(np.outer(x, c)) @ w
        table, mid = values[0::2], values[1::2]
        interp = 0.5 * (table[:-1] + table[1:])
        scale = np.maximum(np.abs(mid), np.abs(table).max(axis=0) * 1e-12)
        # an all-zero ink (ρ = 0) is exact at any size: 0/0 would grow the table to its cap
        scale = np.maximum(scale, np.finfo(float).tiny)
        if np.max(np.abs(interp - mid) / scale) <= rel_tol or n >= TABLE_MAX_SIZE:
            return table
        n = 2 * n - 1


class TableLookup:
    """Linear interpolation of a (n_x, 3) table over x ∈ [0, 1]: per interval its value
    and slope, one contiguous (3, n_x − 1) array of each in the dtype of the lookup (a
    float32 lookup reads float32 tables: half the bytes, the same ~1e-7 relative error the
    G-buffer has), so a lookup is six 1-D gathers from tables that stay in L1/L2."""

    def __init__(self, table: np.ndarray):
        table = np.asarray(table, dtype=np.float64)
        self.size, self.channels = table.shape
        self.n = table.shape[0] - 1
        self._tables = {np.dtype(np.float64): (np.ascontiguousarray(table[:-1].T),
                                               np.ascontiguousarray(np.diff(table, axis=0).T))}

    def tables(self, dtype) -> tuple[np.ndarray, np.ndarray]:
        """(value, slope), each (3, n_x − 1) in ``dtype``."""
        dtype = np.dtype(dtype)
        if dtype not in self._tables:
            self._tables[dtype] = tuple(t.astype(dtype) for t in self._tables[np.dtype(np.float64)])
        return self._tables[dtype]

    def __call__(self, x: np.ndarray) -> np.ndarray:
        """(n,) x → (n, 3); x is clamped to [0, 1]."""
        x = np.asarray(x, dtype=float)
        out = np.zeros((self.channels, x.size))
        self.accumulate(x, np.ones_like(x), out, Scratch(x.dtype, x.size))
        return out.T

    def accumulate(self, x: np.ndarray, g: np.ndarray, out: np.ndarray, scratch) -> None:
        """out[c] += g · T_c(x) for the three channels c: x, g (m,) ; out (3, m), all of
        one dtype; x clamped to [0, 1] (NaN reads entry 0: the NaN of g carries it)."""
        m = x.shape[0]
        value, slope = self.tables(x.dtype)
        pos = np.multiply(x, x.dtype.type(self.n), out=scratch("pos", m))
        np.fmax(pos, 0, out=pos)                             # fmax/fmin: NaN → 0
        np.fmin(pos, self.n, out=pos)
        fl = np.floor(pos, out=scratch("floor", m))
        np.fmin(fl, self.n - 1, out=fl)                      # x = 1: the last interval, t = 1
        i = scratch("index", m, np.intp)
        np.copyto(i, fl, casting="unsafe")
        t = np.subtract(pos, fl, out=pos)
        gt = np.multiply(g, t, out=t)
        a = scratch("gathered", m)
        for c in range(value.shape[0]):
            np.take(value[c], i, out=a, mode="clip")   # "raise" would buffer out
            a *= g
            out[c] += a
            np.take(slope[c], i, out=a, mode="clip")
            a *= gt
            out[c] += a


def table_lookup(table: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Linear interpolation of a (n_x, 3) table over [0, 1] at x (n,) → (n, 3)."""
    return TableLookup(table)(x)


def _exact_kernel(material, weights: np.ndarray) -> Kernel:
    """The 41-wavelength sum: f (n, n_λ) · E cos θi, then @ S cmf / Σ ȳ, in blocks."""
    fitted = isinstance(material, Material)

    def kernel(cos, scale, directions):
        out = np.empty((scale.shape[0], weights.shape[1]))
        dirs = None if fitted else directions()
        for s in range(0, scale.shape[0], EXACT_BLOCK):
            b = slice(s, s + EXACT_BLOCK)
            if fitted:
                f = material.evaluate(Cosines(*(a[b] for a in cos)))
            else:
                f = material.evaluate_directions(*(a[b] for a in dirs))
            out[b] = (f * scale[b, None]) @ weights
        return out

    kernel.cheap = False
    return kernel


def _goniochromatic_kernel(material: Material, weights: np.ndarray) -> Kernel:
    """Seed 000 eq. 5 through :func:`goniochromatic_table`: D/4 · E cos θi · T(x), in the
    dtype of the cosines, accumulated in place (``kernel.accumulate``)."""
    p = material.params
    lookup = TableLookup(goniochromatic_table(p["rho"], p["c"], weights))
    alpha = float(p["alpha"])

    def accumulate(cos, scale, out, scratch):
        """out (3, m) += XYZ of the m pixels (cos_theta_d is not read)."""
        x = goniochromatic_exponent_arg_into(cos.cos_theta_i, cos.cos_theta_o, scratch)
        g = goniochromatic_d4_into(cos.cos_theta_h, alpha, scratch)
        g *= scale
        lookup.accumulate(x, g, out, scratch)

    def kernel(cos, scale, directions):
        ci = np.asarray(cos.cos_theta_i)
        out = np.zeros((lookup.channels, ci.shape[0]), ci.dtype)
        accumulate(cos, np.asarray(scale, ci.dtype), out, Scratch(ci.dtype, ci.shape[0]))
        return out.T

    kernel.accumulate = accumulate
    kernel.needs_cos_d = False
    kernel.table_size = lookup.size
    kernel.cheap = True
    return kernel


def _torrance_sparrow_kernel(material: Material, weights: np.ndarray) -> Kernel:
    """Seed 000 eq. 2 with Schlick's F = f0 + (1 − f0) m, linear in f0: exact."""
    p = material.params
    f0 = np.asarray(p["f0"], dtype=float)
    xyz_f0, xyz_rest = f0 @ weights, (1.0 - f0) @ weights
    alpha, one, zero = p["alpha"], np.ones(1), np.zeros(1)

    def kernel(cos, scale, directions):
        geo = torrance_sparrow(cos, alpha, one)[:, 0] * scale       # F = 1: G D / (4 ci co)
        m = schlick_fresnel(cos.cos_theta_d, zero)[:, 0]              # (1 − cos θd)^5
        return geo[:, None] * (xyz_f0 + m[:, None] * xyz_rest)

    kernel.cheap = True
    return kernel


def _cook_torrance_kernel(material: Material, weights: np.ndarray) -> Kernel | None:
    """Seed 004 eq. 11, separable when the Beckmann slope m is the same at every λ."""
    p = material.params
    m_slope = np.asarray(p["m"], dtype=float)
    if np.ptp(m_slope) > 0:
        return None
    ks, f0 = np.asarray(p["ks"], dtype=float), np.asarray(p["f0"], dtype=float)
    xyz_kd = (np.asarray(p["kd"], dtype=float) / np.pi) @ weights
    xyz_f0, xyz_rest = (ks * f0) @ weights, (ks * (1.0 - f0)) @ weights
    m1, zero = m_slope[:1], np.zeros(1)

    def kernel(cos, scale, directions):
        geo = cook_torrance_specular_geometry(cos, m1)[:, 0]
        fm = schlick_fresnel(cos.cos_theta_d, zero)[:, 0]
        return scale[:, None] * (xyz_kd + geo[:, None] * (xyz_f0 + fm[:, None] * xyz_rest))

    kernel.cheap = True
    return kernel


def _goniochromatic_layers_kernel(material: Material, weights: np.ndarray) -> Kernel | None:
    """``goniochromatic-diffuse`` and ``-coat`` (:func:`gonio_cli.brdf.goniochromatic_coat`):
    the Lambertian body ρ_d/π (one XYZ), eq. 5 through :func:`goniochromatic_table`
    (:func:`_goniochromatic_kernel`, in place) and the achromatic coat (one F0 for every
    λ): its Torrance–Sparrow factor times the light's XYZ. Exact but for eq. 5's table."""
    p = material.params
    coat = material.model == "goniochromatic-coat"
    f0 = np.atleast_1d(np.asarray(p.get("f0_coat", 0.0), dtype=float))
    if f0.size != 1:
        return None
    eq5 = _goniochromatic_kernel(material, weights)
    xyz_d = (np.asarray(p["rho_d"], dtype=float) / np.pi) @ weights
    xyz_light = np.ones(weights.shape[0]) @ weights
    k_coat = float(p["k_coat"]) if coat else 0.0

    def accumulate(cos, scale, out, scratch):
        """out (3, m) += XYZ of the m pixels."""
        eq5.accumulate(cos, scale, out, scratch)
        g = scale
        if coat:                                     # k F G D / (4 ci co) · E cos θi
            g = torrance_sparrow(cos, p["alpha_coat"], f0)[:, 0]
            g *= k_coat
            g *= scale
        tmp = scratch("layer", scale.shape[0])
        for c in range(out.shape[0]):
            np.multiply(scale, scale.dtype.type(xyz_d[c]), out=tmp)
            out[c] += tmp
            if coat:
                np.multiply(g, xyz_light[c], out=tmp)
                out[c] += tmp

    def kernel(cos, scale, directions):
        ci = np.asarray(cos.cos_theta_i)
        out = np.zeros((weights.shape[1], ci.shape[0]), ci.dtype)
        accumulate(cos, np.asarray(scale, ci.dtype), out, Scratch(ci.dtype, ci.shape[0]))
        return out.T

    kernel.accumulate = accumulate
    kernel.table_size = eq5.table_size
    kernel.cheap = True
    return kernel


#: Models with a faster spectral form than the 41-wavelength sum (STYLE 3). Each builder
#: returns a :data:`Kernel`, or None where the form does not apply (then: exact).
TABLE_KERNELS: dict[str, Callable[[Material, np.ndarray], Kernel | None]] = {
    "goniochromatic": _goniochromatic_kernel,
    "goniochromatic-diffuse": _goniochromatic_layers_kernel,
    "goniochromatic-coat": _goniochromatic_layers_kernel,
    "torrance-sparrow": _torrance_sparrow_kernel,
    "cook-torrance": _cook_torrance_kernel,
}


#: Table kernels that run in float32 on a float32 G-buffer (STYLE 3), with the condition
#: on the material; every other kernel works in float64 (from the same G-buffer rows).
SINGLE_PRECISION: dict[str, Callable[[Material], bool]] = {
    "goniochromatic": lambda m: float(m.params["alpha"]) >= FLOAT32_MIN_ALPHA,
}


def work_dtype(material, spectral: str, gbuffer_dtype, substrate: bool = False) -> np.dtype:
    """The dtype the direct-light loop of :mod:`gonio_cli.render.shade` computes a term in:
    the G-buffer's (float32 in the pipeline) for a :data:`SINGLE_PRECISION` table kernel,
    float64 otherwise."""
    if (np.dtype(gbuffer_dtype) == np.float32 and not substrate and spectral == "table"
            and isinstance(material, Material) and material.model in SINGLE_PRECISION
            and SINGLE_PRECISION[material.model](material)):
        return np.dtype(np.float32)
    return np.dtype(np.float64)


def make_kernel(material, weights: np.ndarray, spectral: str = "table") -> Kernel:
    """The XYZ kernel of ``material`` under a light whose S cmf / Σ ȳ is ``weights``."""
    if spectral == "table" and isinstance(material, Material) \
            and material.model in TABLE_KERNELS:
        kernel = TABLE_KERNELS[material.model](material, weights)
        if kernel is not None:
            return kernel
    return _exact_kernel(material, weights)


def substrate_kernel(substrate: dict, weights: np.ndarray) -> Kernel:
    """The dim Phong substrate of seed 000 Figure 8 (normalised Phong, ref. 27:
    :func:`gonio_cli.lobes.phong_lobe`)."""
    spectrum = np.asarray(substrate.get("spectrum", 1.0), dtype=float)
    xyz = np.broadcast_to(spectrum, weights.shape[:1]) @ weights
    kd = float(substrate.get("kd", 0.0))
    ks = float(substrate.get("ks", 0.0))
    n = float(substrate.get("shininess", 1.0))

    def kernel(cos, scale, directions):
        f = np.full(scale.shape, kd / np.pi)
        if ks > 0:
            wi, wo, normal = directions()
            cos_rv = np.einsum("ij,ij->i", reflect(wi, normal), wo)
            f = f + ks * phong_lobe(cos_rv, n)
        return (f * scale)[:, None] * xyz

    kernel.cheap = ks == 0
    return kernel
