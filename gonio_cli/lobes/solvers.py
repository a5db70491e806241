"""Weight solvers of the cosine-lobe fit (seed 001 §4, eqs. 5-6).

:data:`WEIGHT_SOLVERS` (the LP by a warm-started simplex, HiGHS or the compiled simplex;
NNLS; clamped least squares), each ``solve(M, B, time_limit_s) → (X, status, message)``,
with the outcome of a solve (:class:`WeightFit`, :data:`STATUSES`) and its error figures
(:func:`residual_errors`). :func:`gonio_cli.lobes.solve.fit_weights` runs one.
Re-exported by :mod:`gonio_cli.lobes`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..names import pick
from . import LP_TIME_LIMIT_S
from .simplex import lp_l1_simplex, lp_l1_warm, warm_up

# -------------------------------------------------------------------- weight solvers --

#: Outcomes of a weight solve (``WeightFit.status``, and per view in the artifact).
#: Only ``failed`` of the solver whose weights are written is an error; everything else,
#: and every outcome of a comparison solver, is recorded as it is.
STATUSES = {
    "optimal": "the solver's problem solved to optimality",
    "time_limit": "stopped at the time limit: the weights are the best point the solver "
                  "had (feasible, x >= 0) but not the optimum",
    "clamped": "least squares with its negative weights set to 0 (optimal for nothing)",
    "failed": "the solver gave no solution (weights 0)",
}
#: Statuses of a solve that finished its own problem (a ``WeightFit`` with ``success``).
FINISHED = ("optimal", "clamped")


@dataclass
class WeightFit:
    """One weight fit (seed 001 eqs. 5-6), like scipy's ``OptimizeResult``.

    weights : (K, C) float ≥ 0, K = 1 + 2m in :func:`design_matrix` order.
    l1 : Σ over samples and channels of |M x − b| (what the LP minimises).
    rms : sqrt(mean (M x − b)²); rms_relative : sqrt(Σ r² / Σ b²) (scale-free).
    time_s : wall time of the solve; status : a key of :data:`STATUSES`; message : how
    the solver ended. ``success`` is status ≠ failed and ≠ time_limit.
    """

    solver: str
    weights: np.ndarray
    l1: float
    rms: float
    rms_relative: float
    time_s: float
    status: str = "optimal"
    message: str = "solved"

    @property
    def success(self) -> bool:
        return self.status in FINISHED


def _highs(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """min Σ|M x − b| s.t. x ≥ 0 for every column of B, as one LP (seed 001 §4), by HiGHS.

    The L1 objective through slack variables ([Gas84] in seed 001): M x + u − v = b,
    u, v ≥ 0, minimise Σ (u + v); at the optimum u_n v_n = 0, so Σ(u + v) = Σ|r|. All C
    channels are one block-diagonal LP: one HiGHS call, no per-call overhead per channel.
    At the time limit the weights are HiGHS's last point if it has one, else x = 0 (every
    x ≥ 0 is feasible here), with status ``time_limit``.
    """
    from scipy import sparse
    from scipy.optimize import linprog

    N, K = M.shape
    C = B.shape[1]
    block = sparse.hstack([sparse.csr_array(M), sparse.eye_array(N), -sparse.eye_array(N)])
    A = sparse.kron(sparse.eye_array(C), block, format="csc")
    cost = np.tile(np.concatenate([np.zeros(K), np.ones(2 * N)]), C)
    res = linprog(cost, A_eq=A, b_eq=B.T.ravel(), bounds=(0, None), method="highs",
                  options={"time_limit": float(time_limit_s), "presolve": True})
    X = (np.zeros((K, C)) if res.x is None
         else np.maximum(res.x.reshape(C, K + 2 * N)[:, :K].T, 0.0))
    if res.status == 0 and res.x is not None:
        return X, "optimal", "optimal (HiGHS)"
    if res.status == 1:
        return X, "time_limit", (f"HiGHS stopped at its time limit of {time_limit_s:g} s "
                                 f"({res.message.strip()}); "
                                 f"{'its last point' if res.x is not None else 'x = 0'} kept")
    return X, "failed", f"HiGHS failed: {res.message.strip()}"


#: Samples per view above which ``lp`` hands the LP to HiGHS: the dense tableau's work
#: grows ~N³ (N pivots of an N × (K + 2N) tableau), HiGHS's far slower. Measured per view
#: (41 channels, 8 lobes): 19 samples (seed001) 2 ms against HiGHS's 50 ms, 58 (dense)
#: 20 ms against 190 ms, 200 (hemisphere) over 1 s against 0.5 s.
WARM_SIMPLEX_MAX_SAMPLES = 80


def _lp_warm(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """The LP by the warm-started exact simplex of :mod:`gonio_cli.lobes.simplex` (numpy:
    no compiler to load; the channels share M, so each starts from the last optimal
    basis). A channel the simplex cannot certify is re-solved by HiGHS, and so is the
    whole LP when a view has more than :data:`WARM_SIMPLEX_MAX_SAMPLES` samples."""
    if M.shape[0] > WARM_SIMPLEX_MAX_SAMPLES:
        X, status, message = _highs(M, B, time_limit_s)
        return X, status, (f"{message}; by HiGHS: {M.shape[0]} samples per view is above "
                           f"the warm simplex's {WARM_SIMPLEX_MAX_SAMPLES}")
    start = time.perf_counter()
    X, iterations, status = lp_l1_warm(M, B, deadline=start + time_limit_s)
    message = (f"warm-started simplex, {int(iterations.sum())} pivots, "
               f"{int(np.count_nonzero(iterations))} of {B.shape[1]} channels pivoted")
    return _finish_simplex(M, B, X, status, message, start, time_limit_s,
                           "the last optimal basis, clamped to >= 0")


def _lp_simplex(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """The same LP by the compiled dense simplex of :mod:`gonio_cli.lobes.simplex`
    (numba, ~20 µs per channel once loaded); a channel that hits its iteration cap
    (cycling on a degenerate problem) is re-solved by HiGHS."""
    start = time.perf_counter()
    X, iterations, status = lp_l1_simplex(M, B, deadline=start + time_limit_s)
    message = f"dense simplex, {int(iterations.max())} pivots at most"
    return _finish_simplex(M, B, X, status, message, start, time_limit_s, "x = 0")


def _finish_simplex(M, B, X, status, message, start, time_limit_s, unsolved: str):
    """Shared ending of the simplex solvers: channels with status 2 (cap or numerics) go to
    HiGHS with the time left; status 1 (deadline) makes the whole solve ``time_limit``,
    ``unsolved`` saying what those channels' weights are."""
    outcome = "optimal"
    failed = status == 2
    if failed.any():
        left = max(time_limit_s - (time.perf_counter() - start), 1e-3)
        X[:, failed], outcome, note = _highs(M, B[:, failed], left)
        message += f"; {int(failed.sum())} channels re-solved by HiGHS ({note})"
    late = int(np.count_nonzero(status == 1))
    if late:
        return X, "time_limit", (f"stopped at the time limit of {time_limit_s:g} s with "
                                 f"{late} of {B.shape[1]} channels unsolved (their weights: "
                                 f"{unsolved}); {message}")
    return X, outcome, f"{outcome} ({message})"


#: Iterations of Lawson–Hanson per column before scipy's nnls gives up (its default, 3,
#: is hit on nearly collinear lobe columns: E = 3, 8, 20, 50, 120 on a hemisphere view).
#: A solve that converged within 3 per column takes the same path, so its result is the
#: same; one that still does not converge is a ``failed`` status, not a traceback.
NNLS_ITERATIONS_PER_COLUMN = 50


def _nnls(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """Non-negative least squares per channel (scipy.optimize.nnls, Lawson–Hanson)."""
    from scipy.optimize import nnls

    X = np.zeros((M.shape[1], B.shape[1]))
    for c in range(B.shape[1]):
        try:
            X[:, c] = nnls(M, B[:, c], maxiter=NNLS_ITERATIONS_PER_COLUMN * M.shape[1])[0]
        except RuntimeError as exc:         # "Maximum number of iterations reached."
            return X * 0.0, "failed", f"Lawson-Hanson stopped at channel {c}: {exc}"
    return X, "optimal", "optimal (Lawson-Hanson)"


def _lsq_clamp(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """Least squares, then negative weights clamped to 0 (as [KM00]; seed 001 §4 explains
    why it fails: the clamped lobes' error is never corrected by the others)."""
    X = np.linalg.lstsq(M, B, rcond=None)[0]
    clamped = int(np.sum(X < 0))
    return np.maximum(X, 0.0), "clamped", f"{clamped} negative weights clamped to 0"


def _load_compiled_simplex() -> None:
    """Load the numba kernel (disk cache) before the clock and the time limit start."""
    warm_up()


@dataclass(frozen=True)
class WeightSolver:
    """A weight solver: ``solve(M, B, time_limit_s) → (X, status, message)``; ``prepare``
    (optional) runs once before timing (loading a compiled kernel is not solving); ``norm``
    the p of the Σ|r|^p it minimises (1: the LP, 2: least squares), which says how
    quadrature weights scale its rows (w for p = 1, sqrt(w) for p = 2)."""

    solve: Callable
    description: str
    prepare: Callable | None = None
    norm: int = 1


#: Weight solvers by name. ``lp`` (the default) and ``highs`` solve the same LP; ``highs``
#: is the reference the exact simplex solvers are tested against.
WEIGHT_SOLVERS: dict[str, WeightSolver] = {
    "lp": WeightSolver(_lp_warm, "min Σ|Mx − b|, x ≥ 0 (seed 001 §4) by an exact simplex "
                                 "warm-started across channels (numpy), ~1-2 ms per view "
                                 "of seed001's set; by HiGHS above 80 samples per view"),
    "highs": WeightSolver(_highs, "the same LP by scipy's HiGHS (the reference), ~10-50 ms "
                                  "per view, mostly set-up"),
    "lp-simplex": WeightSolver(_lp_simplex, "the same LP by a compiled (numba) dense "
                                            "simplex: fastest per call, ~0.5 s to load",
                               _load_compiled_simplex),
    "nnls": WeightSolver(_nnls, "min Σ(Mx − b)², x ≥ 0: scipy nnls", norm=2),
    "lsq-clamp": WeightSolver(_lsq_clamp, "least squares, negatives clamped to 0 (the failure "
                                          "seed 001 §4 describes)", norm=2),
}
DEFAULT_SOLVER = "lp"


def check_solver(name: str) -> str:
    pick(WEIGHT_SOLVERS, name, "--solver")
    return name


def relative_weights(weight) -> np.ndarray | None:
    """Quadrature weights (N,) sr → the same scaled to mean 1 (None stays None): a sample
    of an equal-area set then counts 1, as in the unweighted sets."""
    if weight is None:
        return None
    w = np.asarray(weight, dtype=float)
    return w / w.mean()


def residual_errors(M: np.ndarray, X: np.ndarray, B: np.ndarray,
                    weight=None) -> tuple[float, float, float]:
    """(L1, RMS, relative RMS) of M X − B over every sample and channel.

    ``weight`` (N,) (quadrature weights, :attr:`Samples.weight`; scaled to mean 1 here)
    makes them sums over solid angle: Σ w|r|, sqrt(Σ w r² / (N C)), sqrt(Σ w r² / Σ w b²).
    None: every sample counts 1 (the figures of the unweighted sets, unchanged)."""
    r = M @ X - B
    w = relative_weights(weight)
    w = np.ones(M.shape[0]) if w is None else w
    total = float(np.sum(w[:, None] * B * B))
    sse = float(np.sum(w[:, None] * r * r))
    return (float(np.sum(w[:, None] * np.abs(r))), float(np.sqrt(sse / r.size)),
            float(np.sqrt(sse / total)) if total > 0 else 0.0)
