"""Fit of the Cook–Torrance BRDF per wavelength, seed 004 §5 (eqs. 9–14).

The model (:func:`gonio_cli.brdf.cook_torrance`, seed 004 eq. 11) with Beckmann D (eq. 9),
the V-groove G (eq. 10) and Schlick's F (eq. 12), every parameter per wavelength:

    f = kd/π + ks F(θd) S(m),   S = D G / (π cos θi cos θo),   F = F0 + (1 − F0) q,
    q = (1 − cos θd)⁵.

For a fixed m it is **linear and non-negative** in (kd, a, b) with a = ks F0 and
b = ks (1 − F0):  f = kd/π + a S + b q S. So per wavelength:

1. ``profile`` (always; final with the nlopt optimisers): for any trial m, (kd, a, b) ≥ 0
   by a 3-column non-negative least squares (:func:`~.cook_torrance_profile.nnls3`,
   exact, all wavelengths and trial m at once); with log residuals (default) from the
   closed form for relative residuals (log y − log f ≈ (y − f)/y) plus Gauss–Newton
   steps, each the same NNLS with reweighted targets. m(λ) by a 49-point scan over log m
   in [``M_MIN``, ``M_MAX``] and a golden section (:func:`~.common.golden_section`)
   inside the best cell, for all wavelengths at once. ks = a + b, F0 = a/(a + b). Golden
   section, not nlopt: each wavelength has its own m, and
   :func:`~.alpha.minimize_log_alpha` is a scalar search (41 of them would cost 41 × ~65
   profile calls instead of ~100).
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

The profile over m (``nnls3``, the m search) is :mod:`.cook_torrance_profile`; here
Levenberg–Marquardt with its analytic derivatives, the F0 separability test and its
standard errors, and the reports.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..brdf import LOG_MAX, cook_torrance, cook_torrance_specular_geometry
from ..brdf_jacobians import dlog_beckmann_dlog_m
from ..errors import FitError, InputError
from .alpha import choose_optimizer
from .common import FitData
from .cook_torrance_profile import (F_FLOOR, M_MAX, M_MIN, MIN_CONFIGURATIONS, Linear,
                                    Profile, search_m)
from .results import FitOptions, FitReport, ModelFit, Stopwatch, error_figures, nm_list

MODEL = "cook-torrance"

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
    free = _run(profile, cols, True, polish)              # all four parameters free
    fin = free.final
    a, b = fin.ks[cols] * fin.f0[cols], fin.ks[cols] * (1.0 - fin.f0[cols])
    se = f0_standard_error(profile, fin.kd[cols], a, b, fin.m[cols], cols)
    vague, fixed = _stable_f0(profile, free, cols, se, polish)
    failed = [float(x) for x in nm[~profile.ok]]
    notes = _notes(nm, free.final, cols, se, vague, fixed, free.at_bound)
    reports = {"profile": _report(
        data, "profile", free.profile, "scan+golden-section", free.evaluations,
        free.time_profile_s,
        "per wavelength: NNLS for (kd, ks*F0, ks*(1-F0)) and a scan + golden section over "
        f"log m in [{M_MIN:g}, {M_MAX:g}]", failed, notes)}
    final = "profile"
    if free.lm is not None:
        reports["levenberg_marquardt"] = _report(
            data, "levenberg_marquardt", free.lm, "scipy-least-squares",
            free.evaluations + free.lm_nfev, free.time_profile_s + free.time_lm_s,
            "seed 004 sec. 5.2: Levenberg-Marquardt (MINPACK) per wavelength on "
            "(kd, ks, m, F0), reparametrised to stay in bounds, from the profile solution",
            failed, notes, free.lm_failed)
        final = "levenberg_marquardt"
    return ModelFit(MODEL, nm, reports, final, data.excluded)


def _stable_f0(profile: Profile, free: Run, cols: np.ndarray, se: np.ndarray, polish):
    """Where F0 is poorly determined (standard error ``se`` > :data:`F0_SE_MAX`), the stable
    choice F0 = 1 (b = 0) if the data do not reject it (likelihood ratio, 1 degree of
    freedom): those wavelengths of the F0 = 1 pass replace ``free``'s, whose counts and
    times then cover both passes and whose ``at_bound`` becomes (L,).

    Returns (the poorly determined columns, those given F0 = 1)."""
    nm = profile.data.wavelength_nm
    fin = free.final
    at_bound = np.zeros(nm.size, bool)
    at_bound[cols] = free.at_bound
    free.at_bound = at_bound
    vague = cols[(se > F0_SE_MAX) & (fin.ks[cols] > 0) & (fin.f0[cols] < 1.0)]
    if not vague.size:
        return vague, np.array([], dtype=int)
    one = _run(profile, vague, False, polish)
    sigma2 = fin.cost[vague] / np.maximum(profile.n_used[vague] - 4, 1)
    accept = one.final.cost[vague] - fin.cost[vague] <= CHI2_1DOF_95 * sigma2
    fixed = vague[accept]
    free.profile.take(one.profile, fixed)
    if free.lm is not None:
        free.lm.take(one.lm, fixed)
    at_bound[fixed] = one.at_bound[accept]
    free.evaluations += one.evaluations
    free.lm_nfev += one.lm_nfev
    fixed_nm = set(nm[fixed].tolist())
    free.lm_failed = ([x for x in free.lm_failed if x not in fixed_nm]
                      + [x for x in one.lm_failed if x in fixed_nm])
    free.time_profile_s += one.time_profile_s
    free.time_lm_s += one.time_lm_s
    return vague, fixed


def _notes(nm: np.ndarray, fin: Spectra, cols: np.ndarray, se: np.ndarray,
           vague: np.ndarray, fixed: np.ndarray, at_bound: np.ndarray) -> dict:
    """The identifiability notes every report carries (wavelength lists, F0's errors)."""
    se_all = np.full(nm.size, np.inf)
    se_all[cols] = se
    return {
        "f0_not_separable_nm": [float(x) for x in nm[fixed]],
        "f0_poorly_determined_nm": [float(x) for x in nm[np.setdiff1d(vague, fixed)]],
        "no_specular_lobe_nm": [float(x) for x in nm[cols[fin.ks[cols] <= 0]]],
        "m_at_bound_nm": [float(x) for x in nm[at_bound]],
        "f0_standard_error": [float(x) if np.isfinite(x) else None for x in se_all],
    }


def _report(data: FitData, method: str, s: Spectra, optimizer: str, evals: int,
            time_s: float, message: str, failed: list, notes: dict, lm_fail=()) -> FitReport:
    """One method's report: its spectra, error figures and a message naming every
    wavelength the notes single out."""
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
