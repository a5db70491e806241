"""Machinery shared by every model fit: data preparation, weights, the α search,
vectorised small solvers, error figures and the result objects (STYLE 9).

Every fit in gonio has the same structure: one wavelength-independent roughness (α, or
none) and a few parameters per wavelength that, for a fixed α, are cheap to find (closed
form or a vectorised 1-D search over all wavelengths at once). The joint problem then
becomes a one-dimensional search over log α of the *profile* cost (the cost with the
per-wavelength parameters optimal for that α). :func:`.alpha.minimize_log_alpha` does that search:
a coarse scan over the whole admissible range (so a stiff, near-mirror lobe or a rough one
is bracketed, never missed by a local method started far away), then a local refinement
with the chosen optimiser (each fitter's ``OPTIMIZERS``).

Here the data and its weights, the small solvers and eq. 5's best point for a fixed α;
the α search is :mod:`.alpha`, the error figures and result objects :mod:`.results`, eq. 5's
c search and the non-negative solves :mod:`.separable`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..errors import FitError, InputError
from ..geometry import Cosines, measurement_cosines
from ..schemas import Measurement

#: Admissible GGX α. Below 1e-3 the lobe is ~0.06° wide, narrower than any goniometer's
#: aperture, so the data cannot tell it from a mirror; above 1 GGX turns retro-peaked and
#: seed 000 eq. 3 defines α in (0, 1].
ALPHA_MIN = 1e-3
ALPHA_MAX = 1.0


def check_alpha(alpha: float | None) -> None:
    """``--alpha`` (None: searched) inside [:data:`ALPHA_MIN`, :data:`ALPHA_MAX`], or one
    line that says so."""
    if alpha is not None and not (ALPHA_MIN <= alpha <= ALPHA_MAX):
        raise InputError(f"--alpha {alpha:g} is outside [{ALPHA_MIN:g}, {ALPHA_MAX:g}]",
                         fix="GGX alpha of seed 000 eq. 3 lies in (0, 1]")


def check_signal(signal: np.ndarray) -> None:
    """At least one wavelength with a usable reading (``signal`` (L,) bool), or a
    :class:`~gonio_cli.errors.FitError`."""
    if not np.any(signal):
        raise FitError("no wavelength has a positive reading of positive weight",
                       fix="check the measurement (all values zero or negative?)")

#: Points of the coarse scan over log α (every 15 % in α across [ALPHA_MIN, ALPHA_MAX]);
#: the profile cost is smooth, so the minimum is bracketed between two neighbours.
ALPHA_SCAN_POINTS = 49

#: Local refinement stops when log α changes by less than this (α to 1e-8 relative).
LOG_ALPHA_XTOL = 1e-8

#: A configuration is "mirror" (ωo the mirror image of ωi) when |θo − θi| is below this (°);
#: goniometers report angles to 0.1° or so.
MIRROR_TOL_DEG = 0.5

#: Floor of the relative standard deviation used for weights (0.5 %): a std estimated from
#: a few repeats can be near zero by chance and would otherwise dominate the fit.
REL_SIGMA_FLOOR = 0.005

#: Step of the central difference used by gradient optimisers on the profile cost, in
#: log α (relative 1e-5 in α: truncation error ~1e-10, far below the cost's noise).
FD_STEP_LOG_ALPHA = 1e-5


# -------------------------------------------------------------------------------- data --

@dataclass
class FitData:
    """A measurement prepared for fitting: geometry, values, weights and masks.

    Attributes
    ----------
    wavelength_nm : (L,) ; theta_i_deg, theta_o_deg : (N,) ; cos : :class:`Cosines` (N,)
    y : (N, L) BRDF in sr⁻¹ ; w : (N, L) weights ≥ 0 (0 = not used) for the chosen
        residuals ; positive : (N, L) bool, y > 0 (log residuals need it)
    residuals : "log", "linear" or "compressive" (a linear residual whose weights
        compress the dynamic range, :func:`prepare`; fitters treat it as linear)
    phi_o_deg : (N,) the detector's azimuth (docs/conventions.md), or None in plane;
        ``cos`` already holds it, so a fitter needs nothing else
    """

    wavelength_nm: np.ndarray
    theta_i_deg: np.ndarray
    theta_o_deg: np.ndarray
    cos: Cosines
    y: np.ndarray
    w: np.ndarray
    positive: np.ndarray
    residuals: str
    excluded: dict[str, Any] = field(default_factory=dict)
    phi_o_deg: np.ndarray | None = None

    @property
    def n_configurations(self) -> int:
        return int(self.theta_i_deg.size)

    def subset(self, rows: np.ndarray) -> "FitData":
        """The same data restricted to a boolean or index selection of configurations."""
        return FitData(self.wavelength_nm, self.theta_i_deg[rows], self.theta_o_deg[rows],
                       Cosines(*(c[rows] for c in self.cos)), self.y[rows], self.w[rows],
                       self.positive[rows], self.residuals, self.excluded,
                       None if self.phi_o_deg is None else self.phi_o_deg[rows])

    def mirror_rows(self) -> np.ndarray:
        """Boolean (N,): the mirror configurations θo ≈ θi, φo = 0 (seed 000 eq. 7)."""
        mirror = np.abs(self.theta_o_deg - self.theta_i_deg) <= MIRROR_TOL_DEG
        return mirror if self.phi_o_deg is None else mirror & (self.phi_o_deg == 0)

    def theta_i_groups(self) -> list[tuple[float, np.ndarray]]:
        """[(θi in degrees, boolean rows)] per distinct angle of incidence, ascending."""
        values = np.unique(np.round(self.theta_i_deg, 6))
        return [(float(t), np.abs(self.theta_i_deg - t) < 1e-6) for t in values]


RESIDUALS = ("compressive", "log", "linear")

#: The compressive residual's floor ε(λ) is this multiple of the median value at that
#: wavelength: configurations far above it (a glossy peak) count by their relative error,
#: those far below it (the dark tail) by their absolute error in units of ε, so neither
#: the peak (as with linear residuals) nor the tail (as with log residuals) dominates.
COMPRESSIVE_FLOOR_OF_MEDIAN = 1.0

#: Weights below this cos θi cos θo are floored there (θ ≈ 89.4° each): a configuration at
#: grazing keeps a little weight rather than none.
GEOMETRY_WEIGHT_FLOOR = 1e-4


def compressive_floor(y: np.ndarray) -> np.ndarray:
    """ε(λ) (L,) of the compressive residual: :data:`COMPRESSIVE_FLOOR_OF_MEDIAN` × the
    median of y (N, L) at each wavelength; an all-dark wavelength takes its RMS, else 1."""
    eps = COMPRESSIVE_FLOOR_OF_MEDIAN * np.median(np.maximum(y, 0.0), axis=0)
    scale = np.sqrt(np.mean(y * y, axis=0))
    return np.where(eps > 0, eps, np.where(scale > 0, scale, 1.0))


def compressive_weights(y: np.ndarray, cos_theta_i: np.ndarray,
                        cos_theta_o: np.ndarray) -> np.ndarray:
    """Weights (N, L) of the compressive residual √w (f − y).

    w = cos θi cos θo / (y + ε(λ))², ε = :data:`COMPRESSIVE_FLOOR_OF_MEDIAN` × the median
    of y at that wavelength. (f − y)/(y + ε) is log(1 + f/ε) − log(1 + y/ε) to first order
    about the data — the compressive transform of the BRDF-fitting literature (e.g. Löw et
    al. 2012; Ngan et al. 2005 weight by the cosines) — in the form that keeps the model
    linear in its linear parameters, so every fitter's closed forms still apply.
    """
    eps = compressive_floor(y)
    geo = np.maximum(np.clip(cos_theta_i, 0, 1) * np.clip(cos_theta_o, 0, 1),
                     GEOMETRY_WEIGHT_FLOOR)
    return geo[:, None] / (np.maximum(y, 0.0) + eps[None, :]) ** 2


def prepare(measurement: Measurement, *, residuals: str = "log",
            exclude_theta_i_deg=(), exclude_theta_o_deg=(), weights=None,
            use_std: bool = True, path=None) -> FitData:
    """Build :class:`FitData` from a measurement.

    Residuals: ``log`` (the core's default, exact for seed 000's closed forms),
    ``compressive`` (``gonio fit``'s default, :func:`compressive_weights`) or ``linear``. Weights: if ``brdf_std`` is present, w = 1/σ² of the mean of the repeats
    (σ = std/√n; in log residuals the relative σ/y), with :data:`REL_SIGMA_FLOOR`;
    configurations read once take the median σ of the repeated ones. Otherwise w = 1
    (log) or 1/ȳ² per wavelength (linear, so each wavelength counts alike). The
    compressive weights are multiplied by the repeats' relative precision (1/rel σ²,
    mean 1) when there are repeats. ``weights`` (N,) ≥ 0, one per configuration of the
    measurement (``--weights``), multiplies the result. Values ≤ 0 get weight 0 in log
    residuals (log undefined) and are counted in ``excluded``.
    """
    if residuals not in RESIDUALS:
        raise InputError(f"--residuals {residuals!r} is not one of {', '.join(RESIDUALS)}")
    ti, to = measurement.theta_i_deg, measurement.theta_o_deg
    keep = np.ones(ti.shape, dtype=bool)
    dropped_ti, dropped_to = [], []
    for flag, angles, dropped, values in (("--exclude-theta-i-deg", exclude_theta_i_deg,
                                           dropped_ti, ti),
                                          ("--exclude-theta-o-deg", exclude_theta_o_deg,
                                           dropped_to, to)):
        for t in angles:
            hit = np.abs(values - float(t)) < 1e-6
            if not hit.any():
                name = "theta_i_deg" if flag.endswith("-i-deg") else "theta_o_deg"
                raise InputError(f"{flag} {t:g}: no configuration has {name}={t:g}",
                                 path=path,
                                 fix=f"measured: {', '.join(f'{v:g}' for v in np.unique(values))}")
            dropped.append(float(t))
            keep &= ~hit
    if weights is not None:
        weights = np.asarray(weights, dtype=float)
        if weights.shape != ti.shape or not np.all(np.isfinite(weights)) or np.any(weights < 0):
            raise InputError(f"--weights must give one finite weight >= 0 per configuration "
                             f"({ti.size}), got {weights.size}", path=path)
        keep &= weights > 0
    if not keep.any():
        raise InputError("every configuration is excluded", path=path,
                         fix="exclude fewer angles or give some configurations weight > 0")
    y = measurement.brdf[keep]
    positive = y > 0
    phi = None if measurement.phi_o_deg is None else measurement.phi_o_deg[keep]
    cos = measurement_cosines(ti[keep], to[keep], phi)
    has_std = measurement.brdf_std is not None and use_std
    if has_std:
        rel = _relative_sigma(y, measurement.brdf_std[keep], measurement.n_repeats[keep])
    if residuals == "compressive":
        w = compressive_weights(y, cos.cos_theta_i, cos.cos_theta_o)
        if has_std:
            precision = 1.0 / rel ** 2
            w = w * precision / np.mean(precision)
    elif has_std:
        # log residuals: σ(log y) ≈ σ/y; linear: σ itself, floored at the relative floor of
        # the wavelength's typical magnitude so near-zero readings do not dominate.
        w = 1.0 / rel ** 2 if residuals == "log" else \
            1.0 / ((rel * y) ** 2 + (REL_SIGMA_FLOOR * _scale(y)) ** 2)
    else:
        w = np.ones_like(y) if residuals == "log" else np.broadcast_to(
            1.0 / _scale(y) ** 2, y.shape).copy()
    if residuals == "log":
        w = np.where(positive, w, 0.0)
    if weights is not None:
        w = w * weights[keep][:, None]
    w = w / np.mean(w[w > 0]) if np.any(w > 0) else w  # scale-free weights, mean 1
    return FitData(measurement.wavelength_nm, ti[keep], to[keep], cos, y, w, positive,
                   residuals, {"theta_i_deg": dropped_ti, "theta_o_deg": dropped_to,
                               "non_positive_values": int((~positive).sum())}, phi)


def _relative_sigma(y: np.ndarray, std: np.ndarray, n_repeats: np.ndarray) -> np.ndarray:
    """Relative standard deviation of each mean (N, L), σ/y with σ = std/√n, floored.

    Configurations read once (no std) and non-positive readings take the median relative
    σ of the repeated readings at their wavelength (or the floor if there are none).
    """
    positive = y > 0
    repeated = (n_repeats > 1)[:, None] & positive
    sigma = std / np.sqrt(np.maximum(n_repeats, 1))[:, None]
    rel = np.where(repeated, sigma / np.where(positive, y, 1.0), np.nan)
    fill = np.full(y.shape[1], REL_SIGMA_FLOOR)
    has = repeated.any(axis=0)
    if has.any():
        fill[has] = np.nanmedian(rel[:, has], axis=0)
    rel = np.where(repeated, rel, fill[None, :])
    return np.sqrt(rel ** 2 + REL_SIGMA_FLOOR ** 2)


def _scale(y: np.ndarray) -> np.ndarray:
    """Per-wavelength typical magnitude (L,), for scale-free linear weights; never 0."""
    s = np.sqrt(np.mean(y * y, axis=0))
    return np.where(s > 0, s, 1.0)


# --------------------------------------------------------------------- small solvers --

def weighted_linear_lsq(X: np.ndarray, Y: np.ndarray, W: np.ndarray):
    """Per-column weighted least squares, all columns at once (closed form).

    Solves min_β Σ_n W[n, l] (Y[n, l] − Σ_k X[n, k] β[k, l])² for each column l.

    Parameters
    ----------
    X : (N, K) design shared by the columns ; Y, W : (N, L)

    Returns
    -------
    beta : (K, L) ; cost : (L,) weighted sum of squared residuals ;
    ok : (L,) bool, False where the weighted normal matrix is singular (too few
    distinct weighted rows); β is 0 there.
    """
    A = np.einsum("nk,nl,nj->lkj", X, W, X)            # (L, K, K)
    b = np.einsum("nk,nl,nl->lk", X, W, Y)             # (L, K)
    K = X.shape[1]
    # Condition test relative to the diagonal scale: below this the columns are dependent.
    diag = np.einsum("lkk->lk", A)
    scale = np.where(diag > 0, diag, 1.0)
    An = A / np.sqrt(scale[:, :, None] * scale[:, None, :])
    det = np.linalg.det(An) if K > 1 else An[:, 0, 0]
    ok = np.all(diag > 0, axis=1) & (np.abs(det) > SINGULAR_TOL)
    eye = np.eye(K)[None]
    beta = np.linalg.solve(np.where(ok[:, None, None], A, eye),
                           np.where(ok[:, None], b, 0.0)[..., None])[..., 0]
    beta = np.where(ok[:, None], beta, 0.0).T          # (K, L)
    r = Y - X @ beta
    return beta, np.sum(W * r * r, axis=0), ok


class LinearProfile:
    """Weighted linear least squares per column with a shifting target, precomputed.

    For targets Y − o[:, None] (Y: (N, L) fixed, o: (N,) an offset that depends on the
    nonlinear parameter, e.g. log D(θh; α)), the design X (N, K) and the weights W (N, L)
    do not change, so the normal matrices and their inverses are computed once. A trial
    offset then costs two matrix–vector products: the profile cost of a whole scan of α
    values is one matrix product. This is what makes step 2 "closed form" in practice.

    The design must contain a constant column (the intercept, log ρ here): each column
    of Y is centred first, which leaves β (but its intercept) and the cost unchanged and
    keeps the expanded cost free of cancellation.
    """

    def __init__(self, X: np.ndarray, Y: np.ndarray, W: np.ndarray):
        self.X = np.asarray(X, dtype=float)
        self.W = np.asarray(W, dtype=float)
        Y = np.asarray(Y, dtype=float)
        sw = self.W.sum(axis=0)
        self.mean = np.where(sw > 0, np.sum(self.W * Y, axis=0) / np.where(sw > 0, sw, 1), 0)
        self.Yc = Y - self.mean                                  # (N, L)
        _, _, self.ok = weighted_linear_lsq(self.X, self.Yc, self.W)
        A = np.einsum("nk,nl,nj->lkj", self.X, self.W, self.X)   # (L, K, K)
        K = self.X.shape[1]
        self.A_inv = np.linalg.inv(np.where(self.ok[:, None, None], A, np.eye(K)))
        self.WX = np.einsum("nl,nk->lkn", self.W, self.X)        # (L, K, N)
        self.b0 = np.einsum("lkn,nl->lk", self.WX, self.Yc)      # (L, K)
        self.S0 = np.sum(self.W * self.Yc ** 2, axis=0)          # (L,)
        self.u = self.W * self.Yc                                # (N, L)
        self.intercept = int(np.argmax(np.all(self.X == 1.0, axis=0)))

    def costs(self, offsets: np.ndarray) -> np.ndarray:
        """Total cost (over the ok columns) for each offset row; offsets (G, N) → (G,)."""
        O = np.atleast_2d(np.asarray(offsets, dtype=float))      # (G, N)
        b = self.b0[None] - np.einsum("lkn,gn->glk", self.WX, O)  # (G, L, K)
        quad = np.einsum("glk,lkj,glj->gl", b, self.A_inv, b)
        yy = self.S0[None] - 2.0 * O @ self.u + (O * O) @ self.W  # (G, L)
        cost = np.maximum(yy - quad, 0.0)
        return np.sum(np.where(self.ok[None], cost, 0.0), axis=1)

    def cost(self, offset: np.ndarray) -> float:
        return float(self.costs(offset[None])[0])

    def solve(self, offset: np.ndarray):
        """β (K, L), exact per-column cost (L,) and ok (L,) for one offset (N,)."""
        b = self.b0 - np.einsum("lkn,n->lk", self.WX, offset)
        beta = np.einsum("lkj,lj->kl", self.A_inv, b)
        beta[self.intercept] += self.mean
        r = self.Yc + self.mean - offset[:, None] - self.X @ beta
        beta = np.where(self.ok[None], beta, 0.0)
        return beta, np.sum(self.W * r * r, axis=0), self.ok


#: Determinant of the unit-diagonal normal matrix below which the design is singular
#: (two columns with correlation above 1 − 1e-10 cannot be separated in float64).
SINGULAR_TOL = 1e-10

#: Golden-section iterations: the bracket shrinks by 0.618 per step, so 80 steps take a
#: bracket of width 100 below 1e-14 (float64 resolution of the argument).
GOLDEN_ITERATIONS = 80
_INV_PHI = (np.sqrt(5.0) - 1.0) / 2.0


def golden_section(fun: Callable[[np.ndarray], np.ndarray], lo, hi,
                   iterations: int = GOLDEN_ITERATIONS) -> tuple[np.ndarray, np.ndarray]:
    """Minimise L independent 1-D functions at once by golden-section search.

    ``fun(x)`` takes (L,) arguments and returns (L,) values (one function per column);
    ``lo``, ``hi``: (L,) brackets (or scalars broadcast with each other). Exact for
    unimodal functions; otherwise a local minimum inside the bracket. Returns (x, f(x)).
    """
    a, b = np.broadcast_arrays(np.asarray(lo, dtype=float), np.asarray(hi, dtype=float))
    a, b = a.copy(), b.copy()
    c = b - _INV_PHI * (b - a)
    d = a + _INV_PHI * (b - a)
    fc, fd = fun(c), fun(d)
    for _ in range(iterations):
        left = fc < fd                                  # the minimum lies in [a, d]
        a, b = np.where(left, a, c), np.where(left, d, b)
        keep_x, keep_f = np.where(left, c, d), np.where(left, fc, fd)
        new_x = np.where(left, b - _INV_PHI * (b - a), a + _INV_PHI * (b - a))
        new_f = fun(new_x)
        c, fc = np.where(left, new_x, keep_x), np.where(left, new_f, keep_f)
        d, fd = np.where(left, keep_x, new_x), np.where(left, keep_f, new_f)
    x = np.where(fc < fd, c, d)
    return x, np.minimum(fc, fd)


# ------------------------------------------------------- eq. 5's spectra for a fixed α --

#: Linear and compressive residuals search α within this factor of the log-residual fit's
#: α (closed form, milliseconds) instead of over the whole range: the profiles of the
#: three residuals have their minima within 10 % of each other on every measurement
#: tried (sample inks, an RGL wrap, an MA-T12 pigment), and each cost evaluation here is
#: a search in c per wavelength (~5 ms) rather than a matrix product.
WARM_ALPHA_FACTOR = 4.0

#: Scan points of that narrower search (every 19 % in α).
WARM_ALPHA_POINTS = 17


class BestPoint:
    """A cost function that counts its calls and keeps the best point it was given (a
    non-finite cost counts as 1e300), and BOBYQA over it from that point."""

    def __init__(self, cost):
        self.cost, self.n, self.x, self.f = cost, 0, None, np.inf

    def __call__(self, v) -> float:
        self.n += 1
        f = self.cost(v)
        f = f if np.isfinite(f) else 1e300
        if f < self.f:
            self.x, self.f = np.array(v, dtype=float), f
        return f

    def bobyqa(self, lo, hi, step, maxeval: int, *, xtol_abs=None, xtol_rel=None,
               ftol_rel=None) -> str:
        """Refine from the best point so far within [lo, hi]; how it stopped, in words
        (the best point evaluated is kept either way)."""
        import nlopt

        opt = nlopt.opt(nlopt.LN_BOBYQA, len(lo))
        opt.set_min_objective(lambda v, grad: self(v))
        opt.set_lower_bounds(list(lo))
        opt.set_upper_bounds(list(hi))
        if xtol_abs is not None:
            opt.set_xtol_abs(list(xtol_abs))
        if xtol_rel is not None:
            opt.set_xtol_rel(xtol_rel)
        if ftol_rel is not None:
            opt.set_ftol_rel(ftol_rel)
        opt.set_maxeval(maxeval)
        opt.set_initial_step(list(step))
        try:
            opt.optimize(np.clip(self.x, lo, hi).tolist())
            if opt.last_optimize_result() == nlopt.MAXEVAL_REACHED:
                return f"stopped after {maxeval} evaluations"
        except nlopt.RoundoffLimited:
            return "stopped at round-off; kept the best point evaluated"
        return "converged"
