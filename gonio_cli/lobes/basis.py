"""The exponent basis search of the cosine-lobe fit (seed 001 §3.2, eq. 4) by nlopt.

:func:`select_basis` adds one lobe at a time, minimising :func:`basis_objective` over
log E (nlopt, imported here only). Re-exported by :mod:`gonio_cli.lobes`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np

from ..errors import InputError
from . import EXPONENT_MAX, EXPONENT_MIN, design_matrix
from .samples import Samples
from .solve import fit_weights

# ------------------------------------------------------------ basis selection (§3.2) --

@dataclass
class BasisStep:
    """The best basis of one lobe count (seed 001 Figures 2 and 3).

    exponents : (m,) sorted ; error : eq. 4, max + mean relative RMS over the database ;
    max_error, mean_error : its two terms ; per_material : relative RMS per material ;
    evaluations : objective evaluations ; time_s ; message : how the search ended.
    """

    n_lobes: int
    exponents: np.ndarray
    error: float
    max_error: float
    mean_error: float
    per_material: list
    evaluations: int
    time_s: float
    message: str


@dataclass
class BasisResult:
    steps: list[BasisStep] = field(default_factory=list)
    solver: str = "nnls"
    n_samples: int = 0
    time_s: float = 0.0


#: Solvers the basis search may use inside eq. 4. ``nnls`` minimises the very RMS that
#: eq. 4 measures, so the objective is continuous in E and can only fall when a lobe is
#: added; ``lp-simplex`` (seed 001's LP, the fast exact solver: HiGHS would take minutes
#: over thousands of evaluations) gives vertex solutions that jump with E.
BASIS_SOLVERS = ("nnls", "lp-simplex")

#: nlopt settings of the exponent search (log E): stop when log E moves < 1e-3 (0.1 % in
#: E, far below what changes a prefiltered map) or the objective < 1e-6 relative.
BASIS_XTOL_LOG = 1e-3
BASIS_FTOL_REL = 1e-6
#: Objective evaluations per exponent being searched (the search is m-dimensional).
BASIS_EVALS_PER_LOBE = 150


def basis_objective(log_exponents, cos_theta_i, cos_rv, groups, targets: Sequence[np.ndarray],
                    solver: str = "nnls"):
    """Seed 001 eq. 4: max_i Error(E, B_i) + mean_i Error(E, B_i).

    The weights are fitted per group of samples (one view angle each, as
    :func:`fit_weight_table` will use them, seed 001 §5.2), and Error(E, B_i) is the
    relative RMS sqrt(Σ r² / Σ b²) of material i over every group, sample and channel,
    so bright and dark materials count alike.

    Parameters
    ----------
    log_exponents : (m,) log E ; cos_theta_i, cos_rv, groups : (N,) ; targets : n arrays
    (N, C). Returns (f, per-material errors (n,)).
    """
    M = design_matrix(cos_theta_i, cos_rv, np.exp(np.asarray(log_exponents, dtype=float)))
    errs = np.empty(len(targets))
    for i, B in enumerate(targets):
        sse = sum(np.sum((M[g] @ fit_weights(M[g], B[g], solver).weights - B[g]) ** 2)
                  for g in groups)
        total = float(np.sum(B * B))
        errs[i] = np.sqrt(sse / total) if total > 0 else 0.0
    return float(errs.max() + errs.mean()), errs


def _gap_starts(log_e: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Candidate log-exponents for a new lobe: midpoints of the gaps between the lobes
    already found and the bounds (seed 001 Fig. 2: exponents spread evenly in log E)."""
    points = np.sort(np.concatenate([[lo, hi], log_e]))
    return 0.5 * (points[:-1] + points[1:])


def select_basis(targets: Sequence[np.ndarray], samples: Samples, max_lobes: int = 11,
                 solver: str = "nnls", exponent_range=(EXPONENT_MIN, EXPONENT_MAX),
                 progress: Callable | None = None) -> BasisResult:
    """Choose exponents for 1 … ``max_lobes`` lobes by nlopt over log E (seed 001 §3.2).

    Parameters
    ----------
    targets : n arrays (N, C), each material's b at ``samples`` (the database).
    samples : :class:`Samples`; weights are fitted per view angle (eq. 4's Error).
    max_lobes : the largest lobe count; solver : one of :data:`BASIS_SOLVERS`.
    progress : optional wrapper of the lobe-count loop (a progress bar).

    One lobe is added at a time; each search starts from the lobes already found plus
    the best gap midpoint (:func:`_gap_starts`), and keeps the best point it evaluated,
    so with ``nnls`` (whose residual cannot grow when a column is added) the error never
    rises with the lobe count. nlopt LN_SBPLX (Subplex: derivative-free, robust to the
    kinks the max in eq. 4 makes) on log E within ``exponent_range``.
    """
    import nlopt

    if solver not in BASIS_SOLVERS:
        raise InputError(f"--solver {solver!r} is not usable for the basis search",
                         fix=f"use one of {', '.join(BASIS_SOLVERS)}")
    if not targets:
        raise InputError("no material to choose a basis for", fix="pass MATERIAL.json files")
    if int(max_lobes) < 1:
        raise InputError(f"--max-lobes {max_lobes} is below 1", fix="e.g. --max-lobes 11")
    lo, hi = np.log(exponent_range[0]), np.log(exponent_range[1])
    if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
        raise InputError(f"exponent range {exponent_range} is not 0 < min < max")
    result = BasisResult(solver=solver, n_samples=samples.n_samples)
    cos_theta_i, cos_rv = samples.cos_theta_i(), samples.cos_rv()
    groups = [samples.view_index == k for k in range(samples.view_angle_deg.size)]
    start_all = time.perf_counter()
    log_e = np.empty(0)
    counts = range(1, int(max_lobes) + 1)
    for m in (progress(counts) if progress else counts):
        t0 = time.perf_counter()
        best = {"x": None, "f": np.inf, "errs": None}
        evals = {"n": 0}

        def f(x):
            evals["n"] += 1
            value, errs = basis_objective(x, cos_theta_i, cos_rv, groups, targets, solver)
            if value < best["f"]:
                best.update(x=np.array(x, dtype=float), f=value, errs=errs)
            return value

        for s in _gap_starts(log_e, lo, hi):
            f(np.append(log_e, s))
        x0 = best["x"].copy()
        opt = nlopt.opt(nlopt.LN_SBPLX, m)
        opt.set_min_objective(lambda x, grad: f(x))
        opt.set_lower_bounds([lo] * m)
        opt.set_upper_bounds([hi] * m)
        opt.set_xtol_abs(BASIS_XTOL_LOG)
        opt.set_ftol_rel(BASIS_FTOL_REL)
        opt.set_maxeval(BASIS_EVALS_PER_LOBE * m)
        opt.set_initial_step(0.5)
        try:
            opt.optimize(x0)
            code = opt.last_optimize_result()
            message = {3: "converged (ftol)", 4: "converged (xtol)",
                       5: "stopped at maxeval"}.get(code, f"nlopt result {code}")
        except nlopt.RoundoffLimited:  # round-off stops: the best point evaluated stands
            message = "nlopt stopped (round-off limited); kept the best point"
        log_e = np.sort(best["x"])
        errs = best["errs"]
        if result.steps and best["f"] > result.steps[-1].error:
            message += "; error rose from the previous count (LP vertex jump; use nnls)"
        result.steps.append(BasisStep(m, np.exp(log_e), best["f"], float(errs.max()),
                                      float(errs.mean()), [float(v) for v in errs],
                                      evals["n"], time.perf_counter() - t0, message))
    result.time_s = time.perf_counter() - start_all
    return result
