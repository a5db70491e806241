"""The colour table's part of the confidence intervals (``tabulated-colour``, docs/fit.md).

The table T (n_h, n_d, n_λ) is fitted by a penalised linear solve
(:mod:`.tabulated_colour`): per wavelength (Xᵀ W X + μ_λ R + ridge_λ I) β = Xᵀ W y, R the
second-difference penalty, μ_λ its weight (κ chosen by GCV). Its entries are parameters
like a spectral parameter's: the one at node j and wavelength λ moves only the residuals at
λ, so each wavelength's block of JᵀJ grows from k to k + n_h n_d and the arrow structure of
:mod:`.uncertainty` stays. The covariance is that of the penalised estimator read as the
posterior under the smoothness prior (Wahba 1983, *J. R. Stat. Soc. B* 45, 133; Hastie,
Tibshirani & Friedman, *Elements of Statistical Learning* §5.8):

    C = σ² (JᵀJ + P)⁻¹,   P = μ_λ R + ridge_λ I on each wavelength's table block,

and σ² = Σ r̂² / (n − tr H), tr H = tr((JᵀJ + P)⁻¹ JᵀJ) the effective number of parameters
(the fit's own GCV denominator), not n − p: 64 nodes per wavelength that the penalty ties
together are not 64 free parameters. Without the penalty (μ = 0) this is the Gauss–Newton
covariance and tr H = p.

A penalised estimator is biased towards tables the penalty leaves alone (bilinear in θh
and θd): the posterior intervals cover a table entry on average over the entries, not each
entry at its nominal level (Nychka 1988, *J. Am. Stat. Assoc.* 83, 1134).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..brdf import MODELS, evaluate
from ..schemas.spec import MAX_MAGNITUDE
from .common import FitData
from .gains import scaled
from .tabulated_colour import penalty

#: A floor for divisions by a model value that may be 0.
TINY = 1e-300


def table_columns(model: str, cos, params: dict) -> np.ndarray:
    """(N, n_h n_d): ∂f/∂T_j of each table node j (flattened as a n_d + b), the same at
    every wavelength: f is linear in T with an achromatic slope (the GGX lobe times the
    node's bilinear weight), so evaluating the model with the table's "wavelengths" set to
    the unit tables gives every column at once."""
    spec = MODELS[model]
    shape = np.shape(params[spec.table_params[0]])[:2]
    m = int(np.prod(shape))
    unit = dict(params, **{n: np.zeros(m) for n in spec.spectral_params})
    unit[spec.table_params[0]] = np.eye(m).reshape(*shape, m)
    zero = dict(unit, **{spec.table_params[0]: np.zeros((*shape, m))})
    return evaluate(model, cos, unit) - evaluate(model, cos, zero)


def response_slope(data: FitData, f: np.ndarray, g_rows: np.ndarray,
                   used: np.ndarray) -> np.ndarray:
    """(N, L) ∂r/∂f of the fit's weighted residuals (:func:`.uncertainty._residuals`)."""
    if data.residuals == "log":
        s = np.sqrt(data.w) / np.maximum(f, TINY)
    else:
        s = np.sqrt(data.w) * g_rows[:, None]
    return np.where(used, s, 0.0)


@dataclass
class TableBlocks:
    """JᵀJ of (scalars; per wavelength the spectral elements then the table's nodes), the
    penalty, and the gradient of Σ r² along the table entries."""

    a: np.ndarray          # (s, s)
    b: np.ndarray          # (L, s, k + m)
    d0: np.ndarray         # (L, k + m, k + m), the data's part
    d: np.ndarray          # d0 + the penalty on the table block
    grad: np.ndarray       # (L, m): ∂Σr²/∂T
    mu: np.ndarray         # (L,) the penalty weights μ_λ
    shape: tuple[int, int]


def blocks(data: FitData, model: str, params: dict, js: np.ndarray, jl: np.ndarray,
           f: np.ndarray, r0: np.ndarray, g_rows: np.ndarray, used: np.ndarray,
           kappa: float) -> TableBlocks:
    """The blocks of JᵀJ + P (module doc) for the scalar columns ``js`` (s, N, L), the
    spectral ones ``jl`` (k, N, L) and the table's (analytic, :func:`table_columns`)."""
    x = table_columns(model, data.cos, params)                         # (N, m)
    slope = response_slope(data, f, g_rows, used)                      # (N, L)
    k, m = jl.shape[0], x.shape[1]
    a = np.einsum("anl,bnl->ab", js, js)
    b = np.concatenate([np.einsum("anl,knl->lak", js, jl),
                        np.einsum("anl,nj->laj", js * slope, x)], axis=2)
    d0 = np.zeros((data.wavelength_nm.size, k + m, k + m))
    d0[:, :k, :k] = np.einsum("knl,jnl->lkj", jl, jl)
    d0[:, :k, k:] = np.einsum("knl,nj->lkj", jl * slope, x)
    d0[:, k:, :k] = np.swapaxes(d0[:, :k, k:], 1, 2)
    # the pairs of nodes a configuration weighs together (≤ 16 per row), as the fitter
    j1, j2 = np.nonzero(np.abs(x).T @ np.abs(x))
    d0[:, k + j1, k + j2] = (slope ** 2).T @ (x[:, j1] * x[:, j2])
    alpha = float(params["alpha"])
    mu, r_pen, ridge = penalty(scaled(data, g_rows), alpha, kappa)
    d = d0.copy()
    d[:, k:, k:] += mu[:, None, None] * r_pen + ridge[:, None, None] * np.eye(m)
    grad = 2.0 * np.einsum("nl,nj->lj", r0 * slope, x)
    shape = np.shape(params[MODELS[model].table_params[0]])[:2]
    return TableBlocks(a, b, d0, d, grad, mu, shape)


def effective_parameters(cov, tb: TableBlocks) -> float:
    """tr H = tr(C JᵀJ) with C = (JᵀJ + P)⁻¹ (unscaled, :func:`.uncertainty._covariance`'s
    blocks) and JᵀJ the data's blocks: the scalar block, twice the cross blocks and each
    wavelength's block."""
    c_ss, c_sl, c_ll = cov
    return float(np.trace(c_ss @ tb.a) + 2.0 * np.einsum("alk,lak->", c_sl, tb.b)
                 + np.einsum("lkj,ljk->", c_ll, tb.d0))


def table_entry(t, sd: np.ndarray, undetermined: np.ndarray, reach: np.ndarray,
                z: float) -> dict:
    """The table's ``fit.intervals`` entry: ``low``/``high`` nested as the table
    (n_h, n_d, n_λ), T ± z sd on the linear scale (f is linear in T) clipped at 0; an entry
    the fit clipped to 0 one-sided, [0, ``reach``]; ``one_sided_at`` and
    ``undetermined_at`` flat indices into the table (C order). ``sd``, ``undetermined`` and
    ``reach`` are (L, n_h n_d)."""
    t = np.asarray(t, dtype=float)
    shape = t.shape
    flat = np.moveaxis(t, -1, 0).reshape(shape[-1], -1)                # (L, m)
    side = flat <= 0.0
    low = np.where(side, 0.0, np.maximum(flat - z * sd, 0.0))
    high = np.where(side, reach, flat + z * sd)
    # no curvature along it (data and penalty alike): the whole range, named
    high = np.where(undetermined, MAX_MAGNITUDE, high)
    low = np.where(undetermined, 0.0, low)

    def nested(v):
        return np.moveaxis(v.reshape(shape[-1], *shape[:-1]), 0, -1)

    return {"low": nested(low).tolist(), "high": nested(high).tolist(),
            "transform": "identity",
            "one_sided_at": [int(i) for i in np.flatnonzero(nested(side))],
            "undetermined_at": [int(i) for i in np.flatnonzero(nested(undetermined))]}


#: The stored factor F of each wavelength's covariance block given the scalars (C ≈ F Fᵀ)
#: keeps the leading eigen-directions of C in the metric of the data's JᵀJ block D0 (the
#: generalised eigenproblem C D0 v = λ v: how much each direction moves the fit at the
#: measured configurations) that carry all but :data:`DROPPED_VARIANCE` of tr(C D0), with
#: :data:`METRIC_FLOOR` · mean diag D0 added so that what the data do not see is kept by
#: its variance. By variance alone the wrong directions are kept: the table's uniform
#: shift against ρ_d (the lobe is nearly flat at a multi-angle instrument's geometries)
#: has a large variance and no effect on f. Each number to :data:`FACTOR_DIGITS`
#: significant digits.
DROPPED_VARIANCE = 1e-3
METRIC_FLOOR = 1e-6
FACTOR_DIGITS = 6


def factor(blocks, d0) -> list:
    """F (L, K, r) nested lists with F Fᵀ ≈ ``blocks`` (L, K, K) (above), ``d0`` the data's
    JᵀJ blocks (L, K, K)."""
    c = np.asarray(blocks, dtype=float)
    d0 = np.asarray(d0, dtype=float)
    k = c.shape[1]
    floor = METRIC_FLOOR * np.mean(np.einsum("lkk->lk", d0), axis=1) + TINY
    g = np.linalg.cholesky(d0 + floor[:, None, None] * np.eye(k))      # M = G Gᵀ
    vals, vecs = np.linalg.eigh(np.swapaxes(g, 1, 2) @ c @ g)          # Gᵀ C G
    vals, vecs = np.maximum(vals[:, ::-1], 0.0), vecs[:, :, ::-1]      # largest first
    share = np.cumsum(vals, axis=1) / np.maximum(np.sum(vals, axis=1, keepdims=True), TINY)
    r = int(np.max(np.sum(share < 1.0 - DROPPED_VARIANCE, axis=1))) + 1
    # F = G⁻ᵀ V √Λ: F Fᵀ = G⁻ᵀ (Gᵀ C G) G⁻¹ = C on the kept directions
    f = np.linalg.solve(np.swapaxes(g, 1, 2), vecs[:, :, :r] * np.sqrt(vals[:, None, :r]))
    return significant(f).tolist()


def significant(x) -> np.ndarray:
    """``x`` rounded to :data:`FACTOR_DIGITS` significant digits (shorter JSON)."""
    x = np.asarray(x, dtype=float)
    with np.errstate(divide="ignore"):
        e = np.floor(np.log10(np.where(x != 0, np.abs(x), 1.0)))
    scale = 10.0 ** (FACTOR_DIGITS - 1 - e)
    return np.round(x * scale) / scale


def conditional(cll: np.ndarray, cross, css: np.ndarray):
    """(R (L, k, s'), C (L, k, k)): the spectral elements' regression on the scalars and
    their covariance given them, C_ll − R C_slᵀ (the Gaussian's conditional)."""
    m = css.shape[0]
    cross = np.asarray(cross, dtype=float).reshape(cll.shape[0], m, cll.shape[1])
    reg = np.einsum("lak,ab->lkb", cross, np.linalg.pinv(css)) if m else \
        np.zeros(cll.shape[:2] + (0,))
    cond = cll - np.einsum("lkb,lbj->lkj", reg, cross)
    return reg, 0.5 * (cond + np.swapaxes(cond, 1, 2))
