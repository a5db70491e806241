"""Weight solvers of the cosine-lobe fit (seed 001 §4, eqs. 5-6) and the weight table (§5.2).

:data:`WEIGHT_SOLVERS` (the LP by a warm-started simplex, HiGHS or the compiled simplex;
NNLS; clamped least squares), :func:`fit_weights` for one view and
:func:`fit_weight_table` for every view angle. Re-exported by :mod:`gonio_cli.lobes`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ..errors import FitError
from ..names import pick
from . import LP_TIME_LIMIT_S, UNSEEN_COLUMN, check_exponents, design_matrix, split_weights
from .samples import Samples, target_values

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
    from .simplex import lp_l1_warm

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
    from .simplex import lp_l1_simplex

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


def _nnls(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """Non-negative least squares per channel (scipy.optimize.nnls, Lawson–Hanson)."""
    from scipy.optimize import nnls

    X = np.empty((M.shape[1], B.shape[1]))
    for c in range(B.shape[1]):
        X[:, c] = nnls(M, B[:, c])[0]
    return X, "optimal", "optimal (Lawson-Hanson)"


def _lsq_clamp(M: np.ndarray, B: np.ndarray, time_limit_s: float = LP_TIME_LIMIT_S):
    """Least squares, then negative weights clamped to 0 (as [KM00]; seed 001 §4 explains
    why it fails: the clamped lobes' error is never corrected by the others)."""
    X = np.linalg.lstsq(M, B, rcond=None)[0]
    clamped = int(np.sum(X < 0))
    return np.maximum(X, 0.0), "clamped", f"{clamped} negative weights clamped to 0"


def _load_compiled_simplex() -> None:
    """Load the numba kernel (disk cache) before the clock and the time limit start."""
    from .simplex import warm_up

    warm_up()


@dataclass(frozen=True)
class WeightSolver:
    """A weight solver: ``solve(M, B, time_limit_s) → (X, status, message)``; ``prepare``
    (optional) runs once before timing (loading a compiled kernel is not solving)."""

    solve: Callable
    description: str
    prepare: Callable | None = None


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
    "nnls": WeightSolver(_nnls, "min Σ(Mx − b)², x ≥ 0: scipy nnls"),
    "lsq-clamp": WeightSolver(_lsq_clamp, "least squares, negatives clamped to 0 (the failure "
                                          "seed 001 §4 describes)"),
}
DEFAULT_SOLVER = "lp"


def check_solver(name: str) -> str:
    pick(WEIGHT_SOLVERS, name, "--solver")
    return name


def residual_errors(M: np.ndarray, X: np.ndarray, B: np.ndarray) -> tuple[float, float, float]:
    """(L1, RMS, relative RMS) of M X − B over every sample and channel."""
    r = M @ X - B
    total = float(np.sum(B * B))
    return (float(np.sum(np.abs(r))), float(np.sqrt(np.mean(r * r))),
            float(np.sqrt(np.sum(r * r) / total)) if total > 0 else 0.0)


def check_design(M: np.ndarray, exponents, where: str = "") -> None:
    """Refuse a sample set that leaves a weight undetermined: a column of M (a lobe the
    samples never see, R·V ≤ 0 or underflowing everywhere) with no non-zero value."""
    if M.shape[0] == 0:
        raise FitError(f"{where}the sample set is empty", fix="use a sample set with samples")
    seen = np.max(np.abs(M), axis=0) > UNSEEN_COLUMN
    if not seen.all():
        k = int(np.argmin(seen))
        m = (M.shape[1] - 1) // 2
        what = "the diffuse term" if k == 0 else (
            f"the {'directional-diffuse' if k <= m else 'gloss'} lobe "
            f"E={np.asarray(exponents)[(k - 1) % m]:g}")
        raise FitError(f"{where}no sample sees {what} (its column of seed 001 eq. 6 is "
                       "zero), so the LP cannot determine its weight",
                       fix="add samples near the mirror direction (R·V > 0)")


def fit_weights(M: np.ndarray, B: np.ndarray, solver: str = DEFAULT_SOLVER,
                time_limit_s: float = LP_TIME_LIMIT_S) -> WeightFit:
    """Non-negative weights x (K, C) with M x ≈ B (seed 001 eqs. 5-6).

    Parameters
    ----------
    M : (N, K) float, :func:`design_matrix`; B : (N, C) float, :func:`target_values`.
    solver : a key of :data:`WEIGHT_SOLVERS`; time_limit_s : the LP's time limit.

    Never raises for a solver's outcome: a time limit or a failure is the result's
    ``status`` (:data:`STATUSES`) and ``message``.
    """
    check_solver(solver)
    if not np.all(np.isfinite(B)):
        raise FitError("the target holds NaN or inf at some sample",
                       fix="check the material's parameters")
    entry = WEIGHT_SOLVERS[solver]
    if entry.prepare is not None:
        entry.prepare()
    start = time.perf_counter()
    X, status, message = entry.solve(M, B, time_limit_s)
    elapsed = time.perf_counter() - start
    l1, rms, rel = residual_errors(M, X, B)
    return WeightFit(solver, X, l1, rms, rel, elapsed, status, message)


# --------------------------------------------------------------- weight table (§5.2) --

@dataclass
class WeightTable:
    """Weights per view angle (seed 001 §5.2) and every solver's errors.

    exponents : (m,) ; view_angle_deg : (V,) ; channels : labels (C,)
    diffuse : (V, C) ; directional_diffuse, gloss : (V, m, C), all ≥ 0, sr⁻¹.
    errors : {solver: {"l1", "rms", "rms_relative", "time_s", "status", "message": (V,)
        lists}}, the written solver first, then the comparisons; status per view is a key
        of :data:`STATUSES`.
    n_samples : (V,) samples per view angle.
    """

    exponents: np.ndarray
    view_angle_deg: np.ndarray
    channels: list
    diffuse: np.ndarray
    directional_diffuse: np.ndarray
    gloss: np.ndarray
    errors: dict[str, dict[str, list]]
    n_samples: list
    solver: str
    time_s: float = 0.0


def fit_weight_table(material, exponents, samples: Samples, channels: str = "spectral",
                     solver: str = DEFAULT_SOLVER, compare: Sequence[str] = (),
                     time_limit_s: float = LP_TIME_LIMIT_S) -> WeightTable:
    """Fit the weights at every view angle of ``samples`` (seed 001 §4 and §5.2).

    ``solver`` gives the weights written; every solver in ``compare`` (none by default) is
    also run on the same samples and its errors, time and status reported. A time limit
    reached, by ``solver`` or a comparison, is a status per view (``time_limit``), never
    an error. Raises FitError if a view's samples leave a weight undetermined
    (:func:`check_design`) or ``solver`` itself returns no solution (``failed``).
    """
    e = check_exponents(exponents)
    check_solver(solver)
    for s in compare:
        check_solver(s)
    b_all, labels = target_values(material, samples, channels)
    M_all = design_matrix(samples.cos_theta_i(), samples.cos_rv(), e)
    V, m, C = samples.view_angle_deg.size, e.size, b_all.shape[1]
    X = np.zeros((V, 1 + 2 * m, C))
    solvers = [solver] + [s for s in compare if s != solver]
    keys = ("l1", "rms", "rms_relative", "time_s", "status", "message")
    errors = {s: {key: [] for key in keys} for s in solvers}
    counts = []
    start = time.perf_counter()
    for k, tv in enumerate(samples.view_angle_deg):
        rows = samples.view_index == k
        where = f"view angle {tv:g} deg: "
        M, B = M_all[rows], b_all[rows]
        check_design(M, e, where)
        counts.append(int(rows.sum()))
        for s in solvers:
            r = fit_weights(M, B, s, time_limit_s)
            if s == solver:
                if r.status == "failed":
                    raise FitError(f"{where}the {s} weight solver failed ({r.message})",
                                   fix="try another --solver (e.g. highs)")
                X[k] = r.weights
            for key in keys:
                errors[s][key].append(getattr(r, key))
    parts = split_weights(np.moveaxis(X, 0, 1), m)            # leading axis K → parts
    return WeightTable(e, samples.view_angle_deg, labels, parts["diffuse"],
                       np.moveaxis(parts["directional_diffuse"], 0, 1),
                       np.moveaxis(parts["gloss"], 0, 1), errors, counts, solver,
                       time.perf_counter() - start)
