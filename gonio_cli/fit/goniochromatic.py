"""Fit of the goniochromatic microfacet BRDF, seed 000 eq. (5): α, then ρ(λ) and c(λ).

The model (in :func:`gonio_cli.brdf.goniochromatic`) is, in logs,

    log f(θi, θo, λ) = log D(θh; α) − log 4 + log ρ(λ) + c(λ) x,   x = 1 − cos((θi+θo)/2),

so for a fixed α it is *linear* in (log ρ(λ), c(λ)) for every wavelength: with log
residuals, step 2 is a weighted linear least-squares problem per wavelength with a closed
form (all 41 wavelengths in one batched 2 × 2 solve, :func:`solve_spectra`). That turns
each nonlinear problem into a 1-D search in log α (:func:`~.alpha.minimize_log_alpha`).

Methods (reported side by side in the material, so a user sees what refinement bought):

- ``paper_two_step`` (seed 000 "Fitting procedure"): step 1 averages the spectrum per
  configuration and fits an arbitrarily scaled GGX (eq. 3) per angle of incidence; α is
  the mean of those. Step 2 fixes α and fits ρ and c per wavelength to the mirror
  configurations (eq. 7), or, with ``step2="all"``, to every configuration.
- ``refined`` (default final): α, ρ and c jointly, i.e. the profile cost over log α
  with the closed-form step 2 over all configurations inside. This removes the bias of
  step 1, which ignores that the exponential term changes along each θo sweep.

With linear or compressive residuals, step 2 is no longer linear in c: ρ keeps its
closed form for a given c, and c is found per wavelength by a scan and a golden-section
search, all wavelengths at once (:func:`~.separable.profile_c`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..brdf import (LOG_MAX, goniochromatic, goniochromatic_exponent_arg, log_ggx_d,
                    log_goniochromatic_d4)
from ..brdf_jacobians import dlog_ggx_d_dlog_alpha
from ..errors import FitError
from ..names import STEP2_NAMES, pick
from .alpha import choose_optimizer, minimize_log_alpha, scan_log_alpha
from .common import (check_alpha, ALPHA_MAX, ALPHA_MIN, FitData, LinearProfile, WARM_ALPHA_FACTOR,
                     WARM_ALPHA_POINTS)
from .results import FitOptions, FitReport, ModelFit, Stopwatch, error_figures, nm_list
from .separable import C_LIMIT, profile_c

#: Step 1 fits α per angle of incidence only from groups with at least this many
#: configurations (2 parameters, scale and α, plus one degree of freedom).
STEP1_MIN_CONFIGURATIONS = 3

#: ``--step2``'s choices (gonio_cli.names, which the shell reads too).
STEP2_MODES = STEP2_NAMES


# ------------------------------------------------------------------------ step 2 core --

def _offset(data: FitData, alpha: float) -> np.ndarray:
    """log D(θh; α) − log 4 per configuration (N,): the α-dependent part of log f
    (:func:`gonio_cli.brdf.log_goniochromatic_d4`)."""
    return log_goniochromatic_d4(data.cos.cos_theta_h, alpha)


def _x(data: FitData) -> np.ndarray:
    """x = 1 − cos((θi+θo)/2) per configuration (N,), eq. (4) and (6)."""
    return goniochromatic_exponent_arg(data.cos.cos_theta_i, data.cos.cos_theta_o)


class Step2:
    """Step 2 for any fixed α on one data set: ρ(λ), c(λ) minimising the residuals.

    With log residuals the normal matrices do not depend on α (only the target shifts by
    log D(θh; α)), so they are factored once (:class:`~.common.LinearProfile`) and a trial
    α costs two matrix–vector products; a scan of 49 α values is one matrix product.
    """

    def __init__(self, data: FitData):
        self.data = data
        self.x = _x(data)
        self.X = np.stack([np.ones_like(self.x), self.x], axis=1)
        log_y = np.log(np.where(data.positive, data.y, 1.0))
        # log-space weights; with linear residuals the log solution only starts the search
        w_log = data.w if data.residuals == "log" else data.positive.astype(float)
        self.linear = LinearProfile(self.X, log_y, w_log)

    def offsets(self, log_alphas) -> np.ndarray:
        """log D − log 4 for each trial α: (G, N)."""
        a = np.exp(np.asarray(log_alphas, dtype=float))[:, None]
        return log_goniochromatic_d4(self.data.cos.cos_theta_h[None, :], a)

    def costs(self, log_alphas) -> np.ndarray:
        """Profile cost for each log α (G,)."""
        if self.data.residuals == "log":
            return self.linear.costs(self.offsets(log_alphas))
        return np.array([self.solve(float(np.exp(g)))[2] for g in np.atleast_1d(log_alphas)])

    def cost(self, log_alpha: float) -> float:
        return float(self.costs([log_alpha])[0])

    def log_costs(self, log_alphas) -> np.ndarray:
        """The log-residual profile cost (G,), whatever the fit's residuals: its minimum
        starts the search of the other residuals (:data:`~.common.WARM_ALPHA_FACTOR`)."""
        return self.linear.costs(self.offsets(log_alphas))

    def log_cost(self, log_alpha: float) -> float:
        return float(self.log_costs([log_alpha])[0])

    def solve(self, alpha: float):
        """Returns ``(rho, c, cost, ok)``: (L,), (L,), the total weighted cost over the
        wavelengths that could be fitted, and (L,) bool; ρ = c = 0 where not ok."""
        off = _offset(self.data, alpha)
        beta, cost, ok = self.linear.solve(off)
        if self.data.residuals == "log":
            rho = np.where(ok, np.exp(np.minimum(beta[0], LOG_MAX)), 0.0)
            return rho, np.where(ok, beta[1], 0.0), float(cost[ok].sum()), ok
        return _solve_spectra_linear(self.data, off, self.x)


def solve_spectra(data: FitData, alpha: float):
    """Step 2 for one α on ``data`` (see :class:`Step2`)."""
    return Step2(data).solve(alpha)


def _solve_spectra_linear(data: FitData, off, x):
    """Linear (and compressive) residuals: ρ closed form given c; c by a scan and a
    golden-section search per wavelength (:func:`~.separable.profile_c`)."""
    _, rho, c, cost = profile_c(x, np.exp(off), data.y, data.w, diffuse=False)
    signal = np.any((data.w > 0) & (data.y > 0), axis=0)
    ok = signal & (np.abs(c) < C_LIMIT * (1 - 1e-6)) & np.isfinite(cost)
    return (np.where(ok, rho, 0.0), np.where(ok, c, 0.0), float(cost[signal].sum()), ok)


# --------------------------------------------------------------------- joint (scipy) --

def joint_least_squares(data: FitData, log_alpha0: float, beta0: np.ndarray,
                        design: np.ndarray):
    """All parameters at once with scipy.optimize.least_squares (trf, analytic Jacobian).

    Model η = log D(α) − log 4 + X β (per wavelength column); residuals √w (log y − η)
    or √w (y − e^η). Parameters: log α and β (K, L). Returns (alpha, beta, nfev, message).
    """
    from scipy.optimize import least_squares
    from scipy.sparse import csr_matrix

    K, L = beta0.shape
    sw = np.sqrt(data.w)
    used = sw > 0
    log_y = np.log(np.where(data.positive, data.y, 1.0))

    def eta(theta):
        a = np.exp(theta[0])
        return _offset(data, a)[:, None] + design @ theta[1:].reshape(K, L), a

    def fun(theta):
        e, _ = eta(theta)
        r = (log_y - e) if data.residuals == "log" else \
            (data.y - np.exp(np.minimum(e, LOG_MAX)))
        return (sw * r)[used]

    # Sparse structure: each residual (n, l) depends on log α and on β[:, l] only.
    n_idx, l_idx = np.nonzero(used)
    n_res = n_idx.size
    rows = np.repeat(np.arange(n_res), 1 + K)
    cols = np.concatenate([np.zeros((n_res, 1), dtype=int),
                           1 + np.arange(K)[None, :] * L + l_idx[:, None]], axis=1).ravel()

    def jac(theta):
        e, a = eta(theta)
        dm = np.ones_like(e) if data.residuals == "log" else np.exp(np.minimum(e, LOG_MAX))
        s = -(sw * dm)[n_idx, l_idx]
        vals = np.concatenate([
            (s * dlog_ggx_d_dlog_alpha(data.cos.cos_theta_h, a)[n_idx])[:, None],
            s[:, None] * design[n_idx]], axis=1).ravel()
        return csr_matrix((vals, (rows, cols)), shape=(n_res, 1 + K * L))

    lo = np.full(1 + K * L, -np.inf)
    hi = np.full(1 + K * L, np.inf)
    lo[0], hi[0] = np.log(ALPHA_MIN), np.log(ALPHA_MAX)
    theta0 = np.concatenate([[np.clip(log_alpha0, lo[0], hi[0])], beta0.ravel()])
    res = least_squares(fun, theta0, jac=jac, bounds=(lo, hi), method="trf",
                        tr_solver="lsmr", x_scale="jac", xtol=1e-10, ftol=1e-10, gtol=1e-10,
                        max_nfev=500)
    return float(np.exp(res.x[0])), res.x[1:].reshape(K, L), int(res.nfev), res.message


# ------------------------------------------------------------------------------ steps --

def step1_alpha_per_theta_i(data: FitData, optimizer: str) -> dict[str, Any]:
    """Seed 000 step 1: spectrum-averaged data, an arbitrarily scaled GGX (eq. 3) per θi.

    For each angle of incidence, log ȳ = log s + log D(θh; α): the scale has a closed form
    for any α (a 1-column :class:`~.common.LinearProfile`), so each θi is a 1-D search.
    With linear residuals the scale is Σ w ȳ D / Σ w D². Returns per-θi α, their mean and
    standard deviation in % of the mean (seed 000 reports < 3 %), and evaluations.
    """
    y_avg = np.mean(data.y, axis=1, keepdims=True)
    positive = y_avg > 0
    w = positive.astype(float) if data.residuals == "log" else np.ones_like(y_avg)
    per, evaluations = [], 0
    for theta_i, rows in data.theta_i_groups():
        ch = data.cos.cos_theta_h[rows]
        usable = int(np.count_nonzero(w[rows, 0] > 0))
        if usable < STEP1_MIN_CONFIGURATIONS or np.ptp(ch) == 0:
            continue

        def offsets(log_alphas, ch=ch):
            return log_ggx_d(ch[None, :], np.exp(np.asarray(log_alphas))[:, None])

        if data.residuals == "log":
            lp = LinearProfile(np.ones((ch.size, 1)),
                               np.log(np.where(positive[rows], y_avg[rows], 1.0)), w[rows])
            costs = lambda g, lp=lp, offsets=offsets: lp.costs(offsets(g))  # noqa: E731
        else:
            def costs(g, yy=y_avg[rows, 0], offsets=offsets):
                D = np.exp(offsets(g))                                 # (G, n)
                s = np.maximum(D @ yy / np.sum(D * D, axis=1), 0.0)
                return np.sum((yy[None] - s[:, None] * D) ** 2, axis=1)
        search = minimize_log_alpha(lambda g, costs=costs: float(costs([g])[0]), optimizer,
                                    costs=costs)
        evaluations += search.evaluations
        per.append({"theta_i_deg": theta_i, "alpha": search.alpha,
                    "configurations": int(ch.size), "at_bound": search.at_bound})
    alphas = np.array([p["alpha"] for p in per])
    mean = float(alphas.mean()) if alphas.size else float("nan")
    spread = float(100.0 * alphas.std(ddof=1) / mean) if alphas.size > 1 else 0.0
    return {"alpha_per_theta_i": per, "alpha_mean": mean,
            "alpha_std_percent_of_mean": spread, "evaluations": evaluations}


def _report(method, data, alpha, rho, c, ok, *, optimizer, evaluations, time_s, message,
            extra=None, success=True) -> FitReport:
    f = goniochromatic(data.cos, alpha, rho, c)
    failed = [float(w) for w in data.wavelength_nm[~ok]]
    status = "success" if success and not failed and np.isfinite(alpha) else "failed"
    if failed and success:
        message = (f"no usable signal at {len(failed)} wavelength(s) "
                   f"({nm_list(failed)}); rho = c = 0 there. " + message)
    return FitReport(method, status, message.strip(),
                     {"alpha": float(alpha), "rho": rho, "c": c},
                     error_figures(data, f), optimizer, evaluations, time_s, failed,
                     extra or {})


def check_identifiable(data: FitData) -> None:
    """α needs configurations off the mirror direction: on it, D ∝ 1/α² is just a scale."""
    if np.all(data.mirror_rows()):
        raise FitError("every configuration is a mirror one (theta_o_deg = theta_i_deg), so "
                       "alpha only scales rho and cannot be fitted",
                       fix="add off-specular configurations or fix it with --alpha")


def fit(data: FitData, options: FitOptions) -> ModelFit:
    """Fit seed 000 eq. (5) to prepared data; returns every method's report.

    Raises :class:`FitError` only when no method can produce parameters at all; a fit
    that runs but cannot be trusted comes back with ``status`` "failed" and a message.
    """
    if options.step2 not in STEP2_MODES:
        pick(STEP2_MODES, options.step2, "--step2")
    optimizer, _ = choose_optimizer("goniochromatic", OPTIMIZERS, options.optimizer)
    check_alpha(options.alpha)
    if options.alpha is None:
        check_identifiable(data)
    reports: dict[str, FitReport] = {}
    sw = Stopwatch()

    # ---- seed 000's two steps
    if options.alpha is None:
        s1 = step1_alpha_per_theta_i(data, optimizer)
        alpha1, evals1 = s1["alpha_mean"], s1["evaluations"]
        extra = {k: s1[k] for k in ("alpha_per_theta_i", "alpha_mean",
                                    "alpha_std_percent_of_mean")}
    else:
        alpha1, evals1, extra = options.alpha, 0, {"alpha_fixed": True}
    extra["step2"] = options.step2
    if not np.isfinite(alpha1):
        reports["paper_two_step"] = FitReport(
            "paper_two_step", "failed",
            f"step 1 needs at least {STEP1_MIN_CONFIGURATIONS} configurations at some angle "
            "of incidence", {}, {}, optimizer, evals1, sw.lap(), [], extra)
    else:
        sub = data.subset(data.mirror_rows()) if options.step2 == "mirror" else data
        n_ti = np.unique(np.round(sub.theta_i_deg, 6)).size
        if options.step2 == "mirror" and n_ti < 2:
            reports["paper_two_step"] = FitReport(
                "paper_two_step", "failed",
                f"step 2 on mirror configurations needs them at 2 or more angles of "
                f"incidence to separate rho and c; found {n_ti}", {"alpha": alpha1}, {},
                optimizer, evals1, sw.lap(), [], extra)
        else:
            rho, c, _, ok = solve_spectra(sub, alpha1)
            reports["paper_two_step"] = _report(
                "paper_two_step", data, alpha1, rho, c, ok, optimizer=optimizer,
                evaluations=evals1 + 1, time_s=sw.lap(),
                message="seed 000 two steps: alpha from spectrum-averaged GGX per "
                        f"theta_i, then rho and c on {options.step2} configurations",
                extra=extra)

    # ---- joint refinement (profile over log α, closed-form step 2 inside)
    if options.refine and options.alpha is None:
        reports["refined"] = refine(data, optimizer, sw)
    final = "refined" if "refined" in reports else "paper_two_step"
    if "rho" not in reports[final].params:  # a step could not run: no spectra to judge
        raise FitError(reports[final].message, fix=_two_step_fix(reports[final], options))
    return ModelFit("goniochromatic", data.wavelength_nm, reports, final, data.excluded)


def _two_step_fix(report: FitReport, options: FitOptions) -> str:
    """What a user can do when seed 000's two steps could not both run (and no joint
    refinement follows): step 1 found no α, or step 2 on mirror rows has one θi."""
    if "alpha" not in report.params:
        return "fix alpha with --alpha, or measure more detector angles at one angle of incidence"
    ways = ["use --step2 all", "add mirror configurations at a second angle of incidence"]
    if options.alpha is None:
        ways.insert(0, "drop --no-refine")
    return ", or ".join(ways)


def _refine_joint(data: FitData, step2: Step2, optimizer: str):
    """``scipy-least-squares``: α and (log ρ, c) jointly, from the scan's best α."""
    grid, costs, i = scan_log_alpha(step2.cost, costs=step2.costs)
    rho, c, _, ok = step2.solve(float(np.exp(grid[i])))
    beta0 = np.stack([np.log(np.where(ok, rho, 1.0)), c])
    sub = data.subset(slice(None))
    sub.w = data.w * ok[None, :]                    # fitted wavelengths only
    alpha, beta, nfev, message = joint_least_squares(sub, grid[i], beta0, step2.X)
    at_bound = bool(np.isclose(alpha, ALPHA_MIN) or np.isclose(alpha, ALPHA_MAX))
    return alpha, len(grid) + nfev, True, message, at_bound


def _refine_profile(data: FitData, step2: Step2, optimizer: str):
    """The nlopt names: α by the 1-D profile search (:func:`minimize_log_alpha`)."""
    if data.residuals == "log":
        search = minimize_log_alpha(step2.cost, optimizer, costs=step2.costs)
    else:  # start where the log-residual profile (closed form) has its minimum
        log_fit = minimize_log_alpha(step2.log_cost, optimizer, costs=step2.log_costs)
        lo = max(np.log(log_fit.alpha / WARM_ALPHA_FACTOR), np.log(ALPHA_MIN))
        hi = min(np.log(log_fit.alpha * WARM_ALPHA_FACTOR), np.log(ALPHA_MAX))
        search = minimize_log_alpha(step2.cost, optimizer, lo=lo, hi=hi,
                                    points=WARM_ALPHA_POINTS, costs=step2.costs)
        search.evaluations += log_fit.evaluations
    return search.alpha, search.evaluations, search.success, search.message, search.at_bound


#: ``--optimizer`` of the joint refinement: each returns (α, evaluations, success,
#: message, α at a bound); the first is the default.
OPTIMIZERS = {
    "nlopt-bobyqa": _refine_profile,
    "nlopt-lbfgs": _refine_profile,
    "scipy-least-squares": _refine_joint,
}


def refine(data: FitData, optimizer: str, sw: Stopwatch | None = None) -> FitReport:
    """α, ρ(λ), c(λ) jointly over all configurations (the default final fit)."""
    sw = sw or Stopwatch()
    step2 = Step2(data)
    alpha, evaluations, success, message, at_bound = OPTIMIZERS[optimizer](data, step2,
                                                                           optimizer)
    # (log ρ, c) at the optimum α are the closed form (for the joint fit the same
    # minimiser): one definition of step 2 for every optimiser.
    rho, c, _, ok = step2.solve(alpha)
    if at_bound:
        message += f"; alpha={alpha:.4g} is at the bound of [{ALPHA_MIN:g}, {ALPHA_MAX:g}]"
    return _report("refined", data, alpha, rho, c, ok, optimizer=optimizer,
                   evaluations=evaluations, time_s=sw.lap(), message=message,
                   success=success, extra={"alpha_at_bound": at_bound})
