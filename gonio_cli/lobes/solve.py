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
from . import (ALBEDO_FLOOR_REL, ENERGY_EXCESS_MAX, ENERGY_EXCESS_WARN, LOBE_RESOLVED_MIN,
               LP_TIME_LIMIT_S,
               UNSEEN_COLUMN, check_exponents, design_matrix, lobe_integral, split_weights)
from .samples import Samples, directional_albedo, target_values

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
    from .simplex import warm_up

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


def lobe_half_width_deg(exponents) -> np.ndarray:
    """The angle (deg) from its axis at which a lobe (R·V)^E falls to
    :data:`LOBE_RESOLVED_MIN` of its peak: acos(LOBE_RESOLVED_MIN^(1/E)) (the half-width
    at half maximum, ≈ sqrt(2 ln 2 / E) rad). ``exponents`` (...) → (...)."""
    e = np.asarray(exponents, dtype=float)
    return np.degrees(np.arccos(np.exp(np.log(LOBE_RESOLVED_MIN) / e)))


def resolved_lobes(M: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Which lobes a view's samples resolve (:data:`LOBE_RESOLVED_MIN`).

    M : (N, 1 + 2m), :func:`design_matrix` of one view: its gloss columns are the lobes'
    values (R·V)^E themselves. Returns (peak (m,): each lobe's largest value over the
    samples, in [0, 1]; resolved (m,) bool: peak ≥ LOBE_RESOLVED_MIN)."""
    m = (M.shape[1] - 1) // 2
    peak = (M[:, 1 + m:].max(axis=0) if M.shape[0] else np.zeros(m))
    return peak, peak >= LOBE_RESOLVED_MIN


def lobe_columns(resolved: np.ndarray) -> np.ndarray:
    """Column indices of :func:`design_matrix` kept when only the ``resolved`` (m,) lobes
    are fitted: the diffuse column and each resolved lobe's two columns."""
    m = resolved.size
    idx = np.flatnonzero(resolved)
    return np.concatenate([[0], 1 + idx, 1 + m + idx]).astype(int)


def check_design(M: np.ndarray, exponents, where: str = "",
                 offset_deg: float | None = None) -> np.ndarray:
    """Refuse a view whose samples leave the fit undetermined, and say which lobes they
    resolve (:func:`resolved_lobes`).

    Refused (FitError): no sample; the diffuse column zero everywhere (no light above the
    horizon); no lobe resolved at all (no sample within the widest lobe's half-width of
    the mirror direction: the fit would have no gloss). ``offset_deg``: the nearest
    sample's angle from the mirror direction, for the message. Returns resolved (m,) bool.
    """
    if M.shape[0] == 0:
        raise FitError(f"{where}the sample set is empty", fix="use a sample set with samples")
    if not np.max(np.abs(M[:, 0])) > UNSEEN_COLUMN:
        raise FitError(f"{where}no sample sees the diffuse term (every light is below the "
                       "horizon), so the fit cannot determine its weight",
                       fix="use lights above the horizon (theta_i_deg inside (-85, 85))")
    e = np.asarray(exponents, dtype=float)
    _, resolved = resolved_lobes(M)
    if not resolved.any():
        widest = float(e.min())
        near = "" if offset_deg is None else f" (the nearest is {offset_deg:.3g} deg away)"
        raise FitError(f"{where}no sample sees any lobe within its half-width of the mirror "
                       f"direction{near}: the widest, E={widest:g}, needs one within "
                       f"{float(lobe_half_width_deg(widest)):.2g} deg, so no lobe weight "
                       "can be determined",
                       fix="add samples near the mirror direction (R.V near 1), e.g. "
                           "--samples seed001 or --samples hemisphere --mirror-dense")
    return resolved


def fit_weights(M: np.ndarray, B: np.ndarray, solver: str = DEFAULT_SOLVER,
                time_limit_s: float = LP_TIME_LIMIT_S, weight=None) -> WeightFit:
    """Non-negative weights x (K, C) with M x ≈ B (seed 001 eqs. 5-6).

    Parameters
    ----------
    M : (N, K) float, :func:`design_matrix`; B : (N, C) float, :func:`target_values`.
    solver : a key of :data:`WEIGHT_SOLVERS`; time_limit_s : the LP's time limit.
    weight : (N,) quadrature weights (:attr:`Samples.weight`) or None. With weights the
        solver minimises Σ w |r|^p, a quadrature of ∫ |r|^p dω (rows scaled by w, or
        sqrt(w) for least squares: :attr:`WeightSolver.norm`), and the errors are the
        weighted ones of :func:`residual_errors`.

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
    w = relative_weights(weight)
    if w is None:
        Ms, Bs = M, B
    else:
        scale = (w if entry.norm == 1 else np.sqrt(w))[:, None]
        Ms, Bs = M * scale, B * scale
    start = time.perf_counter()
    X, status, message = entry.solve(Ms, Bs, time_limit_s)
    elapsed = time.perf_counter() - start
    l1, rms, rel = residual_errors(M, X, B, w)
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
    unresolved : (V, m) bool, lobes left out of a view's fit (weight 0) because no sample
        resolves them (:func:`resolved_lobes`); lobe_peak : (V, m) each lobe's largest
        value over the view's samples; mirror_offset_deg : (V,) the nearest sample's angle
        from each view's mirror direction.
    albedo : (V, C) the material's directional albedo (:func:`directional_albedo`);
        energy_terms : (V, 1 + 2m, C) what each written weight holds (:func:`lobe_energy`),
        energy : (V, C) their sum.
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
    unresolved: np.ndarray | None = None
    lobe_peak: np.ndarray | None = None
    mirror_offset_deg: np.ndarray | None = None
    albedo: np.ndarray | None = None
    energy: np.ndarray | None = None
    energy_terms: np.ndarray | None = None


def lobe_energy(exponents, view_angle_deg, diffuse, directional_diffuse, gloss) -> np.ndarray:
    """What each fitted term sends towards the viewer under unit radiance from everywhere,
    as the renderer integrates it (module docstring; seed 001 eqs. 7-9 with P_E = 1):
    π K_D, cos θv K_DD,i 2π/(E_i+1) (R·N = cos θv) and K_G,i 2π/(E_i+1).

    diffuse (V, C), directional_diffuse and gloss (V, m, C) → (V, 1 + 2m, C) in
    :func:`design_matrix`'s column order (unitless, comparable with the albedo)."""
    integral = lobe_integral(exponents)[None, :, None]
    cos_v = np.cos(np.radians(np.asarray(view_angle_deg, dtype=float)))[:, None, None]
    return np.concatenate([np.pi * np.asarray(diffuse)[:, None, :],
                           cos_v * integral * np.asarray(directional_diffuse),
                           integral * np.asarray(gloss)], axis=1)


def energy_excess(energy: np.ndarray, albedo: np.ndarray) -> np.ndarray:
    """(V, C) fitted energy (summed over terms) ÷ the albedo, each channel's albedo floored
    at :data:`ALBEDO_FLOOR_REL` of its view's brightest (0 where the view is black)."""
    floor = ALBEDO_FLOOR_REL * albedo.max(axis=1, keepdims=True)
    ref = np.maximum(albedo, floor)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(ref > 0, energy / np.where(ref > 0, ref, 1.0),
                        np.where(energy > 0, np.inf, 0.0))


def _term_name(k: int, exponents) -> str:
    m = len(exponents)
    if k == 0:
        return "the diffuse term"
    kind = "directional-diffuse" if k <= m else "gloss"
    return f"the {kind} lobe E={float(exponents[(k - 1) % m]):g}"


def energy_note(table: WeightTable, limit: float = ENERGY_EXCESS_WARN) -> str | None:
    """The sentence that says the weights hold more than ``limit`` × the light the material
    reflects, at the worst view angle and channel (the ratio, the integral against the
    albedo, the term holding most of it, its weight); None when they do not."""
    ratio = energy_excess(table.energy, table.albedo)
    worst = float(np.nanmax(ratio, initial=0.0))
    if not worst > limit:
        return None
    v, c = np.unravel_index(int(np.nanargmax(ratio)), ratio.shape)
    terms = table.energy_terms
    k = int(np.argmax(terms[v, :, c]))
    e = table.exponents
    m = len(e)
    weight = (table.diffuse[v, c] if k == 0 else (table.directional_diffuse[v, k - 1, c]
              if k <= m else table.gloss[v, k - 1 - m, c]))
    label = table.channels[c]
    channel = f"{label:g} nm" if isinstance(label, float) else str(label)
    return (f"view angle {table.view_angle_deg[v]:g} deg: the fitted lobes hold {worst:.3g}x "
            f"the light the material reflects at {channel} (their integral "
            f"{table.energy[v, c]:.3g} against its albedo {table.albedo[v, c]:.3g}), "
            f"{terms[v, k, c] / table.energy[v, c]:.0%} of it in {_term_name(k, e)} (weight "
            f"{weight:.3g} /sr), so a render would be that much too bright there; fit on "
            "samples that hold the gloss's energy (--samples hemisphere --mirror-dense) or "
            "use lobes as sharp as the material's gloss (gonio lobes basis on it)")


def check_energy(table: WeightTable, max_ratio: float = ENERGY_EXCESS_MAX) -> None:
    """Refuse weights that hold more than ``max_ratio`` (:data:`ENERGY_EXCESS_MAX`) × the
    light the material reflects at some view angle and channel: FitError with
    :func:`energy_note`'s sentence (view, channel, ratio, the term holding most of it)."""
    note = energy_note(table, max_ratio)
    if note is not None:
        worst = float(np.nanmax(energy_excess(table.energy, table.albedo)))
        text, _, fix = note.rpartition("; ")
        raise FitError(f"{text} (limit {max_ratio:g}x)",
                       fix=f"{fix}, or accept it with --max-energy-ratio {_round_up(worst):g}")


def _round_up(x: float) -> float:
    """``x`` rounded up to two significant digits (21.39 → 22, 5.1e13 → 5.2e13)."""
    if not np.isfinite(x) or x <= 0:
        return x
    step = 10.0 ** (np.floor(np.log10(x)) - 1)
    return float(np.ceil(x / step) * step)


def unresolved_notes(table: WeightTable, sample_set_name: str) -> list[str]:
    """One sentence per lobe left out of some view's fit (``table.unresolved``): its
    exponent, the view angles, its half-width and the nearest sample's distance from the
    mirror direction, and the fix for this kind of sample set. Empty when none was."""
    if table.unresolved is None or not table.unresolved.any():
        return []
    notes = []
    for i in np.flatnonzero(table.unresolved.any(axis=0)):
        e = float(table.exponents[i])
        views = np.flatnonzero(table.unresolved[:, i])
        angles = ", ".join(f"{table.view_angle_deg[k]:g}" for k in views)
        near = np.asarray(table.mirror_offset_deg)[views]
        width = float(lobe_half_width_deg(e))
        if str(sample_set_name).lower().endswith(".csv"):
            fix = (f"add samples within {width:.2g} deg of the mirror configuration "
                   f"(theta_i_deg = theta_o_deg) at those views to {sample_set_name}")
        elif str(sample_set_name) == "hemisphere":
            fix = "add --mirror-dense (lights down to 0.07 deg from the mirror direction)"
        else:
            fix = "use samples nearer the mirror direction (--samples seed001)"
        nearest = (f"{near.min():.2g}" if f"{near.min():.2g}" == f"{near.max():.2g}"
                   else f"{near.min():.2g}-{near.max():.2g}")
        notes.append(f"lobe E={e:g} left out (weight 0) at view angle(s) {angles} deg: no "
                     f"sample lies within its half-width {width:.2g} deg of the mirror "
                     f"direction (nearest {nearest} deg), so the "
                     f"samples cannot fix its weight; {fix}, or use fewer, wider lobes "
                     "(--lobes N or --exponents)")
    return notes


#: Samples per view per :data:`LP_TIME_LIMIT_S` of the default time limit: HiGHS takes
#: ~0.5 s for 200 samples × 41 channels and ~0.7-1.5 s for the ~340 of ``--mirror-dense``
#: (measured on 2 busy cores), so 100 per second leaves it twice that.
TIME_LIMIT_SAMPLES_PER_S = 100


def default_time_limit_s(samples: Samples) -> float:
    """The LP's default time limit per view: :data:`LP_TIME_LIMIT_S` per
    :data:`TIME_LIMIT_SAMPLES_PER_S` samples of the largest view, at least LP_TIME_LIMIT_S
    (seed001's ~20 samples: 1 s; hemisphere 2 s; with ``--mirror-dense`` ~3.4 s)."""
    per_view = np.bincount(samples.view_index).max() if samples.n_samples else 0
    return LP_TIME_LIMIT_S * max(1.0, per_view / TIME_LIMIT_SAMPLES_PER_S)


def fit_weight_table(material, exponents, samples: Samples, channels: str = "spectral",
                     solver: str = DEFAULT_SOLVER, compare: Sequence[str] = (),
                     time_limit_s: float = LP_TIME_LIMIT_S,
                     max_energy_ratio: float = ENERGY_EXCESS_MAX) -> WeightTable:
    """Fit the weights at every view angle of ``samples`` (seed 001 §4 and §5.2).

    ``solver`` gives the weights written; every solver in ``compare`` (none by default) is
    also run on the same samples and its errors, time and status reported. A time limit
    reached, by ``solver`` or a comparison, is a status per view (``time_limit``), never
    an error. A lobe the view's samples do not resolve (:func:`resolved_lobes`) is left
    out of that view's fit (weight 0; ``unresolved``, and noted in the view's message).
    Samples with quadrature weights are fitted and measured with them (:func:`fit_weights`).

    Raises FitError if a view's samples leave the fit undetermined (:func:`check_design`),
    ``solver`` itself returns no solution (``failed``), or the weights hold more than
    ``max_energy_ratio`` × the material's albedo (:func:`check_energy`; inf: no check).
    Above :data:`ENERGY_EXCESS_WARN` × it is only a note (:func:`energy_note`).
    """
    e = check_exponents(exponents)
    check_solver(solver)
    for s in compare:
        check_solver(s)
    b_all, labels = target_values(material, samples, channels)
    M_all = design_matrix(samples.cos_theta_i(), samples.cos_rv(), e)
    V, m, C = samples.view_angle_deg.size, e.size, b_all.shape[1]
    X = np.zeros((V, 1 + 2 * m, C))
    unresolved = np.zeros((V, m), bool)
    peaks = np.zeros((V, m))
    offsets = samples.mirror_offset_deg() if samples.n_samples else np.zeros(V)
    solvers = [solver] + [s for s in compare if s != solver]
    keys = ("l1", "rms", "rms_relative", "time_s", "status", "message")
    errors = {s: {key: [] for key in keys} for s in solvers}
    counts = []
    start = time.perf_counter()
    for k, tv in enumerate(samples.view_angle_deg):
        rows = samples.view_index == k
        where = f"view angle {tv:g} deg: "
        M, B = M_all[rows], b_all[rows]
        weight = None if samples.weight is None else samples.weight[rows]
        resolved = check_design(M, e, where, float(offsets[k]) if rows.any() else None)
        peaks[k], unresolved[k] = resolved_lobes(M)[0], ~resolved
        cols = lobe_columns(resolved)
        note = ("" if resolved.all() else "; left out (unresolved, weight 0): E=" +
                ", ".join(f"{v:g}" for v in e[~resolved]))
        counts.append(int(rows.sum()))
        for s in solvers:
            r = fit_weights(M[:, cols], B, s, time_limit_s, weight)
            if s == solver:
                if r.status == "failed":
                    raise FitError(f"{where}the {s} weight solver failed ({r.message})",
                                   fix="try another --solver (e.g. highs)")
                X[k][cols] = r.weights
            r.message += note
            for key in keys:
                errors[s][key].append(getattr(r, key))
    parts = split_weights(np.moveaxis(X, 0, 1), m)            # leading axis K → parts
    table = WeightTable(e, samples.view_angle_deg, labels, parts["diffuse"],
                        np.moveaxis(parts["directional_diffuse"], 0, 1),
                        np.moveaxis(parts["gloss"], 0, 1), errors, counts, solver,
                        time.perf_counter() - start, unresolved, peaks, offsets)
    table.energy_terms = lobe_energy(e, table.view_angle_deg, table.diffuse,
                                     table.directional_diffuse, table.gloss)
    table.energy = table.energy_terms.sum(axis=1)
    table.albedo = directional_albedo(material, table.view_angle_deg, channels)
    check_energy(table, max_energy_ratio)
    return table
