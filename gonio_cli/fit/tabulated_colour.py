"""Fit of ``tabulated-colour``: f = ρ_d(λ)/π + T(θh, θd, λ) g(θi, θo; α)
(:func:`gonio_cli.brdf.tabulated_colour`), g the GGX lobe of fixed shape
(:func:`gonio_cli.brdf.ggx_lobe`) and T a table over Rusinkiewicz's half and difference
angles, bilinear between its nodes (:mod:`gonio_cli.brdf_surfaces`; X-Rite AxF's car-paint
colour table, AxF CPA2). Seed 000 eq. 5's exp(c(λ) x) is one analytic colour shift of this
kind; the table takes any smooth one.

For a fixed α the model is linear in (ρ_d, T) with one design matrix X (N, 1 + n_h n_d)
for every wavelength: a column 1/π and, per node, its bilinear weight times g. The table
is kept smooth by a second-difference penalty along θh and along θd (R = D_hᵀD_h + D_dᵀD_d,
divided differences over the node angles; its null space is the tables linear in each
angle, which it leaves alone), so
each wavelength solves

    (Xᵀ W_λ X + μ_λ R) β = Xᵀ W_λ y_λ,   μ_λ = κ · mean diag of the table block of Xᵀ W_λ X,

the weight relative to the data's own scale (the same κ means the same smoothness for any
α, any units). κ is chosen by generalised cross-validation (Golub, Heath & Wahba 1979):
among :data:`SMOOTHNESS_GRID`, the one minimising Σ_λ n_λ RSS_λ / (n_λ − tr H_λ)², tr H_λ =
tr((A + μR)⁻¹ A); it is chosen at the α of a first search with κ = :data:`SMOOTHNESS_START`
and α searched again with it (a fold of ``--model auto`` takes the κ of the fit to all the
data: :data:`SMOOTHNESS_NEAR`). α is a 1-D search (:func:`~.alpha.minimize_log_alpha`) of
the penalised profile cost. Nodes where the solve gives T < 0 are set to 0 (f ≥ 0), and
ρ_d solved again.
"""

from __future__ import annotations

import numpy as np

from ..brdf import evaluate, ggx_lobe
from ..brdf_surfaces import table_weights
from .alpha import choose_optimizer, minimize_log_alpha
from .common import check_alpha, check_signal, ALPHA_MAX, ALPHA_MIN, FitData
from .results import FitOptions, FitReport, ModelFit, Stopwatch, error_figures, nm_list
from .sheen import linear_weights
from .warm import log_alpha_window, near

MODEL = "tabulated-colour"
METHOD = "refined"

#: The table's nodes over θh (degrees): dense near the mirror, where the GGX lobe carries
#: the signal (at α 0.1 it falls to 3 % by θh = 13°), sparse beyond.
THETA_H_NODES_DEG = (0.0, 2.0, 5.0, 10.0, 18.0, 30.0, 50.0, 90.0)

#: The table's nodes over θd (degrees): every 12.9° (8 nodes), the colour shift's scale.
THETA_D_NODES_DEG = tuple(float(x) for x in np.linspace(0.0, 90.0, 8))

#: κ of the α search before the smoothness is chosen, and the κ tried by GCV.
SMOOTHNESS_START = 1e-2
SMOOTHNESS_GRID = (1e-5, 1e-4, 1e-3, 1e-2, 1e-1, 1.0)

#: A ridge of this fraction of the mean diagonal keeps the normal matrix invertible when
#: the data do not reach a node and the penalty's bilinear null space leaves it free.
RIDGE = 1e-9

#: Interpolation weights below this (round-off of a node's own angle) and lobe values below
#: this times the lobe's peak are set to 0: they change no sum of the normal equations
#: beyond round-off, and products of such values can underflow into subnormal numbers.
TINY = 1e-12

#: Scan points of the α search (every 33 % in α, as :mod:`.layered`).
ALPHA_POINTS = 25

#: The key of :attr:`FitOptions.stages <.results.FitOptions>` under which the first fit of
#: a run (``--model auto``: the fit to all the data) leaves its κ for the folds, which
#: search α near that fit's (:mod:`.warm`) with the same smoothness instead of choosing
#: it again.
SMOOTHNESS_NEAR = "tabulated-colour: smoothness"

#: ``--optimizer``: the refinement of the 1-D α search.
OPTIMIZERS = {"nlopt-bobyqa": minimize_log_alpha, "nlopt-lbfgs": minimize_log_alpha}


def second_differences(theta_h_nodes_deg, theta_d_nodes_deg) -> np.ndarray:
    """R (n_h n_d, n_h n_d) = D_hᵀD_h + D_dᵀD_d, D the second divided differences along θh
    (rows a) and θd (columns b) of the table flattened as a n_d + b, each scaled by its
    axis's mean node spacing squared (on even nodes: 1, −2, 1). Tables linear in each
    angle (a + b θh + c θd + d θh θd) are its null space."""
    def d2(nodes):
        x = np.asarray(nodes, dtype=float)
        n = x.size
        out = np.zeros((max(n - 2, 0), n))
        if n < 3:
            return out
        h1, h2 = np.diff(x)[:-1], np.diff(x)[1:]
        scale = 2.0 * np.mean(np.diff(x)) ** 2 / (h1 + h2)
        rows = np.arange(n - 2)
        out[rows, rows] = scale / h1
        out[rows, rows + 1] = -scale * (1 / h1 + 1 / h2)
        out[rows, rows + 2] = scale / h2
        return out
    nh, nd = len(theta_h_nodes_deg), len(theta_d_nodes_deg)
    dh = np.kron(d2(theta_h_nodes_deg), np.eye(nd))
    dd = np.kron(np.eye(nh), d2(theta_d_nodes_deg))
    return dh.T @ dh + dd.T @ dd


def penalty_weights(A: np.ndarray, kappa: float) -> tuple[np.ndarray, np.ndarray]:
    """(μ_λ, ridge_λ) (L,) of the normal matrices A (L, K, K) (ρ_d first): the penalty
    weight κ · mean diag of the table block (module doc) and :data:`RIDGE` · mean diag."""
    diag = np.einsum("lkk->lk", A)
    return kappa * np.mean(diag[:, 1:], axis=1), RIDGE * np.mean(diag, axis=1)


def penalty(data: FitData, alpha: float, kappa: float):
    """(μ (L,), R (n_h n_d, n_h n_d), ridge (L,)): what the fit at (α, κ) added to the
    table block of each wavelength's normal matrix, μ_λ R + ridge_λ I (module doc), for the
    covariance of the penalised estimator (:mod:`.uncertainty_table`). ``data`` as the
    fit saw them (divided by the light-source gains where it had them)."""
    problem = TableProblem(data)
    mu, ridge = penalty_weights(problem.normal(alpha)[0], kappa)
    return mu, problem.R[1:, 1:], ridge


class TableProblem:
    """The regularised linear problem of one data set for any α (module doc)."""

    def __init__(self, data: FitData, theta_h_nodes_deg=THETA_H_NODES_DEG,
                 theta_d_nodes_deg=THETA_D_NODES_DEG):
        self.data = data
        self.nodes = (np.asarray(theta_h_nodes_deg, float), np.asarray(theta_d_nodes_deg, float))
        self.shape = (self.nodes[0].size, self.nodes[1].size)
        self.w = linear_weights(data)
        self.signal = np.any((self.w > 0) & (data.y > 0), axis=0)
        n = data.n_configurations
        hats = table_weights(data.cos, *self.nodes).reshape(n, -1)        # (N, n_h n_d)
        self.hats = np.where(hats < TINY, 0.0, hats)     # round-off of t = 0 or 1: exact 0
        k = 1 + self.hats.shape[1]
        self.R = np.zeros((k, k))
        self.R[1:, 1:] = second_differences(*self.nodes)
        self.rows = np.sum(self.w > 0, axis=0)                            # n_λ
        # the pairs of nodes some configuration weighs together (≤ 16 per row): the table
        # block of XᵀWX is Σ_n w g² h_j h_k over these only (one matrix product per α)
        j, k2 = np.nonzero(self.hats.T @ self.hats)
        self.pairs = (1 + j, 1 + k2)
        self.pair_hats = np.ascontiguousarray(self.hats[:, j] * self.hats[:, k2])  # (N, P)
        a = 1.0 / np.pi
        self.s_aa = a * a * np.sum(self.w, axis=0)                         # (L,)
        self.wy = self.w * data.y
        self.b_a = a * np.sum(self.wy, axis=0)
        self.s_yy = np.sum(self.wy * data.y, axis=0)

    def normal(self, alpha: float):
        """(A (L, K, K), b (L, K), g (N,)) of the design at α: XᵀW_λX and XᵀW_λy."""
        g = ggx_lobe(self.data.cos, alpha)
        g = np.where(g < TINY * np.max(g), 0.0, g)
        n_l, k = self.w.shape[1], 1 + self.hats.shape[1]
        A = np.zeros((n_l, k, k))
        A[:, 0, 0] = self.s_aa
        A[:, 0, 1:] = (self.w * g[:, None]).T @ self.hats / np.pi
        A[:, 1:, 0] = A[:, 0, 1:]
        A[:, self.pairs[0], self.pairs[1]] = (self.w * (g * g)[:, None]).T @ self.pair_hats
        b = np.concatenate([self.b_a[:, None], (self.wy * g[:, None]).T @ self.hats], axis=1)
        return A, b, g

    def solve(self, alpha: float, kappa: float, trace: bool = False):
        """(β (L, K), RSS (L,), penalty (L,), tr H (L,) (with ``trace``, else None), g) at
        α with smoothness κ. RSS = yᵀWy − 2βᵀb + βᵀAβ, from the normal equations."""
        A, b, g = self.normal(alpha)
        mu, ridge = penalty_weights(A, kappa)
        k = A.shape[1]
        M = A + mu[:, None, None] * self.R + ridge[:, None, None] * np.eye(k)
        M = np.where(self.signal[:, None, None], M, np.eye(k))
        beta = np.linalg.solve(M, np.where(self.signal[:, None], b, 0.0)[..., None])[..., 0]
        rss = np.maximum(self.s_yy - 2 * np.sum(beta * b, axis=1)
                         + np.einsum("lk,lkj,lj->l", beta, A, beta), 0.0)
        pen = mu * np.einsum("lk,kj,lj->l", beta, self.R, beta)
        tr = np.einsum("lkj,ljk->l", np.linalg.inv(M), A) if trace else None
        return beta, rss, pen, tr, g

    def cost(self, alpha: float, kappa: float) -> float:
        """The penalised profile cost over the wavelengths with signal."""
        _, rss, pen, _, _ = self.solve(alpha, kappa)
        return float(np.sum((rss + pen)[self.signal]))

    def gcv(self, alpha: float) -> tuple[float, float]:
        """(κ, its GCV score) of :data:`SMOOTHNESS_GRID` with the least GCV at α."""
        best = (SMOOTHNESS_START, np.inf)
        for kappa in SMOOTHNESS_GRID:
            _, rss, _, trace, _ = self.solve(alpha, kappa, trace=True)
            dof = self.rows - trace
            s = self.signal
            score = (float(np.sum(self.rows[s] * rss[s] / dof[s] ** 2))
                     if np.all(dof[s] > 0) else np.inf)
            if score < best[1]:
                best = (kappa, score)
        return best

    def params(self, alpha: float, kappa: float) -> tuple[dict, int]:
        """The material's parameters at (α, κ), T ≥ 0 (ρ_d solved again where a node was
        clipped), and the number of table entries clipped."""
        beta, _, _, _, g = self.solve(alpha, kappa)
        table = beta[:, 1:]                                                # (L, n_h n_d)
        clipped = int(np.sum((table < 0) & self.signal[:, None]))
        table = np.where(self.signal[:, None], np.maximum(table, 0.0), 0.0)
        rest = self.data.y - (self.hats * g[:, None]) @ table.T            # (N, L)
        rho_d = np.pi * np.sum(self.w * rest, axis=0) / np.maximum(
            np.sum(self.w, axis=0), 1e-300)
        rho_d = np.where(self.signal, np.maximum(rho_d, 0.0), 0.0)
        return {"alpha": float(alpha), "rho_d": rho_d,
                "colour_table": np.moveaxis(table.reshape(-1, *self.shape), 0, -1),
                "theta_h_nodes_deg": self.nodes[0].copy(),
                "theta_d_nodes_deg": self.nodes[1].copy()}, clipped


def _alpha(problem: TableProblem, kappa: float, optimizer: str, search, window=None):
    lo, hi, points = np.log(ALPHA_MIN), np.log(ALPHA_MAX), ALPHA_POINTS
    if window is not None:
        lo, hi, points = log_alpha_window(window, lo, hi, points)
    return search(lambda g: problem.cost(float(np.exp(g)), kappa), optimizer, lo=lo, hi=hi,
                  points=points)


def fit(data: FitData, options: FitOptions) -> ModelFit:
    """Fit ``tabulated-colour`` to prepared data (module doc); ``options.alpha`` fixes α.
    One report, ``refined``, with the smoothness κ and its GCV score in its figures."""
    check_alpha(options.alpha)
    optimizer, search = choose_optimizer(MODEL, OPTIMIZERS, options.optimizer)
    sw = Stopwatch()
    problem = TableProblem(data)
    check_signal(problem.signal)
    warm = near(options, "alpha")
    memo = options.stages if options.stages is not None else {}
    success, message, n = True, "alpha fixed", 0
    if options.alpha is not None:
        alpha = float(options.alpha)
        kappa, score = problem.gcv(alpha)
    elif warm is not None and SMOOTHNESS_NEAR in memo:
        # a fold of auto: the smoothness of the fit to all the data, α searched near its α
        kappa, score = memo[SMOOTHNESS_NEAR], float("nan")
        found = _alpha(problem, kappa, optimizer, search, warm["alpha"])
        alpha, success, message, n = found.alpha, found.success, found.message, found.evaluations
    else:
        first = _alpha(problem, SMOOTHNESS_START, optimizer, search,
                       warm["alpha"] if warm else None)
        kappa, score = problem.gcv(first.alpha)
        found = _alpha(problem, kappa, optimizer, search, first.alpha)
        alpha, success, message = found.alpha, found.success, found.message
        n = first.evaluations + found.evaluations
    memo.setdefault(SMOOTHNESS_NEAR, kappa)
    params, clipped = problem.params(alpha, kappa)
    failed = [float(x) for x in data.wavelength_nm[~problem.signal]]
    if failed:
        message = (f"no usable signal at {len(failed)} wavelength(s) ({nm_list(failed)}); "
                   f"rho_d = T = 0 there. " + message)
    status = "success" if success and not failed else "failed"
    f = evaluate(MODEL, data.cos, params)
    # no GCV score: a fold of auto (the full fit's κ), or fewer configurations than the
    # table's effective parameters (κ stays SMOOTHNESS_START)
    extra = {"smoothness": kappa, "gcv": score if np.isfinite(score) else None,
             "table_entries_clipped": clipped}
    report = FitReport(METHOD, status, message, params, error_figures(data, f), optimizer,
                       n, sw.lap(), failed, extra)
    return ModelFit(MODEL, data.wavelength_nm, {METHOD: report}, METHOD, data.excluded)
