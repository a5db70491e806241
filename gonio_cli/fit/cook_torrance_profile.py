"""The profile of the Cook–Torrance fit (:mod:`.cook_torrance`, seed 004 eq. 11) over the
Beckmann roughness m: for a fixed m the model f = kd/π + a S + b q S is linear and
non-negative in (kd, a = ks F0, b = ks (1 − F0)), solved exactly by :func:`nnls3` for every
(trial m, wavelength) column at once (:class:`Profile`), and m is found per wavelength by a
scan over log m and a golden section inside the best cell (:func:`search_m`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..brdf import cook_torrance_specular_geometry, schlick_fresnel
from .common import FitData, SINGULAR_TOL, golden_section

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
