"""An exact small LP solver for the weights: min Σ|M x − b| s.t. x ≥ 0 (seed 001 §4).

Seed 001 solves eq. 6 by linear programming and asks for real-time rates; HiGHS through
scipy costs ~10 ms per call on a 60 × 17 problem, almost all of it set-up. This is a
dense primal simplex on the same slack form, M x + u − v = b, u, v ≥ 0, minimise Σ(u + v)
([Gas84] in seed 001), compiled with numba: ~0.1 ms per channel. It is exact (a vertex
of the same LP; the tests compare its optimum with HiGHS on many random problems).

Structure used: the v columns are the negatives of the u columns in every tableau
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


def lp_l1_simplex(M: np.ndarray, B: np.ndarray):
    """min Σ|M x − b| s.t. x ≥ 0 for every column b of B, exactly.

    Parameters
    ----------
    M : (N, K) float ; B : (N, C) float, finite.

    Returns
    -------
    X : (K, C) float ≥ 0 ; iterations : (C,) int ; ok : (C,) bool, False where the
    iteration cap stopped a channel (the caller re-solves it with HiGHS).
    """
    M = np.ascontiguousarray(M, dtype=float)
    B = np.asarray(B, dtype=float)
    kernel = _kernel()
    N, K = M.shape
    cap = MAX_ITER_PER_VARIABLE * (N + K)
    X = np.zeros((K, B.shape[1]))
    iterations = np.zeros(B.shape[1], dtype=int)
    ok = np.ones(B.shape[1], dtype=bool)
    for c in range(B.shape[1]):
        x, it, status = kernel(M, np.ascontiguousarray(B[:, c]), cap, PIVOT_TOL, COST_TOL)
        X[:, c], iterations[c], ok[c] = x, it, status == 0
    return X, iterations, ok
