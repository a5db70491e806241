"""Cook–Torrance with two or three lobes: a clear coat and flake lobes, as car-paint
models are used in industry.

Models (:func:`gonio_cli.brdf.cook_torrance_lobes`): ``cook-torrance-2`` and
``cook-torrance-3``, seed 004 eq. (11) summed over J lobes with one spectral F0,

    f = kd(λ)/π + Σ_j ks_j F(θd; F0(λ)) D(θh; m_j) G / (π cos θi cos θo),

Beckmann D (eq. 9), V-groove G (eq. 10), Schlick F (eq. 12). ks_j and m_j are one scalar
per lobe, ordered m_1 ≤ m_2 ≤ … (the clear coat first); kd and F0 are spectra.

The fit keeps the separable structure. With A_j = D_j G / (π cos θi cos θo),
S = Σ_j ks_j A_j and q = (1 − cos θd)⁵, Schlick's F = F0 (1 − q) + q, so for fixed
(ks_j, m_j) each wavelength is

    f = kd/π + F0 (1 − q) S + q S,

linear in (kd, F0) with a known offset q S: a two-column non-negative least squares
(:func:`~.separable.nnls2`, closed form, every wavelength at once from ten matrix-vector
products). F0 is kept ≤ 1: where the unconstrained F0 exceeds 1 the minimum over the box
lies on its face F0 = 1 (the cost is convex), and kd alone is solved there. The profile
cost, the sum of the per-wavelength costs over the wavelengths with signal, is then
minimised over the 2J scalars by a coarse start (:func:`m_starts`, each with ks_j from a
non-negative fit of the spectral envelope) and nlopt BOBYQA in (log m_1, u_2 … u_J,
ks_1 … ks_J), log m_j = log m_{j−1} + u_j (log M_MAX − log m_{j−1}), u_j ∈ [0, 1]: the
box maps onto the ordered lobes, which removes the label symmetry.

Identifiability from in-plane data: the m_j (each lobe's width) and kd (the level far
from the peaks) are, and so is the specular part of f. ks_j and F0 are not separately:
scaling every ks_j by s and F0 by 1/s changes f by (s − 1) q S only, and q is below 0.03
up to θd = 60° — the limit of the one-lobe fit (:mod:`.cook_torrance`). The bound F0 ≤ 1
keeps the ks_j from shrinking without limit, the q S term from growing without limit.

Residuals are linear in f with the weights :func:`~.common.prepare` made (compressive by
default; log residuals to first order, (f − y)/y, as :mod:`.layered`).
"""

from __future__ import annotations

import itertools

import numpy as np

from ..brdf import cook_torrance_specular_geometry, evaluate, schlick_fresnel
from ..errors import InputError
from .alpha import choose_optimizer
from .common import BestPoint, FitData
from .results import FitOptions, FitReport, ModelFit, Stopwatch, error_figures, nm_list
from .separable import nnls2
from .cook_torrance_profile import M_MAX, M_MIN
from .warm import WARM_STEP, near

#: Model name by number of lobes.
MODELS = {2: "cook-torrance-2", 3: "cook-torrance-3"}

#: Bounds of each lobe's ks: 0 (no lobe) to 100. ks trades against F0 (module
#: docstring), so a lobe with a small F0 may need ks well above 1, but ks F0 ≤ 1 for a
#: surface that conserves energy; 100 only keeps the search finite.
KS_MAX = 100.0

#: Coarse starts of the lobes' m: a clear coat (the narrowest lobe; 0.005–0.085, a
#: polished to a slightly hazy coat, every factor 1.5: the refinement then starts within
#: 22 % of the coat's m, where the lobe still overlaps the data's mirror readings) and
#: flake lobes (0.15–0.5, the spread of flake orientations in metallic paints, seed 004
#: §5). Every increasing combination is tried.
CLEAR_COAT_STARTS = tuple(float(v) for v in np.round(0.005 * 1.5 ** np.arange(8), 4))
FLAKE_STARTS = (0.15, 0.3, 0.5)


def m_starts(n_lobes: int) -> list[tuple[float, ...]]:
    """The start tuples (m_1 < m_2 < …) of the coarse search: 24 for 2 or 3 lobes."""
    return [(m1,) + flakes for m1 in CLEAR_COAT_STARTS
            for flakes in itertools.combinations(FLAKE_STARTS, n_lobes - 1)]


#: BOBYQA's first steps: 0.3 in log m_1 (35 % in m), 0.1 in each u_j, and this fraction
#: of each start ks (or KS_STEP_FLOOR where the start is 0).
KS_STEP_FRACTION = 0.2
KS_STEP_FLOOR = 1e-3

#: BOBYQA stops when a step changes every variable by less than XTOL_REL (relative; m
#: and ks to ~1e-7, far below what 1 % noise lets the data determine, ~1e-3), when the
#: cost falls by less than FTOL_REL (relative: the cost's own noise is ~1/N, N the
#: readings, ~1e-4), or after MAXEVAL_PER_VARIABLE × 2J evaluations (each ~0.1 ms on
#: 300 × 41 data). The ftol stop matters along the ks–F0 valley (module docstring), where
#: the cost keeps falling by tiny amounts.
XTOL_REL = 1e-7
FTOL_REL = 1e-10
MAXEVAL_PER_VARIABLE = 100

#: F0 counts as at its bound 1 when within this of it (reported per wavelength).
F0_AT_ONE_TOL = 1e-9


class Lobes:
    """The separable problem of one data set: kd(λ), F0(λ) for any fixed lobes."""

    def __init__(self, data: FitData, n_lobes: int):
        self.data, self.n_lobes = data, n_lobes
        # every wavelength with some weighted signal can be fitted
        self.signal = np.any((data.w > 0) & (data.y > 0), axis=0)
        # log residuals to first order: (f − y)/y, i.e. linear ones weighted by 1/y²
        w = (np.where(data.positive, data.w / np.where(data.positive, data.y, 1.0) ** 2, 0.0)
             if data.residuals == "log" else data.w)
        self.w = np.where(self.signal[None, :], w, 0.0)
        self.q = schlick_fresnel(data.cos.cos_theta_d, np.zeros(1))[:, 0]   # (1 − cos θd)⁵
        self.wy = self.w * data.y
        self.s_aa = self.w.sum(axis=0) / np.pi ** 2           # the kd column 1/π
        self.s_ay = self.wy.sum(axis=0) / np.pi
        self.s_yy = (self.wy * data.y).sum(axis=0)

    def lobe_geometry(self, m: np.ndarray) -> np.ndarray:
        """A_j = D(θh; m_j) G / (π cos θi cos θo), (J, N)."""
        return cook_torrance_specular_geometry(self.data.cos, np.asarray(m, float)).T

    def solve(self, m, ks):
        """(kd (L,), F0 (L,), cost (L,)) for lobes (m_j), (ks_j): per wavelength the
        least-squares kd ≥ 0, 0 ≤ F0 ≤ 1."""
        S = np.asarray(ks, float) @ self.lobe_geometry(m)    # (N,)
        P, O = (1.0 - self.q) * S, self.q * S                 # F0 column, offset
        Pw, Ow = P @ self.w, O @ self.w                       # (L,) each
        s_ab, s_bb = Pw / np.pi, (P * P) @ self.w
        s_at = self.s_ay - Ow / np.pi
        s_bt = P @ self.wy - (P * O) @ self.w
        s_tt = self.s_yy - 2.0 * (O @ self.wy) + (O * O) @ self.w
        kd, f0, cost = nnls2(self.s_aa, s_ab, s_bb, s_at, s_bt, s_tt)
        # F0 = 1: f = kd/π + S, kd alone (a 1-column NNLS)
        s_at1 = self.s_ay - (S @ self.w) / np.pi
        s_tt1 = self.s_yy - 2.0 * (S @ self.wy) + (S * S) @ self.w
        kd1 = np.where(self.s_aa > 0, np.maximum(s_at1, 0.0)
                       / np.where(self.s_aa > 0, self.s_aa, 1.0), 0.0)
        cost1 = np.maximum(s_tt1 - kd1 * s_at1, 0.0)
        over = f0 > 1.0
        return (np.where(over, kd1, kd), np.where(over, 1.0, f0),
                np.where(over, cost1, cost))

    def cost(self, m, ks) -> float:
        """The profile cost: Σ over the wavelengths with signal of each one's cost."""
        return float(np.sum(self.solve(m, ks)[2][self.signal]))

    def start_ks(self, m) -> np.ndarray:
        """ks_j for lobes m with F0 = 1, fitted (with a kd) to the spectral envelope
        max_λ y: an upper start, so the inner F0 comes out ≤ 1."""
        y = np.where(self.signal[None, :], self.data.y, -np.inf)
        k = np.argmax(y, axis=1)
        rows = np.arange(y.shape[0])
        env, w = y[rows, k], self.w[rows, k]
        root = np.sqrt(w)
        cols = np.vstack([np.full(env.size, 1.0 / np.pi), self.lobe_geometry(m)]).T
        coef = nnls_small(cols * root[:, None], env * root)
        return np.minimum(coef[1:], KS_MAX)


def nnls_small(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """min ‖A x − b‖ over x ≥ 0 for a few columns (A: (N, K), K ≤ 4), exactly.

    The constrained minimum is the unconstrained one on its support, so every subset of
    columns is solved by least squares and the cheapest feasible (x ≥ 0) solution kept;
    the empty subset (x = 0) is always feasible. 2^K − 1 small solves, no scipy import
    (which alone costs ~0.6 s at start-up).
    """
    k = A.shape[1]
    best, best_cost = np.zeros(k), float(b @ b)
    for size in range(1, k + 1):
        for cols in itertools.combinations(range(k), size):
            sub = A[:, cols]
            x, *_ = np.linalg.lstsq(sub, b, rcond=None)
            if np.all(x >= 0):
                r = sub @ x - b
                cost = float(r @ r)
                if cost < best_cost:
                    best, best_cost = np.zeros(k), cost
                    best[list(cols)] = x
    return best


def _to_m(v: np.ndarray, n_lobes: int) -> np.ndarray:
    """(log m_1, u_2 … u_J) → m (J,), increasing, in [M_MIN, M_MAX]."""
    log_m = [v[0]]
    for u in v[1:n_lobes]:
        log_m.append(log_m[-1] + u * (np.log(M_MAX) - log_m[-1]))
    return np.exp(np.clip(log_m, np.log(M_MIN), np.log(M_MAX)))


def _from_m(m) -> list[float]:
    """Inverse of :func:`_to_m` for an increasing m below M_MAX."""
    log_m = np.log(np.asarray(m, float))
    return [float(log_m[0])] + [float((b - a) / (np.log(M_MAX) - a))
                                for a, b in zip(log_m[:-1], log_m[1:])]


def _search(problem: Lobes, warm: dict | None = None):
    """(m (J,), ks (J,), evaluations, message): the best coarse start, then BOBYQA; with
    ``warm`` (a fold of ``--model auto``: the fit to all the data, :mod:`.warm`) BOBYQA
    from there, with :data:`~.warm.WARM_STEP` first steps."""
    n = problem.n_lobes
    search = BestPoint(lambda v: problem.cost(_to_m(v, n), np.asarray(v[n:], float)))
    lo = [np.log(M_MIN)] + [0.0] * (n - 1) + [0.0] * n
    hi = [np.log(M_MAX)] + [1.0] * (n - 1) + [KS_MAX] * n
    if warm is not None:
        search(np.clip(_from_m([warm[f"m_{j + 1}"] for j in range(n)])
                       + [warm[f"ks_{j + 1}"] for j in range(n)], lo, hi))
    else:
        for m in m_starts(n):
            search(_from_m(m) + problem.start_ks(np.array(m)).tolist())
    x0 = search.x
    step = np.array([0.3] + [0.1] * (n - 1) + [max(KS_STEP_FRACTION * k, KS_STEP_FLOOR)
                                               for k in x0[n:]])
    message = search.bobyqa(lo, hi, step * (WARM_STEP if warm is not None else 1.0),
                            MAXEVAL_PER_VARIABLE * 2 * n, xtol_rel=XTOL_REL, ftol_rel=FTOL_REL)
    v = search.x
    return _to_m(v, n), np.asarray(v[n:], float), search.n, message


#: ``--optimizer``: the lobes' joint search (:func:`_search`); the first is the default.
OPTIMIZERS = {"nlopt-bobyqa": _search}


def fit_lobes(data: FitData, options: FitOptions, n_lobes: int) -> ModelFit:
    """Fit ``cook-torrance-2`` or ``cook-torrance-3`` (``n_lobes`` 2 or 3)."""
    model = MODELS[n_lobes]
    if options.alpha is not None:
        raise InputError(f"--alpha does not apply to --model {model}",
                         fix="its lobes' roughnesses m_j are fitted; drop --alpha")
    optimizer, search = choose_optimizer(model, OPTIMIZERS, options.optimizer)
    sw = Stopwatch()
    problem = Lobes(data, n_lobes)
    if not problem.signal.any():
        raise InputError(f"no wavelength has a positive weighted reading to fit {model} to",
                         fix="check the measurement's values and weights")
    keys = [f"{k}_{j + 1}" for j in range(n_lobes) for k in ("m", "ks")]
    m, ks, evaluations, message = search(problem, near(options, *keys))
    kd, f0, _ = problem.solve(m, ks)
    ok = problem.signal
    params: dict = {"kd": np.where(ok, kd, 0.0), "f0": np.where(ok, f0, 0.0)}
    for j in range(n_lobes):
        params[f"ks_{j + 1}"] = float(ks[j])
        params[f"m_{j + 1}"] = float(m[j])
    notes = []
    at_bound = [f"m_{j + 1}" for j in range(n_lobes)
                if np.isclose(np.log(m[j]), np.log(M_MIN), atol=1e-6)
                or np.isclose(np.log(m[j]), np.log(M_MAX), atol=1e-6)]
    if at_bound:
        notes.append(f"{', '.join(at_bound)} at a bound of [{M_MIN:g}, {M_MAX:g}]")
    unused = [f"lobe {j + 1}" for j in range(n_lobes) if ks[j] == 0.0]
    if unused:
        notes.append(f"{', '.join(unused)} has ks = 0 (its m is not determined)")
    f0_at_one = [float(w) for w in data.wavelength_nm[ok & (f0 >= 1.0 - F0_AT_ONE_TOL)]]
    failed = [float(w) for w in data.wavelength_nm[~ok]]
    status = "success" if not failed else "failed"
    if failed:
        notes.insert(0, f"no usable signal at {len(failed)} wavelength(s) "
                        f"({nm_list(failed)}); kd = f0 = 0 there")
    message = "; ".join(notes + [message])
    f = evaluate(model, data.cos, params)
    report = FitReport("refined", status, message, params, error_figures(data, f),
                       optimizer, evaluations, sw.lap(), failed,
                       {"f0_at_one_nm": f0_at_one})
    return ModelFit(model, data.wavelength_nm, {"refined": report}, "refined", data.excluded)


def fit_2(data: FitData, options: FitOptions) -> ModelFit:
    return fit_lobes(data, options, 2)


def fit_3(data: FitData, options: FitOptions) -> ModelFit:
    return fit_lobes(data, options, 3)
