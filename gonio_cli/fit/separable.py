"""The separable inner problem of eq. 5's fits: for fixed roughnesses, per wavelength the
best c(λ) and the non-negative linear coefficients (ρ_d, ρ[, ρ_2]) — all wavelengths at once.

:func:`profile_c_columns` is the kernel every evaluation of a layered model's outer search
runs (thousands per ``--model auto``), so its cost is kept to a few matrix products: the
scan over c uses e^{c x} of the scan's grid, which depends on the geometry only and is
computed once per data set (:class:`CScan`), with the lobe's shape g moved to the
right-hand side (E @ (w ∘ t) with E = g e^{c x} is e^{c x} @ (g w ∘ t)).
"""

from __future__ import annotations

import numpy as np

#: Bracket of c(λ) (as the default model's linear-residual search): |c| = 60 makes e^{c x}
#: vary by e^27 between normal and 70° incidence, far past any measured material.
C_LIMIT = 60.0

#: Points of the scan over c that brackets each wavelength's minimum: a cell of 1 in c
#: (e^{x}: the profile cost is smooth on that scale), computed as three matrix products.
C_SCAN_POINTS = 121

#: Safeguarded parabolic steps inside the bracketing cells: the cost is smooth, so each
#: step roughly squares the error; 6 steps take a cell of 1 to a cost within 1e-7 (relative)
#: of the minimum, c within ~1e-3 (checked against an 80-step golden section in the
#: tests), far inside c's own uncertainty from 2 % noise (~0.05).
C_PARABOLA_STEPS = 6

#: Exponent cap inside the c search: e^{c x} with |c x| ≤ 60 squares to e^{120}, finite.
_EXP_CAP = 300.0

#: A determinant of the unit-diagonal 2 × 2 normal matrix below this means the two
#: columns (diffuse and lobe) cannot be told apart: the one-column solutions are used.
_DET_TOL = 1e-12


def nnls2(s_aa, s_ab, s_bb, s_at, s_bt, s_tt):
    """min over a ≥ 0, b ≥ 0 of the quadratic with these normal sums, all arrays at once.

    The cost Σ w (a A + b B − t)² = s_tt − 2 a s_at − 2 b s_bt + a² s_aa + 2ab s_ab + b² s_bb.
    Candidates: both free (if feasible), a alone, b alone; the cheapest wins. Returns
    (a, b, cost) broadcast like the inputs; columns with s = 0 get coefficient 0.
    """
    det = s_aa * s_bb - s_ab * s_ab
    well = det > _DET_TOL * np.maximum(s_aa * s_bb, 1e-300)
    safe = np.where(well, det, 1.0)
    a2 = (s_bb * s_at - s_ab * s_bt) / safe
    b2 = (s_aa * s_bt - s_ab * s_at) / safe
    both = well & (a2 >= 0) & (b2 >= 0)
    cost2 = np.where(both, s_tt - a2 * s_at - b2 * s_bt, np.inf)
    a1 = np.where(s_aa > 0, np.maximum(s_at, 0.0) / np.where(s_aa > 0, s_aa, 1.0), 0.0)
    cost_a = s_tt - a1 * s_at
    b1 = np.where(s_bb > 0, np.maximum(s_bt, 0.0) / np.where(s_bb > 0, s_bb, 1.0), 0.0)
    cost_b = s_tt - b1 * s_bt
    pick_both = cost2 <= np.minimum(cost_a, cost_b)
    pick_a = ~pick_both & (cost_a <= cost_b)
    a = np.where(pick_both, a2, np.where(pick_a, a1, 0.0))
    b = np.where(pick_both, b2, np.where(pick_a, 0.0, b1))
    cost = np.where(pick_both, cost2, np.where(pick_a, cost_a, cost_b))
    return a, b, np.maximum(cost, 0.0)


def profile_c(x, g, t, w, diffuse: bool, c_limit: float = C_LIMIT, diffuse_shape=None):
    """Per wavelength, the best (ρ_d, ρ, c) of ρ_d s/π + ρ g e^{c x} against targets t.

    ``x``, ``g``: (N,) (x = 1 − cos((θi+θo)/2), g = D/4); ``t``, ``w``: (N, L) targets and
    weights; ``diffuse_shape`` s (N,): the diffuse term's angular shape, 1 (Lambertian) if
    None. Without ``diffuse`` ρ_d = 0. Returns ρ_d, ρ, c, cost, each (L,).
    """
    return profile_c_columns(x, g, t, w, diffuse, c_limit, diffuse_shape)[:4]


def profile_c_columns(x, g, t, w, diffuse: bool, c_limit: float = C_LIMIT,
                      diffuse_shape=None, extra=None, scan: "CScan | None" = None):
    """:func:`profile_c` with an optional third non-negative column ``extra`` e (N,), a
    lobe of fixed shape (``goniochromatic-two-lobe``'s second GGX lobe): per wavelength
    the best (ρ_d, ρ, c, ρ_2) of ρ_d s/π + ρ g e^{c x} + ρ_2 e, each c's three-column
    problem solved by :func:`nnls3`. Returns ρ_d, ρ, c, cost, ρ_2 (L,) (ρ_2 = 0 without
    ``extra``; then the figures are :func:`profile_c`'s, from :func:`nnls2`).

    ``scan``: the :class:`CScan` of ``x`` (made once per data set by a caller that
    evaluates many roughnesses): c is then refined on nested lattices, a few matrix
    products (:func:`_refine_on_lattices`); without it, by :data:`C_PARABOLA_STEPS`
    parabolic steps. Both find the scan's bracketed minimum; the lattices to
    :data:`C_FINEST_CELL`.
    """
    x = np.asarray(x, dtype=float)
    g = np.asarray(g, dtype=float)
    a = (np.ones_like(x) if diffuse_shape is None else np.asarray(diffuse_shape, float)) / np.pi
    L = t.shape[1]
    wt = w * t
    wa = w * a[:, None]
    s_aa = np.sum(wa * a[:, None], axis=0) if diffuse else np.zeros(L)
    s_at = np.sum(wa * t, axis=0) if diffuse else np.zeros(L)
    s_tt = np.sum(wt * t, axis=0)
    we = None
    if extra is not None:
        e = np.asarray(extra, dtype=float)
        we = w * e[:, None]
        s_ee, s_et = np.sum(we * e[:, None], axis=0), np.sum(we * t, axis=0)
        s_ae = np.sum(wa * e[:, None], axis=0) if diffuse else np.zeros(L)

    def solve(s_ab, s_bb, s_bt, s_be=None):                  # (ρ_d, ρ, cost, ρ_2)
        if extra is None:
            return (*nnls2(s_aa, s_ab, s_bb, s_at, s_bt, s_tt), 0.0)
        out = nnls3(s_aa, s_ab, s_ae, s_bb, s_be, s_ee, s_at, s_bt, s_et, s_tt)
        return out[0], out[1], out[3], out[2]

    if scan is not None and scan.c_limit == c_limit:
        rho_d, rho, c, cost, rho_2 = _refine_on_lattices(scan, g, w, wa if diffuse else None,
                                                         wt, we, solve)
        return rho_d, rho, c, cost, np.broadcast_to(rho_2, c.shape).astype(float)

    def sums_grid(cs):                                       # (G,) → (G, L) each
        E = g[None, :] * np.exp(np.minimum(np.outer(cs, x), _EXP_CAP))
        sums = (E @ wa if diffuse else np.zeros((cs.size, L)), (E * E) @ w, E @ wt)
        return sums + ((E @ we,) if extra is not None else ())

    def sums_per_column(c):                                   # (L,) → (L,) each
        B = g[:, None] * np.exp(np.minimum(x[:, None] * c[None, :], _EXP_CAP))
        sums = (np.sum(wa * B, axis=0) if diffuse else np.zeros(c.size),
                np.sum(w * B * B, axis=0), np.sum(wt * B, axis=0))
        return sums + ((np.sum(we * B, axis=0),) if extra is not None else ())

    grid = np.linspace(-c_limit, c_limit, C_SCAN_POINTS)
    costs = solve(*sums_grid(grid))[2]                        # (G, L)
    k = np.argmin(costs, axis=0)
    cols = np.arange(costs.shape[1])
    kl, kr = np.maximum(k - 1, 0), np.minimum(k + 1, grid.size - 1)
    c = parabolic_minimum(lambda c: solve(*sums_per_column(c))[2],
                          grid[kl], grid[k], grid[kr],
                          costs[kl, cols], costs[k, cols], costs[kr, cols],
                          C_PARABOLA_STEPS)
    rho_d, rho, cost, rho_2 = solve(*sums_per_column(c))
    return rho_d, rho, c, cost, np.broadcast_to(rho_2, c.shape).astype(float)


#: Each lattice of :func:`_refine_on_lattices` divides the cell of the one before by this
#: and spans ± one of its cells (2 × C_REFINE + 1 points).
C_REFINE = 20

#: Lattices after the scan: cells of 1/20, 1/400, 1/8000 of the scan's cell of 1. The last
#: puts c within 6e-5 of the bracketed minimum, the cost within 3e-7 of it (relative;
#: the parabolic steps: c within ~1e-3, 1e-7), far inside c's uncertainty from
#: 2 % noise (~0.05).
C_REFINE_LEVELS = 3

#: The finest lattice's cell in c (for the docs and tests).
C_FINEST_CELL = 2 * C_LIMIT / (C_SCAN_POINTS - 1) / C_REFINE ** C_REFINE_LEVELS


class CScan:
    """e^{c x} at the points of the c search for one geometry x (N,), computed once: the
    scan's grid (G, N), and each lattice's offsets e^{δ x} (N, P). Every evaluation of a
    layered model's outer search (thousands per ``--model auto``) then needs no
    exponential, only matrix products."""

    def __init__(self, x, c_limit: float = C_LIMIT):
        x = np.asarray(x, dtype=float)
        self.c_limit = c_limit
        self.grid = np.linspace(-c_limit, c_limit, C_SCAN_POINTS)
        self.E = np.exp(np.minimum(np.outer(self.grid, x), _EXP_CAP))      # (G, N)
        self.E2 = self.E * self.E
        cell = self.grid[1] - self.grid[0]
        j = np.arange(-C_REFINE, C_REFINE + 1)
        self.offsets = [cell * j / C_REFINE ** m for m in range(1, C_REFINE_LEVELS + 1)]
        self.D = [np.exp(np.minimum(np.outer(x, d), _EXP_CAP)) for d in self.offsets]
        self.D2T = [np.ascontiguousarray((D * D).T) for D in self.D]
        self.DT = [np.ascontiguousarray(D.T) for D in self.D]


def _refine_on_lattices(scan: CScan, g, w, wa, wt, we, solve):
    """(ρ_d, ρ, c, cost, ρ_2) (L,) of :func:`profile_c_columns` on the lattices of
    ``scan``: the scan's best point per wavelength, then on each lattice the best of the
    2 × :data:`C_REFINE` + 1 points around the last best (points past ±c_limit left out).
    The lobe's sums at c are Σ_n r(n) g(n) e^{c x(n)} for the right-hand sides r = w a,
    w t, w e (and Σ w g² e^{2 c x}): with g moved into r, the scan is e^{c x} @ (g r),
    and a lattice around c is e^{δ x}ᵀ @ (g r ∘ e^{c x}), e^{c x} kept per wavelength."""
    L = wt.shape[1]
    rhs = [r for r in (wa, wt, we) if r is not None]
    R = np.concatenate(rhs, axis=1) * g[:, None]                  # (N, kL)
    R2 = w * (g * g)[:, None]                                      # (N, L)
    k = len(rhs)

    def sums(S, S2):                                              # → solve's arguments
        parts = np.split(S, k, axis=1)
        s_ab = parts[0] if wa is not None else np.zeros_like(S2)
        rest = parts[1:] if wa is not None else parts
        return (s_ab, S2, *rest)

    costs = solve(*sums(scan.E @ R, scan.E2 @ R2))[2]            # (G, L)
    best = np.argmin(costs, axis=0)
    c = scan.grid[best]
    cur = scan.E[best].T                                           # (N, L): e^{c x}
    cols = np.arange(L)
    for level, (DT, D2T, d) in enumerate(zip(scan.DT, scan.D2T, scan.offsets)):
        out = solve(*sums(DT @ (R * np.tile(cur, k)), D2T @ (R2 * cur * cur)))
        inside = np.abs(c[None, :] + d[:, None]) <= scan.c_limit * (1 + 1e-12)
        cost = np.where(inside, out[2], np.inf)                    # (P, L)
        j = np.argmin(cost, axis=0)
        c = c + d[j]
        if level + 1 < len(scan.offsets):
            cur = cur * scan.D[level][:, j]
    pick = (j, cols)
    rho_2 = out[3][pick] if np.ndim(out[3]) else 0.0
    return out[0][pick], out[1][pick], c, out[2][pick], rho_2


def nnls3(s_aa, s_ab, s_ae, s_bb, s_be, s_ee, s_at, s_bt, s_et, s_tt):
    """min over a, b, e ≥ 0 of the quadratic with these normal sums (three columns A, B,
    E), all arrays at once: the cheapest of the unconstrained solution (where it is
    feasible and the columns independent) and :func:`nnls2` on each pair (which tries
    each column alone). The NNLS optimum is the least-squares solution on its set of
    positive coefficients, and every candidate is feasible, so the cheapest is the optimum.
    Returns (a, b, e, cost) broadcast like the inputs.
    """
    # the 3 × 3 normal matrix by cofactors (symmetric)
    c_aa = s_bb * s_ee - s_be * s_be
    c_ab = s_ae * s_be - s_ab * s_ee
    c_ae = s_ab * s_be - s_ae * s_bb
    c_bb = s_aa * s_ee - s_ae * s_ae
    c_be = s_ab * s_ae - s_aa * s_be
    c_ee = s_aa * s_bb - s_ab * s_ab
    det = s_aa * c_aa + s_ab * c_ab + s_ae * c_ae
    well = det > _DET_TOL * np.maximum(s_aa * s_bb * s_ee, 1e-300)
    safe = np.where(well, det, 1.0)
    a3 = (c_aa * s_at + c_ab * s_bt + c_ae * s_et) / safe
    b3 = (c_ab * s_at + c_bb * s_bt + c_be * s_et) / safe
    e3 = (c_ae * s_at + c_be * s_bt + c_ee * s_et) / safe
    all3 = well & (a3 >= 0) & (b3 >= 0) & (e3 >= 0)
    best = np.where(all3, s_tt - a3 * s_at - b3 * s_bt - e3 * s_et, np.inf)
    zero = np.zeros_like(best)
    a, b, e = np.where(all3, a3, zero), np.where(all3, b3, zero), np.where(all3, e3, zero)
    pairs = ((lambda p, q: (p, q, zero), (s_aa, s_ab, s_bb, s_at, s_bt)),
             (lambda p, q: (p, zero, q), (s_aa, s_ae, s_ee, s_at, s_et)),
             (lambda p, q: (zero, p, q), (s_bb, s_be, s_ee, s_bt, s_et)))
    for place, sums in pairs:
        p, q, cost = nnls2(*sums, s_tt)
        better = cost < best
        pa, pb, pe = place(p, q)
        a, b, e = (np.where(better, new, old) for new, old in ((pa, a), (pb, b), (pe, e)))
        best = np.where(better, cost, best)
    return a, b, e, np.maximum(best, 0.0)


def parabolic_minimum(fun, left, mid, right, f_left, f_mid, f_right, steps: int):
    """Refine L bracketed 1-D minima at once by safeguarded parabolic interpolation.

    Each column starts from a bracket left ≤ mid ≤ right with f(mid) ≤ f(left), f(right)
    (a scan's best point and its neighbours). A step evaluates the vertex of the parabola
    through the three points — or, where that vertex is not strictly inside the bracket
    or repeats the middle point, the midpoint of the wider half — and keeps the bracket
    around the best point. ``fun``: (L,) → (L,). Returns the best abscissa (L,).
    """
    l, m, r = (np.array(v, dtype=float) for v in (left, mid, right))
    fl, fm, fr = (np.array(v, dtype=float) for v in (f_left, f_mid, f_right))
    for _ in range(steps):
        d1, d2 = m - l, m - r
        num = d1 * d1 * (fm - fr) - d2 * d2 * (fm - fl)
        den = d1 * (fm - fr) - d2 * (fm - fl)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = m - 0.5 * num / den
        width = r - l
        bad = ~np.isfinite(u) | (u <= l) | (u >= r) | (np.abs(u - m) < 1e-12 * (1 + np.abs(m)))
        u = np.where(bad, np.where(r - m > m - l, (m + r) / 2, (l + m) / 2), u)
        live = width > 0
        fu = fun(np.where(live, u, m))
        better = live & (fu < fm)
        right_side = u > m
        # better: the bracket becomes the old middle and the far end around u
        l_new = np.where(better, np.where(right_side, m, l), np.where(right_side, l, u))
        fl_new = np.where(better, np.where(right_side, fm, fl), np.where(right_side, fl, fu))
        r_new = np.where(better, np.where(right_side, r, m), np.where(right_side, u, r))
        fr_new = np.where(better, np.where(right_side, fr, fm), np.where(right_side, fu, fr))
        m = np.where(better, u, m)
        fm = np.where(better, fu, fm)
        l, fl = np.where(live, l_new, l), np.where(live, fl_new, fl)
        r, fr = np.where(live, r_new, r), np.where(live, fr_new, fr)
    return m


