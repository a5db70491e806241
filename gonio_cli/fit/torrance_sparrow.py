"""Fit of seed 000's "standard model": Torrance–Sparrow (eq. 2) with GGX D (eq. 3), the
separable Smith G, and Schlick's Fresnel (seed 004 eq. 12) with F0(λ) per wavelength and
one roughness α (the model of seed 000 Figure 5 and Table 1).

The model (:func:`gonio_cli.brdf.torrance_sparrow`) is, for a fixed α,

    f(θi, θo, λ) = F(cos θd, λ) g(α),   g = G D / (4 cos θi cos θo),
    F = F0 + (1 − F0) q = F0 (1 − q) + q,   q = (1 − cos θd)⁵,

so f = F0(λ) u + v with u = g (1 − q) and v = g q: **one** bounded parameter F0 ∈ [0, 1]
per wavelength, and the joint problem is a 1-D search in log α of the *profile* cost.

- Linear residuals: F0 has a closed form, clipped to [0, 1] (the cost is a convex
  quadratic in F0, so the clipped value is the constrained minimum).
- Log residuals (default): a projected, damped Newton iteration on all wavelengths (and
  all trial α of a scan) at once, started from the closed form for relative residuals
  (log y − log f ≈ (y − f)/y). It converges quadratically, in 3–6 steps; a golden section
  over [0, 1] needs ~60 evaluations of the same (N, G·L) logarithm, which made the
  49-point α scan alone take ~0.1 s.

Optimisers (``FitOptions.optimizer``):

- ``nlopt-bobyqa`` / ``nlopt-lbfgs``: :func:`~.alpha.minimize_log_alpha` on the profile
  cost (coarse log-α scan, then the nlopt method inside the best cell).
- ``scipy-least-squares``: the same scan, then ``scipy.optimize.least_squares`` (trf,
  bounded) over (log α, F0(λ)) jointly with an analytic Jacobian; F0 is then re-solved at
  that α so both optimisers share one definition of the per-wavelength step.

Identifiability from in-plane data: α needs off-mirror configurations (at the mirror
D ∝ 1/α² only rescales, which F0 absorbs); F0 needs a signal at its wavelength. A
wavelength without signal gets F0 = 0 and is named in ``failed_wavelength_nm``.
"""

from __future__ import annotations

import numpy as np

from ..brdf import schlick_fresnel, torrance_sparrow
from ..brdf_jacobians import dlog_ggx_d_dlog_alpha, dlog_smith_g1_dlog_alpha
from ..errors import FitError
from .alpha import choose_optimizer, minimize_log_alpha, scan_log_alpha
from .common import check_alpha, check_signal, ALPHA_MAX, ALPHA_MIN, FitData
from .results import FitOptions, FitReport, ModelFit, Stopwatch, error_figures, nm_list

MODEL = "torrance-sparrow"

#: F0 is a reflectance at normal incidence: physically in [0, 1].
F0_MIN, F0_MAX = 0.0, 1.0

#: Newton on log F0 stops when no wavelength's log F0 moves by more than this (relative
#: 1e-13 in F0, ~500 ulp, far below any noise).
F0_XTOL = 1e-13

#: Lower bound of F0 in log residuals, where the search runs in log F0. Below it F0 u is
#: under 1e-12 of the measured value wherever Schlick's v = g q is not negligible, so the
#: data cannot tell it from 0 (air–glass is 0.04; any real interface is above 1e-4).
F0_LOG_MIN = 1e-12

#: Iteration cap of that Newton iteration; 3–6 steps are typical, the damped fallback
#: needs more only on pathological columns (they keep their best iterate).
F0_MAX_ITERATIONS = 60

#: Newton's second derivative Σ W (J² − r J (1 − J)) (in log F0) is used when it is at
#: least this fraction of Gauss–Newton's Σ W J²; below, the residuals r are so large that
#: the quadratic model is barely convex, and Gauss–Newton's step is the safer one.
NEWTON_MIN_CURVATURE = 0.1

#: Model values are floored here inside log residuals: f = F0 u + v is 0 only for F0 = 0
#: at θd = 0 (retro-reflection), where the log would be −inf. log(tiny) ≈ −708 is finite.
F_FLOOR = np.finfo(float).tiny

#: ``least_squares`` tolerances for the joint fit (relative changes of cost, step and
#: gradient); 1e-12 brings log α within the profile search's own 1e-8.
LSQ_TOL = 1e-12

#: Evaluation cap of the joint ``least_squares`` (it needs ~10–20 on smooth data).
LSQ_MAX_NFEV = 200

#: F0 evaluated at 1 gives F ≡ 1 (Schlick, seed 004 eq. 12), so eq. 2 returns g itself;
#: at 0 it gives q. Used to take g and q from :mod:`gonio_cli.brdf` instead of re-writing.
_ONE, _ZERO = np.ones(1), np.zeros(1)

METHOD = "joint"


# ------------------------------------------------------------------ model derivatives --

def dlog_geometry_dlog_alpha(data: FitData, alpha: float) -> np.ndarray:
    """∂ log g / ∂ log α (N,), g = G D / (4 cos θi cos θo) of seed 000 eq. (2)."""
    cos = data.cos
    return (dlog_ggx_d_dlog_alpha(cos.cos_theta_h, alpha)
            + dlog_smith_g1_dlog_alpha(cos.cos_theta_i, alpha)
            + dlog_smith_g1_dlog_alpha(cos.cos_theta_o, alpha))


# -------------------------------------------------------------- F0 for a fixed α --

class F0Profile:
    """F0(λ) minimising the residuals for any trial α, all wavelengths at once.

    ``solve(log_alphas)`` handles a whole scan of G values of log α in one call: u and v
    are (G, N), F0 and the costs (G, L). Wavelengths without signal (no positive value of
    positive weight) are left out of the cost (their weight is set to 0) and get F0 = 0.
    """

    def __init__(self, data: FitData):
        self.data = data
        self.q = schlick_fresnel(data.cos.cos_theta_d, _ZERO)[:, 0]          # (N,)
        self.signal = np.any((data.w > 0) & (data.y > 0), axis=0)            # (L,)
        self.w = data.w * self.signal                                        # (N, L)
        self.log = data.residuals == "log"
        self.log_y = np.log(np.where(data.positive, data.y, 1.0))

    def geometry(self, log_alphas) -> np.ndarray:
        """g = G D / (4 cos θi cos θo) for each trial α: (G, N), from eq. 2 at F0 = 1."""
        a = np.exp(np.atleast_1d(np.asarray(log_alphas, dtype=float)))[:, None]
        return torrance_sparrow(self.data.cos, a, _ONE)[..., 0]

    def solve(self, log_alphas):
        """F0 (G, L) in [0, 1] and the per-wavelength weighted cost (G, L)."""
        g = self.geometry(log_alphas)
        u, v = g * (1.0 - self.q), g * self.q                               # (G, N)
        W, y = self.w, self.data.y
        if not self.log:
            f0 = _closed_form(u, v, y, W)
            r = y[None] - f0[:, None, :] * u[:, :, None] - v[:, :, None]
            return f0, np.einsum("gnl,nl->gl", r * r, W)
        # start: the closed form for relative residuals (y − f)/y ≈ log y − log f
        f0 = _closed_form(u, v, y, W / np.where(self.data.positive, y, 1.0) ** 2)
        cost = np.zeros_like(f0)
        gi, li = np.nonzero(np.broadcast_to(self.signal, f0.shape))     # columns to solve
        f0[gi, li], cost[gi, li] = _newton_f0(f0[gi, li], u[gi], v[gi],
                                              self.log_y[:, li].T, W[:, li].T)
        return f0, cost

    def costs(self, log_alphas) -> np.ndarray:
        """Profile cost (G,) summed over the wavelengths with signal."""
        return self.solve(log_alphas)[1].sum(axis=1)

    def cost(self, log_alpha: float) -> float:
        return float(self.costs([log_alpha])[0])


def _closed_form(u, v, y, W) -> np.ndarray:
    """argmin over F0 ∈ [0, 1] of Σn W (y − F0 u − v)², (G, L): the unconstrained
    minimiser Σ W u (y − v) / Σ W u², clipped (the cost is a convex quadratic in F0);
    F0_MIN where Σ W u² = 0 (no weight). ``u``, ``v``: (G, N); ``y``, ``W``: (N, L)."""
    num = np.einsum("gn,nl->gl", u, W * y) - np.einsum("gn,nl->gl", u * v, W)
    den = np.einsum("gn,nl->gl", u * u, W)
    ok = den > 0
    return np.where(ok, np.clip(num / np.where(ok, den, 1.0), F0_MIN, F0_MAX), F0_MIN)


def _newton_f0(f0, U, V, log_y, W):
    """Minimise Σn W (log y − log(F0 u + v))² over F0 ∈ [F0_LOG_MIN, 1], one problem per
    column.

    ``U``, ``V``, ``log_y``, ``W``: (C, N), one row per (trial α, wavelength) problem;
    ``f0``: (C,) start. Newton steps in t = log F0, where log f = log(e^t u + v) is linear
    (F0 u ≫ v) or flat (F0 u ≪ v), instead of F0, where its curvature spans decades:
    with J = F0 u / f, δt = Σ W r J / Σ W (J² − r J (1 − J)) (the exact second
    derivative; Gauss–Newton's Σ W J² where that is not clearly positive), projected on
    [log F0_LOG_MIN, 0] and damped per column (a step that raises the column's cost is
    refused and the column's step factor quartered; an accepted one doubles it back to 1).
    Only columns still moving are iterated. Every column ends at its best iterate, never
    worse than the start. Returns (F0 (C,), cost (C,)).
    """
    t_min = np.log(F0_LOG_MIN)
    t = np.log(np.clip(f0, F0_LOG_MIN, F0_MAX))

    def evaluate(x, idx):
        g = np.exp(x)[:, None] * U[idx]
        f = np.maximum(g + V[idx], F_FLOOR)
        r = log_y[idx] - np.log(f)
        return r, g / f, np.einsum("cn,cn->c", r * r, W[idx])

    idx = np.arange(t.size)
    r, J, cost = evaluate(t, idx)
    damp = np.ones_like(t)
    for _ in range(F0_MAX_ITERATIONS):
        w = W[idx]
        wj = w * J
        gauss_newton = np.einsum("cn,cn->c", wj, J)
        newton = gauss_newton - np.einsum("cn,cn->c", wj * r, 1.0 - J)
        curvature = np.where(newton > NEWTON_MIN_CURVATURE * gauss_newton, newton, gauss_newton)
        ok = curvature > 0
        delta = np.where(ok, np.einsum("cn,cn->c", wj, r) / np.where(ok, curvature, 1.0), 0.0)
        trial = np.clip(t[idx] + damp[idx] * delta, t_min, 0.0)
        moving = np.abs(trial - t[idx]) >= F0_XTOL
        if not moving.any():
            break
        idx, trial, r, J = idx[moving], trial[moving], r[moving], J[moving]
        r_t, J_t, cost_t = evaluate(trial, idx)
        better = cost_t <= cost[idx]
        t[idx[better]] = trial[better]
        cost[idx[better]] = cost_t[better]
        r, J = np.where(better[:, None], r_t, r), np.where(better[:, None], J_t, J)
        damp[idx] = np.where(better, np.minimum(2.0 * damp[idx], 1.0), 0.25 * damp[idx])
    return np.exp(t), cost


# ------------------------------------------------------------------ joint (scipy) --

def joint_least_squares(profile: F0Profile, log_alpha0: float, f00: np.ndarray):
    """(log α, F0(λ)) jointly by ``scipy.optimize.least_squares`` (trf, bounded).

    Residuals √w (log y − log f) or √w (y − f) over the used entries, f = F0 u + v;
    analytic Jacobian: ∂f/∂log α = f ∂ log g/∂ log α (u and v are ∝ g), ∂f/∂F0 = u.
    Only wavelengths with signal are parameters. Returns (alpha, nfev, success, message).
    """
    from scipy.optimize import least_squares
    from scipy.sparse import csr_matrix

    data = profile.data
    cols = np.flatnonzero(profile.signal)
    W = profile.w[:, cols]
    sw = np.sqrt(W)
    used = W > 0
    n_rows, n_cols = W.shape
    y, log_y = data.y[:, cols], profile.log_y[:, cols]
    q = profile.q[:, None]
    col_index = np.broadcast_to(np.arange(n_cols), (n_rows, n_cols))[used]
    # Jacobian pattern: each residual depends on log α (column 0) and its own F0 only
    jac_columns = np.column_stack([np.zeros_like(col_index), 1 + col_index]).ravel()
    jac_rows = np.arange(0, 2 * col_index.size + 1, 2)

    def model(theta):
        g = profile.geometry(theta[0])[0][:, None]                           # (N, 1)
        u = g * (1.0 - q)
        return u, np.maximum(theta[1:][None, :] * u + g * q, F_FLOOR)

    def fun(theta):
        _, f = model(theta)
        r = (log_y - np.log(f)) if profile.log else (y - f)
        return (sw * r)[used]

    def jac(theta):
        u, f = model(theta)
        dlog = dlog_geometry_dlog_alpha(data, float(np.exp(theta[0])))[:, None]
        scale = (1.0 / f) if profile.log else np.ones_like(f)
        d_alpha = -(sw * scale * f * dlog)[used]
        d_f0 = -(sw * scale * u)[used]
        return csr_matrix((np.column_stack([d_alpha, d_f0]).ravel(), jac_columns, jac_rows),
                          shape=(d_alpha.size, 1 + n_cols))

    lo = np.concatenate([[np.log(ALPHA_MIN)], np.full(n_cols, F0_MIN)])
    hi = np.concatenate([[np.log(ALPHA_MAX)], np.full(n_cols, F0_MAX)])
    theta0 = np.concatenate([[np.clip(log_alpha0, lo[0], hi[0])], f00[cols]])
    # sparse Jacobian and LSMR: a dense trust-region step (an SVD of the ~6000 × 42
    # Jacobian) cost ~30 ms per iteration, the sparse one ~1 ms
    res = least_squares(fun, theta0, jac=jac, bounds=(lo, hi), method="trf", x_scale="jac",
                        tr_solver="lsmr", xtol=LSQ_TOL, ftol=LSQ_TOL, gtol=LSQ_TOL,
                        max_nfev=LSQ_MAX_NFEV)
    return float(np.exp(res.x[0])), int(res.nfev + res.njev), res.status > 0, res.message


def _search_joint(profile: F0Profile, optimizer: str):
    """``scipy-least-squares``: the scan, then (log α, F0(λ)) jointly."""
    grid, costs, i = scan_log_alpha(profile.cost, costs=profile.costs)
    f00 = profile.solve(grid[i])[0][0]
    alpha, nfev, success, message = joint_least_squares(profile, grid[i], f00)
    return alpha, len(grid) + nfev, success, f"joint least_squares over (log alpha, f0): {message}"


def _search_profile(profile: F0Profile, optimizer: str):
    """The nlopt names: α by the 1-D profile search, F0(λ) in closed form for each α."""
    search = minimize_log_alpha(profile.cost, optimizer, costs=profile.costs)
    return (search.alpha, search.evaluations, search.success,
            f"alpha by profile search ({optimizer}): {search.message}")


#: ``--optimizer``: each returns (α, evaluations, success, message); the first is the
#: default.
OPTIMIZERS = {
    "nlopt-bobyqa": _search_profile,
    "nlopt-lbfgs": _search_profile,
    "scipy-least-squares": _search_joint,
}


# ------------------------------------------------------------------------------ fit --

def fit(data: FitData, options: FitOptions) -> ModelFit:
    """Fit seed 000 eq. (2) (GGX D, Smith G, Schlick F0(λ)) to prepared data.

    Parameters
    ----------
    data : :class:`~.common.FitData` (N configurations, L wavelengths)
    options : ``optimizer`` (a key of :data:`OPTIMIZERS`), ``alpha`` to fix the
        roughness instead of fitting it; ``refine`` and ``step2`` are goniochromatic only.

    Returns
    -------
    :class:`~.results.ModelFit` with one report, ``joint``: ``alpha`` (float) and ``f0``
    (L,) named as in :data:`gonio_cli.brdf.MODELS`, the error figures (seed 004 eq. 14
    among them), status and message; failed wavelengths named, never NaN.

    Raises
    ------
    FitError
        Only when nothing can be fitted: no wavelength has signal, or α is free and every
        configuration is a mirror one (α is then a pure scale).
    """
    sw = Stopwatch()
    check_alpha(options.alpha)
    profile = F0Profile(data)
    check_signal(profile.signal)
    if options.alpha is None and np.all(data.mirror_rows()):
        raise FitError("every configuration is a mirror one (theta_o_deg = theta_i_deg), so "
                       "alpha only scales f0 and cannot be fitted",
                       fix="add off-specular configurations or fix it with --alpha")
    optimizer, search = choose_optimizer(MODEL, OPTIMIZERS, options.optimizer)
    extra: dict = {"alpha_fixed": options.alpha is not None}
    success, at_bound = True, False
    if options.alpha is not None:
        alpha, evaluations, message = float(options.alpha), 1, "alpha fixed; F0 per wavelength"
    else:
        alpha, evaluations, success, message = search(profile, optimizer)
    if options.alpha is None:
        at_bound = bool(np.isclose(alpha, ALPHA_MIN) or np.isclose(alpha, ALPHA_MAX))
        extra["alpha_at_bound"] = at_bound
        if at_bound:
            message += f"; alpha={alpha:.4g} is at the bound of [{ALPHA_MIN:g}, {ALPHA_MAX:g}]"
    f0 = np.where(profile.signal, profile.solve(np.log(alpha))[0][0], F0_MIN)
    high = data.wavelength_nm[profile.signal & (f0 >= F0_MAX)]
    extra["f0_at_upper_bound_nm"] = [float(x) for x in high]
    if high.size:
        message += (f"; f0 = 1 at {nm_list(list(high))}: the data there are brighter than "
                    "eq. 2 can reach with F0 <= 1 (is the measurement in sr^-1?)")
    failed = [float(x) for x in data.wavelength_nm[~profile.signal]]
    if failed:
        message = (f"no usable signal at {len(failed)} wavelength(s) ({nm_list(failed)}); "
                   "f0 = 0 there. " + message)
    status = "success" if success and not failed and np.isfinite(alpha) else "failed"
    f = torrance_sparrow(data.cos, alpha, f0)
    report = FitReport(METHOD, status, message, {"alpha": float(alpha), "f0": f0},
                       error_figures(data, f), optimizer, int(evaluations), sw.lap(),
                       failed, extra)
    return ModelFit(MODEL, data.wavelength_nm, {METHOD: report}, METHOD, data.excluded)
