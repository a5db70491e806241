"""How sure a fit is: 95 % confidence intervals of every fitted parameter (docs/fit.md).

The fit minimises Σ r² over the weighted residuals r = √w (g f − y) (compressive and
linear residuals) or √w (log g f − log y) (log residuals), g the light-source gains (1
without them). Near the optimum the residuals are linear in the parameters u, r ≈ r̂ + J δu,
so the least-squares estimate has the Gauss–Newton covariance

    C = σ² (JᵀJ)⁻¹,   σ² = Σ r̂² / (n − p)

(Seber & Wild 1989, *Nonlinear Regression*, §2.1; Press et al., *Numerical Recipes*
§15.6), n the residuals used (w > 0), p the parameters the data determine. σ² comes from
the residuals, not from the repeats' ``brdf_std``: the fit's weights are scale-free (mean
1, :func:`~.common.prepare`), so the repeats give each reading's *relative* precision
(already in w) but the absolute scale of the scatter around the model is the misfit's,
model error included, which on real data exceeds the repeatability.

**Transforms.** Each parameter is linearised in its natural transform, so the interval
stays in range: log for a positive one (ρ, kd, ks, k_coat, h …), logit for one in (0, 1)
(α, m, F0), none for c. A parameter element at a bound of its range or of the fit's
search (ρ = 0, α = 10⁻³ …) is linearised on the linear scale, one-sided into the range,
and its interval is one-sided: [bound, bound + δ], δ where the local model of the cost
(its slope into the range and its curvature) has risen by 1.645² σ², 1.645 σ where the
fit does not press against the bound (:func:`_reach`). An element the
data do not determine (a direction of JᵀJ with no curvature) gets its whole range and is
named in ``undetermined``: never a NaN.

**Block structure.** A spectral parameter at λ changes only the residuals at λ, so one
central difference that moves a spectral parameter at every wavelength at once gives all
its columns of J: 2 (s + k) + 1 model evaluations in all, s scalar and k spectral
parameters, whatever the number of wavelengths. JᵀJ is then an arrow matrix (a dense
scalar block, block-diagonal k × k per wavelength); the covariance is kept as its scalar
block, the scalar–spectral blocks and the k × k blocks per wavelength. Spectral elements
at two wavelengths are independent given the scalars (the precision matrix has no block
between them), so those blocks are all a draw needs (:mod:`.uncertainty_draws`,
``gonio eval``'s band). The colour table of ``tabulated-colour``: :mod:`.uncertainty_table`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..brdf import MODELS, evaluate
from ..schemas.material import PARAM_RANGES
from .common import ALPHA_MAX, ALPHA_MIN, FitData
from .cook_torrance_lobes import KS_MAX
from .cook_torrance_profile import M_MAX, M_MIN
from .gains import ANGLE_TOL_DEG
from .layered import K_COAT_MAX
from .separable import C_LIMIT
from . import uncertainty_table

#: Confidence level of the intervals, and its two- and one-sided normal quantiles.
LEVEL = 0.95
Z_TWO_SIDED = 1.959963984540054
Z_ONE_SIDED = 1.6448536269514722

#: Central-difference step in the transformed parameter (relative 1e-5 in a log-scaled
#: one): truncation ~1e-10, round-off ~1e-11 relative on f.
FD_STEP = 1e-5

#: An element this close (in its transform, or relative on the linear scale) to a bound is
#: at the bound.
BOUND_TOL = 1e-6

#: Eigenvalues of the normalised JᵀJ below this fraction of the largest are no curvature:
#: the elements that load on them (share > :data:`NULL_SHARE`) are undetermined.
NULL_EIG = 1e-12
NULL_SHARE = 1e-3

#: The fits' own search bounds where they are narrower than the schema's range.
FIT_BOUNDS = {**{k: (ALPHA_MIN, ALPHA_MAX) for k in ("alpha", "alpha_coat", "alpha_2")},
              **{k: (M_MIN, M_MAX) for k in ("m", "m_1", "m_2", "m_3")},
              **{k: (0.0, KS_MAX) for k in ("ks_1", "ks_2", "ks_3")},
              "k_coat": (0.0, K_COAT_MAX), "c": (-C_LIMIT, C_LIMIT)}

#: A floor for divisions by a scale that may be 0 (the smallest normal float's order).
TINY = 1e-300

METHOD = "gauss-newton"

#: A positive parameter whose interval spans more than this factor is "poorly determined"
#: on the verdict line (two decades: the data fix its order of magnitude at best).
POORLY_DETERMINED_RATIO = 100.0


def transform_of(name: str) -> str:
    """"log", "logit" or "identity": the scale on which ``name`` is linearised."""
    r = PARAM_RANGES[name]
    if r.lo == 0.0 and r.hi == 1.0:
        return "logit"
    if r.lo == 0.0:
        return "log"
    return "identity"


def to_u(kind: str, p):
    p = np.asarray(p, dtype=float)
    if kind == "log":
        return np.log(p)
    if kind == "logit":
        return np.log(p) - np.log1p(-p)
    return p


def from_u(kind: str, u):
    u = np.asarray(u, dtype=float)
    if kind == "log":
        return np.exp(u)
    if kind == "logit":
        return 0.5 * (1.0 + np.tanh(0.5 * u))
    return u


def bounds_of(name: str) -> tuple[float, float]:
    """(lowest, highest) value of ``name``: the fit's bounds within the schema's range."""
    r = PARAM_RANGES[name]
    lo, hi = FIT_BOUNDS.get(name, (r.lo, r.hi))
    return float(lo), float(hi)


def at_bound(name: str, p) -> np.ndarray:
    """-1 where an element sits at its lower bound, +1 at its upper, 0 inside."""
    p = np.atleast_1d(np.asarray(p, dtype=float))
    lo, hi = bounds_of(name)
    scale = np.maximum(np.abs(p), TINY)
    low = (p <= lo) | (np.abs(p - lo) <= BOUND_TOL * max(abs(lo), TINY)) if lo != 0 \
        else p <= 0.0
    high = (p >= hi) | (np.abs(p - hi) <= BOUND_TOL * scale) if hi is not None \
        else np.zeros(p.shape, bool)
    return np.where(low, -1, np.where(high, 1, 0))


@dataclass
class Layout:
    """Where each parameter element sits in u: scalars first, then the free log-gains, then
    the spectral elements wavelength by wavelength."""

    scalars: tuple[str, ...]
    spectral: tuple[str, ...]
    n_gains: int          # free gain coordinates (groups − 1: their geometric mean is 1)
    n_wavelengths: int

    @property
    def s(self) -> int:
        return len(self.scalars) + self.n_gains


def _gain_basis(g: int) -> np.ndarray:
    """(g, g − 1) orthonormal basis of the log-gains whose sum is 0 (geometric mean 1)."""
    q, _ = np.linalg.qr(np.eye(g) - 1.0 / g)
    return q[:, :g - 1]


def _residuals(data: FitData, f: np.ndarray, g_rows: np.ndarray, used: np.ndarray):
    gf = f * g_rows[:, None]
    if data.residuals == "log":
        with np.errstate(divide="ignore", invalid="ignore"):
            r = np.sqrt(data.w) * (np.log(np.maximum(gf, TINY)) - np.log(
                np.where(data.positive, data.y, 1.0)))
    else:
        r = np.sqrt(data.w) * (gf - data.y)
    return np.where(used, r, 0.0)


# ----------------------------------------------------------------------- the Jacobian --

def _steps(name: str, p: np.ndarray, side: np.ndarray, kind: str):
    """(plus, minus, divisor) per element: a central step of :data:`FD_STEP` in u inside
    the range; at a bound a one-sided step into the range on the linear scale."""
    nz = np.abs(p[np.abs(p) > 0])
    delta = FD_STEP * max(float(np.median(nz)) if nz.size else 1.0, 1e-12)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(side == 0, to_u(kind, np.where(side == 0, p, 0.5)), 0.0)
    plus = np.where(side == 0, from_u(kind, u + FD_STEP), np.where(side < 0, p + delta, p))
    minus = np.where(side == 0, from_u(kind, u - FD_STEP), np.where(side > 0, p - delta, p))
    return plus, minus, np.where(side == 0, 2.0 * FD_STEP, delta)


def jacobian(model: str, cos, params: dict, sides: dict, response=None):
    """(J_scalar (s, N, L), J_spectral (k, N, L)) of ``response(f)`` (f itself by default)
    with respect to each parameter element on its scale (u inside its range, linear at a
    bound: ``sides``, :func:`at_bound`), f the model at ``cos``; a spectral parameter's
    column at λ is its slice at λ, all found by one central difference (module doc)."""
    spec = MODELS[model]
    response = response or (lambda f: f)

    def column(name):
        p = np.atleast_1d(np.asarray(params[name], dtype=float))
        plus, minus, div = _steps(name, p, sides[name], transform_of(name))
        out = []
        for q in (plus, minus):
            moved = dict(params, **{name: q if np.ndim(params[name]) else float(q[0])})
            out.append(response(evaluate(model, cos, moved)))
        return (out[0] - out[1]) / (div if np.ndim(params[name]) else div[0])

    js = [column(n) for n in spec.scalar_params]
    jl = [column(n) for n in spec.spectral_params]
    shape = (0,) + np.shape(cos.cos_theta_i) + (np.size(next(
        (params[n] for n in spec.spectral_params), np.zeros(1))),)
    return (np.array(js) if js else np.zeros(shape)), (np.array(jl) if jl else np.zeros(shape))


def _gain_columns(data: FitData, f: np.ndarray, gains, g_rows, used) -> np.ndarray:
    """(G − 1, N, L): ∂r/∂z of the free log-gain coordinates z (log g = Q z)."""
    groups = np.array([np.flatnonzero(np.abs(gains.theta_i_deg - t) <= ANGLE_TOL_DEG)[0]
                       for t in data.theta_i_deg])
    per_row = (np.sqrt(data.w) if data.residuals == "log"
               else np.sqrt(data.w) * f * g_rows[:, None])
    per_row = np.where(used, per_row, 0.0)
    q = _gain_basis(gains.gain.size)
    return np.einsum("ng,gz,nl->znl", np.eye(gains.gain.size)[groups], q, per_row)


def _pinv_psd(m: np.ndarray):
    """(pseudo-inverse, elements on a direction without curvature, rank) of symmetric
    positive semi-definite matrices (..., k, k), normalised by their diagonals first."""
    diag = np.einsum("...kk->...k", m)
    zero = diag <= 0
    scale = np.sqrt(np.where(zero, 1.0, diag))
    vals, vecs = np.linalg.eigh(m / (scale[..., :, None] * scale[..., None, :]))
    top = np.max(vals, axis=-1, keepdims=True) if vals.shape[-1] else vals
    null = vals <= NULL_EIG * np.maximum(top, TINY)
    share = np.sum(np.where(null[..., None, :], vecs ** 2, 0.0), axis=-1)
    inv = np.where(null, 0.0, 1.0 / np.where(null, 1.0, vals))
    pinv = np.einsum("...ik,...k,...jk->...ij", vecs, inv, vecs) / (
        scale[..., :, None] * scale[..., None, :])
    return pinv, zero | (share > NULL_SHARE), int((~null).sum())


def _covariance(js: np.ndarray, jl: np.ndarray):
    """(C_ss (s, s), C_sl (s, L, k), C_ll (L, k, k)) of (JᵀJ)⁻¹, the undetermined scalars
    (s,) and spectral elements (L, k), and the rank (:func:`_covariance_of_blocks`)."""
    return _covariance_of_blocks(np.einsum("anl,bnl->ab", js, js),
                                 np.einsum("anl,knl->lak", js, jl),
                                 np.einsum("knl,jnl->lkj", jl, jl))


def _covariance_of_blocks(a: np.ndarray, b: np.ndarray, d: np.ndarray):
    """:func:`_covariance` of the arrow matrix [[A, B], [Bᵀ, D]] (module doc):
    A = J_sᵀJ_s, B_l = J_sᵀJ_l (L, s, k), D_l = J_lᵀJ_l (L, k, k) per wavelength; with the
    Schur complement S = A − Σ B_l D_l⁻¹ B_lᵀ, C_ss = S⁻¹, C_sl = −S⁻¹ B_l D_l⁻¹ and
    C_ll = D_l⁻¹ + D_l⁻¹ B_lᵀ S⁻¹ B_l D_l⁻¹ (block inversion; pseudo-inverses where a
    direction has no curvature)."""
    d_inv, und_l, rank_l = _pinv_psd(d)
    bd = np.einsum("lak,lkj->laj", b, d_inv)               # B_l D_l⁻¹
    s_inv, und_s, rank_s = _pinv_psd(a - np.einsum("laj,lbj->ab", bd, b))
    c_sl = -np.einsum("ab,lbk->alk", s_inv, bd)
    c_ll = d_inv + np.einsum("lak,ab,lbj->lkj", bd, s_inv, bd)
    c_ss = s_inv.copy()
    c_ss[und_s, :] = c_ss[:, und_s] = 0.0
    c_sl[und_s] = 0.0
    c_sl[:, und_l] = 0.0
    c_ll = np.where(und_l[:, :, None] | und_l[:, None, :], 0.0, c_ll)
    return (c_ss, c_sl, c_ll), und_s, und_l, rank_s + rank_l


# ------------------------------------------------------------------------- intervals --

def _reach(sd: np.ndarray, grad_in: np.ndarray, sigma2: float) -> np.ndarray:
    """How far a one-sided interval reaches into the range from its bound: the δ at which
    the local model of the cost, Σr̂² + g δ + σ² δ²/sd² (g ≥ 0 the cost's slope into the
    range, sd² the element's variance), has risen by z² σ², z the one-sided 95 % quantile
    (the likelihood ratio at a boundary, Self & Liang 1987, *J. Am. Stat. Assoc.* 82, 605).
    z · sd where the slope is 0; shorter where the fit presses the element against its
    bound, as a profile of the cost would show."""
    b = np.maximum(np.asarray(grad_in, dtype=float), 0.0) / max(sigma2, TINY)
    z2 = Z_ONE_SIDED ** 2
    var = np.where(sd > 0, sd * sd, 1.0)
    return np.where(sd > 0, 2.0 * z2 / (b + np.sqrt(b * b + 4.0 * z2 / var)), 0.0)


def _interval(name: str, p: np.ndarray, side: np.ndarray, sd: np.ndarray,
              undetermined: np.ndarray, reach: np.ndarray):
    """(low, high) per element (module doc): in the transform inside, one-sided at a
    bound (reaching ``reach`` into the range, :func:`_reach`), the whole range where
    undetermined."""
    kind = transform_of(name)
    lo, hi = bounds_of(name)
    r = PARAM_RANGES[name]
    top = hi if hi is not None else r.hi
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        u = to_u(kind, np.where(side == 0, p, 0.5))
        low = np.where(side == 0, from_u(kind, u - Z_TWO_SIDED * sd),
                       np.where(side < 0, p, p - reach))
        high = np.where(side == 0, from_u(kind, u + Z_TWO_SIDED * sd),
                        np.where(side > 0, p, p + reach))
    # an open end of the range (h > 0 …) is approached, never written
    floor = np.nextafter(r.lo, np.inf) if r.lo_open else r.lo
    low = np.clip(np.where(undetermined, lo, low), floor, top)
    high = np.clip(np.where(undetermined, top, high), floor, top)
    # a logit/log interval rounds onto its open bound only in float: keep it a number
    return np.minimum(low, p), np.maximum(high, p)


def _as_json(x, scalar: bool):
    return float(x[0]) if scalar else [float(v) for v in x]


def _entry(name: str, low, high, side, undetermined, scalar: bool) -> dict[str, Any]:
    return {"low": _as_json(low, scalar), "high": _as_json(high, scalar),
            "transform": transform_of(name),
            "one_sided_at": [int(i) for i in np.flatnonzero(side)],
            "undetermined_at": [int(i) for i in np.flatnonzero(undetermined)]}


def estimate(data: FitData, model: str, params: dict, gains=None,
             smoothness: float | None = None) -> dict[str, Any]:
    """The 95 % intervals of every parameter of a fit (module doc), as the material's
    ``fit.intervals``: ``available`` False (and ``why``) where the data cannot give them.
    ``smoothness``: the κ of a ``tabulated-colour`` fit (its report's ``smoothness``);
    with it the table's entries are parameters under the fit's own penalty
    (:mod:`.uncertainty_table`), without it the table is taken as known."""
    spec = MODELS[model]
    g_rows = (gains.per_configuration(data.theta_i_deg) if gains is not None
              else np.ones(data.n_configurations))
    used = (data.w > 0) & (data.positive if data.residuals == "log" else True)
    sides = {n: at_bound(n, params[n]) for n in spec.scalar_params + spec.spectral_params}
    f = evaluate(model, data.cos, params)
    r0 = _residuals(data, f, g_rows, used)
    js, jl = jacobian(model, data.cos, params, sides,
                      lambda f_moved: _residuals(data, f_moved, g_rows, used))
    grads = (2 * np.einsum("anl,nl->a", js, r0), 2 * np.einsum("knl,nl->lk", jl, r0))
    n_gains = gains.gain.size - 1 if gains is not None and gains.gain.size > 1 else 0
    if n_gains:
        js = np.concatenate([js, _gain_columns(data, f, gains, g_rows, used)])
    layout = Layout(spec.scalar_params, spec.spectral_params, n_gains, data.wavelength_nm.size)
    table = (uncertainty_table.blocks(data, model, params, js, jl, f, r0, g_rows, used,
                                      smoothness)
             if spec.table_params and smoothness is not None else None)
    if table is None:
        cov, und_s, und_l, rank = _covariance(js, jl)
        p_eff = float(rank)
    else:
        cov, und_s, und_l, rank = _covariance_of_blocks(table.a, table.b, table.d)
        p_eff = uncertainty_table.effective_parameters(cov, table)
    n = int(used.sum())
    base = {"level": LEVEL, "method": METHOD, "residuals": data.residuals}
    if n <= p_eff + 0.5:
        return {**base, "available": False,
                "why": f"{n} weighted readings for {p_eff:.4g} parameters: no residual left "
                       f"to estimate the scatter"}
    sigma2 = float(np.sum(r0 ** 2) / (n - p_eff))
    cov = tuple(c * sigma2 for c in cov)
    sd_s = np.sqrt(np.maximum(np.diag(cov[0]), 0.0))
    sd_l = np.sqrt(np.maximum(np.einsum("lkk->lk", cov[2]), 0.0))
    out = {**base, "available": True, "sigma2": sigma2, "dof": n - rank,
           "sigma2_from": "weighted residuals over n - p", "parameters": {}}
    if table is not None:
        out.update(dof=n - p_eff, effective_parameters=p_eff, sigma2_from=(
            "weighted residuals over n - tr H (the penalised fit's effective parameters)"))
    for name in spec.scalar_params + spec.spectral_params:
        scalar = name in spec.scalar_params
        j = (spec.scalar_params if scalar else spec.spectral_params).index(name)
        sd, undetermined, grad = ((sd_s[j:j + 1], und_s[j:j + 1], grads[0][j:j + 1])
                                  if scalar else (sd_l[:, j], und_l[:, j], grads[1][:, j]))
        p = np.atleast_1d(np.asarray(params[name], dtype=float))
        reach = _reach(sd, -sides[name] * grad, sigma2)
        low, high = _interval(name, p, sides[name], sd, undetermined, reach)
        out["parameters"][name] = _entry(name, low, high, sides[name], undetermined, scalar)
    if table is not None:
        k = len(spec.spectral_params)
        out["parameters"][spec.table_params[0]] = uncertainty_table.table_entry(
            params[spec.table_params[0]], sd_l[:, k:], und_l[:, k:],
            _reach(sd_l[:, k:], table.grad, sigma2), Z_TWO_SIDED)
        out["smoothness"] = float(smoothness)
    if n_gains:
        out["sweep_gain"] = _gain_intervals(gains, cov, layout)
    out["covariance"] = _blocks(cov, layout, gains, table)
    return out


def _full_gain_map(layout: Layout, gains) -> np.ndarray:
    """T (s', s): the scalar coordinates → the scalars and every log-gain (log g = Q z)."""
    n_p = len(layout.scalars)
    if not layout.n_gains:
        return np.eye(layout.s)
    g = gains.gain.size
    t = np.zeros((n_p + g, layout.s))
    t[:n_p, :n_p] = np.eye(n_p)
    t[n_p:, n_p:] = _gain_basis(g)
    return t


def _gain_intervals(gains, cov: np.ndarray, layout: Layout) -> dict[str, Any]:
    n_p = len(layout.scalars)
    q = _gain_basis(gains.gain.size)
    c = q @ cov[0][n_p:layout.s, n_p:layout.s] @ q.T
    sd = np.sqrt(np.maximum(np.diag(c), 0.0))
    return {"theta_i_deg": [float(t) for t in gains.theta_i_deg],
            "low": [float(v) for v in gains.gain * np.exp(-Z_TWO_SIDED * sd)],
            "high": [float(v) for v in gains.gain * np.exp(Z_TWO_SIDED * sd)],
            "transform": "log"}


def _blocks(cov, layout: Layout, gains, table=None) -> dict[str, Any]:
    """The covariance as a draw needs it (module doc): the scalar block (the scalars, then
    log g per angle of incidence), the scalar–spectral blocks and the spectral blocks per
    wavelength, each element on its own scale (u, or linear where one-sided); with a
    ``table`` (:mod:`.uncertainty_table`) each wavelength's elements end with the table's
    nodes (``table_shape``, flattened in C order)."""
    t = _full_gain_map(layout, gains)
    c_ss, c_sl, c_ll = cov
    names = list(layout.scalars) + ([f"log_gain_{g:g}" for g in gains.theta_i_deg]
                                    if layout.n_gains else [])
    out = {"scalar_names": names, "spectral_names": list(layout.spectral),
           "scalar": (t @ c_ss @ t.T).tolist(),
           "cross": np.einsum("as,slk->lak", t, c_sl).tolist(),
           "spectral": c_ll.tolist()}
    if table is not None:   # (n_λ, 65, 65) blocks: ~3 MB of JSON; a factor of those given
        # the scalars instead, what a draw needs (:func:`draw`)
        out["table_shape"] = [int(v) for v in table.shape]
        cond = uncertainty_table.conditional(np.asarray(out.pop("spectral")), out["cross"],
                                             np.asarray(out["scalar"]))[1]
        out["conditional_factor"] = uncertainty_table.factor(cond, table.d0)
        out["cross"] = uncertainty_table.significant(out["cross"]).tolist()
    return out


def half_width_text(name: str, value: float, entry: dict) -> str:
    """"alpha 0.180 ± 0.004" (symmetric to 20 %), "alpha 0.18 (0.12-0.27)" otherwise; a
    one-sided interval ("r_sheen 1 (at its upper bound; 95 % >= 0.62)", its far end; "not
    determined below it" where that reaches the range's other end), one spanning more than
    :data:`POORLY_DETERMINED_RATIO`, and one that reaches an end of the range inside it
    (undetermined) say so."""
    low, high = float(entry["low"]), float(entry["high"])
    lo, hi = bounds_of(name)
    edge = np.finfo(float).tiny
    if entry.get("undetermined_at") or (not entry.get("one_sided_at") and (
            low <= max(lo, 0.0) + edge or high >= hi)):
        return f"{name} {value:.3g} (not determined by the data)"
    if entry.get("one_sided_at"):
        upper = low < value if (low < value or high > value) else value >= hi
        far = low if upper else high
        bound, side = ("upper", "below") if upper else ("lower", "above")
        if far <= max(lo, 0.0) + edge or far >= hi:        # it reaches the other end
            return f"{name} {value:.3g} (at its {bound} bound; not determined {side} it)"
        return (f"{name} {value:.3g} (at its {bound} bound; {100 * LEVEL:g} % "
                f"{'>=' if upper else '<='} {far:.2g})")
    if entry.get("transform") in ("log", "logit") and (
            low <= 0 or high > POORLY_DETERMINED_RATIO * low):
        return f"{name} {value:.3g} (poorly determined: {low:.2g}-{high:.2g})"
    lo_w, hi_w = value - low, high - value
    if max(lo_w, hi_w) <= 1.2 * min(lo_w, hi_w) or max(lo_w, hi_w) == 0:
        half = 0.5 * (high - low)
        digits = max(0, min(6, -int(np.floor(np.log10(half))))) if half > 0 else 3
        return f"{name} {value:.{digits}f} ± {half:.{digits}f}"
    return f"{name} {value:.3g} ({low:.3g}-{high:.3g})"
