"""Exact small LP solvers for the weights: min Σ|M x − b| s.t. x ≥ 0 (seed 001 §4).

Seed 001 solves eq. 6 by linear programming and asks for real-time rates; HiGHS through
scipy costs ~10 ms per call on a 60 × 17 problem, almost all of it set-up. Both solvers
here work on the same slack form, M x + u − v = b, u, v ≥ 0, minimise Σ(u + v) ([Gas84]
in seed 001), and are exact (a vertex of the same LP; the tests compare their optimum
with HiGHS on many random problems):

:func:`lp_l1_warm`   numpy, warm-started across the channels that share M (the default
                     ``lp`` solver of ``gonio lobes fit``): ~1-2 ms per view angle for
                     41 channels, and nothing to load.
:func:`lp_l1_simplex` a dense primal simplex compiled with numba (``lp-simplex``, used
                     inside the basis search): ~20 µs per channel once loaded, but loading
                     numba and its cached kernel costs ~0.5-1 s per process.

The numba kernel is compiled with ``cache=True``: numba keeps the machine code in
``__pycache__`` beside this file, or, where that folder is read-only (a system install),
in a per-user cache (``NUMBA_CACHE_DIR`` overrides both), so only the first process on a
machine compiles it.

Structure used by the kernel: the v columns are the negatives of the u columns in every tableau
(A_v = −A_u), and their reduced costs are 2 − d_u (both cost 1), so only the x and u
columns are stored. The start basis is the residuals themselves (x = 0, u or v = |b|),
which is feasible, so no phase 1 is needed. Dantzig's rule picks the entering column;
an iteration cap guards against cycling on degenerate problems (the caller then falls
back to HiGHS).
"""

from __future__ import annotations

import functools

import numpy as np

#: Smallest pivot element accepted in the ratio test: M's entries are ≤ 1 (cosines and
#: lobes), so 1e-11 is far below any real entry and far above float64 round-off of the
#: tableau updates (~1e-14 after tens of pivots).
PIVOT_TOL = 1e-11

#: A reduced cost must be below −COST_TOL for its column to enter: costs are 0 or 1, so
#: round-off is ~1e-15 and 1e-10 stops without leaving any real improvement.
COST_TOL = 1e-10

#: Iterations allowed per (sample + weight): a non-degenerate solve takes ~ (N + K) / 2.
MAX_ITER_PER_VARIABLE = 20


def _simplex_l1(M, b, max_iter, pivot_tol, cost_tol):  # pragma: no cover (numba)
    """One channel: (x (K,), iterations, status 0 optimal / 1 iteration cap / 2 fail)."""
    N, K = M.shape
    W = K + N + 1                       # x columns, u columns, right-hand side
    T = np.zeros((N, W))
    Z = np.zeros(W)                     # reduced costs of the x and u columns
    basic = np.empty(N, np.int64)       # k < K: x_k ; K+n: u_n ; K+N+n: v_n
    for n in range(N):
        s = 1.0 if b[n] >= 0 else -1.0
        for k in range(K):
            T[n, k] = s * M[n, k]
        T[n, K + n] = s
        T[n, W - 1] = abs(b[n])
        basic[n] = K + n if s > 0 else K + N + n
    for k in range(K, K + N):
        Z[k] = 1.0
    for n in range(N):
        for k in range(W):
            Z[k] -= T[n, k]
    it = 0
    while it < max_iter:
        best = -cost_tol
        j = -1
        for k in range(K + N):
            if Z[k] < best:
                best = Z[k]
                j = k
        for n in range(N):
            dv = 2.0 - Z[K + n]
            if dv < best:
                best = dv
                j = K + N + n
        if j < 0:
            break
        ju = j if j < K + N else j - N
        sg = 1.0 if j < K + N else -1.0
        r = -1
        rbest = np.inf
        for n in range(N):
            a = sg * T[n, ju]
            if a > pivot_tol:
                q = T[n, W - 1] / a
                if q < rbest:
                    rbest = q
                    r = n
        if r < 0:                       # unbounded: impossible for Σ|r| ≥ 0 unless NaN
            return np.zeros(K), it, 2
        p = sg * T[r, ju]
        for k in range(W):
            T[r, k] /= p
        for n in range(N):
            if n != r:
                f = sg * T[n, ju]
                if f != 0.0:
                    for k in range(W):
                        T[n, k] -= f * T[r, k]
        for k in range(W):
            Z[k] -= best * T[r, k]
        basic[r] = j
        it += 1
    x = np.zeros(K)
    for n in range(N):
        if basic[n] < K:
            x[basic[n]] = max(T[n, W - 1], 0.0)
    return x, it, 1 if it >= max_iter else 0


@functools.lru_cache(maxsize=1)
def _kernel():
    """The numba-compiled kernel (compiled on first use, cached on disk by numba)."""
    import numba

    return numba.njit(cache=True)(_simplex_l1)


@functools.lru_cache(maxsize=1)
def warm_up() -> None:
    """Load (or compile, the first time on a machine) the kernel once per process, by
    solving a 1 × 1 problem: the caller's clock and time limit then measure solving."""
    _kernel()(np.ones((1, 1)), np.ones(1), 10, PIVOT_TOL, COST_TOL)


def lp_l1_simplex(M: np.ndarray, B: np.ndarray, deadline: float | None = None):
    """min Σ|M x − b| s.t. x ≥ 0 for every column b of B, exactly.

    Parameters
    ----------
    M : (N, K) float ; B : (N, C) float, finite.
    deadline : a ``time.perf_counter()`` value checked between channels; channels not
        started by then are left at x = 0 (feasible, not optimal) with status 1.

    Returns
    -------
    X : (K, C) float ≥ 0 ; iterations : (C,) int ; status : (C,) int, 0 optimal, 1 not
    reached by the deadline, 2 stopped by the iteration cap (the caller re-solves those
    with HiGHS).
    """
    import time

    M = np.ascontiguousarray(M, dtype=float)
    B = np.asarray(B, dtype=float)
    kernel = _kernel()
    N, K = M.shape
    cap = MAX_ITER_PER_VARIABLE * (N + K)
    X = np.zeros((K, B.shape[1]))
    iterations = np.zeros(B.shape[1], dtype=int)
    status = np.zeros(B.shape[1], dtype=int)
    for c in range(B.shape[1]):
        if deadline is not None and time.perf_counter() > deadline:
            status[c:] = 1
            break
        x, it, st = kernel(M, np.ascontiguousarray(B[:, c]), cap, PIVOT_TOL, COST_TOL)
        X[:, c], iterations[c], status[c] = x, it, 0 if st == 0 else 2
    return X, iterations, status


# ----------------------------------------------------- warm-started simplex (numpy) --
# The same LP again, for many channels that share M (every wavelength of one view angle,
# seed 001 §5.2), in plain numpy so that ``gonio lobes fit`` needs neither numba (whose
# import and cache load cost ~0.5-1 s per process) nor scipy. Only b changes between
# channels, and the reduced costs of a basis do not depend on b: the optimal basis of one
# channel is dual feasible for the next, so the next channel starts from it by the dual
# simplex, and every channel whose x_B = B⁻¹ b is already ≥ 0 is optimal at once (one
# matrix product for all of them). Neighbouring wavelengths mostly share a basis.

#: A basic variable counts as non-negative down to −FEAS_REL × max|b| of its channel:
#: B⁻¹ is refactorised from the basis columns before it is trusted (round-off ~1e-14
#: relative for these ~20 × 20 well-scaled bases), so 1e-9 accepts nothing infeasible.
FEAS_REL = 1e-9

#: Harris's ratio test lets a basic variable (or reduced cost) go this fraction of its
#: feasibility tolerance below 0 to choose a larger pivot element; 0.1 keeps the result
#: well inside the tolerance the certificate checks.
HARRIS = 0.1

#: Certify-and-continue rounds of :func:`_solve` before a channel is handed to HiGHS.
REFINE_ROUNDS = 3


def _l1_matrix(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A = [M, I, −I] (N, K + 2N) and the cost c = [0, 1, 1] of the slack form."""
    N, K = M.shape
    eye = np.eye(N)
    return np.hstack([M, eye, -eye]), np.concatenate([np.zeros(K), np.ones(2 * N)])


class _Basis:
    """A basis of the slack-form LP as a full tableau T = B⁻¹ [A | b] (N, W + 1) and its
    reduced costs d (W,); B⁻¹ itself is T's u columns (A_u = I). Rebuilt from the basis
    columns (:meth:`refactor`) before it is trusted, so round-off never accumulates."""

    def __init__(self, A: np.ndarray, c: np.ndarray, basic: np.ndarray, b: np.ndarray):
        self.A, self.c, self.basic = A, c, np.asarray(basic, dtype=np.int64)
        self.K = A.shape[1] - 2 * A.shape[0]
        self.refactor(b)

    def refactor(self, b: np.ndarray) -> None:
        N, W = self.A.shape
        Binv = np.linalg.inv(self.A[:, self.basic])
        self.T = np.empty((N, W + 1))
        self.T[:, :W] = Binv @ self.A
        self.T[:, W] = Binv @ b
        self.d = self.c - self.c[self.basic] @ self.T[:, :W]
        self.d[self.basic] = 0.0

    @property
    def Binv(self) -> np.ndarray:
        return self.T[:, self.K:self.K + self.A.shape[0]]

    def set_rhs(self, b: np.ndarray) -> None:
        self.T[:, -1] = self.Binv @ b

    def pivot(self, r: int, j: int) -> None:
        """Column j enters at row r."""
        T = self.T
        p = T[r] / T[r, j]
        T -= T[:, j, None] * p
        T[r] = p
        self.d -= self.d[j] * p[:-1]
        self.d[j] = 0.0
        self.basic[r] = j


def _ratio_test(num: np.ndarray, den: np.ndarray, allowed: np.ndarray, slack: float) -> int:
    """Harris's two-pass ratio test over ``allowed`` (den > 0 there): the largest step
    t = min (num + slack)/den that keeps every num − t·den ≥ −slack, then, of the columns
    whose num/den ≤ t, the one with the largest pivot element den. Degenerate problems
    (an exact fit has many zero residuals) otherwise pivot on tiny elements and the
    tableau loses its accuracy. −1 if nothing is allowed."""
    q = np.full(num.shape, np.inf)
    np.divide(num + slack, den, out=q, where=allowed)
    t = q.min()
    if t == np.inf:
        return -1
    np.divide(num, den, out=q, where=allowed)
    return int(np.where(q <= t, den, -np.inf).argmax())


def _primal(basis: _Basis, tol: float, max_iter: int) -> int | None:
    """Primal simplex (Dantzig) from a primal-feasible basis; pivots, or None at the cap."""
    for it in range(max_iter + 1):
        d = basis.d
        j = int(d.argmin())
        if d[j] >= -COST_TOL:
            return it
        if it == max_iter:
            return None
        alpha = basis.T[:, j]
        r = _ratio_test(basis.T[:, -1], alpha, alpha > PIVOT_TOL, HARRIS * tol)
        if r < 0:                           # unbounded: impossible for Σ|r| ≥ 0
            return None
        basis.pivot(r, j)
    return None


def _dual(basis: _Basis, tol: float, max_iter: int) -> int | None:
    """Dual simplex from a dual-feasible basis until x_B ≥ −tol; pivots, or None."""
    for it in range(max_iter + 1):
        x_b = basis.T[:, -1]
        r = int(x_b.argmin())
        if x_b[r] >= -tol:
            return it
        if it == max_iter:
            return None
        minus_row = -basis.T[r, :-1]
        allowed = minus_row > PIVOT_TOL
        allowed[basis.basic] = False        # basic columns are unit vectors: never enter
        j = _ratio_test(basis.d, minus_row, allowed, HARRIS * COST_TOL)
        if j < 0:                           # primal infeasible: impossible (x = 0 is)
            return None
        basis.pivot(r, j)
    return None


def _solve(method, basis: _Basis, b: np.ndarray, tol: float, cap: int) -> int | None:
    """Run ``_primal`` or ``_dual``, then certify from a fresh B⁻¹: primal (x_B ≥ −tol)
    and dual (d ≥ −COST_TOL) feasible is optimal. If round-off left only one of the two,
    the simplex that keeps it goes on (a few rounds). Pivots, or None (cap, numerical
    failure or no certificate)."""
    total = 0
    for _ in range(REFINE_ROUNDS):
        its = method(basis, tol, cap - total)
        if its is None:
            return None
        total += its
        try:
            basis.refactor(b)
        except np.linalg.LinAlgError:       # a singular basis: round-off took a bad pivot
            return None
        primal_ok = basis.T[:, -1].min() >= -tol
        dual_ok = basis.d.min() >= -COST_TOL
        if primal_ok and dual_ok:
            return total
        if not (primal_ok or dual_ok):
            return None
        method = _primal if primal_ok else _dual
    return None


def lp_l1_warm(M: np.ndarray, B: np.ndarray, deadline: float | None = None):
    """min Σ|M x − b| s.t. x ≥ 0 for every column b of B, exactly, warm-started.

    The first channel is solved by the primal simplex from the residual basis (x = 0);
    each later one from the last optimal basis by the dual simplex; a channel is accepted
    only when a freshly factorised basis is primal and dual feasible (an optimality
    certificate), and then every other channel it is also optimal for is accepted with it.

    Parameters
    ----------
    M : (N, K) float ; B : (N, C) float, finite.
    deadline : a ``time.perf_counter()`` value; channels not reached by then are left
        not optimal (``status`` 1) with the weights of the last basis clamped to ≥ 0
        (any x ≥ 0 is feasible for this LP).

    Returns
    -------
    X : (K, C) float ≥ 0 ; iterations : (C,) int, pivots spent on each channel ;
    status : (C,) int, 0 optimal, 1 stopped by the deadline, 2 iteration cap or numerical
    failure (the caller re-solves those with HiGHS).
    """
    import time

    M = np.asarray(M, dtype=float)
    B = np.asarray(B, dtype=float)
    N, K = M.shape
    C = B.shape[1]
    A, c = _l1_matrix(M)
    cap = MAX_ITER_PER_VARIABLE * (N + K)
    tol = FEAS_REL * np.max(np.abs(B), axis=0)
    X = np.zeros((K, C))
    iterations = np.zeros(C, dtype=int)
    status = np.zeros(C, dtype=int)
    pending = np.arange(C)
    basis = None
    while pending.size:
        ch = int(pending[0])
        b = B[:, ch]
        if deadline is not None and time.perf_counter() > deadline:
            if basis is not None:
                xb = basis.Binv @ B[:, pending]
                on_x = basis.basic < K
                X[basis.basic[on_x][:, None], pending] = np.maximum(xb[on_x], 0.0)
            status[pending] = 1
            break
        its = None
        if basis is not None:
            basis.set_rhs(b)
            its = _solve(_dual, basis, b, tol[ch], cap)
        if its is None:                     # cold start: the residuals (x = 0) are the basis
            basis = _Basis(A, c, np.where(b >= 0, K + np.arange(N), K + N + np.arange(N)), b)
            its = _solve(_primal, basis, b, tol[ch], cap)
            if its is None:
                status[ch] = 2
                basis = None
                pending = pending[1:]
                continue
        iterations[ch] = its
        xb = basis.Binv @ B[:, pending]
        done = xb.min(axis=0) >= -tol[pending]
        done[0] = True                      # ch itself, certified above
        on_x = basis.basic < K
        cols = pending[done]
        X[basis.basic[on_x][:, None], cols] = np.maximum(xb[on_x][:, done], 0.0)
        pending = pending[~done]
    return X, iterations, status
