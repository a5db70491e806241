"""Fit of ``sheen``, a fabric: f = ρ_d(λ)/π + ρ_sheen(λ) D V + k_spec TS(α)
(:func:`gonio_cli.brdf.sheen`; D V the Charlie sheen of Estevez & Kulla 2017 as glTF
``KHR_materials_sheen`` defines it, :mod:`gonio_cli.brdf_surfaces`).

For fixed sheen roughness r and specular α the model is linear in ρ_d(λ), ρ_sheen(λ) and
the one achromatic k_spec: three known columns (N,) a = 1/π, b = D V (r), e = the
Torrance–Sparrow lobe (α) with F0 0.04 (:func:`gonio_cli.brdf.torrance_sparrow`,
:data:`gonio_cli.brdf_surfaces.FIBRE_F0`). k_spec is shared by the wavelengths, so it is found
first from the joint normal equations with the per-wavelength pairs eliminated (the Schur
complement: k = Σ_λ (q_λ − c_λᵀ A_λ⁻¹ p_λ) / Σ_λ (s_λ − c_λᵀ A_λ⁻¹ c_λ), A_λ the 2 × 2
normal matrix of (a, b), c_λ their products with e, p_λ, q_λ with the data), then
(ρ_d, ρ_sheen) ≥ 0 per wavelength in closed form (:func:`~.separable.nnls2`) on the data
less k e and k again from those, :data:`ROUNDS` times (the constraints may bind). What remains is the
profile cost over (log r, log α): a look at :data:`R_STARTS` × :data:`ALPHA_STARTS`
then nlopt BOBYQA (each evaluation a few sums over N × L: milliseconds).

Residuals as in :mod:`.layered`: linear with :func:`~.common.prepare`'s weights (log
residuals to first order, (f − y)/y).
"""

from __future__ import annotations

import numpy as np

from ..brdf import COS_EPS, evaluate, torrance_sparrow
from ..brdf_surfaces import FIBRE_F0, charlie_sheen
from .alpha import choose_optimizer
from .common import check_alpha, check_signal, ALPHA_MAX, ALPHA_MIN, BestPoint, FitData
from .results import FitOptions, FitReport, ModelFit, Stopwatch, error_figures, nm_list
from .separable import nnls2
from .warm import WARM_STEP, WARM_XTOL, near

MODEL = "sheen"
METHOD = "refined"

#: Bounds of the Charlie roughness r (glTF's sheenRoughness², in (0, 1]): below 0.02 the
#: lobe is sin^50 θh, a rim a few degrees wide at grazing half angles that no in-plane
#: goniometer samples.
R_MIN, R_MAX = 0.02, 1.0

#: Start values looked at before BOBYQA: r from a narrow rim to the broad sheen of velvet,
#: α from a satin's sharp highlight to a broad one.
R_STARTS = (0.1, 0.3, 0.6, 1.0)
ALPHA_STARTS = (0.03, 0.1, 0.3)

#: Evaluations allowed to the 2-D BOBYQA refinement of (log r, log α).
MAXEVAL = 200

#: Rounds of (ρ_d, ρ_sheen) and k_spec in turn after the joint solve (the constraints
#: ρ ≥ 0, k ≥ 0 may bind; without them the joint solve is already exact).
ROUNDS = 3

#: ``--optimizer``: the (log r, log α) search is BOBYQA.
OPTIMIZERS = {"nlopt-bobyqa": None}


def linear_weights(data: FitData) -> np.ndarray:
    """The weights (N, L) of linear residuals f − y: :func:`~.common.prepare`'s, and for
    log residuals those over y² (first order: (f − y)/y), as :mod:`.layered` takes them."""
    if data.residuals != "log":
        return data.w
    return np.where(data.positive, data.w / np.where(data.positive, data.y, 1.0) ** 2, 0.0)


class SheenProblem:
    """The linear problem of one data set: (ρ_d, ρ_sheen)(λ) and k_spec for any (r, α)."""

    def __init__(self, data: FitData):
        self.data = data
        self.w = linear_weights(data)
        self.signal = np.any((self.w > 0) & (data.y > 0), axis=0)
        self.a = np.full(data.n_configurations, 1.0 / np.pi)
        wy = self.w * data.y
        self.s_aa, self.s_at = self.a @ (self.w * self.a[:, None]), self.a @ wy
        self.s_tt = np.sum(wy * data.y, axis=0)

    def solve(self, r: float, alpha: float):
        """(params, cost (L,)) for fixed r and α."""
        w, y, a = self.w, self.data.y, self.a
        b = charlie_sheen(self.data.cos, r, COS_EPS)
        e = torrance_sparrow(self.data.cos, alpha, FIBRE_F0)[:, 0]
        wb, we = w * b[:, None], w * e[:, None]
        s_ab, s_bb, s_ae, s_be, s_ee = a @ wb, b @ wb, a @ we, b @ we, e @ we
        s_bt, s_et = b @ (w * y), e @ (w * y)
        det = self.s_aa * s_bb - s_ab * s_ab
        ok = self.signal & (det > 1e-12 * np.maximum(self.s_aa * s_bb, 1e-300))
        safe = np.where(ok, det, 1.0)

        def quad(u1, u2, v1, v2):           # uᵀ A⁻¹ v per wavelength
            return (u1 * (s_bb * v1 - s_ab * v2) + u2 * (self.s_aa * v2 - s_ab * v1)) / safe

        num = np.where(ok, s_et - quad(s_ae, s_be, self.s_at, s_bt), 0.0)
        den = np.where(ok, s_ee - quad(s_ae, s_be, s_ae, s_be), 0.0)
        k = max(float(np.sum(num)) / float(np.sum(den)), 0.0) if np.sum(den) > 0 else 0.0
        for _ in range(ROUNDS):
            rho_d, rho_s, cost = nnls2(self.s_aa, s_ab, s_bb, self.s_at - k * s_ae,
                                       s_bt - k * s_be,
                                       self.s_tt - 2 * k * s_et + k * k * s_ee)
            if not np.sum(s_ee[self.signal]) > 0:
                break
            rest = s_et - rho_d * s_ae - rho_s * s_be
            k = max(float(np.sum(rest[self.signal]) / np.sum(s_ee[self.signal])), 0.0)
        rho_d, rho_s, cost = nnls2(self.s_aa, s_ab, s_bb, self.s_at - k * s_ae, s_bt - k * s_be,
                                   self.s_tt - 2 * k * s_et + k * k * s_ee)
        params = {"r_sheen": float(r), "alpha": float(alpha), "k_spec": float(k),
                  "rho_d": np.where(self.signal, rho_d, 0.0),
                  "rho_sheen": np.where(self.signal, rho_s, 0.0)}
        return params, cost

    def cost(self, v) -> float:
        """The profile cost at (log r, log α), over the wavelengths with signal."""
        _, cost = self.solve(float(np.exp(v[0])), float(np.exp(v[1])))
        return float(np.sum(cost[self.signal]))


def _search(problem: SheenProblem, warm: dict | None):
    """((r, α), evaluations, message) minimising the profile cost (module doc); with
    ``warm`` (a fold of ``--model auto``) BOBYQA starts there with smaller steps."""
    lo = np.log([R_MIN, ALPHA_MIN])
    hi = np.log([R_MAX, ALPHA_MAX])
    search = BestPoint(problem.cost)
    step, xtol = np.array([0.5, 0.5]), np.array([1e-6, 1e-6])
    if warm is not None:
        search(np.clip(np.log([warm["r_sheen"], warm["alpha"]]), lo, hi))
        step, xtol = WARM_STEP * step, np.full(2, WARM_XTOL)
    else:
        for r in R_STARTS:
            for a in ALPHA_STARTS:
                search(np.log([r, a]))
    message = search.bobyqa(lo, hi, step, MAXEVAL, xtol_abs=xtol)
    return tuple(float(x) for x in np.exp(search.x)), search.n, message


def fit(data: FitData, options: FitOptions) -> ModelFit:
    """Fit ``sheen`` to prepared data (module doc). ``options.alpha`` fixes the specular
    lobe's α (the search is then over r alone). Returns a :class:`~.results.ModelFit` with
    one report, ``refined``; a wavelength without signal is named, its spectra 0."""
    check_alpha(options.alpha)
    optimizer, _ = choose_optimizer(MODEL, OPTIMIZERS, options.optimizer)
    sw = Stopwatch()
    problem = SheenProblem(data)
    check_signal(problem.signal)
    warm = near(options, "r_sheen", "alpha")
    if options.alpha is not None:
        fixed = np.log(options.alpha)
        search = BestPoint(lambda v: problem.cost([v[0], fixed]))
        for r in R_STARTS:
            search([np.log(r)])
        message = search.bobyqa([np.log(R_MIN)], [np.log(R_MAX)], [0.5], MAXEVAL,
                                xtol_abs=[1e-6])
        (r, alpha), n = (float(np.exp(search.x[0])), float(options.alpha)), search.n
        message = "alpha fixed; " + message
    else:
        (r, alpha), n, message = _search(problem, warm)
    params, _ = problem.solve(r, alpha)
    failed = [float(x) for x in data.wavelength_nm[~problem.signal]]
    if failed:
        message = (f"no usable signal at {len(failed)} wavelength(s) ({nm_list(failed)}); "
                   f"rho_d = rho_sheen = 0 there. " + message)
    status = "success" if not failed else "failed"
    f = evaluate(MODEL, data.cos, params)
    report = FitReport(METHOD, status, message, params, error_figures(data, f), optimizer,
                       n, sw.lap(), failed)
    return ModelFit(MODEL, data.wavelength_nm, {METHOD: report}, METHOD, data.excluded)
