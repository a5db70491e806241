"""Fit of the Cook–Torrance BRDF per wavelength, seed 004 §5 (eqs. 9–14).

The model (:func:`gonio_cli.brdf.cook_torrance`, seed 004 eq. 11) with Beckmann D (eq. 9),
the V-groove G (eq. 10) and Schlick's F (eq. 12), every parameter per wavelength:

    f = kd/π + ks F(θd) S(m),   S = D G / (π cos θi cos θo),   F = F0 + (1 − F0) q,
    q = (1 − cos θd)⁵.

For a fixed m it is **linear and non-negative** in (kd, a, b) with a = ks F0 and
b = ks (1 − F0):  f = kd/π + a S + b q S. So per wavelength:

1. ``profile`` (always; final with the nlopt optimisers): for any trial m, (kd, a, b) ≥ 0
   by a 3-column non-negative least squares (:func:`nnls3`, exact, all wavelengths and
   trial m at once); with log residuals (default) from the closed form for relative
   residuals (log y − log f ≈ (y − f)/y) plus Gauss–Newton steps, each the same NNLS
   with reweighted targets. m(λ) by a 49-point scan over log m in [:data:`M_MIN`,
   :data:`M_MAX`] and a golden section (:func:`~.common.golden_section`) inside the best
   cell, for all wavelengths at once. ks = a + b, F0 = a/(a + b). Golden section, not
   nlopt: each wavelength has its own m, and :func:`~.alpha.minimize_log_alpha` is a
   scalar search (41 of them would cost 41 × ~65 profile calls instead of ~100).
2. ``levenberg_marquardt`` (``--optimizer scipy-least-squares``): seed 004 §5.2's own
   method, ``scipy.optimize.least_squares(method="lm")`` (MINPACK) per wavelength on all
   four parameters, reparametrised so kd, ks > 0, F0 ∈ (0, 1) and m ∈ (M_MIN, M_MAX)
   (:func:`levenberg_marquardt`), analytic Jacobian, started from the profile solution
   and kept only where it is not worse. The report's ``optimizer`` names what ran.

Identifiability from in-plane data:

- kd: the level far from the specular peak; m: the lobe's width. Both identifiable when
  the lobe is sampled off its peak. Where the fitted lobe vanishes (ks = 0, e.g. a
  diffuse white standard), m and F0 have no effect: m is kept at the search's value,
  F0 = 1, and the report names those wavelengths (``no_specular_lobe_nm``).
- ks and F0 separate **only** through the angular change of Schlick's term, q S: q runs
  from ~1e-6 at θd = 20° to 0.03 at 60° and 0.12 at 70°. For a metal (F0 ≈ 0.9) that is
  a 0.3 % effect at 60°, below 2 % noise; for a clear coat (F0 ≈ 0.04) it is ~70 %. When
  the standard error of F0 (:func:`f0_standard_error`: Gauss–Newton covariance at the
  solution, noise estimated from the residuals) exceeds :data:`F0_SE_MAX`, the data
  cannot separate them: kd, ks, m are refitted with the stable choice F0 = 1 (F ≡ 1, so
  ks is the product ks·F0 the data determine), kept where the data do not reject it
  (likelihood ratio, :data:`CHI2_1DOF_95`) and named in ``f0_not_separable_nm``. Where
  F0 = 1 is rejected the fitted F0 stays, named in ``f0_poorly_determined_nm``.
  ``f0_standard_error`` (L,) is in every report.

Failure is a value: a wavelength with fewer than :data:`MIN_CONFIGURATIONS` usable
readings is named in ``failed_wavelength_nm`` with kd = ks = 0 (f = 0), m = M_MAX, F0 = 1.
Relative RMSE (seed 004 eq. 14) is among the error figures of every report.

Why one module: the fit with its analytic derivatives, the F0 separability test and the
standard errors belong to one model's equations (seed 004 eq. 11); split, the
derivatives would sit away from the function they differentiate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..brdf import LOG_MAX, cook_torrance, cook_torrance_specular_geometry, schlick_fresnel
from ..brdf_jacobians import dlog_beckmann_dlog_m
from ..errors import FitError, InputError
from .alpha import choose_optimizer
from .common import FitData, SINGULAR_TOL, golden_section
from .results import FitOptions, FitReport, ModelFit, Stopwatch, error_figures, nm_list

MODEL = "cook-torrance"

#: Bounds of the Beckmann RMS slope m (seed 004 eq. 9). Below 1e-3 the lobe is ~0.06°
#: wide, narrower than any goniometer's aperture (as for GGX's α, common.ALPHA_MIN).
#: Above 1 (45° RMS facet slope) D is no longer peaked at the normal (that already
#: happens for m² > ½) and is nearly flat over the measured θh: the lobe cannot be told
#: from kd/π. A wavelength whose m reaches a bound is named in the report.
M_MIN, M_MAX = 1e-3, 1.0

#: Scan points over log m (every 15 % in m, as the α scan of common): the profile cost is
#: smooth in log m, so its minimum lies between the best point's neighbours.
M_SCAN_POINTS = 49

#: m counts as at a bound when log m is this close to log M_MIN or log M_MAX (the golden
#: section's final bracket is ~1e-11 wide).
M_AT_BOUND_TOL = 1e-6

#: Golden-section steps inside the two scan cells around the best point (width 0.29 in
#: log m): 0.618^50 · 0.29 ≈ 1e-11, below the float64 resolution of the cost's minimum.
M_GOLDEN_ITERATIONS = 50

#: Gauss–Newton steps on (kd, a, b) for log residuals after the relative-residual start
#: (log y − log f ≈ (y − f)/y). Each step multiplies the error by ~ the residual size
#: (0.02 at 2 % noise; quadratic on exact data), and the profile's value is off by the
#: square of that error: 1 step inside the m search (3 gave the same m to 1e-12 on the
#: tests' synthetic cases, at 3× the time); :data:`FINAL_GN_STEPS` at the chosen m.
SEARCH_GN_STEPS = 1
FINAL_GN_STEPS = 12

#: Gauss–Newton linearises log f at f; where the current model is off by more than this
#: factor (e^6 ≈ 400) the linearisation point is clamped to it, so a far-off trial m
#: cannot give an absurd weight w/f². It only matters in the scan's far tails.
LOG_LINEARISE_LIMIT = 6.0

#: Model values are floored here inside logs (f = 0 needs kd = 0 and a lobe underflowing
#: to 0); log(tiny) ≈ −708 keeps the cost finite and huge.
F_FLOOR = np.finfo(float).tiny

#: Four parameters per wavelength, plus one degree of freedom to estimate the noise that
#: decides whether ks and F0 separate.
MIN_CONFIGURATIONS = 5

#: F0 counts as separable from ks when its standard error is below this. ±0.1 is what it
#: takes to tell a dielectric coat (F0 ≈ 0.04) from a metal (0.5–0.95).
F0_SE_MAX = 0.1

#: The stable choice F0 = 1 replaces a poorly determined F0 only where it raises the
#: cost by less than this many σ² (the 95 % point of χ² with 1 degree of freedom): the
#: likelihood-ratio test of F0 = 1 against a free F0 does not reject it.
CHI2_1DOF_95 = 3.841

#: Equilibrated normal matrices of the covariance with a condition number above this are
#: treated as singular (the direction is not determined at all).
COVARIANCE_COND_MAX = 1e12

#: Starting values for the log/logit parameters of Levenberg–Marquardt must be finite:
#: a profile value of exactly 0 (kd) or 1 (F0) is started this close to it (relative to
#: the wavelength's peak reading for kd).
LM_START_EPS = 1e-9

#: MINPACK tolerances (relative change of cost, step; gradient) and evaluation cap.
LM_TOL = 1e-12
LM_MAX_NFEV = 400

#: Schlick's F at F0 = 0 is q = (1 − cos θd)⁵ (seed 004 eq. 12): q taken from brdf.
_ZERO = np.zeros(1)


# ------------------------------------------------------------------ model pieces --

def nnls3(S: np.ndarray, q: np.ndarray, z: np.ndarray, W: np.ndarray,
          free_b: np.ndarray | None = None) -> np.ndarray:
    """Non-negative least squares of f = kd/π + a S + b q S for every column at once.

    Minimises Σn W (z − f)² over kd, a, b ≥ 0, per column. ``S``, ``z``, ``W``: (N, C);
    ``q``: (N,); ``free_b``: (C,) bool, False forces b = 0 (F0 = 1). Exact: the
    constrained minimum is the unconstrained minimum on its support, so every subset of
    the three columns is solved in closed form (equilibrated normal equations, so each
    singularity test is scale-free), the feasible solutions (non-singular, ≥ 0) are
    compared by their cost Σ W z² − βᵀb, and the cheapest is kept; the empty subset
    (β = 0) is always feasible. Explicit 1×1, 2×2 and 3×3 formulas on (C,) arrays keep a
    call at ~40 numpy operations however many columns there are.
    Returns (3, C) = (kd, a, b).
    """
    qc = q[:, None]
    WS = W * S
    qWS = qc * WS
    p = 1.0 / np.pi
    A = np.empty((3, 3, S.shape[1]))
    A[0, 0] = W.sum(axis=0) * p * p
    A[0, 1] = A[1, 0] = WS.sum(axis=0) * p
    A[0, 2] = A[2, 0] = qWS.sum(axis=0) * p
    A[1, 1] = np.einsum("nc,nc->c", WS, S)
    A[1, 2] = A[2, 1] = np.einsum("nc,nc->c", qWS, S)
    A[2, 2] = np.einsum("nc,nc->c", qWS * qc, S)
    b = np.stack([np.einsum("nc,nc->c", W, z) * p, np.einsum("nc,nc->c", WS, z),
                  np.einsum("nc,nc->c", qWS, z)])                           # (3, C)
    d = np.sqrt(np.maximum(np.diagonal(A).T, 0.0))                           # (3, C)
    live = d > 0
    d = np.where(live, d, 1.0)
    R = A / (d[:, None] * d[None, :])                                        # unit diagonal
    bn = b / d
    best = np.zeros_like(b)
    gain = np.zeros(S.shape[1])                 # βᵀb of the best subset so far (empty: 0)
    allow_b = np.ones(S.shape[1], bool) if free_b is None else free_b

    def consider(beta_n, ok, members):
        nonlocal best, gain
        beta = np.zeros_like(b)
        for k, j in enumerate(members):
            beta[j] = beta_n[k] / d[j]
        ok = ok & np.all(beta >= 0.0, axis=0) & np.all(live[list(members)], axis=0)
        if 2 in members:
            ok &= allow_b
        g = np.einsum("kc,kc->c", beta, b)
        take = ok & (g > gain)
        best = np.where(take, beta, best)
        gain = np.where(take, g, gain)

    for j in range(3):                                                       # one column
        consider([bn[j]], np.ones_like(gain, bool), (j,))
    for i, j in ((0, 1), (0, 2), (1, 2)):                                    # two columns
        r = R[i, j]
        det = 1.0 - r * r
        ok = det > SINGULAR_TOL
        det = np.where(ok, det, 1.0)
        consider([(bn[i] - r * bn[j]) / det, (bn[j] - r * bn[i]) / det], ok, (i, j))
    r01, r02, r12 = R[0, 1], R[0, 2], R[1, 2]                                # all three
    c00, c11, c22 = 1.0 - r12 * r12, 1.0 - r02 * r02, 1.0 - r01 * r01
    c01, c02, c12 = r02 * r12 - r01, r01 * r12 - r02, r01 * r02 - r12
    det = c00 + r01 * c01 + r02 * c02
    ok = det > SINGULAR_TOL
    det = np.where(ok, det, 1.0)
    consider([(c00 * bn[0] + c01 * bn[1] + c02 * bn[2]) / det,
              (c01 * bn[0] + c11 * bn[1] + c12 * bn[2]) / det,
              (c02 * bn[0] + c12 * bn[1] + c22 * bn[2]) / det], ok, (0, 1, 2))
    return best


# --------------------------------------------------------------- profile over m --

@dataclass
class Linear:
    """(kd, a, b) per column and the column's cost in the fit's residuals; (C,) each."""

    kd: np.ndarray
    a: np.ndarray
    b: np.ndarray
    cost: np.ndarray


class Profile:
    """(kd, a, b) optimal for any trial m, and the cost they leave, per wavelength.

    Columns are (trial m, wavelength) pairs: ``solve(log_m, cols)`` takes (C,) log m and
    the wavelength index of each column, so a whole scan is one call.
    """

    def __init__(self, data: FitData):
        self.data = data
        self.q = schlick_fresnel(data.cos.cos_theta_d, _ZERO)[:, 0]          # (N,)
        self.log = data.residuals == "log"
        usable = data.w > 0
        self.n_used = usable.sum(axis=0)
        self.ok = np.any(usable & (data.y > 0), axis=0) & (self.n_used >= MIN_CONFIGURATIONS)
        self.w = data.w * self.ok
        self.y_safe = np.where(data.positive, data.y, 1.0)
        self.log_y = np.log(self.y_safe)

    def specular(self, log_m: np.ndarray) -> np.ndarray:
        """S = D G / (π cos θi cos θo) of eq. 11 for each column's m: (N, C)."""
        return cook_torrance_specular_geometry(self.data.cos, np.exp(log_m))

    def model(self, lin: Linear, S: np.ndarray) -> np.ndarray:
        return lin.kd / np.pi + (lin.a + lin.b * self.q[:, None]) * S

    def cost_of(self, f: np.ndarray, cols: np.ndarray) -> np.ndarray:
        w = self.w[:, cols]
        if self.log:
            r = self.log_y[:, cols] - np.log(np.maximum(f, F_FLOOR))
        else:
            r = self.data.y[:, cols] - f
        return np.einsum("nc,nc->c", w * r, r)

    def solve(self, log_m, cols, free_b=None, steps: int = SEARCH_GN_STEPS) -> Linear:
        """(kd, a, b) ≥ 0 minimising each column's cost for its m; (C,) each.

        ``log_m``, ``cols`` (wavelength index), ``free_b`` (False: F0 = 1): (C,) each.
        Log residuals: relative-residual start, then ``steps`` Gauss–Newton steps; each
        column keeps its cheapest iterate.
        """
        S = self.specular(np.asarray(log_m, dtype=float))
        w, q, fb = self.w[:, cols], self.q, free_b
        if not self.log:
            beta = nnls3(S, q, self.data.y[:, cols], w, fb)
            lin = Linear(*beta, cost=np.zeros(len(cols)))
            lin.cost = self.cost_of(self.model(lin, S), cols)
            return lin
        y, log_y = self.y_safe[:, cols], self.log_y[:, cols]
        beta = nnls3(S, q, y, w / (y * y), fb)                    # relative residuals
        best = Linear(*beta, cost=np.zeros(len(cols)))
        f = self.model(best, S)
        best.cost = self.cost_of(f, cols)
        for _ in range(steps):
            # Gauss–Newton on log residuals: log f(β') ≈ log f + (f(β') − f)/f, i.e. a
            # weighted NNLS with weights w/f² and targets f (1 + log y − log f)
            fl = np.clip(f, y * np.exp(-LOG_LINEARISE_LIMIT), y * np.exp(LOG_LINEARISE_LIMIT))
            beta = nnls3(S, q, fl * (1.0 + log_y - np.log(fl)), w / (fl * fl), fb)
            trial = Linear(*beta, cost=np.zeros(len(cols)))
            f = self.model(trial, S)
            trial.cost = self.cost_of(f, cols)
            better = trial.cost < best.cost
            best = Linear(*(np.where(better, getattr(trial, k), getattr(best, k))
                            for k in ("kd", "a", "b", "cost")))
        return best


def search_m(profile: Profile, cols: np.ndarray, free_b: np.ndarray):
    """m for each wavelength in ``cols`` by scan + golden section over log m.

    Returns (log m (C,), :class:`Linear` at it, evaluations, at_bound (C,) bool).
    """
    grid = np.linspace(np.log(M_MIN), np.log(M_MAX), M_SCAN_POINTS)
    n = len(cols)
    g_all = np.repeat(grid, n)
    c_all = np.tile(cols, M_SCAN_POINTS)
    scan = profile.solve(g_all, c_all, np.tile(free_b, M_SCAN_POINTS)).cost
    scan = np.where(np.isfinite(scan), scan, np.inf).reshape(M_SCAN_POINTS, n)
    i = np.argmin(scan, axis=0)
    lo, hi = grid[np.maximum(i - 1, 0)], grid[np.minimum(i + 1, M_SCAN_POINTS - 1)]

    def cost(log_m):
        return profile.solve(log_m, cols, free_b).cost

    log_m, best = golden_section(cost, lo, hi, M_GOLDEN_ITERATIONS)
    scan_best = scan[i, np.arange(n)]
    log_m = np.where(best <= scan_best, log_m, grid[i])         # never worse than the scan
    lin = profile.solve(log_m, cols, free_b, steps=FINAL_GN_STEPS)
    at_bound = np.minimum(np.abs(log_m - grid[0]), np.abs(log_m - grid[-1])) < M_AT_BOUND_TOL
    # profile evaluations per wavelength: the scan, golden's 2 + 1 per step, the final one
    return log_m, lin, M_SCAN_POINTS + M_GOLDEN_ITERATIONS + 3, at_bound


# ------------------------------------------------------- Levenberg–Marquardt (scipy) --

def levenberg_marquardt(profile: Profile, col: int, kd: float, ks: float, m: float,
                        f0: float, free_f0: bool):
    """Seed 004 §5.2 for one wavelength: MINPACK Levenberg–Marquardt on
    p = (log kd, log ks, logit s, logit F0), log m = log M_MIN + s (log M_MAX − log M_MIN).

    LM has no bounds, so the parametrisation carries them: kd, ks > 0, F0 in (0, 1) and m
    in the profile search's [M_MIN, M_MAX] (an unbounded log m runs off to infinity where
    the lobe vanishes and m has no effect). Residuals √w (log y − log f) or √w (y − f)
    over the used configurations; analytic Jacobian. F0 is held at 1 when ``free_f0`` is
    False. Returns (kd, ks, m, f0, cost, nfev, converged).
    """
    from scipy.optimize import least_squares
    from scipy.special import expit, logit

    data = profile.data
    rows = profile.w[:, col] > 0
    sw = np.sqrt(profile.w[rows, col])
    y, log_y, q = data.y[rows, col], profile.log_y[rows, col], profile.q[rows]
    cos = type(data.cos)(*(c[rows] for c in data.cos))
    scale = float(np.max(np.abs(y)))
    lo, span = np.log(M_MIN), np.log(M_MAX) - np.log(M_MIN)

    def parts(p):
        kd_, ks_ = np.exp(np.minimum(p[:2], LOG_MAX))
        s = float(expit(p[2]))
        m_ = float(np.exp(lo + span * s))
        F0 = float(expit(p[3])) if free_f0 else 1.0
        S = cook_torrance_specular_geometry(cos, np.array([m_]))[:, 0]
        F = F0 + (1.0 - F0) * q
        f = kd_ / np.pi + ks_ * F * S
        return kd_, ks_, m_, s, F0, S, F, f

    def fun(p):
        f = parts(p)[-1]
        r = (log_y - np.log(np.maximum(f, F_FLOOR))) if profile.log else (y - f)
        return sw * r

    def jac(p):
        kd_, ks_, m_, s, F0, S, F, f = parts(p)
        dlog_m = span * s * (1.0 - s)
        cols = [np.full_like(f, kd_ / np.pi), ks_ * F * S,
                ks_ * F * S * dlog_beckmann_dlog_m(cos.cos_theta_h, m_)[:, 0] * dlog_m]
        if free_f0:
            cols.append(ks_ * S * (1.0 - q) * F0 * (1.0 - F0))
        J = np.stack(cols, axis=1)
        if profile.log:
            J = J / np.maximum(f, F_FLOOR)[:, None]
        return -sw[:, None] * J

    def inside(x):
        return float(logit(np.clip(x, LM_START_EPS, 1.0 - LM_START_EPS)))

    p0 = [np.log(max(kd, LM_START_EPS * np.pi * scale)), np.log(ks),
          inside((np.log(m) - lo) / span)]
    if free_f0:
        p0.append(inside(f0))
    res = least_squares(fun, np.array(p0), jac=jac, method="lm", xtol=LM_TOL, ftol=LM_TOL,
                        gtol=LM_TOL, max_nfev=LM_MAX_NFEV)
    kd_, ks_, m_, _, F0, *_ = parts(res.x)
    return (kd_, ks_, m_, F0, float(np.sum(res.fun ** 2)), int(res.nfev + res.njev),
            res.status > 0)


# ------------------------------------------------------------------ identifiability --

def f0_standard_error(profile: Profile, kd, a, b, m, cols) -> np.ndarray:
    """Standard error of F0 = a/(a + b) per column from the Gauss–Newton covariance.

    Parameters (kd, a, b, log m), derivatives of f: 1/π, S, q S, (a + b q) S ∂ log D/∂ log m
    (divided by f for log residuals); covariance σ² (Jᵀ W J)⁻¹ with σ² = cost/(n − 4);
    F0's variance by the delta method. ``inf`` where undetermined (no lobe, a singular
    normal matrix); 0 where the fit is exact (σ = 0).
    """
    S = profile.specular(np.log(m))
    q = profile.q[:, None]
    spec = a + b * q
    D = np.stack([np.full_like(S, 1.0 / np.pi), S, q * S,
                  spec * S * dlog_beckmann_dlog_m(profile.data.cos.cos_theta_h, m)], axis=-1)
    f = kd / np.pi + spec * S
    if profile.log:
        D = D / np.maximum(f, F_FLOOR)[..., None]
    w = profile.w[:, cols]
    M = np.einsum("nc,nci,ncj->cij", w, D, D)                               # (C, 4, 4)
    sigma2 = profile.cost_of(f, cols) / np.maximum(profile.n_used[cols] - 4, 1)
    d = np.sqrt(np.einsum("cii->ci", M))
    ok = np.all(d > 0, axis=1) & (a + b > 0)
    d = np.where(d > 0, d, 1.0)
    Mn = M / (d[:, :, None] * d[:, None, :])
    with np.errstate(divide="ignore", invalid="ignore"):   # cond of a singular matrix: inf
        ok &= np.linalg.cond(np.where(ok[:, None, None], Mn, np.eye(4))) < COVARIANCE_COND_MAX
    Mn = np.where(ok[:, None, None], Mn, np.eye(4))
    inv = np.linalg.inv(Mn) / (d[:, :, None] * d[:, None, :])
    s = np.where(a + b > 0, a + b, 1.0)
    g = np.stack([b, -a], axis=1) / (s * s)[:, None]                        # ∂F0/∂(a, b)
    var = sigma2 * np.einsum("ci,cij,cj->c", g, inv[:, 1:3, 1:3], g)
    return np.where(ok, np.sqrt(np.maximum(var, 0.0)), np.inf)


# ------------------------------------------------------------------------------ fit --

@dataclass
class Spectra:
    """The four spectra of eq. 11, (L,) each, and the per-wavelength cost."""

    kd: np.ndarray
    ks: np.ndarray
    m: np.ndarray
    f0: np.ndarray
    cost: np.ndarray

    FIELDS = ("kd", "ks", "m", "f0", "cost")

    @classmethod
    def empty(cls, L: int) -> "Spectra":
        # failed wavelengths: f = 0 (kd = ks = 0); m and F0 finite and inert
        return cls(np.zeros(L), np.zeros(L), np.full(L, M_MAX), np.ones(L), np.zeros(L))

    def put_linear(self, cols, log_m, lin: Linear) -> None:
        ks = lin.a + lin.b
        self.kd[cols], self.ks[cols], self.m[cols] = lin.kd, ks, np.exp(log_m)
        self.f0[cols] = np.where(ks > 0, lin.a / np.where(ks > 0, ks, 1.0), 1.0)
        self.cost[cols] = lin.cost

    def take(self, other: "Spectra", cols) -> None:
        """Replace the wavelengths ``cols`` by those of ``other``."""
        for k in self.FIELDS:
            getattr(self, k)[cols] = getattr(other, k)[cols]

    def copy(self) -> "Spectra":
        return Spectra(*(np.array(getattr(self, k)) for k in self.FIELDS))

    def params(self) -> dict:
        return {"kd": self.kd, "ks": self.ks, "m": self.m, "f0": self.f0}


@dataclass
class Run:
    """One pass of the fit over some wavelengths: profile solution, LM solution (or
    None), evaluations, LM evaluations, wavelengths where LM did not converge, times."""

    profile: Spectra
    lm: Spectra | None
    evaluations: int
    at_bound: np.ndarray
    lm_nfev: int
    lm_failed: list
    time_profile_s: float
    time_lm_s: float

    @property
    def final(self) -> Spectra:
        return self.lm if self.lm is not None else self.profile


def _keep_profile(profile: Profile, prof: Spectra, cols: np.ndarray, free_f0: bool):
    """``golden-section``: the profile solution is final (no polish)."""
    return None, 0, []


def _polish_lm(profile: Profile, prof: Spectra, cols: np.ndarray, free_f0: bool):
    """``scipy-least-squares``: seed 004's Levenberg–Marquardt per wavelength from the
    profile solution, kept where it is not worse. Returns (spectra, evaluations, the
    wavelengths where it stopped before converging)."""
    lm, nfev, failed = prof.copy(), 0, []
    for c in cols:
        if prof.ks[c] <= 0:  # no lobe: m and F0 inert, the profile's kd is final
            continue
        kd, ks, m, f0, cost, n, ok = levenberg_marquardt(
            profile, c, prof.kd[c], prof.ks[c], prof.m[c], prof.f0[c], free_f0)
        nfev += n
        if not ok:
            failed.append(float(profile.data.wavelength_nm[c]))
        if cost <= prof.cost[c] and np.all(np.isfinite([kd, ks, m, f0])):
            lm.kd[c], lm.ks[c], lm.m[c], lm.f0[c], lm.cost[c] = kd, ks, m, f0, cost
    return lm, nfev, failed


#: ``--optimizer``: what follows the profile fit (scan + golden section over log m, always
#: run); the first is the default.
OPTIMIZERS = {
    "golden-section": _keep_profile,
    "scipy-least-squares": _polish_lm,
}


def _run(profile: Profile, cols: np.ndarray, free_f0: bool, polish) -> Run:
    """Profile fit (and ``polish`` from it, a value of :data:`OPTIMIZERS`) of the
    wavelengths ``cols`` with F0 free or = 1."""
    sw = Stopwatch()
    L = profile.data.wavelength_nm.size
    log_m, lin, evaluations, at_bound = search_m(profile, cols, np.full(cols.size, free_f0))
    prof = Spectra.empty(L)
    prof.put_linear(cols, log_m, lin)
    t_profile = sw.lap()
    lm, nfev, failed = polish(profile, prof, cols, free_f0)
    return Run(prof, lm, evaluations, at_bound, nfev, failed, t_profile, sw.lap())


def fit(data: FitData, options: FitOptions) -> ModelFit:
    """Fit seed 004 eq. (11) per wavelength (kd, ks, m, F0) to prepared data.

    Parameters
    ----------
    data : :class:`~.common.FitData` (N configurations, L wavelengths)
    options : ``optimizer`` (a key of :data:`OPTIMIZERS`): ``scipy-least-squares`` adds
        seed 004's Levenberg–Marquardt after the profile fit; ``golden-section`` (the
        default) leaves the profile fit final. ``alpha``
        does not apply (this model's roughness m is per wavelength).

    Returns
    -------
    :class:`~.results.ModelFit` with reports ``profile`` (and ``levenberg_marquardt``),
    parameters ``kd``, ``ks``, ``m``, ``f0`` (L,) as in :data:`gonio_cli.brdf.MODELS`,
    error figures including seed 004 eq. 14's relative RMSE.

    Raises
    ------
    FitError
        Only when no wavelength has :data:`MIN_CONFIGURATIONS` usable readings.
    """
    if options.alpha is not None:
        raise InputError("--alpha does not apply to --model cook-torrance",
                         fix="its roughness m is fitted per wavelength; drop --alpha")
    profile = Profile(data)
    nm = data.wavelength_nm
    cols = np.flatnonzero(profile.ok)
    if cols.size == 0:
        raise FitError(f"no wavelength has {MIN_CONFIGURATIONS} or more usable readings "
                       "(positive, with weight)", fix="check the measurement")
    _, polish = choose_optimizer(MODEL, OPTIMIZERS, options.optimizer)

    # ---- all four parameters free
    free = _run(profile, cols, True, polish)
    fin = free.final
    a, b = fin.ks[cols] * fin.f0[cols], fin.ks[cols] * (1.0 - fin.f0[cols])
    se = f0_standard_error(profile, fin.kd[cols], a, b, fin.m[cols], cols)

    # ---- where F0 is poorly determined, the stable choice F0 = 1 (b = 0) if the data
    #      do not reject it (likelihood ratio, 1 degree of freedom)
    vague = cols[(se > F0_SE_MAX) & (fin.ks[cols] > 0) & (fin.f0[cols] < 1.0)]
    fixed_cols = np.array([], dtype=int)
    evaluations, lm_nfev, lm_failed = free.evaluations, free.lm_nfev, list(free.lm_failed)
    t_profile, t_lm = free.time_profile_s, free.time_lm_s
    at_bound = np.zeros(nm.size, bool)
    at_bound[cols] = free.at_bound
    if vague.size:
        one = _run(profile, vague, False, polish)
        sigma2 = fin.cost[vague] / np.maximum(profile.n_used[vague] - 4, 1)
        accept = one.final.cost[vague] - fin.cost[vague] <= CHI2_1DOF_95 * sigma2
        fixed_cols = vague[accept]
        free.profile.take(one.profile, fixed_cols)
        if free.lm is not None:
            free.lm.take(one.lm, fixed_cols)
        at_bound[fixed_cols] = one.at_bound[accept]
        evaluations += one.evaluations
        lm_nfev += one.lm_nfev
        fixed_nm = set(nm[fixed_cols].tolist())
        lm_failed = ([x for x in lm_failed if x not in fixed_nm]
                     + [x for x in one.lm_failed if x in fixed_nm])
        t_profile, t_lm = t_profile + one.time_profile_s, t_lm + one.time_lm_s
    fin = free.final

    failed = [float(x) for x in nm[~profile.ok]]
    se_all = np.full(nm.size, np.inf)
    se_all[cols] = se
    vague_kept = np.setdiff1d(vague, fixed_cols)
    notes = {
        "f0_not_separable_nm": [float(x) for x in nm[fixed_cols]],
        "f0_poorly_determined_nm": [float(x) for x in nm[vague_kept]],
        "no_specular_lobe_nm": [float(x) for x in nm[cols[fin.ks[cols] <= 0]]],
        "m_at_bound_nm": [float(x) for x in nm[at_bound]],
        "f0_standard_error": [float(x) if np.isfinite(x) else None for x in se_all],
    }

    def report(method, s: Spectra, optimizer, evals, time_s, message, lm_fail=()):
        msg = [message]
        if failed:
            msg.insert(0, f"fewer than {MIN_CONFIGURATIONS} usable readings at "
                          f"{len(failed)} wavelength(s) ({nm_list(failed)}); kd = ks = 0 there")
        if notes["f0_not_separable_nm"]:
            msg.append(f"ks and F0 not separable at {nm_list(notes['f0_not_separable_nm'])} "
                       f"(standard error of F0 > {F0_SE_MAX:g}: Schlick's change over the "
                       "measured angles is within the noise); kept the stable choice F0 = 1 "
                       "there, so ks is the product ks*F0")
        if notes["f0_poorly_determined_nm"]:
            msg.append(f"F0 poorly determined (standard error > {F0_SE_MAX:g}) at "
                       f"{nm_list(notes['f0_poorly_determined_nm'])}, but the data reject "
                       "F0 = 1 there: fitted values kept")
        if notes["no_specular_lobe_nm"]:
            msg.append(f"no specular lobe (ks = 0) at {nm_list(notes['no_specular_lobe_nm'])}"
                       "; m and F0 have no effect there")
        if notes["m_at_bound_nm"]:
            msg.append(f"m at a bound of [{M_MIN:g}, {M_MAX:g}] at "
                       f"{nm_list(notes['m_at_bound_nm'])}")
        if lm_fail:
            msg.append(f"Levenberg-Marquardt stopped before converging at "
                       f"{nm_list(list(lm_fail))}; kept the better of it and the profile "
                       "solution (the profile solution is a minimum on its own)")
        status = "failed" if failed else "success"
        f = cook_torrance(data.cos, s.kd, s.ks, s.m, s.f0)
        return FitReport(method, status, "; ".join(msg), s.params(), error_figures(data, f),
                         optimizer, int(evals), time_s, list(failed), dict(notes))

    reports = {"profile": report(
        "profile", free.profile, "scan+golden-section", evaluations, t_profile,
        "per wavelength: NNLS for (kd, ks*F0, ks*(1-F0)) and a scan + golden section over "
        f"log m in [{M_MIN:g}, {M_MAX:g}]")}
    final = "profile"
    if free.lm is not None:
        reports["levenberg_marquardt"] = report(
            "levenberg_marquardt", free.lm, "scipy-least-squares", evaluations + lm_nfev,
            t_profile + t_lm,
            "seed 004 sec. 5.2: Levenberg-Marquardt (MINPACK) per wavelength on "
            "(kd, ks, m, F0), reparametrised to stay in bounds, from the profile solution",
            lm_failed)
        final = "levenberg_marquardt"
    return ModelFit(MODEL, nm, reports, final, data.excluded)
